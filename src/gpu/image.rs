//! 3D images (volumes and derived data) and 2D images (render targets), with one view each.
//!
//! Decisions: optimal tiling in GPU-only memory; one full view per image; the layout is not
//! tracked here but by the barriers that move it (see `sync.rs`), because every use site knows
//! what it needs and what came before.

use super::device::{Device, DeviceShared};
use super::error::{GpuError, GpuResult, vk_err};
use super::memory::{MemoryIntent, TrackedAllocation};
use ash::vk;
use std::sync::{Arc, Mutex};

/// Description of an image.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ImageDesc {
    /// Name shown in the memory ledger and in errors.
    pub name: String,
    /// Width, height, depth (depth 1 for a 2D image).
    pub extent: [u32; 3],
    /// Texel format.
    pub format: vk::Format,
    /// Usage flags.
    pub usage: vk::ImageUsageFlags,
    /// 2D or 3D.
    pub image_type: vk::ImageType,
}

impl ImageDesc {
    /// A 3D volume written by a compute shader and then sampled.
    pub fn volume(name: &str, extent: [u32; 3], format: vk::Format) -> Self {
        ImageDesc {
            name: name.into(),
            extent,
            format,
            usage: vk::ImageUsageFlags::STORAGE
                | vk::ImageUsageFlags::SAMPLED
                | vk::ImageUsageFlags::TRANSFER_SRC
                | vk::ImageUsageFlags::TRANSFER_DST,
            image_type: vk::ImageType::TYPE_3D,
        }
    }

    /// A 2D image a compute shader writes and the host reads back (or a presenter copies).
    pub fn render_target(name: &str, width: u32, height: u32, format: vk::Format) -> Self {
        ImageDesc {
            name: name.into(),
            extent: [width, height, 1],
            format,
            usage: vk::ImageUsageFlags::STORAGE
                | vk::ImageUsageFlags::TRANSFER_SRC
                | vk::ImageUsageFlags::SAMPLED,
            image_type: vk::ImageType::TYPE_2D,
        }
    }
}

fn create_info(desc: &ImageDesc) -> vk::ImageCreateInfo<'static> {
    vk::ImageCreateInfo::default()
        .image_type(desc.image_type)
        .format(desc.format)
        .extent(vk::Extent3D {
            width: desc.extent[0],
            height: desc.extent[1],
            depth: desc.extent[2],
        })
        .mip_levels(1)
        .array_layers(1)
        .samples(vk::SampleCountFlags::TYPE_1)
        .tiling(vk::ImageTiling::OPTIMAL)
        .usage(desc.usage)
        .sharing_mode(vk::SharingMode::EXCLUSIVE)
        .initial_layout(vk::ImageLayout::UNDEFINED)
}

impl Device {
    /// Bytes of device memory an image of `desc` would take, asked before it exists
    /// (vkGetDeviceImageMemoryRequirements, core in Vulkan 1.3): the driver's padding included.
    pub fn image_memory_bytes(&self, desc: &ImageDesc) -> u64 {
        let info = create_info(desc);
        let query = vk::DeviceImageMemoryRequirements::default().create_info(&info);
        let mut requirements = vk::MemoryRequirements2::default();
        // SAFETY: a query with a valid create info on a live Vulkan 1.3 device.
        unsafe {
            self.shared
                .raw
                .get_device_image_memory_requirements(&query, &mut requirements)
        };
        requirements.memory_requirements.size
    }
}

/// A Vulkan image with its memory and a view of the whole image.
pub struct Image {
    pub(crate) raw: vk::Image,
    pub(crate) view: vk::ImageView,
    desc: ImageDesc,
    allocation: Mutex<Option<TrackedAllocation>>,
    device: Arc<DeviceShared>,
}

impl Image {
    /// Creates the image, binds GPU-only memory and creates its view.
    pub fn new(device: &Device, desc: ImageDesc) -> GpuResult<Arc<Image>> {
        let shared = &device.shared;
        let limit = match desc.image_type {
            vk::ImageType::TYPE_3D => shared.adapter.max_image_dimension_3d,
            _ => 16384,
        };
        if desc.extent.iter().any(|&e| e == 0 || e > limit) {
            return Err(GpuError::Unsupported(format!(
                "image `{}` of {}x{}x{} texels exceeds this device's limit of {limit} per side",
                desc.name, desc.extent[0], desc.extent[1], desc.extent[2]
            )));
        }
        let info = create_info(&desc);
        // SAFETY: valid create info on a live device.
        let raw =
            unsafe { shared.raw.create_image(&info, None) }.map_err(vk_err("vkCreateImage"))?;
        // SAFETY: raw was just created on this device.
        let requirements = unsafe { shared.raw.get_image_memory_requirements(raw) };
        let bound = shared.allocate_bound(
            &desc.name,
            requirements,
            MemoryIntent::GpuOnly,
            false,
            "vkBindImageMemory",
            // SAFETY: an unbound image of this device, memory allocated for its requirements.
            |memory, offset| unsafe { shared.raw.bind_image_memory(raw, memory, offset) },
        );
        let tracked = match bound {
            Ok(t) => t,
            Err(e) => {
                // SAFETY: unused image without memory.
                unsafe { shared.raw.destroy_image(raw, None) };
                return Err(e);
            }
        };
        let destroy = |tracked: TrackedAllocation| {
            shared.free_memory(tracked);
            // SAFETY: unused image.
            unsafe { shared.raw.destroy_image(raw, None) };
        };
        let view_type = if desc.image_type == vk::ImageType::TYPE_3D {
            vk::ImageViewType::TYPE_3D
        } else {
            vk::ImageViewType::TYPE_2D
        };
        let view_info = vk::ImageViewCreateInfo::default()
            .image(raw)
            .view_type(view_type)
            .format(desc.format)
            .subresource_range(full_range());
        // SAFETY: raw is a bound image of this device.
        let view = match unsafe { shared.raw.create_image_view(&view_info, None) } {
            Ok(v) => v,
            Err(e) => {
                destroy(tracked);
                return Err(GpuError::from_vk("vkCreateImageView", e));
            }
        };
        shared.name_object(raw, &desc.name);
        shared.name_object(view, &format!("{} (view)", desc.name));
        Ok(Arc::new(Image {
            raw,
            view,
            desc,
            allocation: Mutex::new(Some(tracked)),
            device: shared.clone(),
        }))
    }

    /// Width, height, depth.
    pub fn extent(&self) -> [u32; 3] {
        self.desc.extent
    }

    /// Texel format.
    pub fn format(&self) -> vk::Format {
        self.desc.format
    }

    /// Name given at creation.
    pub fn name(&self) -> &str {
        &self.desc.name
    }

    /// Number of texels.
    pub fn texel_count(&self) -> u64 {
        self.desc.extent.iter().map(|&e| e as u64).product()
    }

    /// The raw handle.
    pub fn raw(&self) -> vk::Image {
        self.raw
    }
}

/// The whole colour subresource (one mip, one layer).
pub(crate) fn full_range() -> vk::ImageSubresourceRange {
    vk::ImageSubresourceRange {
        aspect_mask: vk::ImageAspectFlags::COLOR,
        base_mip_level: 0,
        level_count: 1,
        base_array_layer: 0,
        layer_count: 1,
    }
}

impl Drop for Image {
    fn drop(&mut self) {
        // SAFETY: dropped only when no recording or submission holds it (they keep Arcs until
        // their fence signals).
        unsafe {
            self.device.raw.destroy_image_view(self.view, None);
            self.device.raw.destroy_image(self.raw, None);
        }
        // A poisoned slot still holds the allocation: freed, never skipped.
        let slot = self.allocation.get_mut().unwrap_or_else(|p| p.into_inner());
        if let Some(tracked) = slot.take() {
            self.device.free_memory(tracked);
        }
    }
}
