//! The classified volume of a render target (issue 33 item 1, the lean sample): every voxel
//! classified once (raymarch.comp's MODE 3) into an RGBA8 volume that a CLASSIFIED variant
//! samples with one fetch instead of classifying each sample.
//!
//! Decisions:
//! - One volume per render target, rebuilt inside the frame's own recording when what the
//!   classification reads changed ([`ClassifyKey`]: the windows, colours, step, gradient and
//!   curvature scales, colour map, the variant's classification constants and the input images),
//!   so an orbit rebuilds nothing and a window change costs one pass over the voxels. One copy
//!   suffices for every frame in flight: the barrier before the rebuild orders the reads of
//!   earlier submissions to the queue before its writes.
//! - RGBA8: 4 bytes a voxel, the colour premultiplied by the opacity so the trilinear fetch
//!   interpolates opacity-weighted colours (no dark fringes from empty voxels' colour). The
//!   accuracy study measures what the 8 bits and the pre-classification cost.
//! - A scene with a cut (crop, clip planes, cut-away) is drawn with the per-sample variant: its
//!   cut faces need the window opacity f(v) at each sample (`Scene::has_cut`).

use super::Engine;
use super::render::RenderTarget;
use crate::gpu::{Access, GpuResult, Image, ImageDesc, Recording};
use crate::passes::raymarch::{RaymarchInputs, RaymarchVariant};
use crate::scene::uniforms::RaymarchUniforms;
use ash::vk;
use std::sync::Arc;

/// The texel format of the classified volume.
pub const CLASSIFIED_FORMAT: vk::Format = vk::Format::R8G8B8A8_UNORM;

/// The classified volume of a `dims` volume (as the engine creates it and the plan declares it).
pub fn classified_desc(dims: [u32; 3]) -> ImageDesc {
    ImageDesc::volume("classified volume", dims, CLASSIFIED_FORMAT)
}

/// What a classified volume was built from: when it differs, the volume is rebuilt.
#[derive(Clone, Debug, PartialEq)]
pub struct ClassifyKey {
    values: Vec<f32>,
    variant: RaymarchVariant,
    images: [usize; 4],
}

impl ClassifyKey {
    /// The key of classifying with `variant` (a classifier), uniforms `block` and the images
    /// in `inputs`.
    pub fn new(
        block: &RaymarchUniforms,
        variant: RaymarchVariant,
        inputs: &RaymarchInputs<'_>,
    ) -> Self {
        let mut values = Vec::with_capacity(160);
        let mut push = |v: &[f32]| values.extend_from_slice(v);
        push(&block.dims);
        push(&block.march[..1]);
        push(&block.march[3..]);
        push(&block.curvature);
        push(&block.derived_scale[..2]);
        push(&block.intensity);
        push(&block.crop_hi[3..]);
        for v in block
            .windows
            .iter()
            .chain(&block.colours)
            .chain(&block.colormap)
            .chain(&block.gradient_to_world)
        {
            push(v);
        }
        for v in [
            &block.vessel_window,
            &block.vessel_colour,
            &block.head_window,
            &block.head_colour,
            &block.brain_grid,
        ] {
            push(v);
        }
        let ptr = |image: &Arc<Image>| Arc::as_ptr(image) as usize;
        ClassifyKey {
            values,
            variant,
            images: [
                ptr(inputs.volume),
                ptr(inputs.gradient),
                ptr(inputs.vesselness),
                ptr(inputs.brain_mask),
            ],
        }
    }
}

/// A render target's classified volume and what it holds.
pub struct ClassifiedVolume {
    image: Arc<Image>,
    key: Option<ClassifyKey>,
}

impl Engine {
    /// The classified volume `target` draws this frame with DVR variant `variant`: rebuilt in
    /// `rec` first when `key` differs from what it holds (or it does not exist or has other
    /// dimensions). `inputs` are the frame's inputs (their `classified` fields are replaced).
    /// Afterwards the volume was last accessed as `Access::ComputeSampled`, and `target`'s image
    /// as `Access::ComputeWriteImage` when a rebuild bound it.
    pub(super) fn classified_input(
        &mut self,
        rec: &mut Recording,
        target: &mut RenderTarget,
        variant: RaymarchVariant,
        inputs: &RaymarchInputs<'_>,
        uniforms: &Arc<crate::gpu::Buffer>,
        key: ClassifyKey,
    ) -> GpuResult<Arc<Image>> {
        let dims = inputs.volume.extent();
        let reusable = target
            .classified
            .as_ref()
            .is_some_and(|c| c.image.extent() == dims);
        if !reusable {
            target.classified = Some(ClassifiedVolume {
                image: Image::new(&self.device, classified_desc(dims))?,
                key: None,
            });
        }
        let Some(volume) = target.classified.as_mut() else {
            return Err(crate::gpu::GpuError::Internal(
                "classified volume missing".into(),
            ));
        };
        let image = volume.image.clone();
        if volume.key.as_ref() == Some(&key) {
            return Ok(image);
        }
        // A volume never written has nothing to order and no layout to keep.
        let before = if volume.key.is_none() {
            Access::Nothing
        } else {
            Access::ComputeSampled
        };
        volume.key = Some(key);
        self.counters.classify_runs += 1;
        let placeholder = self.placeholders.normal.clone();
        let classifier = self.raymarch_pass(variant.classifier())?;
        let classify_inputs = RaymarchInputs {
            classified: &placeholder,
            classified_out: &image,
            ..*inputs
        };
        // Orders earlier frames' reads of the volume (earlier submissions to this queue) before
        // its rewrite, and moves both storage images to GENERAL (the target is bound, not used).
        rec.barriers(
            &[],
            &[
                (&image, before, Access::ComputeWriteImage),
                (&target.image, Access::Nothing, Access::ComputeWriteImage),
            ],
        );
        rec.begin_pass("classify");
        classifier.record_classify(
            rec,
            &classify_inputs,
            uniforms,
            &target.image,
            &target.counters,
        )?;
        rec.end_pass();
        // Orders the classified writes before the raymarch samples them.
        rec.barriers(
            &[],
            &[(&image, Access::ComputeWriteImage, Access::ComputeSampled)],
        );
        Ok(image)
    }
}
