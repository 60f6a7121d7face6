//! Rendering frames of a prepared volume: uniforms, raymarch, readback.
//!
//! Decisions:
//! - A [`RenderTarget`] owns the output image, its readback buffer and two uniform buffers used
//!   alternately (one per frame in flight), so writing the next frame's parameters never touches
//!   memory the GPU may still read.
//! - Empty-space skipping reads the frame's occupancy bits (made by the brick-bounds pass from
//!   the volume's brick ranges, computed once) from a buffer per frame in flight. The bits
//!   depend only on the volume and the classification, so a frame with the same classification
//!   (an orbit) neither runs the pass nor writes the buffer (issue 13 item 5; occupancy.rs).
//! - Recording and submitting are separate (issue 13 item 5): [`Engine::record_render`] records
//!   the raymarch (and the copies back, when the target reads back) into a caller's
//!   [`Recording`], so a caller can put it into its own submission with other work (the viewer's
//!   composition); [`Engine::finish_frame`] reads the results after that submission's wait.
//!   [`Engine::render`] is the two with a submission of its own in between.
//! - Rendering checks that the derived volumes the scene needs exist (the caller derives them
//!   from `Effects::derivative_outputs`), and fails with a typed error instead of sampling a
//!   placeholder by mistake.

use super::Engine;
use super::classified::ClassifyKey;
use super::derive::Derived;
use super::occupancy::{BoundsInputs, OccupancySlots, occupancy_addressable};
use super::prepare::PreparedVolume;
use super::prepare::VolumeLayout;
use crate::gpu::{
    Access, Buffer, BufferDesc, GpuError, GpuResult, Image, ImageDesc, PassTiming, Recording,
};
use crate::passes::occupancy::BRICK_SIDE;
use crate::passes::raymarch::{COUNTER_WORDS, RaymarchInputs, RaymarchVariant};
use crate::scene::uniforms::{AtlasInfo, FrameInputs, GradientStats, RaymarchUniforms};
use crate::scene::{Scene, VolumeGeometry};
use ash::vk;
use std::sync::Arc;

pub use crate::gpu::FRAMES_IN_FLIGHT;

/// Empty-space skipping is used only when at most this fraction of the 8^3 bricks can hold a
/// visible sample. With (nearly) every brick visible there is nothing to skip and the brick
/// lookups only cost: on the H100 at 1920x1080, MNI152 under adaptive windows that then made
/// every brick visible rendered 13 % faster without skipping, while the phantom (20 % of bricks
/// visible) rendered 2.8x faster with it (ACCURACY.md). Since the darkest window no longer
/// reaches the zero background, MNI152 has 28.8 % of its bricks visible and skips (2.28x faster,
/// BENCHMARKS.md).
pub const MAX_OCCUPANCY_FOR_SKIPPING: f64 = 0.9;

/// An output image with its readback buffer and per-frame uniform buffers.
pub struct RenderTarget {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    pub(super) image: Arc<Image>,
    readback: Arc<Buffer>,
    uniforms: [Arc<Buffer>; FRAMES_IN_FLIGHT],
    next_uniforms: usize,
    pub(super) counters: Arc<Buffer>,
    counters_host: Arc<Buffer>,
    // Occupancy bits and opacity bounds per frame slot, and what each holds.
    occupancy: OccupancySlots,
    // A label overlay drawn in 3D, its colour table per frame slot and which table each holds
    // (labels.rs).
    pub(super) labels: Option<super::labels::AttachedLabels>,
    pub(super) label_colour_buffers: Vec<Option<Arc<Buffer>>>,
    pub(super) label_colours_written: [u64; FRAMES_IN_FLIGHT],
    // Intensity layers drawn in 3D, their colour tables and brick bits (layers.rs).
    pub(super) layers: super::layers::AttachedLayers,
    // The transfer-function table per frame slot (transfer.rs).
    pub(super) tables: super::transfer::TableSlots,
    // The matcap per frame slot (matcap.rs).
    pub(super) matcaps: super::matcap::MatcapSlots,
    // The classified volume of CLASSIFIED variants (classified.rs).
    pub(super) classified: Option<super::classified::ClassifiedVolume>,
    // A picking target (pick.rs): the view pixel it marches and the view's size.
    pub(super) pick: Option<(crate::scene::uniforms::PixelPick, [u32; 2])>,
    /// Compile in and read the benchmark counters (samples marched / classified) each frame.
    pub count_samples: bool,
    /// Copy each frame back to the host (off for frame-rate measurements: `Frame` is then
    /// empty of pixels).
    pub read_back: bool,
}

/// Samples one frame took (benchmark counters).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct SampleCounts {
    /// Volume samples taken (trilinear fetches of I_norm).
    pub marched: u64,
    /// Samples that passed classification (each also fetched the derived volumes).
    pub classified: u64,
}

/// A raymarch recorded by [`Engine::record_render`], to be read with [`Engine::finish_frame`]
/// after its submission completed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[must_use = "finish the frame after the submission's wait to read its pixels and counts"]
pub struct RecordedFrame {
    read_back: bool,
    count: bool,
    skipped_empty_space: bool,
}

/// One rendered frame, read back.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// RGBA8 pixels, rows top to bottom (or RGBA f32 values for a float target, see
    /// [`Frame::values`]).
    pub rgba8: Vec<u8>,
    /// RGBA f32 values when the target format is R32G32B32A32_SFLOAT, else empty.
    pub values: Vec<f32>,
    /// GPU time of the raymarch.
    pub gpu_timings: Vec<PassTiming>,
    /// Sample counts, when the target counts samples.
    pub samples: Option<SampleCounts>,
    /// Whether this frame skipped empty space (the scene asked for it and enough bricks were
    /// empty: see [`MAX_OCCUPANCY_FOR_SKIPPING`]).
    pub skipped_empty_space: bool,
}

impl RenderTarget {
    /// The output image (left in `Access::ComputeWriteImage` by a render that does not read
    /// back), for a presenter that copies it into a window.
    pub fn image(&self) -> &Arc<Image> {
        &self.image
    }

    /// GPU time of the last brick-bounds pass a frame of this target ran (it runs when the
    /// classification changes; empty before).
    pub fn brick_bounds_timings(&self) -> &[PassTiming] {
        &self.occupancy.timings
    }
}

/// What a render target holds, as [`Engine::render_target`] creates it and as the pass plan
/// declares it.
pub struct RenderTargetDescs {
    /// The output image.
    pub image: ImageDesc,
    /// Its host copy.
    pub readback: BufferDesc,
    /// The raymarch's uniforms, one buffer per frame in flight.
    pub uniforms: [BufferDesc; FRAMES_IN_FLIGHT],
    /// The raymarch's sample counters and their host copy.
    pub counters: [BufferDesc; 2],
}

/// The descriptions of a `width` x `height` target in `format` (RGBA8 or RGBA32F).
pub fn render_target_descs(
    width: u32,
    height: u32,
    format: vk::Format,
) -> GpuResult<RenderTargetDescs> {
    if width == 0 || height == 0 {
        return Err(GpuError::InvalidRequest(format!(
            "image size {width}x{height} has a zero side"
        )));
    }
    let texel = match format {
        vk::Format::R8G8B8A8_UNORM => 4,
        vk::Format::R32G32B32A32_SFLOAT => 16,
        other => {
            return Err(GpuError::InvalidRequest(format!(
                "render targets are RGBA8 or RGBA32F, not {other:?}"
            )));
        }
    };
    let size = std::mem::size_of::<RaymarchUniforms>() as u64;
    let counter_bytes = (COUNTER_WORDS * 4) as u64;
    Ok(RenderTargetDescs {
        image: ImageDesc::render_target("render target", width, height, format),
        readback: BufferDesc::readback(
            "render target (host)",
            width as u64 * height as u64 * texel,
        ),
        uniforms: std::array::from_fn(|frame| {
            BufferDesc::uniform(&format!("raymarch uniforms (frame {frame})"), size)
        }),
        counters: [
            BufferDesc::gpu_storage("raymarch sample counters", counter_bytes),
            BufferDesc::readback("raymarch sample counters (host)", counter_bytes),
        ],
    })
}

impl Engine {
    /// Creates a `width` x `height` render target in `format` (RGBA8_UNORM for pictures,
    /// R32G32B32A32_SFLOAT for accuracy studies).
    pub fn render_target(
        &self,
        width: u32,
        height: u32,
        format: vk::Format,
    ) -> GpuResult<RenderTarget> {
        let descs = render_target_descs(width, height, format)?;
        let image = Image::new(&self.device, descs.image)?;
        let readback = Buffer::new(&self.device, descs.readback)?;
        let mut uniforms = Vec::with_capacity(FRAMES_IN_FLIGHT);
        for desc in descs.uniforms {
            uniforms.push(Buffer::new(&self.device, desc)?);
        }
        let uniforms: [Arc<Buffer>; FRAMES_IN_FLIGHT] = uniforms
            .try_into()
            .map_err(|_| GpuError::Internal("one uniform buffer per frame in flight".into()))?;
        let [counters, counters_host] = descs.counters;
        let counters = Buffer::new(&self.device, counters)?;
        let counters_host = Buffer::new(&self.device, counters_host)?;
        Ok(RenderTarget {
            width,
            height,
            image,
            readback,
            uniforms,
            next_uniforms: 0,
            counters,
            counters_host,
            occupancy: OccupancySlots::new(FRAMES_IN_FLIGHT),
            labels: None,
            label_colour_buffers: vec![None; FRAMES_IN_FLIGHT],
            label_colours_written: [0; FRAMES_IN_FLIGHT],
            layers: Default::default(),
            tables: Default::default(),
            matcaps: Default::default(),
            classified: None,
            pick: None,
            count_samples: false,
            read_back: true,
        })
    }

    /// Renders `scene` into `target`, waits, and reads the frame back.
    pub fn render(
        &mut self,
        target: &mut RenderTarget,
        prepared: &PreparedVolume,
        derived: Option<&Derived>,
        scene: &Scene,
    ) -> GpuResult<Frame> {
        self.render_frame(target, prepared, derived, scene, None)
    }

    /// Renders `scene` into `target` and copies the pixels straight into `out`, a buffer the
    /// caller owns (`width * height * 4` bytes for RGBA8, rows top to bottom; 16 bytes a pixel
    /// for RGBA32F); the returned frame carries timings and counts but no pixel vectors.
    pub fn render_into(
        &mut self,
        target: &mut RenderTarget,
        prepared: &PreparedVolume,
        derived: Option<&Derived>,
        scene: &Scene,
        out: &mut [u8],
    ) -> GpuResult<Frame> {
        let needed = target.readback.size() as usize;
        if out.len() != needed {
            return Err(GpuError::InvalidRequest(format!(
                "the output buffer has {} bytes; a {}x{} frame of {:?} needs {needed}",
                out.len(),
                target.width,
                target.height,
                target.image.format()
            )));
        }
        self.render_frame(target, prepared, derived, scene, Some(out))
    }

    fn render_frame(
        &mut self,
        target: &mut RenderTarget,
        prepared: &PreparedVolume,
        derived: Option<&Derived>,
        scene: &Scene,
        out: Option<&mut [u8]>,
    ) -> GpuResult<Frame> {
        let read_back = target.read_back || out.is_some();
        let _span = crate::files::trace::span("frame", "render");
        let mut rec = Recording::new(&self.device, "raymarch")?;
        let recorded = self.record_frame(&mut rec, target, prepared, derived, scene, read_back)?;
        let gpu_timings = rec.submit()?.wait()?;
        self.finish_frame(target, recorded, gpu_timings, out)
    }

    /// Records the raymarch of `scene` into `rec`, a recording the caller submits (with other
    /// work of its own, before or after), and, when `target.read_back`, the copy of the image to
    /// host memory. After the submission's `wait`, [`Engine::finish_frame`] reads the frame.
    /// Without readback the image is left in `Access::ComputeWriteImage` for the caller's next
    /// barrier. The target's uniforms alternate between two buffers, so at most
    /// [`FRAMES_IN_FLIGHT`] recordings of one target may be in flight at once.
    pub fn record_render(
        &mut self,
        rec: &mut Recording,
        target: &mut RenderTarget,
        prepared: &PreparedVolume,
        derived: Option<&Derived>,
        scene: &Scene,
    ) -> GpuResult<RecordedFrame> {
        let read_back = target.read_back;
        self.record_frame(rec, target, prepared, derived, scene, read_back)
    }

    fn record_frame(
        &mut self,
        rec: &mut Recording,
        target: &mut RenderTarget,
        prepared: &PreparedVolume,
        derived: Option<&Derived>,
        scene: &Scene,
        read_back: bool,
    ) -> GpuResult<RecordedFrame> {
        self.ensure_placeholder_layouts()?;
        self.counters.frames += 1;
        let effects = scene.effects;
        let needed = effects.derivative_outputs();
        let (gradient, normal, stats, store_scale) = match (needed, derived) {
            (None, _) => (
                None,
                None,
                GradientStats {
                    max_magnitude: 0.0,
                    tau: 0.0,
                },
                [1.0, 1.0],
            ),
            (Some(outputs), Some(d)) => {
                let missing = (outputs.magnitude && d.volumes.gradient.is_none())
                    || (outputs.curvature && !d.volumes.outputs.curvature)
                    || (outputs.normal && d.volumes.normal.is_none());
                if missing {
                    return Err(GpuError::InvalidRequest(format!(
                        "the scene needs derived volumes {outputs:?}, but only {:?} were computed",
                        d.volumes.outputs
                    )));
                }
                (
                    d.volumes.gradient.clone(),
                    d.volumes.normal.clone(),
                    d.stats,
                    d.volumes.store_scale,
                )
            }
            (Some(outputs), None) => {
                return Err(GpuError::InvalidRequest(format!(
                    "the scene needs the derivative pass ({outputs:?}) but none was run"
                )));
            }
        };
        let geometry = VolumeGeometry::new(prepared.dims, prepared.affine)
            .map_err(|e| GpuError::UnusableInput(e.to_string()))?;
        let count = target.count_samples;
        let (atlas, brick_table) = match &prepared.layout {
            VolumeLayout::Whole => (AtlasInfo::default(), self.placeholders.occupancy.clone()),
            VolumeLayout::Bricked(a) => {
                // The resident bricks were chosen for one scene; a scene that can see more would
                // draw holes, so it is refused instead.
                super::bricked::check_residency(prepared, a, scene)?;
                let e = prepared.normalized.extent();
                let info = AtlasInfo {
                    dims: e,
                    brick: a.brick,
                    halo: a.halo,
                    grid: a.grid,
                    slots: a.slots,
                };
                (info, a.table.clone())
            }
        };
        let mut variant = RaymarchVariant::of_layout(&effects, count, atlas.brick > 0);
        variant.pick = target.pick.is_some();
        variant.texel_lookups = self.texel_lookups();
        // The brain mask is read where the derived volumes hold one the switch uses (a head).
        variant.brain = variant.mode == 0
            && effects.brain != crate::passes::brain::BrainSwitch::Off
            && derived
                .and_then(|d| d.brain.as_ref())
                .is_some_and(|b| b.image.is_some() && b.use_for(effects.brain));
        // The head layer's window is not among the brick-bounds channels (four tissues and the
        // vessels): with it visible, skipping is off rather than lossy.
        if variant.brain && scene.classification.head.visible {
            variant.skip_empty = false;
            variant.long_steps = false;
        }
        // Cut faces take f(v) per sample, which a classified volume does not hold.
        variant.classified &= !scene.has_cut();
        let frame_slot = target.next_uniforms;
        let (label_values, label_colours, label_bits) =
            self.label_inputs(target, prepared, scene, frame_slot)?;
        variant.labels = label_bits.is_some();
        let dvr = scene.effects.mode == crate::scene::RenderMode::Dvr;
        let layers = self.layer_inputs(target, prepared, dvr, frame_slot)?;
        variant.layers = layers.count;
        let label_bits = target.extra_brick_bits(label_bits, prepared.dims, layers.count > 0);
        // Skipping with vessels needs the vesselness's brick ranges (lossless only with them).
        if variant.vessels && derived.and_then(|d| d.vessel_ranges.as_ref()).is_none() {
            variant.skip_empty = false;
        }
        target.next_uniforms = (target.next_uniforms + 1) % FRAMES_IN_FLIGHT;
        let mut bricks = [1, 1, 1, BRICK_SIDE];
        let occupancy = if variant.skip_empty {
            let ranges = self.brick_ranges(prepared)?;
            // With the head layer hidden (else skipping is off), the tissues show only where
            // the brain mask reaches: the rest of the head is empty space.
            let ranges = match derived.and_then(|d| d.brain.as_ref()) {
                Some(brain) if variant.brain => brain.ranges_inside(&ranges),
                _ => ranges,
            };
            let brick_count = ranges.grid.iter().map(|&g| g as u64).product();
            // A device whose texel buffers cannot address the bits does not skip.
            variant.skip_empty =
                occupancy_addressable(&self.device, brick_count, variant.texel_lookups);
            let inputs = BoundsInputs {
                ranges: ranges.clone(),
                vessels: derived
                    .and_then(|d| d.vessel_ranges.clone())
                    .filter(|_| variant.vessels),
                labels: label_bits,
            };
            // Made even when this frame does not skip, so the buffers a scene with skipping
            // holds do not depend on the view: the plan lists them.
            let (buffer, occupied) = if variant.skip_empty {
                self.occupancy_for_frame(&mut target.occupancy, frame_slot, inputs, scene)?
            } else {
                (self.placeholders.uint_texels.clone(), 1.0)
            };
            // Nothing to skip: the lookups would only cost (lossless either way).
            variant.skip_empty &= occupied <= MAX_OCCUPANCY_FOR_SKIPPING;
            bricks = [ranges.grid[0], ranges.grid[1], ranges.grid[2], ranges.side];
            if variant.skip_empty {
                buffer
            } else {
                bricks = [1, 1, 1, BRICK_SIDE];
                self.placeholders.uint_texels.clone()
            }
        } else {
            self.placeholders.uint_texels.clone()
        };
        // Long steps read the bounds next to the bits: off without skipping.
        variant.long_steps &= variant.skip_empty;
        let block = RaymarchUniforms::new(
            scene,
            &geometry,
            &FrameInputs {
                gradients: stats,
                store_scale,
                bricks,
                // A picking target marches one pixel of a view of this size (pick.rs).
                width: target.pick.map_or(target.width, |(_, view)| view[0]),
                height: target.pick.map_or(target.height, |(_, view)| view[1]),
                atlas,
                brain_grid: derived
                    .and_then(|d| d.brain.as_ref())
                    .filter(|_| variant.brain)
                    .map_or([1.0; 3], |b| b.grid_extent()),
                pick: target.pick.map(|(pick, _)| pick),
            },
        );
        let mut block = block;
        block.layer_to_texture = layers.uniforms.to_texture;
        block.layer_window = layers.uniforms.window;
        block.layer_decode = layers.uniforms.decode;
        block.layer_bricks = layers.uniforms.bricks;
        // The farthest empty-space jump in bricks: the distance map's cap, or the brick itself.
        block.atlas_slots[3] = if self.config.distance_skipping {
            255
        } else {
            1
        };
        let uniforms = target.uniforms[frame_slot].clone();
        uniforms.write(0, bytemuck::bytes_of(&block))?;

        let linear = self.linear.clone();
        let gradient = gradient.unwrap_or_else(|| self.placeholders.gradient.clone());
        let normal = normal.unwrap_or_else(|| self.placeholders.normal.clone());
        let vesselness = match (variant.vessels, derived.and_then(|d| d.vesselness.clone())) {
            (false, _) => self.placeholders.gradient.clone(),
            (true, Some(v)) => v,
            (true, None) => {
                return Err(GpuError::InvalidRequest(
                    "the scene shows vessels, but no vesselness was computed".into(),
                ));
            }
        };
        let brain_mask = match derived.and_then(|d| d.brain.as_ref()) {
            Some(b) if variant.brain => b
                .image
                .clone()
                .unwrap_or_else(|| self.placeholders.gradient.clone()),
            _ => self.placeholders.gradient.clone(),
        };
        let transfer_table =
            self.transfer_table_input(target, scene, frame_slot, variant.classify_table)?;
        let matcap = self.matcap_input(target, frame_slot, variant.lighting == 2)?;
        let storage_placeholder = self.placeholders.storage.clone();
        let sampled_placeholder = self.placeholders.normal.clone();
        // The bits' texel view exists only where the variant reads it.
        let occupancy_texels = if variant.texel_lookups {
            occupancy.clone()
        } else {
            self.placeholders.uint_texels.clone()
        };
        let mut inputs = RaymarchInputs {
            transfer_table: &transfer_table,
            matcap: &matcap,
            brain_mask: &brain_mask,
            volume: &prepared.normalized,
            gradient: &gradient,
            normal: &normal,
            vesselness: &vesselness,
            occupancy: &occupancy,
            occupancy_texels: &occupancy_texels,
            brick_table: &brick_table,
            label_values: &label_values,
            label_colours: &label_colours,
            layers: [&layers.images[0], &layers.images[1]],
            layer_colours: &layers.colours,
            layer_bricks: &layers.bricks,
            classified: &sampled_placeholder,
            classified_out: &storage_placeholder,
            sampler: &linear,
        };
        let classified = if variant.classified {
            let key = ClassifyKey::new(&block, variant.classifier(), &inputs);
            Some(self.classified_input(rec, target, variant, &inputs, &uniforms, key)?)
        } else {
            None
        };
        if let Some(image) = &classified {
            inputs.classified = image;
        }
        let pass = self.raymarch_pass(variant)?;
        if count {
            rec.fill_buffer(&target.counters, 0, (COUNTER_WORDS * 4) as u64, 0);
            // Orders the zeroing before the shader's counter atomics.
            rec.barriers(
                &[(
                    &target.counters,
                    Access::TransferWrite,
                    Access::ComputeWriteBuffer,
                )],
                &[],
            );
        }
        rec.begin_pass("raymarch");
        pass.record(rec, &inputs, &uniforms, &target.image, &target.counters)?;
        rec.end_pass();
        if count {
            // Orders the counter atomics before the copy to host memory, and the copy before
            // the host reads it.
            rec.barriers(
                &[(
                    &target.counters,
                    Access::ComputeWriteBuffer,
                    Access::TransferRead,
                )],
                &[],
            );
            rec.copy_buffer(
                &target.counters,
                &target.counters_host,
                (COUNTER_WORDS * 4) as u64,
            );
            rec.barriers(
                &[(
                    &target.counters_host,
                    Access::TransferWrite,
                    Access::HostRead,
                )],
                &[],
            );
        }
        if read_back {
            // Orders the raymarch's writes before the copy to host memory.
            rec.barriers(
                &[],
                &[(
                    &target.image,
                    Access::ComputeWriteImage,
                    Access::TransferRead,
                )],
            );
            rec.copy_image_to_buffer(&target.image, &target.readback);
            // Makes the copied pixels visible to the host.
            rec.barriers(
                &[(&target.readback, Access::TransferWrite, Access::HostRead)],
                &[],
            );
        }
        rec.keep(uniforms);
        Ok(RecordedFrame {
            read_back,
            count,
            skipped_empty_space: variant.skip_empty,
        })
    }

    /// Reads the frame `recorded` into `target` once the submission that carried it has been
    /// waited on; `gpu_timings` are that wait's pass times (they go into the frame as they are).
    /// `out`, when given, receives the pixels instead of the frame's vectors (it must have the
    /// target's size, and the recording must have read back).
    pub fn finish_frame(
        &self,
        target: &RenderTarget,
        recorded: RecordedFrame,
        gpu_timings: Vec<PassTiming>,
        out: Option<&mut [u8]>,
    ) -> GpuResult<Frame> {
        let RecordedFrame {
            read_back,
            count,
            skipped_empty_space,
        } = recorded;
        if out.is_some() && !read_back {
            return Err(GpuError::InvalidRequest(
                "an output buffer was given for a frame recorded without readback (set \
                 RenderTarget::read_back before recording)"
                    .into(),
            ));
        }
        let mut bytes = Vec::new();
        if let Some(out) = out {
            let needed = target.readback.size() as usize;
            if out.len() != needed {
                return Err(GpuError::InvalidRequest(format!(
                    "the output buffer has {} bytes; a {}x{} frame needs {needed}",
                    out.len(),
                    target.width,
                    target.height
                )));
            }
            target.readback.read(0, out)?;
        } else if read_back {
            bytes = vec![0u8; target.readback.size() as usize];
            target.readback.read(0, &mut bytes)?;
        }
        let (rgba8, values) = if bytes.is_empty() {
            (Vec::new(), Vec::new())
        } else if target.image.format() == vk::Format::R8G8B8A8_UNORM {
            (bytes, Vec::new())
        } else {
            (
                Vec::new(),
                super::readback::decode(target.image.format(), &bytes)?,
            )
        };
        let samples = if count {
            let mut words = vec![0u8; COUNTER_WORDS * 4];
            target.counters_host.read(0, &mut words)?;
            let mut counts = SampleCounts::default();
            for (i, w) in words.chunks_exact(4).enumerate() {
                let v = u32::from_le_bytes([w[0], w[1], w[2], w[3]]) as u64;
                if i % 2 == 0 {
                    counts.marched += v;
                } else {
                    counts.classified += v;
                }
            }
            Some(counts)
        } else {
            None
        };
        Ok(Frame {
            width: target.width,
            height: target.height,
            rgba8,
            values,
            gpu_timings,
            samples,
            skipped_empty_space,
        })
    }
}
