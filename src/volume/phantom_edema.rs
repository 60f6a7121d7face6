//! The phantom's perilesional edema (issue 15 item 6): a low-contrast shell around the lesion,
//! with its own label ([`super::phantom::Tissue::Edema`]), to measure whether the lesion stays
//! visible through it (tests/phantom_edema.rs, ACCURACY.md "Lesion through edema").
//!
//! Decisions:
//! - Intensity 720: T1-hypointense relative to WM (850) but above GM (600). Vasogenic edema is
//!   white matter with extra extracellular water, which lengthens T1 and darkens it on a T1w
//!   image; mild edema stays brighter than cortex. 130 raw units below WM is 6.5 noise sigmas:
//!   visible on a slice, but inside the GM-WM gap of the histogram (too few voxels to make a
//!   mode), so the adaptive windows do not move and it is "low contrast" for the classifier.
//! - Geometry: a sphere shell from the lesion's surface out by max(4 mm, 2 voxels), in the
//!   phantom's scaled mm. The floor keeps a ring at least two voxels wide around the lesion on
//!   small test grids (the lesion itself has a 2-voxel floor), so its footprint can be measured.
//! - Blended in nesting order after the ventricles and before the lesion, with the same one-voxel
//!   ramp as every structure, so it replaces WM around the lesion and the lesion replaces it.

/// Nominal raw intensity of the edema (module doc).
pub const EDEMA_NOMINAL: f64 = 720.0;

/// Thickness of the shell in phantom mm, before the floor.
pub const EDEMA_THICKNESS_MM: f64 = 4.0;

/// Smallest thickness in voxels.
pub const EDEMA_FLOOR_VOXELS: f64 = 2.0;

/// Thickness in voxels for a phantom whose mm is `voxels_per_mm` voxels.
pub(super) fn thickness(voxels_per_mm: f64) -> f64 {
    (EDEMA_THICKNESS_MM * voxels_per_mm).max(EDEMA_FLOOR_VOXELS)
}

/// Signed distance (voxels, > 0 inside) to the edema's outer surface, at `distance` voxels
/// from the lesion's centre; the lesion's own layer then covers the inner part.
pub(super) fn inside(distance: f64, lesion_radius: f64, thickness: f64) -> f64 {
    lesion_radius + thickness - distance
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edema_lies_between_gm_and_wm_and_has_a_floor() {
        let n = super::super::phantom::NOMINAL;
        assert!(n.gm < EDEMA_NOMINAL && EDEMA_NOMINAL < n.wm);
        assert_eq!(thickness(1.0), 4.0);
        assert_eq!(thickness(0.25), 2.0);
        assert_eq!(inside(6.0, 4.5, 4.0), 2.5);
    }
}
