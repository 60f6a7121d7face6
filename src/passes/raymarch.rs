//! The raymarch (shaders/raymarch.comp): one compute pass over the image in 8x8 tiles.
//!
//! Decisions: one pipeline per [`RaymarchVariant`] (the specialization constants a scene's
//! effects resolve to; the mapping is `scene::variant`, so this pass never imports the scene),
//! created on first use and cached by the engine, so switching effects back is instant and
//! effects that mean the same shader share one pipeline. Inputs a variant
//! does not read are bound to 1-texel or 1-word placeholders. Parameters arrive in a uniform
//! buffer the caller wrote for this frame (double-buffered by the caller), never as a pipeline
//! change.

use crate::gpu::shaders::table;
use crate::gpu::{
    Access, Buffer, ComputePipeline, DescriptorSet, Device, GpuResult, Image, Recording, Resource,
    Sampler, SpecValue,
};
use ash::vk;
use std::sync::Arc;

/// u32 counter slots of the benchmark counters (512 pairs; see raymarch.comp).
pub const COUNTER_WORDS: usize = 1024;

/// The specialization constants of one raymarch pipeline.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub struct RaymarchVariant {
    /// 0 DVR, 1 MIP, 2 MinIP, 3 classify the voxels into the classified volume
    /// ([`RaymarchVariant::classifier`]).
    pub mode: u32,
    /// 0 off, 1 stored k, 2 k on the fly.
    pub curvature_mode: u32,
    /// Phong shading.
    pub shading: bool,
    /// 0 stored gradient, 1 central on the fly, 2 Sobel on the fly.
    pub gradient_mode: u32,
    /// 0 nearest, 1 trilinear, 2 tricubic.
    pub interpolation: u32,
    /// Naive opacity correction.
    pub naive_opacity: bool,
    /// Empty-space skipping.
    pub skip_empty: bool,
    /// Benchmark sample counters.
    pub count_samples: bool,
    /// Textures are brick atlases read through a brick table.
    pub bricked: bool,
    /// A label overlay is drawn (labels.glsl).
    pub labels: bool,
    /// Intensity layers drawn, 0..=2 (layers.glsl).
    pub layers: u32,
    /// The vessel channel is drawn (classification.glsl).
    pub vessels: bool,
    /// Longer steps in bricks of low opacity bound (needs `skip_empty`).
    pub long_steps: bool,
    /// Tissues classified inside the brain mask, the head layer outside (classification.glsl).
    pub brain: bool,
    /// Tissue windows from the transfer-function table (classification.glsl).
    pub classify_table: bool,
    /// 0 headlight Phong, 1 studio lighting, 2 matcap (lighting.glsl; only with `shading`).
    pub lighting: u32,
    /// Occlusion and shadow at each ray's surface (lighting.glsl; DVR).
    pub depth_cues: bool,
    /// One view pixel's first visible sample instead of a picture (depth picking; the engine's
    /// `pick`, never a scene's frame).
    pub pick: bool,
    /// DVR samples the classified volume (one RGBA8 fetch) instead of classifying each sample
    /// (the lean sample, issue 33 item 1); set by the engine where the scene allows it.
    pub classified: bool,
    /// The occupancy bits and the transfer-function table are read through texel buffers
    /// instead of storage buffers; set by the engine on devices that prefer them
    /// (`AdapterInfo::prefers_texel_lookups`).
    pub texel_lookups: bool,
}

impl RaymarchVariant {
    /// The variant as its specialization constants read, for plans and logs.
    pub fn describe(&self) -> String {
        let on = |b: bool| if b { "on" } else { "off" };
        let mut text = format!(
            "raymarch (MODE={}, CURVATURE={}, SHADING={}, GRADIENT={}, INTERPOLATION={}",
            ["dvr", "mip", "minip", "classify"]
                .get(self.mode as usize)
                .unwrap_or(&"?"),
            ["off", "stored", "on-the-fly"]
                .get(self.curvature_mode as usize)
                .unwrap_or(&"?"),
            on(self.shading),
            ["stored", "central", "sobel"]
                .get(self.gradient_mode as usize)
                .unwrap_or(&"?"),
            ["nearest", "trilinear", "tricubic"]
                .get(self.interpolation as usize)
                .unwrap_or(&"?"),
        );
        if self.layers > 0 {
            text.push_str(&format!(", LAYERS={}", self.layers));
        }
        for (name, value) in [
            ("NAIVE_OPACITY", self.naive_opacity),
            ("SKIP_EMPTY", self.skip_empty),
            ("COUNT_SAMPLES", self.count_samples),
            ("BRICKED", self.bricked),
            ("LABELS", self.labels),
            ("VESSELS", self.vessels),
            ("LONG_STEPS", self.long_steps),
            ("BRAIN", self.brain),
            ("CLASSIFY_TABLE", self.classify_table),
            ("STUDIO_LIGHTING", self.lighting == 1),
            ("MATCAP", self.lighting == 2),
            ("DEPTH_CUES", self.depth_cues),
            ("PICK", self.pick),
            ("CLASSIFIED", self.classified),
            ("TEXEL_LOOKUPS", self.texel_lookups),
        ] {
            text.push_str(&format!(", {name}={}", on(value)));
        }
        text.push(')');
        text
    }

    /// The variant (MODE 3) that classifies the voxels into the classified volume a
    /// CLASSIFIED variant samples: this one's classification inputs, nothing of its picture.
    pub fn classifier(&self) -> RaymarchVariant {
        RaymarchVariant {
            mode: 3,
            shading: false,
            count_samples: false,
            skip_empty: false,
            long_steps: false,
            bricked: false,
            labels: false,
            layers: 0,
            lighting: 0,
            depth_cues: false,
            pick: false,
            classified: false,
            ..*self
        }
    }

    /// Trilinear fetches per marched sample and per classified sample (for cost models).
    pub fn fetches(&self) -> (f64, f64) {
        let per_fetch = match self.interpolation {
            0 | 1 => 1.0,
            _ => 8.0,
        };
        if self.mode != 0 {
            return (per_fetch, 0.0);
        }
        if self.classified {
            // The classified volume, then the normals where shaded.
            return (per_fetch, per_fetch * self.shading as u32 as f64);
        }
        // The vessel channel reads the vesselness, the brain mask its mask, at every marched
        // sample.
        let marched = per_fetch * (1.0 + self.vessels as u32 as f64 + self.brain as u32 as f64);
        let gradient = match self.gradient_mode {
            0 => 1.0 + self.shading as u32 as f64,
            1 => 6.0,
            _ => 24.0,
        };
        let curvature = if self.curvature_mode == 2 {
            13.0 + if self.gradient_mode == 1 { 0.0 } else { 6.0 }
        } else {
            0.0
        };
        (marched, per_fetch * (gradient + curvature))
    }
}

/// Sampled inputs of one raymarch (images in `Access::ComputeSampled`).
#[derive(Clone, Copy)]
pub struct RaymarchInputs<'a> {
    /// I_norm.
    pub volume: &'a Arc<Image>,
    /// |g| or (|g|, k), or a placeholder.
    pub gradient: &'a Arc<Image>,
    /// Normals, or a placeholder.
    pub normal: &'a Arc<Image>,
    /// The vesselness, or a placeholder.
    pub vesselness: &'a Arc<Image>,
    /// The brain mask, or a placeholder.
    pub brain_mask: &'a Arc<Image>,
    /// Occupancy bits, or a placeholder (the storage-buffer binding).
    pub occupancy: &'a Arc<Buffer>,
    /// The same bits with an R32_UINT texel view where the variant has TEXEL_LOOKUPS, else a
    /// placeholder texel buffer (the texel binding; the variant reads one of the two).
    pub occupancy_texels: &'a Arc<Buffer>,
    /// Brick table of a bricked volume, or a placeholder.
    pub brick_table: &'a Arc<Buffer>,
    /// The labels of a label overlay (two u16 per word), or a placeholder.
    pub label_values: &'a Arc<Buffer>,
    /// The overlay's RGBA8 colour per label, or a placeholder.
    pub label_colours: &'a Arc<Buffer>,
    /// The layers' codes on their own grids (`engine::layers`), or placeholders.
    pub layers: [&'a Arc<Image>; 2],
    /// The layers' colour tables (positive then negative, 256 RGBA8 each, per layer), or a
    /// placeholder.
    pub layer_colours: &'a Arc<Buffer>,
    /// One bit per base brick where a layer may draw, or a placeholder.
    pub layer_bricks: &'a Arc<Buffer>,
    /// The classified volume a CLASSIFIED variant samples, or a placeholder.
    pub classified: &'a Arc<Image>,
    /// The classified volume MODE 3 writes (`Access::ComputeWriteImage`), or the storage
    /// placeholder.
    pub classified_out: &'a Arc<Image>,
    /// The transfer-function table (`scene::transfer_table`), or a placeholder; bound as a
    /// storage buffer and as an RGBA32F texel buffer (the variant reads one).
    pub transfer_table: &'a Arc<Buffer>,
    /// The matcap (`scene::matcap`) of a matcap-lit variant, or a placeholder.
    pub matcap: &'a Arc<Buffer>,
    /// Clamp-to-edge sampler with the filter the interpolation needs.
    pub sampler: &'a Arc<Sampler>,
}

/// The raymarch pipeline of one variant.
pub struct RaymarchPass {
    pipeline: Arc<ComputePipeline>,
}

impl RaymarchPass {
    /// The compiled pipeline (for its statistics and workgroup).
    pub fn pipeline(&self) -> &Arc<ComputePipeline> {
        &self.pipeline
    }

    /// Creates the pipeline for `variant`.
    pub fn new(
        device: &Device,
        variant: RaymarchVariant,
        cache: vk::PipelineCache,
    ) -> GpuResult<Self> {
        let pipeline = ComputePipeline::new(
            device,
            &table::RAYMARCH,
            &[
                ("MODE", SpecValue::U32(variant.mode)),
                ("CURVATURE_MODE", SpecValue::U32(variant.curvature_mode)),
                ("SHADING", SpecValue::Bool(variant.shading)),
                ("GRADIENT_MODE", SpecValue::U32(variant.gradient_mode)),
                ("COUNT_SAMPLES", SpecValue::Bool(variant.count_samples)),
                ("INTERPOLATION", SpecValue::U32(variant.interpolation)),
                ("NAIVE_OPACITY", SpecValue::Bool(variant.naive_opacity)),
                ("SKIP_EMPTY", SpecValue::Bool(variant.skip_empty)),
                ("LONG_STEPS", SpecValue::Bool(variant.long_steps)),
                ("BRICKED", SpecValue::Bool(variant.bricked)),
                ("LABELS", SpecValue::Bool(variant.labels)),
                ("VESSELS", SpecValue::Bool(variant.vessels)),
                ("BRAIN", SpecValue::Bool(variant.brain)),
                ("CLASSIFY_TABLE", SpecValue::Bool(variant.classify_table)),
                ("LIGHTING", SpecValue::U32(variant.lighting)),
                ("DEPTH_CUES", SpecValue::Bool(variant.depth_cues)),
                ("PICK", SpecValue::Bool(variant.pick)),
                ("LAYERS", SpecValue::U32(variant.layers)),
                ("CLASSIFIED", SpecValue::Bool(variant.classified)),
                ("TEXEL_LOOKUPS", SpecValue::Bool(variant.texel_lookups)),
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
        let set = self.descriptor_set(inputs, uniforms, target, counters)?;
        // Moves the target to GENERAL for storage writes; the last frame's pixels are not needed.
        rec.barriers(&[], &[(target, Access::Nothing, Access::ComputeWriteImage)]);
        let [w, h, _] = target.extent();
        let groups = self.pipeline.workgroups_for([w, h, 1]);
        rec.dispatch(&self.pipeline, &[set], &[], groups)
    }

    /// Records a classifier's (MODE 3) pass: every voxel of `inputs.classified_out` (in
    /// `Access::ComputeWriteImage`, a `dims` volume) written. `target` and `counters` are bound
    /// but not touched; `target` must be in `Access::ComputeWriteImage`.
    pub fn record_classify(
        &self,
        rec: &mut Recording,
        inputs: &RaymarchInputs<'_>,
        uniforms: &Arc<Buffer>,
        target: &Arc<Image>,
        counters: &Arc<Buffer>,
    ) -> GpuResult<()> {
        let set = self.descriptor_set(inputs, uniforms, target, counters)?;
        let groups = self.pipeline.workgroups_for(inputs.classified_out.extent());
        rec.dispatch(&self.pipeline, &[set], &[], groups)
    }

    fn descriptor_set(
        &self,
        inputs: &RaymarchInputs<'_>,
        uniforms: &Arc<Buffer>,
        target: &Arc<Image>,
        counters: &Arc<Buffer>,
    ) -> GpuResult<Arc<DescriptorSet>> {
        let s = inputs.sampler;
        DescriptorSet::new(
            &self.pipeline,
            0,
            &[
                (
                    "volume",
                    Resource::CombinedImageSampler(inputs.volume.clone(), s.clone()),
                ),
                (
                    "gradient_volume",
                    Resource::CombinedImageSampler(inputs.gradient.clone(), s.clone()),
                ),
                (
                    "normal_volume",
                    Resource::CombinedImageSampler(inputs.normal.clone(), s.clone()),
                ),
                (
                    "vesselness_volume",
                    Resource::CombinedImageSampler(inputs.vesselness.clone(), s.clone()),
                ),
                (
                    "brain_mask",
                    Resource::CombinedImageSampler(inputs.brain_mask.clone(), s.clone()),
                ),
                ("target", Resource::StorageImage(target.clone())),
                ("params", Resource::Buffer(uniforms.clone())),
                ("counters", Resource::Buffer(counters.clone())),
                ("occupancy", Resource::Buffer(inputs.occupancy.clone())),
                (
                    "occupancy_texels",
                    Resource::TexelBuffer(inputs.occupancy_texels.clone()),
                ),
                ("brick_table", Resource::Buffer(inputs.brick_table.clone())),
                (
                    "label_values",
                    Resource::Buffer(inputs.label_values.clone()),
                ),
                (
                    "label_colours",
                    Resource::Buffer(inputs.label_colours.clone()),
                ),
                (
                    "transfer_table",
                    Resource::Buffer(inputs.transfer_table.clone()),
                ),
                (
                    "transfer_texels",
                    Resource::TexelBuffer(inputs.transfer_table.clone()),
                ),
                ("matcap", Resource::Buffer(inputs.matcap.clone())),
                (
                    "layer_volume_0",
                    Resource::CombinedImageSampler(inputs.layers[0].clone(), s.clone()),
                ),
                (
                    "layer_volume_1",
                    Resource::CombinedImageSampler(inputs.layers[1].clone(), s.clone()),
                ),
                (
                    "layer_colours",
                    Resource::Buffer(inputs.layer_colours.clone()),
                ),
                (
                    "layer_bricks",
                    Resource::Buffer(inputs.layer_bricks.clone()),
                ),
                (
                    "classified_volume",
                    Resource::CombinedImageSampler(inputs.classified.clone(), s.clone()),
                ),
                (
                    "classified_out",
                    Resource::StorageImage(inputs.classified_out.clone()),
                ),
            ],
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_workgroup_is_an_8x8_tile() {
        assert_eq!(table::RAYMARCH.workgroup_size, [8, 8, 1]);
    }
}
