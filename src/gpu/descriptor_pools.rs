//! Descriptor pools per pipeline set, sized once and reset for reuse instead of destroyed.
//!
//! Decisions:
//! - The pool sizes of a set come from the build-time reflection table and are computed once,
//!   when the pipeline is created (issue 13 item 5), not at every `DescriptorSet::new`.
//! - Each pool holds exactly one set, so a set gives its pool back on its own: when the last
//!   `Arc` of a [`super::DescriptorSet`] drops, which is after every submission that bound it has
//!   completed (submissions keep their sets until their fence signals), the pool is reset with
//!   `vkResetDescriptorPool` and kept for the next set of this pipeline's layout: pools per
//!   layout, reset rather than sets freed, as Granite's descriptor-set allocator does, but
//!   returned by ownership (screen-13's leases) instead of by frame counting.
//! - The free list is bounded ([`MAX_FREE_POOLS`]); pools beyond it are destroyed. A pool that
//!   fails to reset is destroyed and the fault recorded in the device's fault log.

use super::device::DeviceShared;
use super::error::{GpuError, GpuResult, vk_err};
use super::pipeline::descriptor_type;
use super::shaders::ShaderInfo;
use ash::vk;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

/// Free pools kept per pipeline set.
pub const MAX_FREE_POOLS: usize = 16;

/// The reusable pools of one descriptor set layout of one pipeline.
pub(crate) struct DescriptorPools {
    device: Arc<DeviceShared>,
    sizes: Vec<vk::DescriptorPoolSize>,
    free: Mutex<Vec<vk::DescriptorPool>>,
    created: AtomicU64,
}

impl DescriptorPools {
    /// Sizes for set `set` of `shader`, computed from the reflection once.
    pub(crate) fn new(device: &Arc<DeviceShared>, shader: &ShaderInfo, set: u32) -> Self {
        let mut sizes: Vec<vk::DescriptorPoolSize> = Vec::new();
        for b in shader.bindings.iter().filter(|b| b.set == set) {
            let ty = descriptor_type(b.kind);
            match sizes.iter_mut().find(|s| s.ty == ty) {
                Some(s) => s.descriptor_count += b.count,
                None => sizes.push(vk::DescriptorPoolSize {
                    ty,
                    descriptor_count: b.count,
                }),
            }
        }
        DescriptorPools {
            device: device.clone(),
            sizes,
            free: Mutex::new(Vec::new()),
            created: AtomicU64::new(0),
        }
    }

    /// A pool with room for one set: a reset one from the free list, or a new one.
    pub(crate) fn take(&self) -> GpuResult<vk::DescriptorPool> {
        let reused = self
            .free
            .lock()
            .map_err(|_| {
                GpuError::Internal("a descriptor-pool free list was poisoned by a panic".into())
            })?
            .pop();
        if let Some(pool) = reused {
            return Ok(pool);
        }
        let info = vk::DescriptorPoolCreateInfo::default()
            .max_sets(1)
            .pool_sizes(&self.sizes);
        // SAFETY: valid create info on a live device.
        let pool = unsafe { self.device.raw.create_descriptor_pool(&info, None) }
            .map_err(vk_err("vkCreateDescriptorPool"))?;
        self.created.fetch_add(1, Ordering::Relaxed);
        Ok(pool)
    }

    /// Takes back a pool whose set no submission uses any more: reset and kept, or destroyed
    /// when the list is full or the reset fails (the failure is recorded, not skipped).
    pub(crate) fn give_back(&self, pool: vk::DescriptorPool) {
        let raw = &self.device.raw;
        // SAFETY: the pool's one set is no longer used by any pending command buffer.
        if let Err(e) =
            unsafe { raw.reset_descriptor_pool(pool, vk::DescriptorPoolResetFlags::empty()) }
        {
            self.device
                .faults
                .record(&GpuError::from_vk("vkResetDescriptorPool", e));
            // SAFETY: as above.
            unsafe { raw.destroy_descriptor_pool(pool, None) };
            return;
        }
        // A poisoned list is a plain Vec of handles: recovered, so the pool is not lost.
        let mut free = self.free.lock().unwrap_or_else(|p| p.into_inner());
        if free.len() < MAX_FREE_POOLS {
            free.push(pool);
        } else {
            // SAFETY: as above.
            unsafe { raw.destroy_descriptor_pool(pool, None) };
        }
    }

    /// Pools created so far (tests: reuse keeps this at the number in use at once).
    #[cfg(test)]
    pub(crate) fn created(&self) -> u64 {
        self.created.load(Ordering::Relaxed)
    }
}

impl Drop for DescriptorPools {
    fn drop(&mut self) {
        let free = self.free.get_mut().unwrap_or_else(|p| p.into_inner());
        for pool in free.drain(..) {
            // SAFETY: free pools hold no set in use (their sets were dropped, then reset).
            unsafe { self.device.raw.destroy_descriptor_pool(pool, None) };
        }
    }
}
