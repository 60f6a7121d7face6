//! Another frame of a 4-D volume prepared like the frame on screen: the viewer's cine
//! (`app::viewer::cine`) changes frame without opening the file again.
//!
//! Decisions:
//! - "Prepare these samples with the same analysis": the new frame is uploaded and normalized
//!   with the physical range of the frame first shown (`passes::normalize::plan_physical` with
//!   this frame's own stored-to-physical map), so one I_norm value means the same scanner value
//!   in every frame and the first frame's analysis (peaks, tissue windows, the look) stays valid:
//!   the picture does not flicker from frame to frame. Values beyond that range clip at its ends,
//!   as the robust range already clips the brightest voxels.
//! - Skipped, because the analysis is kept: min/max, the robust range's passes, the histogram
//!   and its analysis. The histogram fields are the first frame's (what the histogram panel and
//!   the windows were made from). One submission: upload, normalize.
//! - Derived volumes: the same outputs as the frame on screen holds, recomputed from the new
//!   I_norm, except the brain mask, which is shared (`Arc`) with the first frame (brain
//!   extraction is the slowest pass, and a mask that moved from frame to frame would make the
//!   picture flicker).
//! - Whole volumes only: a bricked volume's residency depends on its own values (the caller
//!   opens those frames the full way, `Engine::open_with`), and so does a first frame whose
//!   normalization is constant (no range to keep).

use super::Engine;
use super::brain::BrainMask;
use super::derive::Derived;
use super::prepare::{PrepareTimings, PreparedVolume, VolumeLayout, normalized_desc};
use super::upload::upload_samples;
use crate::gpu::{GpuError, GpuResult, Image, Recording};
use crate::passes::brain::BrainSwitch;
use crate::passes::derivatives::DerivativeOutputs;
use crate::passes::normalize::plan_physical;
use crate::volume::Volume;
use std::sync::Arc;
use std::time::Instant;

impl Engine {
    /// `volume` (another frame of the volume `old` is: same grid) uploaded and normalized with
    /// `old`'s range, with `old`'s histogram and analysis (module decisions). An
    /// `InvalidRequest` for a bricked `old`, a constant one, or a frame of another grid.
    pub fn prepare_frame(
        &mut self,
        volume: &Volume,
        old: &PreparedVolume,
    ) -> GpuResult<PreparedVolume> {
        let start = Instant::now();
        check_like(volume, old)?;
        let (Some(lo), Some(hi)) = (old.normalization.imin, old.normalization.imax) else {
            return Err(not_frame("the frame on screen has no finite range"));
        };
        let normalization = plan_physical(old.dims, lo, hi, volume.to_physical);
        let device = self.device.clone();
        let kind = volume.samples.kind();
        let normalized = Image::new(&device, normalized_desc(old.dims, old.normalized.format()))?;
        let mut rec = Recording::new(&device, "frame: upload and normalize")?;
        let before_upload = Instant::now();
        let (samples, upload_path) = upload_samples(&device, &mut rec, &volume.samples)?;
        let upload_ms = ms(before_upload);
        let before_normalize = Instant::now();
        let passes = self.kind_passes(kind)?;
        passes.normalize.record_for_sampling(
            &mut rec,
            &samples,
            &normalization.params,
            &normalized,
        )?;
        let gpu_timings = rec.submit()?.wait()?;
        let prepared = PreparedVolume {
            dims: old.dims,
            kind,
            upload_path,
            normalized,
            layout: VolumeLayout::Whole,
            stored_range: None,
            normalization,
            range: old.range,
            histogram: old.histogram,
            tissue_histogram: old.tissue_histogram,
            mask_edge_voxels: old.mask_edge_voxels,
            voxel_count: old.voxel_count,
            finite_voxels: old.finite_voxels,
            linear_part: old.linear_part,
            affine: old.affine,
            identity: old.identity.clone(),
            gpu_timings,
            timings: PrepareTimings {
                upload_ms,
                normalize_ms: ms(before_normalize),
                wall_ms: ms(start),
                ..PrepareTimings::default()
            },
            brick_ranges: std::sync::OnceLock::new(),
        };
        Ok(prepared)
    }

    /// The derived volumes `outputs` of a frame made by [`Engine::prepare_frame`]: recomputed,
    /// except the brain mask, which is `brain` (the first frame's, shared) when `outputs` asks
    /// for one.
    pub fn derive_frame(
        &mut self,
        prepared: &PreparedVolume,
        outputs: DerivativeOutputs,
        brain: Option<Arc<BrainMask>>,
    ) -> GpuResult<Derived> {
        let wanted = outputs.brain;
        let share = wanted != BrainSwitch::Off && brain.is_some();
        let computed = DerivativeOutputs {
            brain: if share { BrainSwitch::Off } else { wanted },
            ..outputs
        };
        let mut derived = self.derive(prepared, computed)?;
        if share {
            derived.brain = brain;
            derived.volumes.outputs.brain = wanted;
        }
        Ok(derived)
    }
}

/// `volume` can be prepared like `old`: a whole, non-constant volume of the same grid.
fn check_like(volume: &Volume, old: &PreparedVolume) -> GpuResult<()> {
    if !matches!(old.layout, VolumeLayout::Whole) {
        return Err(not_frame("the frame on screen is bricked"));
    }
    if old.normalization.constant {
        return Err(not_frame(
            "the frame on screen has a constant normalization",
        ));
    }
    let dims = volume.dims.map(|d| d as u64);
    let samples = volume.samples.len() as u64;
    if dims != old.dims.map(u64::from) || samples != old.voxel_count {
        return Err(not_frame(&format!(
            "a frame of {:?} voxels is not a frame of the {:?} volume on screen",
            volume.dims, old.dims
        )));
    }
    Ok(())
}

fn not_frame(why: &str) -> GpuError {
    GpuError::InvalidRequest(format!("cannot prepare it as another frame: {why}"))
}

/// Milliseconds since `since`.
fn ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}
