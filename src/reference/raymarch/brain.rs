//! The raymarch twin's brain mask (issue 27): tissues classified inside it, the head layer
//! outside, as the GPU's BRAIN variant does (classification.glsl `brain_weight`). Split from
//! `mod.rs` by concern.

use super::inputs::check_values;
use super::{ReferenceError, ReferenceRaymarch};

impl<'a> ReferenceRaymarch<'a> {
    /// Classifies tissues inside a brain mask (DVR; issue 27), as the GPU does where the
    /// derived volumes hold a mask in use: `mask` (0 or 1 per working voxel, the GPU's R8 mask
    /// read back, on the working grid of `factors`-voxel blocks) is sampled as
    /// `reference::brain_mask` says and weighs the tissues, `1 - mask` the head layer
    /// (`Classification::classify_masked`).
    pub fn with_brain_mask(
        mut self,
        mask: &'a [f64],
        dims: [usize; 3],
        factors: [u32; 3],
    ) -> Result<Self, ReferenceError> {
        check_values("brain mask", dims.map(|d| d as u32), mask, |v| {
            (0.0..=1.0).contains(v)
        })?;
        self.brain_mask = Some(crate::reference::brain_mask::WorkingMask {
            values: mask,
            dims,
            factors,
        });
        Ok(self)
    }
}
