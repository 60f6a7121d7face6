//! f64 twin of `shaders/include/layers.glsl`: intensity layers in the DVR raymarch.
//!
//! Same rules as the shader: a sample's base index position maps to the layer's index position
//! through the layer's index map; off the grid (beyond the outer voxels' half-voxel border)
//! nothing is drawn; on it the value is the trilinear interpolation of the 16-bit codes the GPU
//! holds, decoded; `LayerStyle::colour_of` picks the side and the table entry; the opacity per
//! mm is the layer's, corrected for the step; with shading, the normal is the side-signed central
//! difference over one base voxel per axis (0 off the grid) mapped to world by the gradient
//! matrix. The GPU filters in f32 (and some devices with 8-bit sub-texel weights), so a sample
//! within rounding of the threshold can fall on the other side: comparisons allow a few pixels.

use super::ReferenceRaymarch;
use super::formulas::{composite, opacity_correct};
use crate::scene::layer::{LayerStyle, LayerTables};
use crate::scene::layer_grid::{LayerCodes, LayerGrid, sample_codes};
use glam::{DMat3, DMat4, DVec3, DVec4};

/// One layer as a render target holds it: its grid and codes, the map from the base volume's
/// index space into the layer's, and its style.
#[derive(Clone, Copy, Debug)]
pub struct ReferenceLayer<'a> {
    /// The voxels (as drawn: clusters removed).
    pub grid: &'a LayerGrid,
    /// Their 16-bit codes (`LayerGrid::codes`).
    pub codes: &'a LayerCodes,
    /// Base index position -> layer index position (`LayerGrid::index_map`).
    pub index_map: DMat4,
    /// How it is drawn.
    pub style: LayerStyle,
}

impl ReferenceLayer<'_> {
    fn value(&self, p: DVec3) -> Option<f64> {
        let q = (self.index_map * DVec4::from((p, 1.0))).truncate();
        sample_codes(self.grid, self.codes, q)
    }

    /// The colour (unshaded, RGB in [0, 1]), step-corrected opacity and world shading normal
    /// (zero without `shading`) the layer adds at base index position `p`, or None.
    pub fn sample(
        &self,
        p: DVec3,
        tables: &LayerTables,
        gradient_to_world: DMat3,
        shading: bool,
        opacity_exponent: f64,
    ) -> Option<([f64; 3], f64, DVec3)> {
        let v = self.value(p)?;
        let rgb = self.style.colour_of(v, tables)?;
        if self.style.opacity <= 0.0 {
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
        let opacity = f64::from(self.style.opacity as f32);
        Some((
            rgb.map(|c| f64::from(c) / 255.0),
            opacity_correct(opacity, opacity_exponent),
            normal,
        ))
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
