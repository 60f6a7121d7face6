//! Per-queue reuse of what every submission needs: a command pool and its buffer, a fence, a
//! timestamp query pool and the pass-breadcrumb buffer.
//!
//! Decisions:
//! - Taken from Granite's per-frame context (`vulkan/device.cpp`, `command_pool.cpp`): a command
//!   pool is reset as a whole (`vkResetCommandPool`) once the fence of the work recorded from it
//!   has signalled, and then records again; nothing is created per frame. From screen-13's leases
//!   (`pool/lease.rs`): a [`Lease`] is taken by [`super::Recording::new`] and goes back to the
//!   free list only from the [`super::Submission`] after its fence was waited on, or from a
//!   recording that was never submitted; so a lease is never handed out while the GPU may still
//!   use it. wgpu-hal's Vulkan encoder does the same with its command-buffer free list (reset
//!   pool, reuse buffers) and we follow it in resetting the fence when it comes back, not when it
//!   is taken, so a leased fence is always unsignalled.
//! - One queue per device (see `device.rs`), so the recycler is per device, which is per queue.
//! - The breadcrumb buffer is a raw buffer with memory from the allocator, not a [`super::Buffer`]:
//!   a `Buffer` holds an `Arc` of the device, and the device holds the free list, so that would be
//!   a reference cycle and the device would never be destroyed. It is zeroed on the host when
//!   leased (the GPU is done with it then).
//! - The free list is bounded ([`MAX_FREE`]): a burst of submissions in flight creates more
//!   leases, and those beyond the bound are destroyed when they come back, so memory stays
//!   bounded. A lease whose work was lost or timed out is leaked, never reused or destroyed
//!   under the GPU's feet; a lease that fails to reset is destroyed and the failure reported.

use super::device::DeviceShared;
use super::error::{GpuError, GpuResult, vk_err};
use super::memory::{self, MemoryIntent, TrackedAllocation};
use super::timestamps::MAX_PASSES;
use ash::vk;
use std::ptr::NonNull;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

/// Free leases kept per device; more in flight at once are created and destroyed on return.
pub const MAX_FREE: usize = 8;

/// Bytes of the breadcrumb buffer: one 32-bit slot per timed pass.
const CRUMB_BYTES: u64 = 4 * MAX_PASSES as u64;

/// What one submission records with: owned by a recording, then by its submission, then back
/// in the free list.
pub(crate) struct Lease {
    pub(crate) pool: vk::CommandPool,
    pub(crate) cmd: vk::CommandBuffer,
    pub(crate) fence: vk::Fence,
    /// Null when the queue has no timestamps.
    pub(crate) queries: vk::QueryPool,
    pub(crate) crumbs: vk::Buffer,
    crumbs_memory: Option<TrackedAllocation>,
    crumbs_ptr: Option<NonNull<u8>>,
}

// SAFETY: the handles are plain Vulkan handles; the mapped pointer is only written (zeroes) or
// read through `zero_crumbs`/`read_crumbs` by the lease's one owner, ordered by its fence.
unsafe impl Send for Lease {}
// SAFETY: as above.
unsafe impl Sync for Lease {}

impl Lease {
    /// Copies the first `out.len()` breadcrumb bytes (call after the fence or on device loss).
    pub(crate) fn read_crumbs(&self, out: &mut [u8]) {
        let len = out.len().min(CRUMB_BYTES as usize);
        if let Some(p) = self.crumbs_ptr {
            // SAFETY: the mapping covers CRUMB_BYTES bytes and `len` is clamped to it.
            unsafe { std::ptr::copy_nonoverlapping(p.as_ptr(), out.as_mut_ptr(), len) };
        }
    }

    fn zero_crumbs(&self) {
        if let Some(p) = self.crumbs_ptr {
            // SAFETY: the mapping covers CRUMB_BYTES; the GPU is done with a leased buffer.
            unsafe { std::ptr::write_bytes(p.as_ptr(), 0, CRUMB_BYTES as usize) };
        }
    }

    /// A stable identity for tests (the command pool's handle).
    #[cfg(test)]
    pub(crate) fn id(&self) -> u64 {
        ash::vk::Handle::as_raw(self.pool)
    }
}

/// The device's free list of leases, with counts for tests and reports.
#[derive(Default)]
pub struct Recycler {
    free: Mutex<Vec<Lease>>,
    created: AtomicU64,
    reused: AtomicU64,
    destroyed: AtomicU64,
}

/// How often leases were created and reused on a device.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct RecyclerCounts {
    /// Leases created (command pool, fence, query pool, breadcrumb buffer each).
    pub created: u64,
    /// Recordings that took a lease from the free list instead.
    pub reused: u64,
    /// Leases destroyed on return (free list full, or a reset failed).
    pub destroyed: u64,
    /// Leases in the free list now.
    pub free: usize,
}

impl Recycler {
    /// A lease ready to record: its pool reset, its fence unsignalled, its breadcrumbs zero.
    pub(crate) fn lease(&self, device: &DeviceShared) -> GpuResult<Lease> {
        let reused = self.free_list()?.pop();
        let lease = match reused {
            Some(lease) => {
                self.reused.fetch_add(1, Ordering::Relaxed);
                lease
            }
            None => {
                let lease = create(device)?;
                self.created.fetch_add(1, Ordering::Relaxed);
                lease
            }
        };
        lease.zero_crumbs();
        Ok(lease)
    }

    /// Takes back a lease whose work has completed (its fence signalled) or was never
    /// submitted: resets its pool and fence and keeps it, or destroys it when the list is full.
    /// A failed reset destroys the lease and is returned as the error.
    pub(crate) fn give_back(&self, device: &DeviceShared, lease: Lease) -> GpuResult<()> {
        // SAFETY: the caller guarantees no command buffer of the pool is pending and the fence
        // is not in use by a queue (signalled, or never submitted).
        let reset = unsafe {
            device
                .raw
                .reset_command_pool(lease.pool, vk::CommandPoolResetFlags::empty())
                .map_err(vk_err("vkResetCommandPool"))
                .and_then(|()| {
                    device
                        .raw
                        .reset_fences(&[lease.fence])
                        .map_err(vk_err("vkResetFences"))
                })
        };
        if let Err(e) = reset {
            self.destroy(device, lease);
            return Err(e);
        }
        let mut free = match self.free_list() {
            Ok(free) => free,
            Err(e) => {
                self.destroy(device, lease);
                return Err(e);
            }
        };
        if free.len() < MAX_FREE {
            free.push(lease);
        } else {
            drop(free);
            self.destroy(device, lease);
        }
        Ok(())
    }

    /// Destroys every free lease (device shutdown, after the queue is idle).
    pub(crate) fn destroy_all(&self, device: &DeviceShared) {
        let leases = match self.free.lock() {
            Ok(mut free) => std::mem::take(&mut *free),
            // The list is a plain Vec; a panic while holding it cannot leave a half-made lease.
            Err(poisoned) => std::mem::take(&mut *poisoned.into_inner()),
        };
        for lease in leases {
            self.destroy(device, lease);
        }
    }

    /// Counts so far.
    pub fn counts(&self) -> RecyclerCounts {
        RecyclerCounts {
            created: self.created.load(Ordering::Relaxed),
            reused: self.reused.load(Ordering::Relaxed),
            destroyed: self.destroyed.load(Ordering::Relaxed),
            free: self.free.lock().map(|f| f.len()).unwrap_or(0),
        }
    }

    fn free_list(&self) -> GpuResult<std::sync::MutexGuard<'_, Vec<Lease>>> {
        self.free.lock().map_err(|_| {
            GpuError::Internal(
                "the command-pool free list was poisoned by a panic on another thread".into(),
            )
        })
    }

    fn destroy(&self, device: &DeviceShared, lease: Lease) {
        self.destroyed.fetch_add(1, Ordering::Relaxed);
        destroy(device, lease);
    }
}

/// Creates a lease; on failure destroys what was made.
fn create(device: &DeviceShared) -> GpuResult<Lease> {
    let mut lease = Lease {
        pool: vk::CommandPool::null(),
        cmd: vk::CommandBuffer::null(),
        fence: vk::Fence::null(),
        queries: vk::QueryPool::null(),
        crumbs: vk::Buffer::null(),
        crumbs_memory: None,
        crumbs_ptr: None,
    };
    match fill(device, &mut lease) {
        Ok(()) => Ok(lease),
        Err(e) => {
            destroy(device, lease);
            Err(e)
        }
    }
}

fn fill(device: &DeviceShared, lease: &mut Lease) -> GpuResult<()> {
    let raw = &device.raw;
    let pool_info =
        vk::CommandPoolCreateInfo::default().queue_family_index(device.adapter.queue_family);
    // SAFETY: valid create infos on a live device; every handle made is stored in `lease`, which
    // the caller destroys on error.
    unsafe {
        lease.pool = raw
            .create_command_pool(&pool_info, None)
            .map_err(vk_err("vkCreateCommandPool"))?;
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(lease.pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        lease.cmd = raw
            .allocate_command_buffers(&alloc)
            .map_err(vk_err("vkAllocateCommandBuffers"))?
            .first()
            .copied()
            .ok_or_else(|| GpuError::Internal("vkAllocateCommandBuffers returned none".into()))?;
        lease.fence = raw
            .create_fence(&vk::FenceCreateInfo::default(), None)
            .map_err(vk_err("vkCreateFence"))?;
        if device.adapter.timestamp_valid_bits > 0 {
            let info = vk::QueryPoolCreateInfo::default()
                .query_type(vk::QueryType::TIMESTAMP)
                .query_count(2 * MAX_PASSES);
            lease.queries = raw
                .create_query_pool(&info, None)
                .map_err(vk_err("vkCreateQueryPool"))?;
        }
        let info = vk::BufferCreateInfo::default()
            .size(CRUMB_BYTES)
            .usage(vk::BufferUsageFlags::TRANSFER_DST)
            .sharing_mode(vk::SharingMode::EXCLUSIVE);
        lease.crumbs = raw
            .create_buffer(&info, None)
            .map_err(vk_err("vkCreateBuffer"))?;
        let requirements = raw.get_buffer_memory_requirements(lease.crumbs);
        let tracked = memory::allocate(
            &device.allocator,
            &device.ledger,
            &device.memory_properties,
            "pass breadcrumbs",
            requirements,
            MemoryIntent::Readback,
            true,
        )?;
        let memory = tracked.allocation.memory();
        let offset = tracked.allocation.offset();
        lease.crumbs_ptr = tracked.allocation.mapped_ptr().map(|p| p.cast::<u8>());
        lease.crumbs_memory = Some(tracked);
        raw.bind_buffer_memory(lease.crumbs, memory, offset)
            .map_err(vk_err("vkBindBufferMemory"))?;
    }
    if lease.crumbs_ptr.is_none() {
        return Err(GpuError::Unsupported(
            "host-visible memory for the pass breadcrumbs could not be mapped".into(),
        ));
    }
    Ok(())
}

fn destroy(device: &DeviceShared, lease: Lease) {
    // SAFETY: the lease's work completed or was never submitted (callers' guarantee); destroying
    // null handles is a no-op, and the pool frees its command buffer.
    unsafe {
        device.raw.destroy_command_pool(lease.pool, None);
        device.raw.destroy_fence(lease.fence, None);
        device.raw.destroy_query_pool(lease.queries, None);
        device.raw.destroy_buffer(lease.crumbs, None);
    }
    if let Some(tracked) = lease.crumbs_memory {
        device.free_memory(tracked);
    }
}
