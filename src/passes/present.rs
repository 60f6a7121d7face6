//! Composing a frame: the raymarched image, the egui interface over it, then the window.
//!
//! Decisions:
//! - egui-ash-renderer draws the interface (it is built on the same ash 0.38 and gpu-allocator
//!   0.28 as the engine, supports dynamic rendering, and needs no render pass or framebuffer
//!   objects); it gets its own gpu-allocator instance on the engine's device, so its buffers
//!   never appear in the engine's memory ledger of volumes.
//! - Every frame is composed in one image the viewer owns (RGBA8 UNORM, like the raymarch and
//!   PNG output): clear, blit the raymarch target into the 3D view's rectangle, draw egui over
//!   it, then blit the result into the swapchain image. Screenshots and `--offscreen` read this
//!   image, so they show exactly what the window shows.
//! - One submission per frame, in three timed passes (`compose`, `interface`, `to window`),
//!   waiting for the acquire semaphore at the transfer stage and signalling the present's
//!   semaphore. Frames in flight: [`FRAMES_IN_FLIGHT`]; a slot's submission is waited for before
//!   the slot's command resources, acquire semaphore and raymarch target are reused.
//! - egui texture uploads (font atlas, rarely) block until the queue is idle inside the
//!   renderer (egui-ash-renderer), so they happen before recording, never inside a timed pass,
//!   and only after waiting for the frames in flight (an upload may rewrite a texture they sample).
//!   Textures egui frees are destroyed once the frame that last drew them has finished.

use crate::gpu::FRAMES_IN_FLIGHT;
use crate::gpu::error::vk_err;
use crate::gpu::swapchain::Acquired;
use crate::gpu::{
    Access, Buffer, BufferDesc, Device, GpuError, GpuResult, Image, ImageDesc, PassTiming,
    Recording, Submission,
};
use ash::vk;
use egui_ash_renderer::allocator::GpuAllocator;
use egui_ash_renderer::{DynamicRendering, Options, RenderMode, Renderer};
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};
use std::sync::{Arc, Mutex};

/// Format of the composed frame (and of the raymarch target).
pub const COMPOSITE_FORMAT: vk::Format = vk::Format::R8G8B8A8_UNORM;

/// The blit of a raymarch target of `extent` into `rect` (x, y, w, h) of a `frame`-sized image:
/// (source rectangle, destination rectangle, filter). A target of the rectangle's size is
/// copied pixel for pixel; a smaller one (adaptive quality's image scale) is stretched over it
/// with linear filtering, so a coarse frame is softer rather than blocky. Either is clipped to
/// the frame, the source in proportion.
fn blit_rects(
    extent: [u32; 2],
    rect: [u32; 4],
    frame: [u32; 2],
) -> ([u32; 4], [u32; 4], vk::Filter) {
    let w = rect[2].min(frame[0].saturating_sub(rect[0]));
    let h = rect[3].min(frame[1].saturating_sub(rect[1]));
    if extent[0] >= rect[2] && extent[1] >= rect[3] {
        let (w, h) = (w.min(extent[0]), h.min(extent[1]));
        return ([0, 0, w, h], [rect[0], rect[1], w, h], vk::Filter::NEAREST);
    }
    let part = |n: u32, of: u32, side: u32| {
        ((n as u64 * side as u64).div_ceil(of.max(1) as u64) as u32).min(side)
    };
    (
        [
            0,
            0,
            part(w, rect[2], extent[0]),
            part(h, rect[3], extent[1]),
        ],
        [rect[0], rect[1], w, h],
        vk::Filter::LINEAR,
    )
}

/// A finished frame's GPU times.
#[derive(Clone, Debug)]
pub struct Completed {
    /// The frame's serial number (as passed to [`Painter::paint`]).
    pub serial: u64,
    /// GPU time per pass of the composition.
    pub passes: Vec<PassTiming>,
}

/// What to draw in one frame.
pub struct FrameSpec<'a> {
    /// Serial number, for [`Completed`].
    pub serial: u64,
    /// Frame size in pixels.
    pub size: [u32; 2],
    /// The raymarch target (in `Access::ComputeWriteImage` if `fresh`, else already in
    /// `Access::TransferRead` from an earlier frame) and the rectangle (x, y, w, h) in pixels it
    /// fills.
    pub raymarch: Option<(&'a Arc<Image>, bool, [u32; 4])>,
    /// Index of that target in the viewer's set (to know which frames read it).
    pub target_index: Option<usize>,
    /// Clear colour of the frame.
    pub clear: [f32; 4],
    /// Tessellated interface.
    pub primitives: &'a [egui::ClippedPrimitive],
    /// egui's pixels per point.
    pub pixels_per_point: f32,
    /// Texture changes to apply before drawing and free after.
    pub textures: egui::TexturesDelta,
    /// The swapchain image to copy the frame into (window mode).
    pub window: Option<Acquired>,
    /// Also copy the frame to host memory (read with [`Painter::screenshot`]).
    pub screenshot: bool,
}

struct Slot {
    submission: Option<Submission>,
    serial: u64,
    reads_target: Option<usize>,
    free: Vec<egui::TextureId>,
}

/// The frame composer.
pub struct Painter {
    slots: Vec<Slot>,
    next_slot: usize,
    renderer: Option<Renderer<GpuAllocator>>,
    egui_allocator: Option<Arc<Mutex<Allocator>>>,
    upload_pool: vk::CommandPool,
    composite: Option<(Arc<Image>, Access)>,
    readback: Option<Arc<Buffer>>,
    completed: Vec<Completed>,
    device: Device,
}

impl Painter {
    /// Creates the egui renderer on `device` (which must have been created for presentation:
    /// dynamic rendering, graphics queue).
    pub fn new(device: &Device) -> GpuResult<Painter> {
        let instance = device.instance();
        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: instance.raw().clone(),
            device: device.raw().clone(),
            physical_device: device.physical(),
            debug_settings: Default::default(),
            buffer_device_address: false,
            allocation_sizes: Default::default(),
        })
        .map_err(|e| GpuError::OutOfDeviceMemory {
            during: "creating the interface's allocator".into(),
            detail: e.to_string(),
        })?;
        let allocator = Arc::new(Mutex::new(allocator));
        let pool_info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(device.adapter().queue_family)
            .flags(vk::CommandPoolCreateFlags::TRANSIENT);
        // SAFETY: valid create info on a live device.
        let upload_pool = unsafe { device.raw().create_command_pool(&pool_info, None) }
            .map_err(vk_err("vkCreateCommandPool"))?;
        let renderer = Renderer::with_gpu_allocator(
            allocator.clone(),
            device.raw().clone(),
            RenderMode::DynamicRendering(DynamicRendering {
                color_attachment_format: COMPOSITE_FORMAT,
                depth_attachment_format: None,
                stencil_attachment_format: None,
            }),
            Options {
                in_flight_frames: FRAMES_IN_FLIGHT,
                enable_depth_test: false,
                enable_depth_write: false,
                srgb_framebuffer: false,
            },
        );
        let renderer = match renderer {
            Ok(r) => r,
            Err(e) => {
                // SAFETY: the pool was never used.
                unsafe { device.raw().destroy_command_pool(upload_pool, None) };
                return Err(renderer_error("creating the interface renderer", e));
            }
        };
        Ok(Painter {
            slots: (0..FRAMES_IN_FLIGHT)
                .map(|_| Slot {
                    submission: None,
                    serial: 0,
                    reads_target: None,
                    free: Vec::new(),
                })
                .collect(),
            next_slot: 0,
            renderer: Some(renderer),
            egui_allocator: Some(allocator),
            upload_pool,
            composite: None,
            readback: None,
            completed: Vec::new(),
            device: device.clone(),
        })
    }

    /// The slot the next frame uses.
    pub fn next_slot(&self) -> usize {
        self.next_slot
    }

    /// Waits for the frame in `slot` (if any) and records its times in `Painter::completed`.
    pub fn wait_slot(&mut self, slot: usize) -> GpuResult<()> {
        let Some(s) = self.slots.get_mut(slot) else {
            return Ok(());
        };
        if let Some(submission) = s.submission.take() {
            let serial = s.serial;
            let passes = submission.wait()?;
            self.completed.push(Completed { serial, passes });
        }
        s.reads_target = None;
        if !s.free.is_empty() {
            let free = std::mem::take(&mut s.free);
            if let Some(renderer) = &mut self.renderer {
                for id in free {
                    renderer
                        .free_texture(id)
                        .map_err(|e| renderer_error("freeing an interface texture", e))?;
                }
            }
        }
        Ok(())
    }

    /// Waits for every frame in flight.
    pub fn wait_all(&mut self) -> GpuResult<()> {
        for slot in 0..self.slots.len() {
            self.wait_slot(slot)?;
        }
        Ok(())
    }

    /// Waits for the frames that read raymarch target `index` (before it is rendered into).
    pub fn release_target(&mut self, index: usize) -> GpuResult<()> {
        for slot in 0..self.slots.len() {
            if self.slots[slot].reads_target == Some(index) {
                self.wait_slot(slot)?;
            }
        }
        Ok(())
    }

    /// GPU times of frames finished since the last call, oldest first.
    pub fn take_completed(&mut self) -> Vec<Completed> {
        let mut done = std::mem::take(&mut self.completed);
        done.sort_by_key(|c| c.serial);
        done
    }

    fn composite(&mut self, size: [u32; 2]) -> GpuResult<(Arc<Image>, Access)> {
        if let Some((image, access)) = &self.composite
            && image.extent()[0] == size[0]
            && image.extent()[1] == size[1]
        {
            return Ok((image.clone(), *access));
        }
        // A new size: the frames in flight may still read the old image and buffer; they
        // hold Arcs of them, and `wait_all` below also keeps the readback from being reused.
        self.wait_all()?;
        let image = Image::new(
            &self.device,
            ImageDesc {
                name: "composed frame".into(),
                extent: [size[0], size[1], 1],
                format: COMPOSITE_FORMAT,
                usage: vk::ImageUsageFlags::COLOR_ATTACHMENT
                    | vk::ImageUsageFlags::TRANSFER_SRC
                    | vk::ImageUsageFlags::TRANSFER_DST,
                image_type: vk::ImageType::TYPE_2D,
            },
        )?;
        let readback = Buffer::new(
            &self.device,
            BufferDesc::readback("composed frame (host)", size[0] as u64 * size[1] as u64 * 4),
        )?;
        self.composite = Some((image.clone(), Access::Nothing));
        self.readback = Some(readback);
        Ok((image, Access::Nothing))
    }

    /// Records and submits one frame in the next slot (the caller waited for that slot with
    /// [`Painter::wait_slot`] before acquiring its swapchain image). `frame` is a recording the
    /// caller began with this frame's compute work (the raymarch, through
    /// `Engine::record_render`): the composition is appended to it, so the frame is one
    /// submission and the host never waits for the raymarch on its own; its pass times come
    /// back with the composition's in [`Completed`].
    pub fn paint(&mut self, mut spec: FrameSpec, frame: Option<Recording>) -> GpuResult<()> {
        // Whatever happens below, the deltas are consumed (egui asserts that in debug builds).
        let mut textures = Deltas(std::mem::take(&mut spec.textures));
        let slot = self.next_slot;
        self.wait_slot(slot)?;
        let (composite, before) = self.composite(spec.size)?;
        let readback = self
            .readback
            .clone()
            .ok_or_else(|| GpuError::InvalidRequest("no readback buffer".into()))?;

        // Texture uploads and frees, outside any timed pass (module docs).
        if !textures.0.set.is_empty() {
            self.wait_all()?;
            let pool = self.upload_pool;
            let Some(renderer) = self.renderer.as_mut() else {
                return Err(GpuError::InvalidRequest(
                    "the interface renderer is gone".into(),
                ));
            };
            for (id, deltas) in &textures.0.set {
                for delta in deltas {
                    self.device
                        .with_queue(|queue| renderer.set_texture(queue, pool, *id, delta))?
                        .map_err(|e| renderer_error("uploading an interface texture", e))?;
                }
            }
        }

        let [width, height] = spec.size;
        let mut rec = match frame {
            Some(rec) => rec,
            None => Recording::new(&self.device, "frame composition")?,
        };
        rec.begin_pass("compose");
        // Orders the previous frame's read of the composed image (copy to the window) before
        // this frame's clear, and moves it to TRANSFER_DST.
        rec.barriers(&[], &[(&composite, before, Access::TransferWrite)]);
        rec.clear_colour(&composite, spec.clear);
        if let Some((target, fresh, rect)) = spec.raymarch {
            let target_before = if fresh {
                Access::ComputeWriteImage
            } else {
                Access::TransferRead
            };
            // Orders the raymarch's writes before the copy that reads them (TRANSFER_SRC), and
            // the clear before the copy's writes to the same image.
            rec.barriers(
                &[],
                &[
                    (target, target_before, Access::TransferRead),
                    (&composite, Access::TransferWrite, Access::TransferWrite),
                ],
            );
            let (src, dst, filter) = blit_rects(
                [target.extent()[0], target.extent()[1]],
                rect,
                [width, height],
            );
            if dst[2] > 0 && dst[3] > 0 && src[2] > 0 && src[3] > 0 {
                rec.blit(target, src, composite.raw, dst, filter);
            }
        }
        // Orders the clear and copy before egui blends over them (attachment reads and writes).
        rec.barriers(
            &[],
            &[(&composite, Access::TransferWrite, Access::ColorAttachment)],
        );
        rec.begin_pass("interface");
        let extent = vk::Extent2D { width, height };
        let attachment = [vk::RenderingAttachmentInfo::default()
            .image_view(composite.view)
            .image_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
            .load_op(vk::AttachmentLoadOp::LOAD)
            .store_op(vk::AttachmentStoreOp::STORE)];
        let rendering = vk::RenderingInfo::default()
            .render_area(vk::Rect2D {
                offset: vk::Offset2D::default(),
                extent,
            })
            .layer_count(1)
            .color_attachments(&attachment);
        let cmd = rec.command_buffer();
        let Some(renderer) = self.renderer.as_mut() else {
            return Err(GpuError::InvalidRequest(
                "the interface renderer is gone".into(),
            ));
        };
        // SAFETY: the command buffer is recording; the composed image is kept alive by the
        // recording (barriers keep it) and in COLOR_ATTACHMENT_OPTIMAL.
        unsafe { self.device.raw().cmd_begin_rendering(cmd, &rendering) };
        let drawn = renderer.cmd_draw(cmd, extent, spec.pixels_per_point, spec.primitives);
        // SAFETY: matches the begin above.
        unsafe { self.device.raw().cmd_end_rendering(cmd) };
        drawn.map_err(|e| renderer_error("recording the interface", e))?;
        // Orders egui's attachment writes before the copies that read the composed image.
        rec.barriers(
            &[],
            &[(&composite, Access::ColorAttachment, Access::TransferRead)],
        );
        if spec.screenshot {
            rec.copy_image_to_buffer(&composite, &readback);
            // Makes the copied pixels visible to the host.
            rec.barriers(&[(&readback, Access::TransferWrite, Access::HostRead)], &[]);
        }
        let mut waits = Vec::new();
        let mut signals = Vec::new();
        if let Some(window) = &spec.window {
            rec.begin_pass("to window");
            // Chains with the acquire semaphore's wait (transfer stage) and moves the
            // swapchain image to TRANSFER_DST, discarding what it showed before.
            rec.external_image_barriers(&[(
                window.image,
                Access::SwapchainAcquired,
                Access::TransferWrite,
            )]);
            let w = width.min(window.extent.width);
            let h = height.min(window.extent.height);
            rec.blit(
                &composite,
                [0, 0, w, h],
                window.image,
                [0, 0, w, h],
                vk::Filter::NEAREST,
            );
            // Makes the copy available to the presentation engine (through the signal
            // semaphore) and moves the image to PRESENT_SRC.
            rec.external_image_barriers(&[(window.image, Access::TransferWrite, Access::Present)]);
            waits.push((window.wait, vk::PipelineStageFlags2::ALL_TRANSFER));
            signals.push(window.signal);
        }
        rec.keep(readback);
        let submission = rec.submit_with_semaphores(&waits, &signals)?;
        self.composite = Some((composite, Access::TransferRead));
        let s = &mut self.slots[slot];
        s.submission = Some(submission);
        s.serial = spec.serial;
        s.reads_target = spec.target_index;
        s.free = std::mem::take(&mut textures.0.free).into_iter().collect();
        self.next_slot = (slot + 1) % self.slots.len();
        Ok(())
    }

    /// Waits for every frame and returns the last composed frame's RGBA8 pixels (the frame must
    /// have been painted with `screenshot: true`).
    pub fn screenshot(&mut self) -> GpuResult<(u32, u32, Vec<u8>)> {
        self.wait_all()?;
        let (Some((image, _)), Some(readback)) = (&self.composite, &self.readback) else {
            return Err(GpuError::InvalidRequest("no frame was drawn yet".into()));
        };
        let [w, h, _] = image.extent();
        let mut pixels = vec![0u8; w as usize * h as usize * 4];
        readback.read(0, &mut pixels)?;
        Ok((w, h, pixels))
    }
}

impl Drop for Painter {
    fn drop(&mut self) {
        // Frames in flight use the renderer's buffers and the composed image: wait first (a
        // failed wait leaks them instead, see Submission's Drop).
        for slot in &mut self.slots {
            drop(slot.submission.take());
        }
        // The renderer frees its objects through its allocator and the device.
        drop(self.renderer.take());
        drop(self.egui_allocator.take());
        // SAFETY: the frames that used the upload pool have finished (uploads wait for idle).
        unsafe {
            self.device
                .raw()
                .destroy_command_pool(self.upload_pool, None)
        };
    }
}

/// A host copy of every egui texture, so a new painter (after a device loss) can be given
/// the textures egui sent to the old one: egui sends each texture once and then only changes.
#[derive(Default)]
pub struct TextureMirror {
    textures: std::collections::HashMap<egui::TextureId, (egui::ColorImage, egui::TextureOptions)>,
}

impl TextureMirror {
    /// Applies a frame's texture changes to the copies.
    pub fn record(&mut self, delta: &egui::TexturesDelta) {
        for (id, deltas) in &delta.set {
            for d in deltas {
                let egui::ImageData::Color(image) = &d.image;
                match d.pos {
                    None => {
                        self.textures.insert(*id, ((**image).clone(), d.options));
                    }
                    Some([x0, y0]) => {
                        let Some((full, options)) = self.textures.get_mut(id) else {
                            continue;
                        };
                        *options = d.options;
                        let [w, h] = image.size;
                        for y in 0..h {
                            for x in 0..w {
                                let (tx, ty) = (x0 + x, y0 + y);
                                if tx < full.size[0] && ty < full.size[1] {
                                    full.pixels[ty * full.size[0] + tx] = image.pixels[y * w + x];
                                }
                            }
                        }
                    }
                }
            }
        }
        for id in &delta.free {
            self.textures.remove(id);
        }
    }

    /// Every texture as a full upload.
    pub fn full_upload(&self) -> egui::TexturesDelta {
        let mut delta = egui::TexturesDelta::default();
        for (id, (image, options)) in &self.textures {
            let full = egui::epaint::ImageDelta::full(image.clone(), *options);
            delta.set.insert(*id, [full].into_iter().collect());
        }
        delta
    }
}

/// Texture changes that are cleared when dropped (applied, deferred, or lost with the frame).
struct Deltas(egui::TexturesDelta);

impl Drop for Deltas {
    fn drop(&mut self) {
        self.0.clear();
    }
}

fn renderer_error(during: &str, e: egui_ash_renderer::RendererError) -> GpuError {
    match e {
        egui_ash_renderer::RendererError::Vulkan(r) => GpuError::from_vk("egui-ash-renderer", r),
        egui_ash_renderer::RendererError::GpuAllocator(
            gpu_allocator::AllocationError::OutOfMemory,
        ) => GpuError::OutOfDeviceMemory {
            during: during.into(),
            detail: "the interface's vertex or texture memory".into(),
        },
        other => GpuError::InvalidRequest(format!("{during}: {other}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_smaller_target_is_stretched_over_the_view_and_clipped_in_proportion() {
        // Full size: a copy (nearest), clipped to the frame.
        let (src, dst, filter) = blit_rects([200, 100], [10, 20, 200, 100], [150, 400]);
        assert_eq!(
            (src, dst, filter),
            ([0, 0, 140, 100], [10, 20, 140, 100], vk::Filter::NEAREST)
        );
        // Half size: stretched (linear) over the whole rectangle.
        let (src, dst, filter) = blit_rects([100, 50], [10, 20, 200, 100], [640, 480]);
        assert_eq!(
            (src, dst, filter),
            ([0, 0, 100, 50], [10, 20, 200, 100], vk::Filter::LINEAR)
        );
        // Half size, the frame cuts the rectangle at 140 of 200 pixels: 70 source pixels.
        let (src, dst, _) = blit_rects([100, 50], [10, 20, 200, 100], [150, 400]);
        assert_eq!((src, dst), ([0, 0, 70, 50], [10, 20, 140, 100]));
    }
}
