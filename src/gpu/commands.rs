//! Command recording and submission; resources stay alive until the GPU is done with them.
//!
//! Decisions:
//! - A [`Recording`] leases its command pool and buffer, fence, timestamp query pool and
//!   breadcrumb buffer from the device's recycler (`recycler.rs`: Granite's per-frame context,
//!   screen-13's leases), and collects an `Arc` of every resource it records a command on; the
//!   [`Submission`] it becomes holds both until its fence signals (screen-13's `cmd_buf.rs`), then
//!   gives the lease back. Dropping a submission without waiting waits, so nothing the GPU may
//!   still read is ever destroyed or reused; a recording dropped unsubmitted gives its lease back
//!   at once. A lease whose work was lost or timed out is leaked, never reused.
//! - Each pass is bracketed by timestamps and, for a lost device, a breadcrumb: after a pass the
//!   recording writes its number into its own slot of a small host-visible buffer, so a device-lost
//!   error names the first pass that never finished (kajiya's crash marker).
//! - Barriers come only from `sync.rs`'s vocabulary and are batched into one
//!   `vkCmdPipelineBarrier2` per call.

use super::buffer::Buffer;
use super::descriptors::DescriptorSet;
use super::device::{Device, DeviceShared};
use super::error::{GpuError, GpuResult, vk_err};
use super::image::Image;
use super::pipeline::ComputePipeline;
use super::recycler::Lease;
use super::sync::{Access, buffer_barrier, image_barrier};
use super::timestamps::{MAX_PASSES, PassTiming, TimestampPool};
use ash::vk;
use std::any::Any;
use std::sync::Arc;

/// How long a wait may take before the engine reports a timeout instead of hanging forever.
const WAIT_LIMIT_NS: u64 = 120 * 1_000_000_000;

/// Commands being recorded for one submission.
pub struct Recording {
    device: Arc<DeviceShared>,
    // Some until submitted (then the submission holds it) or dropped (then given back).
    lease: Option<Lease>,
    cmd: vk::CommandBuffer,
    // The device's breadcrumb buffer and the byte offset of this recording's slot in it.
    crumbs: Option<(vk::Buffer, u64)>,
    keep_alive: Vec<Arc<dyn Any + Send + Sync>>,
    timestamps: Option<TimestampPool>,
    pass_names: Vec<String>,
    pass_open: bool,
    label: String,
}

impl Recording {
    /// Starts recording; `label` names the work in errors.
    pub fn new(device: &Device, label: &str) -> GpuResult<Recording> {
        let shared = device.shared.clone();
        let lease = shared.recycler.lease(&shared)?;
        let recording = Recording {
            cmd: lease.cmd,
            crumbs: lease
                .crumbs
                .map(|(buffer, slot)| (buffer, Lease::crumb_offset(slot))),
            timestamps: TimestampPool::new(&shared, lease.queries),
            lease: Some(lease),
            device: shared,
            keep_alive: Vec::new(),
            pass_names: Vec::new(),
            pass_open: false,
            label: label.to_string(),
        };
        let begin = vk::CommandBufferBeginInfo::default()
            .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
        // SAFETY: the leased command buffer is in the initial state (its pool was reset when the
        // lease came back). On error the recording drops and gives the lease back.
        unsafe {
            recording
                .device
                .raw
                .begin_command_buffer(recording.cmd, &begin)
        }
        .map_err(vk_err("vkBeginCommandBuffer"))?;
        if let Some(t) = &recording.timestamps {
            t.reset(&recording.device, recording.cmd);
        }
        Ok(recording)
    }

    /// Identity of the leased command pool, for tests of reuse.
    #[cfg(test)]
    pub(crate) fn lease_id(&self) -> u64 {
        self.lease.as_ref().map_or(0, |l| l.id())
    }

    /// Keeps `resource` alive until this work has completed.
    pub fn keep<T: Any + Send + Sync>(&mut self, resource: Arc<T>) {
        self.keep_alive.push(resource);
    }

    /// Starts a named, timed pass.
    pub fn begin_pass(&mut self, name: &str) {
        if self.pass_open {
            self.end_pass();
        }
        if let Some(t) = &mut self.timestamps {
            t.begin(&self.device, self.cmd, name);
        }
        if let Some(utils) = &self.device.debug_utils
            && let Ok(label) = std::ffi::CString::new(name.replace('\0', " "))
        {
            let info = vk::DebugUtilsLabelEXT::default().label_name(&label);
            // SAFETY: a command buffer in the recording state; the label is closed in end_pass.
            unsafe { utils.cmd_begin_debug_utils_label(self.cmd, &info) };
        }
        self.pass_names.push(name.to_string());
        self.pass_open = true;
    }

    /// Ends the open pass: writes its end timestamp and its breadcrumb.
    pub fn end_pass(&mut self) {
        if !self.pass_open {
            return;
        }
        self.pass_open = false;
        if let Some(t) = &self.timestamps {
            t.end(&self.device, self.cmd);
        }
        if let Some(utils) = &self.device.debug_utils {
            // SAFETY: closes the label begin_pass opened in this command buffer.
            unsafe { utils.cmd_end_debug_utils_label(self.cmd) };
        }
        let index = self.pass_names.len() as u64 - 1;
        if let Some((buffer, base)) = self.crumbs
            && index < MAX_PASSES as u64
        {
            // SAFETY: the breadcrumb buffer lives as long as the device; this recording's lease
            // owns the slot at `base`, and each pass writes only its own 4-byte word of it, so
            // the fills never overlap.
            unsafe {
                self.device
                    .raw
                    .cmd_fill_buffer(self.cmd, buffer, base + 4 * index, 4, 1)
            };
        }
    }

    /// Binds `pipeline` and `sets`, pushes `push` and dispatches `groups` workgroups.
    pub fn dispatch(
        &mut self,
        pipeline: &Arc<ComputePipeline>,
        sets: &[Arc<DescriptorSet>],
        push: &[u8],
        groups: [u32; 3],
    ) -> GpuResult<()> {
        let shader = pipeline.shader();
        if push.len() as u32 != shader.push_constant_bytes {
            return Err(GpuError::InvalidRequest(format!(
                "shader {} takes {} bytes of push constants, got {}",
                shader.name,
                shader.push_constant_bytes,
                push.len()
            )));
        }
        let limit = self.device.adapter.max_workgroup_count_x;
        if groups.iter().any(|&g| g > limit) {
            return Err(GpuError::InvalidRequest(format!(
                "dispatch of {groups:?} workgroups for {} exceeds the device limit of {limit}",
                shader.name
            )));
        }
        if groups.contains(&0) {
            return Ok(());
        }
        let raw = &self.device.raw;
        // SAFETY: all handles are alive and kept alive by this recording until completion.
        unsafe {
            raw.cmd_bind_pipeline(self.cmd, vk::PipelineBindPoint::COMPUTE, pipeline.raw);
            for set in sets {
                raw.cmd_bind_descriptor_sets(
                    self.cmd,
                    vk::PipelineBindPoint::COMPUTE,
                    pipeline.layout,
                    set.set_index,
                    &[set.raw],
                    &[],
                );
            }
            if !push.is_empty() {
                raw.cmd_push_constants(
                    self.cmd,
                    pipeline.layout,
                    vk::ShaderStageFlags::COMPUTE,
                    0,
                    push,
                );
            }
            raw.cmd_dispatch(self.cmd, groups[0], groups[1], groups[2]);
        }
        self.keep(pipeline.clone());
        for set in sets {
            self.keep(set.clone());
        }
        Ok(())
    }

    /// Records the barriers between uses of the given buffers and images, in one call.
    pub fn barriers(
        &mut self,
        buffers: &[(&Arc<Buffer>, Access, Access)],
        images: &[(&Arc<Image>, Access, Access)],
    ) {
        let buffer_barriers: Vec<_> = buffers
            .iter()
            .filter_map(|(b, before, after)| buffer_barrier(b.raw, *before, *after))
            .collect();
        let image_barriers: Vec<_> = images
            .iter()
            .map(|(i, before, after)| image_barrier(i.raw, *before, *after))
            .collect();
        if buffer_barriers.is_empty() && image_barriers.is_empty() {
            return;
        }
        for (b, ..) in buffers {
            self.keep((*b).clone());
        }
        for (i, ..) in images {
            self.keep((*i).clone());
        }
        let dependency = vk::DependencyInfo::default()
            .buffer_memory_barriers(&buffer_barriers)
            .image_memory_barriers(&image_barriers);
        // SAFETY: handles alive; barriers built from the access table.
        unsafe { self.device.raw.cmd_pipeline_barrier2(self.cmd, &dependency) };
    }

    /// Fills `size` bytes at `offset` with the 32-bit `value`.
    pub fn fill_buffer(&mut self, buffer: &Arc<Buffer>, offset: u64, size: u64, value: u32) {
        // SAFETY: buffer alive and kept alive.
        unsafe {
            self.device
                .raw
                .cmd_fill_buffer(self.cmd, buffer.raw, offset, size, value)
        };
        self.keep(buffer.clone());
    }

    /// Copies `size` bytes from the start of `src` to the start of `dst`.
    pub fn copy_buffer(&mut self, src: &Arc<Buffer>, dst: &Arc<Buffer>, size: u64) {
        let region = [vk::BufferCopy {
            src_offset: 0,
            dst_offset: 0,
            size,
        }];
        // SAFETY: buffers alive and kept alive; sizes checked by the caller's allocation.
        unsafe {
            self.device
                .raw
                .cmd_copy_buffer(self.cmd, src.raw, dst.raw, &region)
        };
        self.keep(src.clone());
        self.keep(dst.clone());
    }

    /// Copies a whole image (in TRANSFER_SRC_OPTIMAL) into a tightly packed buffer.
    pub fn copy_image_to_buffer(&mut self, src: &Arc<Image>, dst: &Arc<Buffer>) {
        let extent = src.extent();
        let region = [image_region(extent)];
        // SAFETY: image alive, in the layout the barrier before this call established.
        unsafe {
            self.device.raw.cmd_copy_image_to_buffer(
                self.cmd,
                src.raw,
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                dst.raw,
                &region,
            )
        };
        self.keep(src.clone());
        self.keep(dst.clone());
    }

    /// Copies a tightly packed buffer into a whole image (in TRANSFER_DST_OPTIMAL).
    pub fn copy_buffer_to_image(&mut self, src: &Arc<Buffer>, dst: &Arc<Image>) {
        let region = [image_region(dst.extent())];
        // SAFETY: as above.
        unsafe {
            self.device.raw.cmd_copy_buffer_to_image(
                self.cmd,
                src.raw,
                dst.raw,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                &region,
            )
        };
        self.keep(src.clone());
        self.keep(dst.clone());
    }

    /// Copies regions of a buffer into an image (in TRANSFER_DST_OPTIMAL).
    pub fn copy_buffer_to_image_regions(
        &mut self,
        src: &Arc<Buffer>,
        dst: &Arc<Image>,
        regions: &[vk::BufferImageCopy],
    ) {
        if regions.is_empty() {
            return;
        }
        // SAFETY: buffer and image alive and kept alive; the regions were computed from their
        // sizes by the caller; the image is in the layout the barrier before this established.
        unsafe {
            self.device.raw.cmd_copy_buffer_to_image(
                self.cmd,
                src.raw,
                dst.raw,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                regions,
            )
        };
        self.keep(src.clone());
        self.keep(dst.clone());
    }

    /// The command buffer being recorded, for a third-party recorder (the viewer's egui
    /// renderer). Whatever such a recorder uses must outlive this work: keep it with
    /// [`Recording::keep`] or wait for the submission before destroying it.
    pub fn command_buffer(&self) -> vk::CommandBuffer {
        self.cmd
    }

    /// Records barriers on images this crate does not own (swapchain images), in one call; the
    /// owner keeps them alive until the submission completes.
    pub fn external_image_barriers(&mut self, images: &[(vk::Image, Access, Access)]) {
        let image_barriers: Vec<_> = images
            .iter()
            .map(|(i, before, after)| image_barrier(*i, *before, *after))
            .collect();
        if image_barriers.is_empty() {
            return;
        }
        let dependency = vk::DependencyInfo::default().image_memory_barriers(&image_barriers);
        // SAFETY: the caller guarantees the images are alive; barriers from the access table.
        unsafe { self.device.raw.cmd_pipeline_barrier2(self.cmd, &dependency) };
    }

    /// Clears a whole colour image (in TRANSFER_DST_OPTIMAL) to `rgba`.
    pub fn clear_colour(&mut self, image: &Arc<Image>, rgba: [f32; 4]) {
        let colour = vk::ClearColorValue { float32: rgba };
        // SAFETY: image alive and kept alive, in the layout the caller's barrier established.
        unsafe {
            self.device.raw.cmd_clear_color_image(
                self.cmd,
                image.raw,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                &colour,
                &[super::image::full_range()],
            )
        };
        self.keep(image.clone());
    }

    /// Copies the rectangle `src_rect` (x, y, width, height) of the 2D image `src` (in
    /// TRANSFER_SRC_OPTIMAL) onto `dst_rect` of `dst` (in TRANSFER_DST_OPTIMAL), converting
    /// formats and scaling with `filter` when the sizes differ. `dst` may be an image this crate
    /// does not own (a swapchain image): its owner keeps it alive.
    pub fn blit(
        &mut self,
        src: &Arc<Image>,
        src_rect: [u32; 4],
        dst: vk::Image,
        dst_rect: [u32; 4],
        filter: vk::Filter,
    ) {
        let corners = |r: [u32; 4]| {
            [
                vk::Offset3D {
                    x: r[0] as i32,
                    y: r[1] as i32,
                    z: 0,
                },
                vk::Offset3D {
                    x: (r[0] + r[2]) as i32,
                    y: (r[1] + r[3]) as i32,
                    z: 1,
                },
            ]
        };
        let layers = vk::ImageSubresourceLayers {
            aspect_mask: vk::ImageAspectFlags::COLOR,
            mip_level: 0,
            base_array_layer: 0,
            layer_count: 1,
        };
        let region = [vk::ImageBlit {
            src_subresource: layers,
            src_offsets: corners(src_rect),
            dst_subresource: layers,
            dst_offsets: corners(dst_rect),
        }];
        // SAFETY: both images alive (src kept by this recording, dst by its owner), in the
        // layouts the caller's barriers established.
        unsafe {
            self.device.raw.cmd_blit_image(
                self.cmd,
                src.raw,
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                dst,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                &region,
                filter,
            )
        };
        self.keep(src.clone());
    }

    /// Ends recording and submits to the compute queue.
    pub fn submit(self) -> GpuResult<Submission> {
        self.submit_with_semaphores(&[], &[])
    }

    /// Ends recording and submits, waiting for each `(semaphore, stage)` before that stage of
    /// this work runs and signalling `signal` when all of it is done (swapchain acquire and
    /// present). The semaphores' owner keeps them alive until the submission completes.
    pub fn submit_with_semaphores(
        mut self,
        wait: &[(vk::Semaphore, vk::PipelineStageFlags2)],
        signal: &[vk::Semaphore],
    ) -> GpuResult<Submission> {
        self.end_pass();
        let device = self.device.clone();
        // SAFETY: the command buffer is in the recording state.
        unsafe { device.raw.end_command_buffer(self.cmd) }.map_err(vk_err("vkEndCommandBuffer"))?;
        let Some(lease) = self.lease.take() else {
            return Err(GpuError::Internal(format!(
                "recording `{}` has no command buffer",
                self.label
            )));
        };
        let cmd_info = [vk::CommandBufferSubmitInfo::default().command_buffer(self.cmd)];
        let wait_infos: Vec<_> = wait
            .iter()
            .map(|(semaphore, stage)| {
                vk::SemaphoreSubmitInfo::default()
                    .semaphore(*semaphore)
                    .stage_mask(*stage)
            })
            .collect();
        let signal_infos: Vec<_> = signal
            .iter()
            .map(|semaphore| {
                vk::SemaphoreSubmitInfo::default()
                    .semaphore(*semaphore)
                    .stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
            })
            .collect();
        let submit = [vk::SubmitInfo2::default()
            .wait_semaphore_infos(&wait_infos)
            .command_buffer_infos(&cmd_info)
            .signal_semaphore_infos(&signal_infos)];
        let result = match device.queue.lock() {
            // SAFETY: the queue is externally synchronized by the mutex; cmd is executable.
            Ok(queue) => unsafe { device.raw.queue_submit2(*queue, &submit, lease.fence) }
                .map_err(vk_err("vkQueueSubmit2")),
            Err(_) => Err(GpuError::Internal(
                "the queue lock was poisoned by a panic on another thread".into(),
            )),
        };
        let submission = Submission {
            submitted_at: std::time::Instant::now(),
            device: device.clone(),
            fence: lease.fence,
            lease: Some(lease),
            keep_alive: std::mem::take(&mut self.keep_alive),
            timestamps: self.timestamps.take(),
            pass_names: std::mem::take(&mut self.pass_names),
            label: std::mem::take(&mut self.label),
            submitted: result.is_ok(),
            finished: false,
        };
        match result {
            Ok(()) => Ok(submission),
            // Not submitted: the submission's drop gives the lease back (or, for a lost
            // device, leaks it).
            Err(e) => Err(submission.lost_or(e)),
        }
    }
}

fn image_region(extent: [u32; 3]) -> vk::BufferImageCopy {
    vk::BufferImageCopy {
        buffer_offset: 0,
        buffer_row_length: 0,
        buffer_image_height: 0,
        image_subresource: vk::ImageSubresourceLayers {
            aspect_mask: vk::ImageAspectFlags::COLOR,
            mip_level: 0,
            base_array_layer: 0,
            layer_count: 1,
        },
        image_offset: vk::Offset3D::default(),
        image_extent: vk::Extent3D {
            width: extent[0],
            height: extent[1],
            depth: extent[2],
        },
    }
}

impl Drop for Recording {
    fn drop(&mut self) {
        if let Some(lease) = self.lease.take() {
            // Never submitted, so the GPU never saw it: back to the free list at once.
            if let Err(e) = self.device.recycler.give_back(&self.device, lease) {
                self.device.faults.record(&e);
            }
        }
    }
}

/// Submitted work; holds every resource it uses until its fence signals.
pub struct Submission {
    device: Arc<DeviceShared>,
    fence: vk::Fence,
    // Some until the fence was waited on and the lease given back.
    lease: Option<Lease>,
    keep_alive: Vec<Arc<dyn Any + Send + Sync>>,
    timestamps: Option<TimestampPool>,
    pass_names: Vec<String>,
    label: String,
    submitted: bool,
    finished: bool,
    // When vkQueueSubmit2 returned (places the passes on a trace's GPU track).
    submitted_at: std::time::Instant,
}

impl Submission {
    /// Waits for the work to finish and returns the GPU time of each pass (empty if the queue
    /// has no timestamps).
    pub fn wait(mut self) -> GpuResult<Vec<PassTiming>> {
        self.wait_fence()?;
        let completed = std::time::Instant::now();
        let timings = match &self.timestamps {
            Some(t) => t.results(&self.device),
            None => Ok(Vec::new()),
        };
        if let Ok(passes) = &timings {
            let named: Vec<(&str, f64)> =
                passes.iter().map(|p| (p.name.as_str(), p.gpu_ms)).collect();
            crate::files::trace::gpu_passes(self.submitted_at, completed, &named);
        }
        // The queries were read: the lease may record again.
        self.give_back()?;
        timings
    }

    /// Gives the lease back once its work completed (or was never submitted); a failed reset
    /// is returned (the lease is then destroyed, not reused).
    fn give_back(&mut self) -> GpuResult<()> {
        if self.submitted && !self.finished {
            return Ok(());
        }
        match self.lease.take() {
            Some(lease) => self.device.recycler.give_back(&self.device, lease),
            None => Ok(()),
        }
    }

    fn wait_fence(&mut self) -> GpuResult<()> {
        if self.finished || !self.submitted {
            return Ok(());
        }
        // SAFETY: the fence belongs to this device and was submitted with the work.
        let result = unsafe {
            self.device
                .raw
                .wait_for_fences(&[self.fence], true, WAIT_LIMIT_NS)
        };
        match result {
            Ok(()) => {
                self.finished = true;
                Ok(())
            }
            Err(vk::Result::TIMEOUT) => Err(GpuError::Timeout(self.label.clone())),
            Err(e) => {
                let err = GpuError::from_vk("vkWaitForFences", e);
                Err(self.lost_or(err))
            }
        }
    }

    /// Turns a device-lost error into one that names the first pass that did not finish.
    fn lost_or(&self, err: GpuError) -> GpuError {
        if !matches!(err, GpuError::DeviceLost(_)) {
            return err;
        }
        let mut crumbs = vec![0u8; 4 * self.pass_names.len().min(MAX_PASSES as usize)];
        if let Some(lease) = &self.lease {
            lease.read_crumbs(&mut crumbs);
        }
        let finished = crumbs
            .chunks_exact(4)
            .take_while(|c| c != &[0, 0, 0, 0])
            .count();
        let place = match self.pass_names.get(finished) {
            Some(pass) => format!("{} (pass `{pass}` did not finish)", self.label),
            None => self.label.clone(),
        };
        GpuError::DeviceLost(place)
    }
}

impl Drop for Submission {
    fn drop(&mut self) {
        // Never free or reuse what the GPU may still use: wait first. On a lost device or a
        // timeout the resources and the lease are leaked rather than destroyed or recycled
        // under the GPU's feet.
        if self.wait_fence().is_err() && self.submitted {
            std::mem::forget(std::mem::take(&mut self.keep_alive));
            self.lease = None;
            return;
        }
        if let Err(e) = self.give_back() {
            self.device.faults.record(&e);
        }
    }
}
