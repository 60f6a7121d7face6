//! Device memory by intent, with every live allocation named and counted.
//!
//! Decisions:
//! - Sub-allocation is gpu-allocator's (made for ash; named allocations, GpuOnly / CpuToGpu /
//!   GpuToCpu). The engine speaks in [`MemoryIntent`]s and this file is the one place that maps
//!   them to memory locations (gpu-allocator `src/vulkan/mod.rs`, Granite's `BufferDomain`).
//! - Staging buffers must live in host memory on a discrete GPU: gpu-allocator's CpuToGpu prefers
//!   DEVICE_LOCAL|HOST_VISIBLE (ReBAR on the H100), so [`MemoryIntent::Staging`] masks the
//!   device-local types out whenever a host-only host-visible type exists.
//! - A [`MemoryLedger`] records name, size, intent and memory flags of every live allocation, so
//!   integrators can see what is held (and tests can check that everything is freed).

use super::error::{GpuError, GpuResult};
use ash::vk;
use gpu_allocator::MemoryLocation;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme, Allocator};
use std::collections::BTreeMap;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

/// What a piece of memory is for; decides where it lives.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MemoryIntent {
    /// Only the GPU touches it (volumes, derived data, output images).
    GpuOnly,
    /// The host writes it and the GPU reads it in place (uniforms; volumes on unified memory).
    Upload,
    /// Host memory the host fills for a transfer into a GpuOnly resource (discrete GPUs).
    Staging,
    /// The GPU writes it and the host reads it back.
    Readback,
}

impl MemoryIntent {
    fn location(self) -> MemoryLocation {
        match self {
            MemoryIntent::GpuOnly => MemoryLocation::GpuOnly,
            MemoryIntent::Upload | MemoryIntent::Staging => MemoryLocation::CpuToGpu,
            MemoryIntent::Readback => MemoryLocation::GpuToCpu,
        }
    }
}

/// One live allocation as the ledger reports it.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct AllocationRecord {
    /// Name given by the code that allocated it (`normalized volume`, `minmax result`, ...).
    pub name: String,
    /// Bytes of device memory.
    pub bytes: u64,
    /// Intent it was allocated for.
    pub intent: MemoryIntent,
    /// Property flags of the memory type it landed in, e.g. `DEVICE_LOCAL | HOST_VISIBLE`.
    pub memory_type: String,
}

/// Every live allocation of one device, and how many were ever made and freed.
#[derive(Debug, Default)]
pub struct MemoryLedger {
    next_id: AtomicU64,
    freed: AtomicU64,
    live: Mutex<BTreeMap<u64, AllocationRecord>>,
}

impl MemoryLedger {
    /// Snapshot of the live allocations, oldest first.
    pub fn live(&self) -> Vec<AllocationRecord> {
        let live = self.live.lock().unwrap_or_else(|p| p.into_inner());
        live.values().cloned().collect()
    }

    /// Total bytes held.
    pub fn total_bytes(&self) -> u64 {
        let live = self.live.lock().unwrap_or_else(|p| p.into_inner());
        live.values().map(|r| r.bytes).sum()
    }

    /// Allocations made since the device was created.
    pub fn allocations_made(&self) -> u64 {
        self.next_id.load(Ordering::Relaxed)
    }

    /// Allocations freed since the device was created.
    pub fn allocations_freed(&self) -> u64 {
        self.freed.load(Ordering::Relaxed)
    }

    fn insert(&self, record: AllocationRecord) -> u64 {
        let id = self.next_id.fetch_add(1, Ordering::Relaxed);
        // Recovered, not skipped, when poisoned: one insert or remove cannot leave the map
        // half-updated, and a skipped entry would make the ledger lie.
        self.live
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .insert(id, record);
        id
    }

    fn remove(&self, id: u64) {
        let removed = self
            .live
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .remove(&id)
            .is_some();
        if removed {
            self.freed.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// An allocation plus its ledger entry.
pub(crate) struct TrackedAllocation {
    pub(crate) allocation: Allocation,
    ledger_id: u64,
    // For the error when freeing fails.
    name: String,
}

/// Allocates memory for a resource; out-of-memory names the resource and its size.
pub(crate) fn allocate(
    allocator: &Mutex<Allocator>,
    ledger: &MemoryLedger,
    memory: &vk::PhysicalDeviceMemoryProperties,
    name: &str,
    mut requirements: vk::MemoryRequirements,
    intent: MemoryIntent,
    linear: bool,
) -> GpuResult<TrackedAllocation> {
    if intent == MemoryIntent::Staging {
        requirements.memory_type_bits = host_only_types(memory, requirements.memory_type_bits);
    }
    let desc = AllocationCreateDesc {
        name,
        requirements,
        location: intent.location(),
        linear,
        allocation_scheme: AllocationScheme::GpuAllocatorManaged,
    };
    let mut allocator = allocator
        .lock()
        .map_err(|_| GpuError::Internal("the allocator was poisoned by an earlier panic".into()))?;
    let allocation = allocator.allocate(&desc).map_err(|e| match e {
        gpu_allocator::AllocationError::OutOfMemory => GpuError::OutOfDeviceMemory {
            during: format!("allocating `{name}`"),
            detail: format!("{} bytes requested", requirements.size),
        },
        other => GpuError::OutOfDeviceMemory {
            during: format!("allocating `{name}`"),
            detail: format!("{} bytes: {other}", requirements.size),
        },
    })?;
    let ledger_id = ledger.insert(AllocationRecord {
        name: name.to_string(),
        bytes: allocation.size(),
        intent,
        memory_type: format!("{:?}", allocation.memory_properties()),
    });
    Ok(TrackedAllocation {
        allocation,
        ledger_id,
        name: name.to_string(),
    })
}

/// Frees an allocation and removes its ledger entry.
pub(crate) fn free(
    allocator: &Mutex<Allocator>,
    ledger: &MemoryLedger,
    tracked: TrackedAllocation,
) -> GpuResult<()> {
    ledger.remove(tracked.ledger_id);
    let name = tracked.name;
    let mut allocator = allocator.lock().map_err(|_| {
        GpuError::Internal(format!(
            "the allocator was poisoned by an earlier panic; `{name}` was not freed"
        ))
    })?;
    // A failure means the allocation was already freed, which the ownership rules prevent.
    allocator
        .free(tracked.allocation)
        .map_err(|e| GpuError::Internal(format!("freeing `{name}` failed: {e}")))
}

/// The memory types among `allowed` that are host-visible but not device-local, if any exist;
/// otherwise `allowed` unchanged (unified memory has no host-only types).
fn host_only_types(memory: &vk::PhysicalDeviceMemoryProperties, allowed: u32) -> u32 {
    let mut mask = 0;
    for (i, t) in memory.memory_types[..memory.memory_type_count as usize]
        .iter()
        .enumerate()
    {
        let host_only = t
            .property_flags
            .contains(vk::MemoryPropertyFlags::HOST_VISIBLE)
            && !t
                .property_flags
                .contains(vk::MemoryPropertyFlags::DEVICE_LOCAL);
        if host_only && allowed & (1 << i) != 0 {
            mask |= 1 << i;
        }
    }
    if mask == 0 { allowed } else { mask }
}
