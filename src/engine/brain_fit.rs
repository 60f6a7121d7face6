//! The tissue fit inside the brain mask (issue 28, item 2): once brain extraction has run and
//! its mask is used, the tissue mixture is refitted to the histogram of the voxels inside the
//! mask, and the windows follow that fit.
//!
//! Decisions:
//! - A host pass: the mask (a few hundred kB on the working grid) is read back and exported to
//!   the volume's grid by nearest lookup (`WorkingMask::export_nearest`: each voxel its block;
//!   the trilinear export `derive --maps brain` writes cost about 250 ms of chris_t1's first
//!   pixel on this machine, and differs only in a half-block rim), and each voxel inside is normalized with the
//!   volume's own `imin`/`imax` (eq. 1 in f64, then f32 and the kernel's binning, as
//!   `reference::histogram_of_samples` does). No new GPU pass, no volume-sized readback.
//! - A bright-CSF head's mask leaves the outer CSF out; the fit then reads the first, open-band
//!   mask, kept on the host (`BrainMask::fit_mask`, `engine/brain_extract.rs` says why).
//! - Frame 0 of the stored samples (what the histogram kernel saw); a denoised volume's
//!   histogram is still the raw one inside the mask, which differs only by the filter's noise.
//! - The fit replaces the windows only when it is sound (`analysis::tissue_fit::is_sound`); the
//!   whole-volume analysis (peaks, Table-1 row) is unchanged, and the report's `fit` says that
//!   the brain mask decided.

use super::Engine;
use super::readback::read_image;
use super::twin::Twin;
use crate::analysis::{FitDomain, TissueReport, WindowsFrom, tissue_fit};
use crate::gpu::{Access, GpuResult};
use crate::reference::BINS;
use crate::reference::brain_mask::WorkingMask;
use crate::reference::tissue_fit::histogram_inside_mask;
use crate::volume::Volume;

/// Refits `report`'s tissue classes to `hist` (the histogram inside the brain); true when the
/// windows changed.
pub fn refit_report(report: &mut TissueReport, hist: &[u32; BINS]) -> bool {
    let h = crate::analysis::spikes::cap_top_bin(&hist.map(f64::from));
    let from = ((report.background_threshold * BINS as f64) as usize).max(1);
    let (first, last) = tissue_fit::occupied_range(&h, from);
    let contrast = report.contrast.contrast;
    let Some((fit, mixture)) = tissue_fit::fit_tissues(
        &h,
        (first, last),
        contrast,
        FitDomain::BrainMask,
        (report.imin, report.imax),
    ) else {
        return false;
    };
    if !fit.sound {
        // The windows stay where they were; the report shows the rejected fit beside them.
        report.rejected_fit = Some(fit);
        return false;
    }
    report.fit = Some(fit);
    report.adaptive_windows = crate::analysis::windows_from_fit(
        &mixture,
        contrast,
        (report.background_threshold * BINS as f64) as usize,
        &report.params,
    );
    report.windows_from = WindowsFrom::Fit;
    report.fallback = None;
    true
}

impl Engine {
    /// Refits `report` inside the brain mask `twin` holds, when it holds one that is used (module
    /// doc); true when the windows changed, so the caller rebuilds its scene.
    pub fn refit_in_brain(
        &self,
        volume: &Volume,
        twin: &Twin,
        report: &mut TissueReport,
    ) -> GpuResult<bool> {
        if !crate::analysis::fits_tissues_for(&report.modality, report.contrast.kind) {
            return Ok(false);
        }
        let Some(brain) = twin.derived().and_then(|d| d.brain.as_ref()) else {
            return Ok(false);
        };
        let (true, Some(image)) = (brain.used, &brain.image) else {
            return Ok(false);
        };
        let _span = crate::files::trace::span("tissue fit in the brain mask", "prepare");
        let values: Vec<f64> = match &brain.fit_mask {
            Some(fit_mask) => fit_mask.iter().map(|&v| f64::from(v)).collect(),
            None => read_image(self.device(), image, Access::ComputeSampled)?
                .values
                .iter()
                .map(|&v| f64::from(v))
                .collect(),
        };
        let mask = WorkingMask {
            values: &values,
            dims: image.extent().map(|d| d as usize),
            factors: brain.factors,
        };
        // Every second voxel along each axis: an eighth of the work (on the first pixel's path)
        // and still hundreds of thousands of brain voxels for 256 bins.
        let hist = histogram_inside_mask(volume.voxel_grid(), &mask, 2, (report.imin, report.imax));
        Ok(refit_report(report, &hist))
    }
}
