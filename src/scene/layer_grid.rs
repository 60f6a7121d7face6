//! A layer's voxels on its own grid (issue 31 item 4): physical values, the map from the base
//! volume's index space into the layer's, the data's default window, cluster removal, the
//! 16-bit encoding the GPU samples, trilinear sampling (the f64 twin of the shader's) and the
//! blend over a slice.
//!
//! Decisions:
//! - **The layer keeps its own grid**: nothing is resampled on the host. A base-volume index
//!   position `p` maps to the layer's index position `q = A_layer^-1 A_base p` (composed once in
//!   f64); the GPU samples the layer's texture there trilinearly, the slices and the twin here.
//!   Outside the layer's grid (beyond the outer voxels' half-voxel border, where a clamped
//!   sampler would smear the edge outwards) nothing is drawn.
//! - **Values in physical units** (after the file's scaling); NaN and infinities, which SPM and
//!   FSL write outside the brain, read as 0 (counted, so a client can say it).
//! - **16-bit unsigned normalized texels** over the layer's [min, max]: trilinear filtering of
//!   that format is core Vulkan everywhere (32-bit float filtering is not), a step of
//!   (max - min) / 65535 (2e-4 in a z-map of range +-6.5); the twin samples the same codes.

use super::layer::{LayerDefaults, LayerError, LayerStyle, LayerTables};
use super::slice::IndexGrid;
use crate::volume::Volume;
use glam::{DMat4, DVec3, DVec4};

/// A layer's voxels on its own grid.
#[derive(Clone, Debug, PartialEq)]
pub struct LayerGrid {
    /// The file's name.
    pub name: String,
    /// Voxels along i, j, k (x fastest).
    pub dims: [usize; 3],
    /// Index to world (mm), column-major.
    pub to_world: DMat4,
    /// Physical values (non-finite ones as 0).
    pub values: Vec<f32>,
    /// How many voxels were not finite.
    pub non_finite: usize,
}

/// A layer's texels: 16-bit codes and the map back to values (`lo + scale * code / 65535`).
#[derive(Clone, Debug, PartialEq)]
pub struct LayerCodes {
    /// One code per voxel, x fastest.
    pub codes: Vec<u16>,
    /// The value of code 0.
    pub lo: f64,
    /// The value of code 65535 minus `lo`.
    pub scale: f64,
}

impl LayerCodes {
    /// The value a code stands for (as the GPU's unorm read and decode computes it).
    pub fn value(&self, code: u16) -> f64 {
        self.lo + self.scale * f64::from(code) / 65535.0
    }
}

impl LayerGrid {
    /// The layer `volume` (frame 0), in physical units.
    pub fn from_volume(volume: &Volume) -> Result<LayerGrid, LayerError> {
        let to_world = DMat4::from_cols_array_2d(&volume.orientation.affine).transpose();
        let det = to_world.determinant();
        if !det.is_finite() || det.abs() < 1e-300 {
            return Err(LayerError::Singular(volume.name.clone()));
        }
        let mut non_finite = 0;
        let values = (0..volume.samples.len())
            .map(|i| {
                let v = volume.to_physical.apply(volume.samples.get(i));
                if v.is_finite() {
                    v as f32
                } else {
                    non_finite += 1;
                    0.0
                }
            })
            .collect();
        Ok(LayerGrid {
            name: volume.name.clone(),
            dims: volume.dims,
            to_world,
            values,
            non_finite,
        })
    }

    /// Base-volume index position -> this layer's index position, for a base volume whose
    /// index-to-world matrix is `base_to_world` (row-major, as `Orientation::affine`).
    pub fn index_map(&self, base_to_world: &[[f64; 4]; 4]) -> DMat4 {
        let base = DMat4::from_cols_array_2d(base_to_world).transpose();
        self.to_world.inverse() * base
    }

    /// The data's default window (module decisions of `scene::layer`).
    pub fn defaults(&self) -> LayerDefaults {
        let mut magnitudes: Vec<f32> = self
            .values
            .iter()
            .filter(|v| **v != 0.0)
            .map(|v| v.abs())
            .collect();
        if magnitudes.is_empty() {
            return LayerDefaults {
                lo: 0.5,
                hi: 1.0,
                two_sided: false,
            };
        }
        magnitudes.sort_unstable_by(f32::total_cmp);
        let at =
            |q: f64| f64::from(magnitudes[((magnitudes.len() - 1) as f64 * q).round() as usize]);
        let (lo, mut hi) = (at(0.95), at(0.995));
        if hi <= lo {
            hi = lo + lo.abs().max(1e-6);
        }
        let two_sided = self.values.iter().any(|&v| f64::from(v) <= -lo);
        LayerDefaults { lo, hi, two_sided }
    }

    /// The values `style` draws from: clusters smaller than `style.cluster` set to 0; returns
    /// them with the number of clusters kept and removed (0, 0 without a cluster size).
    pub fn clustered(&self, style: &LayerStyle) -> (LayerGrid, (usize, usize)) {
        let mut grid = self.clone();
        if style.cluster <= 1 {
            return (grid, (0, 0));
        }
        let (threshold, negative) = (style.threshold as f32, style.negative.is_some());
        let side = |v: f32| {
            if v >= threshold {
                1
            } else if negative && v <= -threshold {
                -1
            } else {
                0
            }
        };
        let counts = crate::volume::clusters::remove_small_clusters(
            &mut grid.values,
            grid.dims,
            side,
            style.cluster as usize,
            0.0,
        );
        (grid, counts)
    }

    /// The 16-bit codes of the values (module decisions).
    pub fn codes(&self) -> LayerCodes {
        let (lo, hi) = self
            .values
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        let (lo, hi) = (f64::from(lo), f64::from(hi));
        let scale = if hi > lo { hi - lo } else { 1.0 };
        let codes = self
            .values
            .iter()
            .map(|&v| {
                ((f64::from(v) - lo) / scale * 65535.0)
                    .round()
                    .clamp(0.0, 65535.0) as u16
            })
            .collect();
        LayerCodes { codes, lo, scale }
    }

    /// Whether layer index position `q` lies on the grid (module decisions).
    pub fn covers(&self, q: DVec3) -> bool {
        (0..3).all(|a| q[a] >= -0.5 && q[a] <= self.dims[a] as f64 - 0.5)
    }
}

/// Trilinear interpolation of `value(i, j, k)` on a `dims` grid at index position `q`, indices
/// clamped to the grid (a clamp-to-edge sampler's rule); the caller checks coverage.
pub fn trilinear(dims: [usize; 3], q: DVec3, value: impl Fn(usize, usize, usize) -> f64) -> f64 {
    let base = q.floor();
    let f = q - base;
    let clamp = |c: f64, a: usize| (c.max(0.0) as usize).min(dims[a] - 1);
    let mut sum = 0.0;
    for corner in 0..8 {
        let o = [corner & 1, (corner >> 1) & 1, corner >> 2];
        let idx: [usize; 3] = std::array::from_fn(|a| clamp(base[a] + o[a] as f64, a));
        let w: f64 = (0..3)
            .map(|a| if o[a] == 1 { f[a] } else { 1.0 - f[a] })
            .product();
        sum += w * value(idx[0], idx[1], idx[2]);
    }
    sum
}

/// The layer value at layer index position `q` from its 16-bit codes (the GPU's sample), None
/// off the grid.
pub fn sample_codes(grid: &LayerGrid, codes: &LayerCodes, q: DVec3) -> Option<f64> {
    if !grid.covers(q) {
        return None;
    }
    let [nx, ny, _] = grid.dims;
    let code = |i: usize, j: usize, k: usize| f64::from(codes.codes[i + nx * (j + ny * k)]);
    Some(codes.value(0) + codes.scale * trilinear(grid.dims, q, code) / 65535.0)
}

/// Blends the layer over the RGBA slice `rgba` whose pixels lie at the base volume's index
/// positions `slice` (`index_map` from [`LayerGrid::index_map`]); returns the pixels drawn.
pub fn blend_layer_slice(
    rgba: &mut [u8],
    slice: &IndexGrid,
    layer: (&LayerGrid, &LayerCodes, DMat4),
    style: &LayerStyle,
    tables: &LayerTables,
) -> usize {
    let (grid, codes, index_map) = layer;
    let mut drawn = 0;
    for y in 0..slice.height as usize {
        for x in 0..slice.width as usize {
            let p = DVec4::new(
                slice.origin[0] + x as f64 * slice.du[0] + y as f64 * slice.dv[0],
                slice.origin[1] + x as f64 * slice.du[1] + y as f64 * slice.dv[1],
                slice.origin[2] + x as f64 * slice.du[2] + y as f64 * slice.dv[2],
                1.0,
            );
            let q = (index_map * p).truncate();
            let Some(rgb) = sample_codes(grid, codes, q).and_then(|v| style.colour_of(v, tables))
            else {
                continue;
            };
            let at = 4 * (y * slice.width as usize + x);
            for c in 0..3 {
                let grey = f64::from(rgba[at + c]);
                let mixed = grey * (1.0 - style.opacity) + f64::from(rgb[c]) * style.opacity;
                rgba[at + c] = mixed.round() as u8;
            }
            drawn += 1;
        }
    }
    drawn
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::layer::LayerSpec;
    use crate::volume::{LinearMap, Samples};

    fn layer(dims: [usize; 3], affine: [[f64; 4]; 4], values: Vec<f32>) -> LayerGrid {
        let volume = Volume::from_voxels(
            "layer",
            dims,
            Samples::from_f32(&values),
            affine,
            LinearMap::IDENTITY,
        )
        .unwrap();
        LayerGrid::from_volume(&volume).unwrap()
    }

    fn scaled(s: f64, t: [f64; 3]) -> [[f64; 4]; 4] {
        [
            [s, 0.0, 0.0, t[0]],
            [0.0, s, 0.0, t[1]],
            [0.0, 0.0, s, t[2]],
            [0.0, 0.0, 0.0, 1.0],
        ]
    }

    #[test]
    fn a_coarser_shifted_layer_is_read_at_the_same_world_point() {
        // Layer: 2 mm voxels starting at world (1, 1, 1); base: 1 mm voxels from 0.
        let mut values = vec![0.0f32; 27];
        values[1 + 3 * (1 + 3)] = 8.0; // layer voxel (1,1,1) = world (3, 3, 3)
        let grid = layer([3, 3, 3], scaled(2.0, [1.0; 3]), values);
        let m = grid.index_map(&scaled(1.0, [0.0; 3]));
        let q = (m * DVec4::new(3.0, 3.0, 3.0, 1.0)).truncate();
        assert!((q - DVec3::ONE).length() < 1e-12);
        let codes = grid.codes();
        let v = sample_codes(&grid, &codes, q).unwrap();
        assert!((v - 8.0).abs() < 1e-3, "{v}");
        // Half-way to the next layer voxel: half the value (trilinear).
        let half = sample_codes(&grid, &codes, DVec3::new(1.5, 1.0, 1.0)).unwrap();
        assert!((half - 4.0).abs() < 1e-3, "{half}");
        assert!(sample_codes(&grid, &codes, DVec3::new(-0.6, 0.0, 0.0)).is_none());
        assert!(sample_codes(&grid, &codes, DVec3::new(2.5, 2.5, 2.5)).is_some());
    }

    #[test]
    fn non_finite_values_read_as_zero_and_defaults_see_both_sides() {
        let mut values: Vec<f32> = (0..100).map(|i| i as f32 / 10.0).collect();
        values[0] = f32::NAN;
        values[1] = -9.5;
        let grid = layer([100, 1, 1], scaled(1.0, [0.0; 3]), values);
        assert_eq!(grid.non_finite, 1);
        assert_eq!(grid.values[0], 0.0);
        let d = grid.defaults();
        assert!(d.lo > 9.0 && d.hi > d.lo && d.two_sided, "{d:?}");
    }

    #[test]
    fn clusters_below_the_size_are_gone_before_drawing() {
        let mut values = vec![0.0f32; 64];
        values[0] = 5.0; // a lone voxel
        for i in [40, 41, 42] {
            values[i] = 5.0; // a run of three
        }
        let grid = layer([4, 4, 4], scaled(1.0, [0.0; 3]), values);
        let style = LayerSpec::parse("x:red-yellow:1:5:cluster=2")
            .unwrap()
            .style_for(&grid.defaults())
            .unwrap();
        let (kept, counts) = grid.clustered(&style);
        assert_eq!(counts, (1, 1));
        assert_eq!(kept.values[0], 0.0);
        assert_eq!(kept.values[41], 5.0);
    }
}
