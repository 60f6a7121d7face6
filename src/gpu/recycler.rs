//! Per-queue reuse of what every submission needs: a command pool and its buffer, a fence, a
//! timestamp query pool and the pass-breadcrumb buffer.
//!
//! Decisions:
//! - Taken from Granite's per-frame context (`vulkan/device.cpp`, `command_pool.cpp`): a command
//!   pool is reset as a whole (`vkResetCommandPool`) once the fence of the work recorded from it
//!   has signalled, and then records again; nothing is created per frame. wgpu-hal's Vulkan
//!   command encoder does the same with its pool (`reset_all`: reset the pool, the buffers go back
//!   to its free list).
//! - From screen-13 (`src/pool/mod.rs`): a `Lease` goes back to a bounded cache when its owner
//!   is done, and a command buffer is leased only when its fence has signalled
//!   (`can_lease_command_buffer` queries the fence at lease time). Here the lease is returned
//!   only by the [`super::Submission`] after its fence was waited on, or by a recording that was
//!   never submitted, so everything in the free list is idle and leasing needs no fence query;
//!   the fence is reset when the lease comes back, so a leased fence is always unsignalled.
//! - One queue per device (see `device.rs`), so the recycler is per device, which is per queue.
//! - Breadcrumbs live in one host-visible buffer per device, [`CRUMB_SLOTS`] slots of one
//!   recording's breadcrumbs each; a lease keeps its slot for its lifetime and zeroes it on the
//!   host when leased (the GPU is done with it then). One buffer, created at the first lease and
//!   freed with the device, so the memory ledger holds one fixed "pass breadcrumbs" allocation
//!   the plan lists, not a number that depends on how many submissions were once in flight. A
//!   lease beyond the slots records without breadcrumbs (a lost device is then reported without
//!   the pass name). It is a raw buffer, not a [`super::Buffer`]: a `Buffer` holds an `Arc` of
//!   the device, which holds the recycler: a reference cycle that would never be freed.
//! - The free list is bounded ([`MAX_FREE`]): a burst of submissions in flight creates more
//!   leases, and those beyond the bound are destroyed when they come back, so memory stays
//!   bounded. A lease whose work was lost or timed out is leaked, never reused or destroyed
//!   under the GPU's feet; a lease that fails to reset is destroyed and the failure reported.

use super::buffer::{BufferDesc, create_bound};
use super::device::DeviceShared;
use super::error::{GpuError, GpuResult, vk_err};
use super::memory::{MemoryIntent, TrackedAllocation};
use super::timestamps::MAX_PASSES;
use ash::vk;
use std::ptr::NonNull;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

/// Free leases kept per device; more in flight at once are created and destroyed on return.
pub const MAX_FREE: usize = 8;

/// Bytes of one recording's breadcrumbs: one 32-bit word per timed pass.
const CRUMB_BYTES: u64 = 4 * MAX_PASSES as u64;

/// Recordings that can have breadcrumbs at once (leases alive, free or in flight).
pub const CRUMB_SLOTS: u32 = 64;

/// Bytes of a device's breadcrumb buffer (the plan lists it as "pass breadcrumbs").
pub const CRUMB_BUFFER_BYTES: u64 = CRUMB_BYTES * CRUMB_SLOTS as u64;

/// What one submission records with: owned by a recording, then by its submission, then back
/// in the free list.
pub(crate) struct Lease {
    pub(crate) pool: vk::CommandPool,
    pub(crate) cmd: vk::CommandBuffer,
    pub(crate) fence: vk::Fence,
    /// Null when the queue has no timestamps.
    pub(crate) queries: vk::QueryPool,
    /// The device's breadcrumb buffer and this lease's slot in it (None: no slot was free).
    pub(crate) crumbs: Option<(vk::Buffer, u32)>,
    crumbs_ptr: Option<NonNull<u8>>,
}

// SAFETY: the handles are plain Vulkan handles; the mapped pointer points at this lease's own
// slot and is only written (zeroes) or read through `zero_crumbs`/`read_crumbs` by the lease's
// one owner, ordered by its fence.
unsafe impl Send for Lease {}
// SAFETY: as above.
unsafe impl Sync for Lease {}

impl Lease {
    /// Byte offset of this lease's breadcrumbs in the device's breadcrumb buffer.
    pub(crate) fn crumb_offset(slot: u32) -> u64 {
        slot as u64 * CRUMB_BYTES
    }

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

/// The device's breadcrumb buffer and its free slots.
struct Crumbs {
    buffer: vk::Buffer,
    memory: Option<TrackedAllocation>,
    mapped: Option<NonNull<u8>>,
    free_slots: Vec<u32>,
}

// SAFETY: the mapped pointer is only offset into slots handed to one lease each.
unsafe impl Send for Crumbs {}

/// The device's free list of leases, with counts for tests and reports.
#[derive(Default)]
pub struct Recycler {
    free: Mutex<Vec<Lease>>,
    crumbs: Mutex<Option<Crumbs>>,
    created: AtomicU64,
    reused: AtomicU64,
    destroyed: AtomicU64,
}

/// How often leases were created and reused on a device.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct RecyclerCounts {
    /// Leases created (command pool and buffer, fence, query pool, breadcrumb slot each).
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
                let lease = self.create(device)?;
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

    /// Destroys every free lease and the breadcrumb buffer (device shutdown, after the queue
    /// is idle).
    pub(crate) fn destroy_all(&self, device: &DeviceShared) {
        // The list is a plain Vec; a panic while holding it cannot leave a half-made lease.
        let leases = std::mem::take(&mut *self.free.lock().unwrap_or_else(|p| p.into_inner()));
        for lease in leases {
            self.destroy(device, lease);
        }
        let crumbs = self.crumbs.lock().unwrap_or_else(|p| p.into_inner()).take();
        if let Some(crumbs) = crumbs {
            // SAFETY: the queue is idle; no lease is left to use the buffer.
            unsafe { device.raw.destroy_buffer(crumbs.buffer, None) };
            if let Some(tracked) = crumbs.memory {
                device.free_memory(tracked);
            }
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
        self.release(device, lease);
    }

    /// Destroys a lease's objects and frees its breadcrumb slot.
    fn release(&self, device: &DeviceShared, lease: Lease) {
        if let Some((_, slot)) = lease.crumbs {
            let mut crumbs = self.crumbs.lock().unwrap_or_else(|p| p.into_inner());
            if let Some(c) = crumbs.as_mut() {
                c.free_slots.push(slot);
            }
        }
        destroy(device, lease);
    }

    /// Creates a lease; on failure destroys what was made.
    fn create(&self, device: &DeviceShared) -> GpuResult<Lease> {
        let mut lease = Lease {
            pool: vk::CommandPool::null(),
            cmd: vk::CommandBuffer::null(),
            fence: vk::Fence::null(),
            queries: vk::QueryPool::null(),
            crumbs: None,
            crumbs_ptr: None,
        };
        let made = fill(device, &mut lease).and_then(|()| self.take_slot(device, &mut lease));
        match made {
            Ok(()) => Ok(lease),
            Err(e) => {
                self.release(device, lease);
                Err(e)
            }
        }
    }

    /// Gives `lease` a breadcrumb slot if one is free (creating the buffer at the first lease).
    fn take_slot(&self, device: &DeviceShared, lease: &mut Lease) -> GpuResult<()> {
        let mut crumbs = self.crumbs.lock().map_err(|_| {
            GpuError::Internal("the breadcrumb slots were poisoned by a panic".into())
        })?;
        if crumbs.is_none() {
            *crumbs = Some(create_crumbs(device)?);
        }
        let Some(c) = crumbs.as_mut() else {
            return Ok(());
        };
        if let (Some(slot), Some(base)) = (c.free_slots.pop(), c.mapped) {
            lease.crumbs = Some((c.buffer, slot));
            // SAFETY: slot < CRUMB_SLOTS, so the offset lies inside the mapped buffer.
            lease.crumbs_ptr =
                NonNull::new(unsafe { base.as_ptr().add(Lease::crumb_offset(slot) as usize) });
        }
        Ok(())
    }
}

fn fill(device: &DeviceShared, lease: &mut Lease) -> GpuResult<()> {
    let raw = &device.raw;
    let pool_info =
        vk::CommandPoolCreateInfo::default().queue_family_index(device.adapter.queue_family);
    // SAFETY: valid create infos on a live device; every handle made is stored in `lease`, which
    // the caller releases on error.
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
    }
    Ok(())
}

/// The breadcrumb buffer as it is created (and as the pass plan declares it): written only by
/// `vkCmdFillBuffer`, read by the host after a device loss.
pub fn breadcrumb_desc() -> BufferDesc {
    BufferDesc {
        name: "pass breadcrumbs".into(),
        size: CRUMB_BUFFER_BYTES,
        usage: vk::BufferUsageFlags::TRANSFER_DST,
        intent: MemoryIntent::Readback,
        texel_format: None,
    }
}

/// The device's breadcrumb buffer, every slot free.
fn create_crumbs(device: &DeviceShared) -> GpuResult<Crumbs> {
    let (buffer, tracked, mapped) = create_bound(device, &breadcrumb_desc())?;
    Ok(Crumbs {
        buffer,
        memory: Some(tracked),
        mapped,
        // Popped from the end: slot 0 first.
        free_slots: (0..CRUMB_SLOTS).rev().collect(),
    })
}

fn destroy(device: &DeviceShared, lease: Lease) {
    // SAFETY: the lease's work completed or was never submitted (callers' guarantee); destroying
    // null handles is a no-op, and the pool frees its command buffer.
    unsafe {
        device.raw.destroy_command_pool(lease.pool, None);
        device.raw.destroy_fence(lease.fence, None);
        device.raw.destroy_query_pool(lease.queries, None);
    }
}
