//! Command recording and submission; resources stay alive until the GPU is done with them.
//!
//! Decisions:
//! - A [`Recording`] owns its command pool and buffer and collects an `Arc` of every resource it
//!   records a command on; the [`Submission`] it becomes holds them until its fence signals
//!   (screen-13's `cmd_buf.rs`). Dropping a submission without waiting waits, so nothing the GPU
//!   may still read is ever destroyed.
//! - Each pass is bracketed by timestamps and, for a lost device, a breadcrumb: after a pass the
//!   recording writes its number into its own slot of a small host-visible buffer, so a device-lost
//!   error names the first pass that never finished (kajiya's crash marker).
//! - Barriers come only from `sync.rs`'s vocabulary and are batched into one
//!   `vkCmdPipelineBarrier2` per call.

use super::buffer::{Buffer, BufferDesc};
use super::descriptors::DescriptorSet;
use super::device::{Device, DeviceShared};
use super::error::{GpuError, GpuResult, vk_err};
use super::image::Image;
use super::pipeline::ComputePipeline;
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
    pool: vk::CommandPool,
    cmd: vk::CommandBuffer,
    keep_alive: Vec<Arc<dyn Any + Send + Sync>>,
    timestamps: Option<TimestampPool>,
    breadcrumbs: Arc<Buffer>,
    pass_names: Vec<String>,
    pass_open: bool,
    label: String,
}

impl Recording {
    /// Starts recording; `label` names the work in errors.
    pub fn new(device: &Device, label: &str) -> GpuResult<Recording> {
        let shared = device.shared.clone();
        let pool_info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(shared.adapter.queue_family)
            .flags(vk::CommandPoolCreateFlags::TRANSIENT);
        // SAFETY: valid create info on a live device.
        let pool = unsafe { shared.raw.create_command_pool(&pool_info, None) }
            .map_err(vk_err("vkCreateCommandPool"))?;
        let destroy_pool = |e: GpuError| {
            // SAFETY: the pool has no command buffer in use.
            unsafe { shared.raw.destroy_command_pool(pool, None) };
            e
        };
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        // SAFETY: pool belongs to this device.
        let cmd = match unsafe { shared.raw.allocate_command_buffers(&alloc) } {
            Ok(c) => c[0],
            Err(e) => {
                return Err(destroy_pool(GpuError::from_vk(
                    "vkAllocateCommandBuffers",
                    e,
                )));
            }
        };
        let begin = vk::CommandBufferBeginInfo::default()
            .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
        // SAFETY: freshly allocated command buffer.
        if let Err(e) = unsafe { shared.raw.begin_command_buffer(cmd, &begin) } {
            return Err(destroy_pool(GpuError::from_vk("vkBeginCommandBuffer", e)));
        }
        let timestamps = TimestampPool::new(&shared).map_err(destroy_pool)?;
        if let Some(t) = &timestamps {
            t.reset(&shared, cmd);
        }
        let breadcrumbs = Buffer::with_data(
            device,
            BufferDesc::readback("pass breadcrumbs", 4 * MAX_PASSES as u64),
            &vec![0u8; 4 * MAX_PASSES as usize],
        )
        .map_err(destroy_pool)?;
        Ok(Recording {
            device: shared,
            pool,
            cmd,
            keep_alive: Vec::new(),
            timestamps,
            breadcrumbs,
            pass_names: Vec::new(),
            pass_open: false,
            label: label.to_string(),
        })
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
        let index = self.pass_names.len() as u64 - 1;
        if index < MAX_PASSES as u64 {
            // SAFETY: the breadcrumb buffer is kept alive by this recording; each pass writes
            // only its own 4-byte slot, so the fills never overlap.
            unsafe {
                self.device
                    .raw
                    .cmd_fill_buffer(self.cmd, self.breadcrumbs.raw, 4 * index, 4, 1)
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
        // SAFETY: valid create info.
        let fence = unsafe {
            device
                .raw
                .create_fence(&vk::FenceCreateInfo::default(), None)
        }
        .map_err(vk_err("vkCreateFence"))?;
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
            Ok(queue) => unsafe { device.raw.queue_submit2(*queue, &submit, fence) },
            Err(_) => Err(vk::Result::ERROR_UNKNOWN),
        };
        let submission = Submission {
            device: device.clone(),
            fence,
            pool: self.pool,
            keep_alive: std::mem::take(&mut self.keep_alive),
            timestamps: self.timestamps.take(),
            breadcrumbs: self.breadcrumbs.clone(),
            pass_names: std::mem::take(&mut self.pass_names),
            label: std::mem::take(&mut self.label),
            submitted: result.is_ok(),
            finished: false,
        };
        // The pool now belongs to the submission.
        self.pool = vk::CommandPool::null();
        match result {
            Ok(()) => Ok(submission),
            Err(e) => Err(submission.lost_or(GpuError::from_vk("vkQueueSubmit2", e))),
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
        if self.pool != vk::CommandPool::null() {
            // SAFETY: never submitted (submit() nulls the pool), so the GPU never saw it.
            unsafe { self.device.raw.destroy_command_pool(self.pool, None) };
            if let Some(t) = &self.timestamps {
                t.destroy(&self.device);
            }
        }
    }
}

/// Submitted work; holds every resource it uses until its fence signals.
pub struct Submission {
    device: Arc<DeviceShared>,
    fence: vk::Fence,
    pool: vk::CommandPool,
    keep_alive: Vec<Arc<dyn Any + Send + Sync>>,
    timestamps: Option<TimestampPool>,
    breadcrumbs: Arc<Buffer>,
    pass_names: Vec<String>,
    label: String,
    submitted: bool,
    finished: bool,
}

impl Submission {
    /// Waits for the work to finish and returns the GPU time of each pass (empty if the queue
    /// has no timestamps).
    pub fn wait(mut self) -> GpuResult<Vec<PassTiming>> {
        self.wait_fence()?;
        match &self.timestamps {
            Some(t) => t.results(&self.device),
            None => Ok(Vec::new()),
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
        let finished = match self.breadcrumbs.read(0, &mut crumbs) {
            Ok(()) => crumbs
                .chunks_exact(4)
                .take_while(|c| c != &[0, 0, 0, 0])
                .count(),
            Err(_) => 0,
        };
        let place = match self.pass_names.get(finished) {
            Some(pass) => format!("{} (pass `{pass}` did not finish)", self.label),
            None => self.label.clone(),
        };
        GpuError::DeviceLost(place)
    }
}

impl Drop for Submission {
    fn drop(&mut self) {
        // Never free what the GPU may still use: wait first. On a lost device or a timeout the
        // resources are leaked rather than destroyed under the GPU's feet.
        if self.wait_fence().is_err() && self.submitted {
            std::mem::forget(std::mem::take(&mut self.keep_alive));
            return;
        }
        // SAFETY: the work completed (or was never submitted); nothing uses these objects.
        unsafe {
            self.device.raw.destroy_fence(self.fence, None);
            self.device.raw.destroy_command_pool(self.pool, None);
        }
        if let Some(t) = &self.timestamps {
            t.destroy(&self.device);
        }
    }
}
