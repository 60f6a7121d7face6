//! Buffers: a handle, its memory, its name; destroyed when the last owner drops it.
//!
//! Decision (kajiya's `BufferDesc`): a buffer is described by value with intent-named
//! constructors, and host access goes through checked `write`/`read` on mapped, host-coherent
//! memory (gpu-allocator only maps HOST_COHERENT types for CpuToGpu/GpuToCpu, so no flushes).

use super::device::{Device, DeviceShared};
use super::error::{GpuError, GpuResult, vk_err};
use super::memory::{MemoryIntent, TrackedAllocation};
use ash::vk;
use std::sync::{Arc, Mutex};

/// Description of a buffer.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BufferDesc {
    /// Name shown in the memory ledger and in errors.
    pub name: String,
    /// Size in bytes (> 0).
    pub size: u64,
    /// Vulkan usage flags.
    pub usage: vk::BufferUsageFlags,
    /// Where the memory lives.
    pub intent: MemoryIntent,
    /// When set, the buffer is also a uniform texel buffer of this format: one view over the
    /// whole buffer, made and destroyed with it ([`BufferDesc::with_texel_view`]).
    pub texel_format: Option<vk::Format>,
}

impl BufferDesc {
    /// A storage buffer only the GPU touches (filled by transfers or shaders).
    pub fn gpu_storage(name: &str, size: u64) -> Self {
        BufferDesc {
            name: name.into(),
            size,
            usage: vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::TRANSFER_DST
                | vk::BufferUsageFlags::TRANSFER_SRC,
            intent: MemoryIntent::GpuOnly,
            texel_format: None,
        }
    }

    /// A storage buffer the host writes and the GPU reads in place.
    pub fn host_storage(name: &str, size: u64) -> Self {
        BufferDesc {
            name: name.into(),
            size,
            usage: vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_DST,
            intent: MemoryIntent::Upload,
            texel_format: None,
        }
    }

    /// A uniform buffer the host rewrites between frames.
    pub fn uniform(name: &str, size: u64) -> Self {
        BufferDesc {
            name: name.into(),
            size,
            usage: vk::BufferUsageFlags::UNIFORM_BUFFER,
            intent: MemoryIntent::Upload,
            texel_format: None,
        }
    }

    /// Host memory for a copy into a GPU-only resource.
    pub fn staging(name: &str, size: u64) -> Self {
        BufferDesc {
            name: name.into(),
            size,
            usage: vk::BufferUsageFlags::TRANSFER_SRC,
            intent: MemoryIntent::Staging,
            texel_format: None,
        }
    }

    /// Host-readable memory the GPU copies or writes results into.
    pub fn readback(name: &str, size: u64) -> Self {
        BufferDesc {
            name: name.into(),
            size,
            usage: vk::BufferUsageFlags::TRANSFER_DST | vk::BufferUsageFlags::STORAGE_BUFFER,
            intent: MemoryIntent::Readback,
            texel_format: None,
        }
    }

    /// This buffer, also read as a uniform texel buffer of `format` (`texelFetch` on a
    /// `samplerBuffer`): on software devices a texel fetch is one vectorized gather, where a
    /// storage-buffer read at a per-invocation index is a loop over the lanes with a bounds test
    /// in each (Mesa's llvmpipe, `emit_load_mem`), so a per-sample table lookup belongs here.
    pub fn with_texel_view(mut self, format: vk::Format) -> Self {
        self.usage |= vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER;
        self.texel_format = Some(format);
        self
    }
}

/// Bytes of one texel of the texel-buffer formats the engine uses.
fn texel_bytes(format: vk::Format) -> Option<u64> {
    match format {
        vk::Format::R32G32B32A32_SFLOAT => Some(16),
        vk::Format::R32_UINT | vk::Format::R32_SFLOAT => Some(4),
        _ => None,
    }
}

/// A Vulkan buffer with its memory.
pub struct Buffer {
    pub(crate) raw: vk::Buffer,
    desc: BufferDesc,
    allocation: Mutex<Option<TrackedAllocation>>,
    mapped: Option<std::ptr::NonNull<u8>>,
    /// The texel view over the whole buffer (null without `desc.texel_format`).
    pub(crate) texel_view: vk::BufferView,
    device: Arc<DeviceShared>,
}

// SAFETY: the mapped pointer refers to memory owned by this buffer; host access through it is
// only via `write`/`read`, which copy bytes and are safe to call from any thread (the memory is
// coherent; ordering against the GPU is the caller's fences, as for any Vulkan resource).
unsafe impl Send for Buffer {}
// SAFETY: as above.
unsafe impl Sync for Buffer {}

impl Device {
    /// Bytes of device memory a buffer of `desc` would take, asked before it exists
    /// (vkGetDeviceBufferMemoryRequirements, core in Vulkan 1.3): alignment included.
    pub fn buffer_memory_bytes(&self, desc: &BufferDesc) -> u64 {
        let info = vk::BufferCreateInfo::default()
            .size(desc.size.max(1))
            .usage(desc.usage)
            .sharing_mode(vk::SharingMode::EXCLUSIVE);
        let query = vk::DeviceBufferMemoryRequirements::default().create_info(&info);
        let mut requirements = vk::MemoryRequirements2::default();
        // SAFETY: a query with a valid create info on a live Vulkan 1.3 device.
        unsafe {
            self.shared
                .raw
                .get_device_buffer_memory_requirements(&query, &mut requirements)
        };
        requirements.memory_requirements.size
    }
}

/// Creates a buffer of `desc`, allocates and binds its memory, and maps it when the host touches
/// it; on failure nothing is left behind. Shared by [`Buffer::new`] and the device's own
/// breadcrumb buffer (which cannot be a `Buffer`: a `Buffer` holds the device).
pub(crate) fn create_bound(
    shared: &DeviceShared,
    desc: &BufferDesc,
) -> GpuResult<(vk::Buffer, TrackedAllocation, Option<std::ptr::NonNull<u8>>)> {
    let info = vk::BufferCreateInfo::default()
        .size(desc.size)
        .usage(desc.usage)
        .sharing_mode(vk::SharingMode::EXCLUSIVE);
    // SAFETY: valid create info on a live device.
    let raw = unsafe { shared.raw.create_buffer(&info, None) }.map_err(vk_err("vkCreateBuffer"))?;
    // SAFETY: raw was just created on this device.
    let requirements = unsafe { shared.raw.get_buffer_memory_requirements(raw) };
    let bound = shared.allocate_bound(
        &desc.name,
        requirements,
        desc.intent,
        true,
        "vkBindBufferMemory",
        // SAFETY: an unbound buffer of this device, memory allocated for its requirements.
        |memory, offset| unsafe { shared.raw.bind_buffer_memory(raw, memory, offset) },
    );
    let tracked = match bound {
        Ok(t) => t,
        Err(e) => {
            // SAFETY: the buffer has no memory and was never used.
            unsafe { shared.raw.destroy_buffer(raw, None) };
            return Err(e);
        }
    };
    let mapped = tracked.allocation.mapped_ptr().map(|p| p.cast::<u8>());
    if desc.intent != MemoryIntent::GpuOnly && mapped.is_none() {
        shared.free_memory(tracked);
        // SAFETY: never used.
        unsafe { shared.raw.destroy_buffer(raw, None) };
        return Err(GpuError::Unsupported(format!(
            "host-visible memory for `{}` could not be mapped",
            desc.name
        )));
    }
    shared.name_object(raw, &desc.name);
    Ok((raw, tracked, mapped))
}

impl Buffer {
    /// Creates a buffer and binds memory to it.
    pub fn new(device: &Device, desc: BufferDesc) -> GpuResult<Arc<Buffer>> {
        if desc.size == 0 {
            return Err(GpuError::InvalidRequest(format!(
                "buffer `{}` has size 0",
                desc.name
            )));
        }
        let texels = match desc.texel_format {
            Some(format) => Some(checked_texels(device, &desc, format)?),
            None => None,
        };
        let shared = &device.shared;
        let (raw, tracked, mapped) = create_bound(shared, &desc)?;
        // From here the Buffer owns the handle and the memory: an error below drops it.
        let mut buffer = Buffer {
            raw,
            desc,
            allocation: Mutex::new(Some(tracked)),
            mapped,
            texel_view: vk::BufferView::null(),
            device: shared.clone(),
        };
        if let Some(format) = texels {
            let info = vk::BufferViewCreateInfo::default()
                .buffer(raw)
                .format(format)
                .offset(0)
                .range(vk::WHOLE_SIZE);
            // SAFETY: a live buffer of this device, made with UNIFORM_TEXEL_BUFFER usage; the
            // format is one every device supports for uniform texel buffers, and the texel count
            // was checked against maxTexelBufferElements.
            buffer.texel_view = unsafe { shared.raw.create_buffer_view(&info, None) }
                .map_err(vk_err("vkCreateBufferView"))?;
        }
        Ok(Arc::new(buffer))
    }

    /// Creates a host-visible buffer holding `bytes`.
    pub fn with_data(device: &Device, desc: BufferDesc, bytes: &[u8]) -> GpuResult<Arc<Buffer>> {
        let buffer = Buffer::new(device, desc)?;
        buffer.write(0, bytes)?;
        Ok(buffer)
    }

    /// Size in bytes.
    pub fn size(&self) -> u64 {
        self.desc.size
    }

    /// Name given at creation.
    pub fn name(&self) -> &str {
        &self.desc.name
    }

    /// The raw handle.
    pub fn raw(&self) -> vk::Buffer {
        self.raw
    }

    /// Copies `bytes` into mapped memory at `offset`. The caller orders this against GPU use
    /// (write before submitting work that reads it, or after the fence of work that used it).
    pub fn write(&self, offset: u64, bytes: &[u8]) -> GpuResult<()> {
        let ptr = self.host_range(offset, bytes.len() as u64)?;
        // Large writes are split across threads: the first touch of fresh mapped pages bounds
        // one thread (files/parallel.rs).
        // SAFETY: host_range checked that [offset, offset + len) lies inside the mapped memory,
        // which does not overlap the caller's slice.
        unsafe { crate::files::parallel::copy_to(ptr, bytes) };
        Ok(())
    }

    /// Copies `out.len()` bytes from mapped memory at `offset` into `out`.
    pub fn read(&self, offset: u64, out: &mut [u8]) -> GpuResult<()> {
        let ptr = self.host_range(offset, out.len() as u64)?;
        // SAFETY: host_range checked the range lies inside the mapped memory.
        unsafe { std::ptr::copy_nonoverlapping(ptr as *const u8, out.as_mut_ptr(), out.len()) };
        Ok(())
    }

    fn host_range(&self, offset: u64, len: u64) -> GpuResult<*mut u8> {
        let base = self.mapped.ok_or_else(|| {
            GpuError::InvalidRequest(format!("buffer `{}` is not host-visible", self.desc.name))
        })?;
        let end = offset
            .checked_add(len)
            .filter(|&end| end <= self.desc.size)
            .ok_or_else(|| {
                GpuError::InvalidRequest(format!(
                    "range {offset}+{len} lies outside buffer `{}` of {} bytes",
                    self.desc.name, self.desc.size
                ))
            })?;
        let _ = end;
        // SAFETY: offset <= size, checked above, and the mapping covers the whole buffer.
        Ok(unsafe { base.as_ptr().add(offset as usize) })
    }
}

/// `desc`'s texel format, after checking that the device can address all its texels.
fn checked_texels(device: &Device, desc: &BufferDesc, format: vk::Format) -> GpuResult<vk::Format> {
    let bytes = texel_bytes(format).ok_or_else(|| {
        GpuError::InvalidRequest(format!(
            "buffer `{}`: texel format {format:?} is not one the engine reads",
            desc.name
        ))
    })?;
    let limit = device.adapter().max_texel_buffer_elements as u64;
    let texels = desc.size / bytes;
    if texels > limit {
        return Err(GpuError::Unsupported(format!(
            "buffer `{}` holds {texels} texels; this device's texel buffers address {limit}",
            desc.name
        )));
    }
    Ok(format)
}

impl Drop for Buffer {
    fn drop(&mut self) {
        if self.texel_view != vk::BufferView::null() {
            // SAFETY: as for the buffer below; the view is destroyed before its buffer.
            unsafe { self.device.raw.destroy_buffer_view(self.texel_view, None) };
        }
        // SAFETY: a Buffer is dropped only when no recording or submission holds it any more
        // (they keep Arcs until their fence signals), so the GPU no longer uses it.
        unsafe { self.device.raw.destroy_buffer(self.raw, None) };
        // A poisoned slot still holds the allocation: freed, never skipped.
        let slot = self.allocation.get_mut().unwrap_or_else(|p| p.into_inner());
        if let Some(tracked) = slot.take() {
            self.device.free_memory(tracked);
        }
    }
}
