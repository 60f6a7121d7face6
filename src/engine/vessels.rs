//! The multi-scale vesselness volume of a prepared volume (`passes::vesselness`).
//!
//! Decisions: one submission for every scale (the scratch volumes live until it completes, so
//! the peak is the response plus two scratch volumes: `passes::vesselness::vesselness_descs`);
//! whole volumes only for now: a brick atlas would need the Gaussian's halo to grow with the
//! scale (up to 3 sigma, 9 voxels at 3 mm), which the atlas's fixed halo does not have, so a
//! bricked volume is a typed error rather than seams at brick faces.

use super::Engine;
use super::prepare::{PreparedVolume, VolumeLayout};
use crate::gpu::{GpuError, GpuResult, Image, PassTiming, Recording};
use crate::passes::vesselness::{VesselnessParams, VesselnessPass};
use std::sync::Arc;

/// The vesselness volume and the GPU time it took.
pub struct Vesselness {
    /// R32_SFLOAT in [0, 1], left in `Access::ComputeSampled`.
    pub image: Arc<Image>,
    /// The parameters it was computed with.
    pub params: VesselnessParams,
    /// GPU time of the passes (one timed pass for all scales).
    pub gpu_timings: Vec<PassTiming>,
}

impl Engine {
    /// Computes the multi-scale vesselness of `prepared` (module decisions).
    pub fn vesselness(
        &mut self,
        prepared: &PreparedVolume,
        params: &VesselnessParams,
    ) -> GpuResult<Vesselness> {
        let _span = crate::files::trace::span("vesselness", "prepare");
        if matches!(prepared.layout, VolumeLayout::Bricked(_)) {
            return Err(GpuError::InvalidRequest(
                "vesselness needs the whole volume on the GPU; this one is bricked (run without --bricked or with a larger --memory-budget)".into(),
            ));
        }
        params.validate()?;
        let device = self.device.clone();
        let pass = VesselnessPass::new(&device, self.pipeline_cache.raw())?;
        let mut rec = Recording::new(&device, "vesselness")?;
        rec.begin_pass("vesselness");
        let image = pass.record(
            &device,
            &mut rec,
            &prepared.normalized,
            &self.nearest,
            prepared.linear_part,
            params,
        )?;
        rec.end_pass();
        let gpu_timings = rec.submit()?.wait()?;
        Ok(Vesselness {
            image,
            params: params.clone(),
            gpu_timings,
        })
    }
}
