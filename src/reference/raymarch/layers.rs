//! f64 twin of `shaders/include/layers.glsl`: intensity layers in the DVR raymarch.
//!
//! Same rules as the shader: a sample's base index position maps to the layer's index position
//! through the layer's index map; off the grid (beyond the outer voxels' half-voxel border)
//! nothing is drawn; on it the value is the trilinear interpolation of the 16-bit codes the GPU
//! holds, decoded; the side and the table entry follow `scene::layer`'s rule (written again here, so the
//! twin checks it rather than shares it); the opacity per
//! mm is the layer's, corrected for the step; with shading, the normal is the side-signed central
//! difference over one base voxel per axis (0 off the grid) mapped to world by the gradient
//! matrix. The GPU filters in f32 (and some devices with 8-bit sub-texel weights), so a sample
//! within rounding of the threshold can fall on the other side: comparisons allow a few pixels.

use super::ReferenceRaymarch;
use super::formulas::{composite, opacity_correct};
use glam::{DMat3, DMat4, DVec3, DVec4};

/// Entries of a colour table per side (as `scene::layer::LAYER_LUT_ENTRIES`).
const ENTRIES: usize = 256;

/// One layer as a render target holds it, in plain numbers (the twin takes no scene types, so
/// it checks them rather than shares them): its 16-bit codes on its own grid, how they decode,
/// the map from the base volume's index space into the layer's, and how it is drawn.
#[derive(Clone, Copy, Debug)]
pub struct ReferenceLayer<'a> {
    /// Voxels along i, j, k.
    pub dims: [usize; 3],
    /// One code per voxel, x fastest.
    pub codes: &'a [u16],
    /// Value of code 0 and the value span of codes 0..65535.
    pub decode: [f64; 2],
    /// Base index position -> layer index position.
    pub index_map: DMat4,
    /// lo, hi (the map's ends) and the threshold on |v|.
    pub window: [f64; 3],
    /// Opacity per mm of a drawn sample.
    pub opacity: f64,
    /// RGBA8 words (as `unpackUnorm4x8` reads them) of the positive side's 256 entries.
    pub positive: &'a [u32],
    /// The negative side's 256 entries; None: values below 0 are not drawn.
    pub negative: Option<&'a [u32]>,
}

impl ReferenceLayer<'_> {
    /// The decoded trilinear value at layer index position `q`, None off the grid.
    fn value_at(&self, q: DVec3) -> Option<f64> {
        let covered = (0..3).all(|a| q[a] >= -0.5 && q[a] <= self.dims[a] as f64 - 0.5);
        if !covered || self.codes.len() != self.dims.iter().product::<usize>() {
            return None;
        }
        let base = q.floor();
        let f = q - base;
        let mut code = 0.0;
        for corner in 0..8 {
            let o = [corner & 1, (corner >> 1) & 1, corner >> 2];
            let idx: [usize; 3] = std::array::from_fn(|a| {
                ((base[a] + o[a] as f64).max(0.0) as usize).min(self.dims[a] - 1)
            });
            let w: f64 = (0..3)
                .map(|a| if o[a] == 1 { f[a] } else { 1.0 - f[a] })
                .product();
            code +=
                w * f64::from(self.codes[idx[0] + self.dims[0] * (idx[1] + self.dims[1] * idx[2])]);
        }
        Some(self.decode[0] + self.decode[1] * code / 65535.0)
    }

    fn value(&self, p: DVec3) -> Option<f64> {
        self.value_at((self.index_map * DVec4::from((p, 1.0))).truncate())
    }

    /// The RGB (0..1) value `v` is drawn with, None where it is not drawn.
    fn colour_of(&self, v: f64) -> Option<[f64; 3]> {
        let [lo, hi, threshold] = self.window;
        let (table, x) = if v >= threshold {
            (self.positive, (v - lo) / (hi - lo))
        } else {
            match self.negative {
                Some(table) if v <= -threshold => (table, (-v - lo) / (hi - lo)),
                _ => return None,
            }
        };
        let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
        let entry = ((x * (ENTRIES - 1) as f64 + 0.5).floor() as usize).min(ENTRIES - 1);
        let word = *table.get(entry)?;
        Some([0, 8, 16].map(|shift| f64::from((word >> shift) & 0xff) / 255.0))
    }

    /// The colour (unshaded, RGB in [0, 1]), step-corrected opacity and world shading normal
    /// (zero without `shading`) the layer adds at base index position `p`, or None.
    pub fn sample(
        &self,
        p: DVec3,
        gradient_to_world: DMat3,
        shading: bool,
        opacity_exponent: f64,
    ) -> Option<([f64; 3], f64, DVec3)> {
        let v = self.value(p)?;
        let rgb = self.colour_of(v)?;
        if self.opacity <= 0.0 {
            return None;
        }
        let mut normal = DVec3::ZERO;
        if shading {
            let side = if v >= 0.0 { 1.0 } else { -1.0 };
            let mut d = DVec3::ZERO;
            for axis in 0..3 {
                let e = DVec3::from_array(std::array::from_fn(|a| f64::from(u8::from(a == axis))));
                d[axis] = self.value(p + e).unwrap_or(0.0) - self.value(p - e).unwrap_or(0.0);
            }
            normal = gradient_to_world * (0.5 * side * d);
        }
        // The GPU stores opacity in f32.
        let opacity = f64::from(self.opacity as f32);
        Some((rgb, opacity_correct(opacity, opacity_exponent), normal))
    }
}

impl ReferenceRaymarch<'_> {
    /// Each drawn layer's medium, before the tissue and the label at the same position (the
    /// shader's order); the first drawn layer's normal is the surface normal so far.
    pub(super) fn composite_layers(
        &self,
        acc: &mut [f64; 4],
        normal: &mut DVec3,
        layers: &[Option<([f64; 3], f64, DVec3)>],
        (solid, view_direction): (bool, DVec3),
    ) {
        let mut drew = false;
        for (colour, opacity, layer_normal) in layers.iter().flatten() {
            // On a cut face unshaded, as the tissue there.
            let layer_normal = if solid { &DVec3::ZERO } else { layer_normal };
            let colour = if self.shading {
                if !drew {
                    *normal = *layer_normal;
                }
                self.lit(*colour, *layer_normal, view_direction)
            } else {
                *colour
            };
            composite(acc, colour, *opacity);
            drew = true;
        }
    }
}
