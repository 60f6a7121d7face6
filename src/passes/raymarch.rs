//! The raymarch (shaders/raymarch.comp): one compute pass over the image in 8x8 tiles.
//!
//! Decisions: one pipeline per [`Effects`] combination (mode, curvature, shading, gradient
//! source), created on first use and cached by the engine, so switching effects back is instant.
//! Inputs a variant does not read are bound to 1-texel placeholders. Parameters arrive in a
//! uniform buffer the caller wrote for this frame (double-buffered by the caller), never as a
//! pipeline change.

use crate::gpu::shaders::table;
use crate::gpu::{
    Access, Buffer, ComputePipeline, DescriptorSet, Device, GpuResult, Image, Recording, Resource,
    Sampler, SpecValue,
};
use crate::scene::{Effects, GradientSource, RenderMode};
use ash::vk;
use std::sync::Arc;

/// u32 counter slots of the benchmark counters (512 pairs; see raymarch.comp).
pub const COUNTER_WORDS: usize = 1024;

/// Sampled inputs of one raymarch (all in `Access::ComputeSampled`).
pub struct RaymarchInputs<'a> {
    /// I_norm.
    pub volume: &'a Arc<Image>,
    /// |g| or (|g|, k), or a placeholder.
    pub gradient: &'a Arc<Image>,
    /// Normals, or a placeholder.
    pub normal: &'a Arc<Image>,
    /// Trilinear clamp-to-edge sampler.
    pub linear: &'a Arc<Sampler>,
}

/// The raymarch pipeline of one effects combination.
pub struct RaymarchPass {
    pipeline: Arc<ComputePipeline>,
}

impl RaymarchPass {
    /// Creates the pipeline specialized for `effects`; `count_samples` compiles in the benchmark
    /// counters.
    pub fn new(
        device: &Device,
        effects: Effects,
        count_samples: bool,
        cache: vk::PipelineCache,
    ) -> GpuResult<Self> {
        let mode = match effects.mode {
            RenderMode::Dvr => 0,
            RenderMode::Mip => 1,
            RenderMode::MinIp => 2,
        };
        let dvr = effects.mode == RenderMode::Dvr;
        let pipeline = ComputePipeline::new(
            device,
            &table::RAYMARCH,
            &[
                ("MODE", SpecValue::U32(mode)),
                ("CURVATURE", SpecValue::Bool(dvr && effects.curvature)),
                ("SHADING", SpecValue::Bool(dvr && effects.shading)),
                (
                    "GRADIENT_ON_THE_FLY",
                    SpecValue::Bool(effects.gradient_source == GradientSource::OnTheFly),
                ),
                ("COUNT_SAMPLES", SpecValue::Bool(count_samples)),
            ],
            cache,
        )?;
        Ok(RaymarchPass { pipeline })
    }

    /// Records the raymarch into `target` (previous contents discarded); afterwards the target
    /// was last accessed as `Access::ComputeWriteImage`. `counters` (2 x 512 u32, zeroed by the
    /// caller when counting) is written only by a counting pipeline.
    pub fn record(
        &self,
        rec: &mut Recording,
        inputs: &RaymarchInputs<'_>,
        uniforms: &Arc<Buffer>,
        target: &Arc<Image>,
        counters: &Arc<Buffer>,
    ) -> GpuResult<()> {
        let set = DescriptorSet::new(
            &self.pipeline,
            0,
            &[
                (
                    "volume",
                    Resource::CombinedImageSampler(inputs.volume.clone(), inputs.linear.clone()),
                ),
                (
                    "gradient_volume",
                    Resource::CombinedImageSampler(inputs.gradient.clone(), inputs.linear.clone()),
                ),
                (
                    "normal_volume",
                    Resource::CombinedImageSampler(inputs.normal.clone(), inputs.linear.clone()),
                ),
                ("target", Resource::StorageImage(target.clone())),
                ("params", Resource::Buffer(uniforms.clone())),
                ("counters", Resource::Buffer(counters.clone())),
            ],
        )?;
        // Moves the target to GENERAL for storage writes; the last frame's pixels are not needed.
        rec.barriers(&[], &[(target, Access::Nothing, Access::ComputeWriteImage)]);
        let [w, h, _] = target.extent();
        let groups = self.pipeline.workgroups_for([w, h, 1]);
        rec.dispatch(&self.pipeline, &[set], &[], groups)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::uniforms::RaymarchUniforms;

    #[test]
    fn uniform_block_matches_the_shader() {
        let params = table::RAYMARCH.binding("params").unwrap();
        assert_eq!(
            params.block_bytes as usize,
            std::mem::size_of::<RaymarchUniforms>()
        );
    }

    #[test]
    fn the_workgroup_is_an_8x8_tile() {
        assert_eq!(table::RAYMARCH.workgroup_size, [8, 8, 1]);
    }
}
