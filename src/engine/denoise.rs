//! Denoising a prepared volume before its derivatives (`passes::denoise`).
//!
//! Decision: the result is a new [`PreparedVolume`] whose I_norm is the filtered volume and
//! whose analysis (range, histogram) is the original's, so every later step (derive,
//! vesselness, render) takes it unchanged. Whole volumes only: the filters read up to 5 voxels
//! across brick faces, more than the atlas halo holds, so a bricked volume is a typed error
//! (on the open path before the host preparation starts, naming `--denoise`).
//! - On the open path (`SceneRecipe::denoise`, `--denoise` of render/view/bench/plan) the
//!   denoised I_norm *replaces* the original: the original is dropped as soon as the pass is
//!   done, so what is held while rendering is unchanged, and only the preparation's peak holds
//!   both (plus the Gaussian's two R32F scratch volumes); the plan counts them as transient.
//!   Measured with `morphray plan --json` on a 48^3 phantom (lavapipe): the ledger holds
//!   8857744 bytes after set-up with none, median and gaussian:1 alike; the planned peak is
//!   9103224, 9398136 and 10282872 bytes.

use super::Engine;
use super::open::OpenError;
use super::prepare::{PreparedVolume, VolumeLayout};
use crate::gpu::{GpuError, GpuResult, Recording};
use crate::passes::denoise::{Denoise, DenoisePass};
use crate::scene::SceneRecipe;

/// Why a bricked volume is not denoised, and what to do (the command line's names).
const BRICKED: &str = "--denoise needs the whole volume on the GPU, but this one is bricked \
     (--bricked, or over the memory budget): run without --bricked, with a larger \
     --memory-budget, or with --denoise none";

/// Fails (before any work) when `recipe` asks for denoising of a volume that will be bricked.
pub(super) fn check_denoise_whole(recipe: &SceneRecipe) -> Result<(), OpenError> {
    if recipe.denoise == Denoise::None {
        return Ok(());
    }
    Err(OpenError::Gpu(GpuError::InvalidRequest(BRICKED.into())))
}

impl Engine {
    /// The opened whole volume with I_norm denoised as `recipe` asks (unchanged for none). The
    /// original I_norm is dropped here: the denoised one replaces it (module doc).
    pub(super) fn denoise_opened(
        &mut self,
        prepared: PreparedVolume,
        recipe: &SceneRecipe,
    ) -> GpuResult<PreparedVolume> {
        Ok(self
            .denoise(&prepared, &recipe.denoise)?
            .unwrap_or(prepared))
    }

    /// `prepared` with I_norm denoised by `denoise` (None for `Denoise::None`).
    pub fn denoise(
        &mut self,
        prepared: &PreparedVolume,
        denoise: &Denoise,
    ) -> GpuResult<Option<PreparedVolume>> {
        if *denoise == Denoise::None {
            return Ok(None);
        }
        let _span = crate::files::trace::span("denoise", "prepare");
        if matches!(prepared.layout, VolumeLayout::Bricked(_)) {
            return Err(GpuError::InvalidRequest(BRICKED.into()));
        }
        let device = self.device.clone();
        let pass = DenoisePass::new(&device, self.pipeline_cache.raw())?;
        let mut rec = Recording::new(&device, "denoise")?;
        rec.begin_pass("denoise");
        let image = pass.record(
            &device,
            &mut rec,
            &prepared.normalized,
            &self.nearest,
            prepared.linear_part,
            denoise,
        )?;
        rec.end_pass();
        let timings = rec.submit()?.wait()?;
        let Some(normalized) = image else {
            return Ok(None);
        };
        let mut gpu_timings = prepared.gpu_timings.clone();
        gpu_timings.extend(timings);
        Ok(Some(PreparedVolume {
            dims: prepared.dims,
            kind: prepared.kind,
            upload_path: prepared.upload_path,
            normalized,
            layout: prepared.layout.clone(),
            stored_range: prepared.stored_range,
            normalization: prepared.normalization,
            range: prepared.range,
            histogram: prepared.histogram,
            tissue_histogram: prepared.tissue_histogram,
            mask_edge_voxels: prepared.mask_edge_voxels,
            voxel_count: prepared.voxel_count,
            finite_voxels: prepared.finite_voxels,
            linear_part: prepared.linear_part,
            affine: prepared.affine,
            identity: prepared.identity.clone(),
            gpu_timings,
            timings: prepared.timings.clone(),
            brick_ranges: std::sync::OnceLock::new(),
        }))
    }
}
