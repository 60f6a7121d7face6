//! Barriers from a small access vocabulary, mapped by one table.
//!
//! Decision (wgpu-hal `conv.rs`, vk-sync-rs): call sites say what came before and what comes
//! next ([`Access`]), never raw stage/access/layout triples; [`access_info`] is the only place
//! that knows the Vulkan flags, and it is unit-tested without a GPU. Every barrier a pass records
//! carries a comment saying what it orders.

use ash::vk;

/// How a resource was or will be used.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Access {
    /// No previous use (contents may be discarded).
    Nothing,
    /// Written by the host through a mapping.
    HostWrite,
    /// Read by the host through a mapping.
    HostRead,
    /// Source of a transfer (copy).
    TransferRead,
    /// Destination of a transfer (copy, fill).
    TransferWrite,
    /// Read by a compute shader as a storage buffer or a uniform buffer.
    ComputeReadBuffer,
    /// Written (or atomically updated) by a compute shader as a storage buffer.
    ComputeWriteBuffer,
    /// Sampled or fetched by a compute shader (image in SHADER_READ_ONLY_OPTIMAL).
    ComputeSampled,
    /// Written by a compute shader as a storage image (image in GENERAL).
    ComputeWriteImage,
    /// Read and written by a compute shader as a storage image (image in GENERAL): a running
    /// result updated in place across dispatches (the vesselness maximum over scales).
    ComputeReadWriteImage,
    /// Drawn into (and blended over) as a colour attachment by graphics work (the viewer's
    /// interface), image in COLOR_ATTACHMENT_OPTIMAL.
    ColorAttachment,
    /// A swapchain image just acquired, whose acquire semaphore the submission waits for at the
    /// transfer stage (the viewer's first use of it is a copy): a barrier from here chains with
    /// that wait; the previous contents are discarded.
    SwapchainAcquired,
    /// Handed to the presentation engine (image in PRESENT_SRC_KHR); the submission's signal
    /// semaphore, which the present waits for, makes the frame's writes visible to it.
    Present,
}

/// The Vulkan flags of one access.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AccessInfo {
    /// Pipeline stages involved.
    pub stages: vk::PipelineStageFlags2,
    /// Memory accesses involved.
    pub access: vk::AccessFlags2,
    /// Image layout the access needs (UNDEFINED for buffers or "don't care").
    pub layout: vk::ImageLayout,
}

/// The table: one row per [`Access`].
pub fn access_info(access: Access) -> AccessInfo {
    use vk::AccessFlags2 as A;
    use vk::ImageLayout as L;
    use vk::PipelineStageFlags2 as S;
    let (stages, access, layout) = match access {
        Access::Nothing => (S::NONE, A::NONE, L::UNDEFINED),
        Access::HostWrite => (S::HOST, A::HOST_WRITE, L::GENERAL),
        Access::HostRead => (S::HOST, A::HOST_READ, L::GENERAL),
        Access::TransferRead => (S::ALL_TRANSFER, A::TRANSFER_READ, L::TRANSFER_SRC_OPTIMAL),
        Access::TransferWrite => (S::ALL_TRANSFER, A::TRANSFER_WRITE, L::TRANSFER_DST_OPTIMAL),
        Access::ComputeReadBuffer => (
            S::COMPUTE_SHADER,
            A::SHADER_STORAGE_READ | A::UNIFORM_READ,
            L::UNDEFINED,
        ),
        Access::ComputeWriteBuffer => (
            S::COMPUTE_SHADER,
            A::SHADER_STORAGE_WRITE | A::SHADER_STORAGE_READ,
            L::UNDEFINED,
        ),
        Access::ComputeSampled => (
            S::COMPUTE_SHADER,
            A::SHADER_SAMPLED_READ,
            L::SHADER_READ_ONLY_OPTIMAL,
        ),
        Access::ComputeWriteImage => (S::COMPUTE_SHADER, A::SHADER_STORAGE_WRITE, L::GENERAL),
        Access::ComputeReadWriteImage => (
            S::COMPUTE_SHADER,
            A::SHADER_STORAGE_READ | A::SHADER_STORAGE_WRITE,
            L::GENERAL,
        ),
        Access::ColorAttachment => (
            S::COLOR_ATTACHMENT_OUTPUT,
            A::COLOR_ATTACHMENT_READ | A::COLOR_ATTACHMENT_WRITE,
            L::COLOR_ATTACHMENT_OPTIMAL,
        ),
        // Same stage as the semaphore wait, no access: the semaphore already made the
        // presentation engine's reads available; UNDEFINED discards what was shown before.
        Access::SwapchainAcquired => (S::ALL_TRANSFER, A::NONE, L::UNDEFINED),
        // Nothing on this queue reads it afterwards; the semaphore signal (all commands) orders
        // the transition before the present.
        Access::Present => (S::BOTTOM_OF_PIPE, A::NONE, L::PRESENT_SRC_KHR),
    };
    AccessInfo {
        stages,
        access,
        layout,
    }
}

fn is_write(access: Access) -> bool {
    matches!(
        access,
        Access::HostWrite
            | Access::TransferWrite
            | Access::ComputeWriteBuffer
            | Access::ComputeWriteImage
            | Access::ComputeReadWriteImage
            | Access::ColorAttachment
    )
}

/// A barrier on a buffer between two uses; `None` when none is needed (read after read).
pub fn buffer_barrier(
    buffer: vk::Buffer,
    before: Access,
    after: Access,
) -> Option<vk::BufferMemoryBarrier2<'static>> {
    if !is_write(before) && !is_write(after) {
        return None;
    }
    let (b, a) = (access_info(before), access_info(after));
    Some(
        vk::BufferMemoryBarrier2::default()
            .src_stage_mask(b.stages)
            .src_access_mask(if is_write(before) {
                b.access
            } else {
                vk::AccessFlags2::NONE
            })
            .dst_stage_mask(a.stages)
            .dst_access_mask(a.access)
            .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .buffer(buffer)
            .offset(0)
            .size(vk::WHOLE_SIZE),
    )
}

/// A barrier on a whole image between two uses, including its layout transition. Always
/// returned: even read-after-read may change layout. `Access::Nothing` before discards contents.
pub fn image_barrier(
    image: vk::Image,
    before: Access,
    after: Access,
) -> vk::ImageMemoryBarrier2<'static> {
    let (b, a) = (access_info(before), access_info(after));
    vk::ImageMemoryBarrier2::default()
        .src_stage_mask(b.stages)
        .src_access_mask(if is_write(before) {
            b.access
        } else {
            vk::AccessFlags2::NONE
        })
        .dst_stage_mask(a.stages)
        .dst_access_mask(a.access)
        .old_layout(b.layout)
        .new_layout(a.layout)
        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .image(image)
        .subresource_range(super::image::full_range())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn read_after_read_on_a_buffer_needs_no_barrier() {
        assert!(
            buffer_barrier(
                vk::Buffer::null(),
                Access::ComputeReadBuffer,
                Access::ComputeReadBuffer
            )
            .is_none()
        );
        assert!(
            buffer_barrier(
                vk::Buffer::null(),
                Access::TransferRead,
                Access::ComputeReadBuffer
            )
            .is_none()
        );
    }

    #[test]
    fn write_then_read_makes_the_write_available_to_the_reader() {
        let b = buffer_barrier(
            vk::Buffer::null(),
            Access::ComputeWriteBuffer,
            Access::HostRead,
        )
        .unwrap();
        assert_eq!(b.src_stage_mask, vk::PipelineStageFlags2::COMPUTE_SHADER);
        assert!(
            b.src_access_mask
                .contains(vk::AccessFlags2::SHADER_STORAGE_WRITE)
        );
        assert_eq!(b.dst_stage_mask, vk::PipelineStageFlags2::HOST);
        assert_eq!(b.dst_access_mask, vk::AccessFlags2::HOST_READ);
    }

    #[test]
    fn read_then_write_is_an_execution_dependency_without_source_access() {
        let b = buffer_barrier(
            vk::Buffer::null(),
            Access::ComputeReadBuffer,
            Access::TransferWrite,
        )
        .unwrap();
        assert_eq!(b.src_access_mask, vk::AccessFlags2::NONE);
        assert_eq!(b.src_stage_mask, vk::PipelineStageFlags2::COMPUTE_SHADER);
        assert!(b.dst_access_mask.contains(vk::AccessFlags2::TRANSFER_WRITE));
    }

    #[test]
    fn image_barriers_move_to_the_layout_each_use_needs() {
        let i = image_barrier(
            vk::Image::null(),
            Access::Nothing,
            Access::ComputeWriteImage,
        );
        assert_eq!(
            (i.old_layout, i.new_layout),
            (vk::ImageLayout::UNDEFINED, vk::ImageLayout::GENERAL)
        );
        let i = image_barrier(
            vk::Image::null(),
            Access::ComputeWriteImage,
            Access::ComputeSampled,
        );
        assert_eq!(i.new_layout, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL);
        assert!(
            i.src_access_mask
                .contains(vk::AccessFlags2::SHADER_STORAGE_WRITE)
        );
        assert_eq!(i.dst_access_mask, vk::AccessFlags2::SHADER_SAMPLED_READ);
        let i = image_barrier(
            vk::Image::null(),
            Access::ComputeSampled,
            Access::TransferRead,
        );
        assert_eq!(i.new_layout, vk::ImageLayout::TRANSFER_SRC_OPTIMAL);
        assert_eq!(i.src_access_mask, vk::AccessFlags2::NONE);
    }

    #[test]
    fn every_access_has_consistent_flags() {
        let all = [
            Access::Nothing,
            Access::HostWrite,
            Access::HostRead,
            Access::TransferRead,
            Access::TransferWrite,
            Access::ComputeReadBuffer,
            Access::ComputeWriteBuffer,
            Access::ComputeSampled,
            Access::ComputeWriteImage,
            Access::ColorAttachment,
            Access::SwapchainAcquired,
            Access::Present,
        ];
        for a in all {
            let info = access_info(a);
            // An access without stages is only valid for "nothing".
            assert_eq!(
                info.stages == vk::PipelineStageFlags2::NONE,
                a == Access::Nothing,
                "{a:?}"
            );
            // No memory access: "nothing", and the two hand-overs with the presentation
            // engine, whose memory dependency is the semaphore's.
            assert_eq!(
                info.access == vk::AccessFlags2::NONE,
                matches!(
                    a,
                    Access::Nothing | Access::SwapchainAcquired | Access::Present
                ),
                "{a:?}"
            );
        }
    }

    #[test]
    fn a_frame_moves_the_swapchain_image_from_acquire_to_present() {
        // Acquired -> copy destination: chained to the semaphore wait at the transfer stage,
        // discarding old contents, no source access to make available.
        let i = image_barrier(
            vk::Image::null(),
            Access::SwapchainAcquired,
            Access::TransferWrite,
        );
        assert_eq!(i.src_stage_mask, vk::PipelineStageFlags2::ALL_TRANSFER);
        assert_eq!(i.src_access_mask, vk::AccessFlags2::NONE);
        assert_eq!(
            (i.old_layout, i.new_layout),
            (
                vk::ImageLayout::UNDEFINED,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL
            )
        );
        // Copy destination -> present: the copy's writes are made available, layout for the
        // presentation engine.
        let i = image_barrier(vk::Image::null(), Access::TransferWrite, Access::Present);
        assert!(i.src_access_mask.contains(vk::AccessFlags2::TRANSFER_WRITE));
        assert_eq!(i.new_layout, vk::ImageLayout::PRESENT_SRC_KHR);
        assert_eq!(i.dst_access_mask, vk::AccessFlags2::NONE);
    }

    #[test]
    fn the_interface_draws_over_the_copied_frame() {
        // Copy of the raymarched image -> egui's colour attachment: a write-after-write that
        // must make the copy visible to blending (which reads the attachment).
        let i = image_barrier(
            vk::Image::null(),
            Access::TransferWrite,
            Access::ColorAttachment,
        );
        assert!(i.src_access_mask.contains(vk::AccessFlags2::TRANSFER_WRITE));
        assert_eq!(
            i.dst_stage_mask,
            vk::PipelineStageFlags2::COLOR_ATTACHMENT_OUTPUT
        );
        assert!(
            i.dst_access_mask
                .contains(vk::AccessFlags2::COLOR_ATTACHMENT_READ)
        );
        assert_eq!(i.new_layout, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL);
        // Interface drawn -> copy source (to the swapchain or a screenshot).
        let i = image_barrier(
            vk::Image::null(),
            Access::ColorAttachment,
            Access::TransferRead,
        );
        assert!(
            i.src_access_mask
                .contains(vk::AccessFlags2::COLOR_ATTACHMENT_WRITE)
        );
        assert_eq!(i.new_layout, vk::ImageLayout::TRANSFER_SRC_OPTIMAL);
        // The raymarch target goes back to GENERAL after the copy read it: an execution
        // dependency (write after read) without source access.
        let i = image_barrier(
            vk::Image::null(),
            Access::TransferRead,
            Access::ComputeWriteImage,
        );
        assert_eq!(i.src_access_mask, vk::AccessFlags2::NONE);
        assert_eq!(i.src_stage_mask, vk::PipelineStageFlags2::ALL_TRANSFER);
        assert_eq!(i.new_layout, vk::ImageLayout::GENERAL);
    }
}
