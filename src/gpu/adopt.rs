//! Devices an integrator already created: morphray works on their `VkInstance`, `VkDevice` and
//! one of their queues instead of creating its own.
//!
//! Decisions:
//! - Adoption is `unsafe`: Vulkan cannot tell morphray which features a device was created with,
//!   or whether the integrator uses the queue from another thread at the same time; the caller
//!   promises both ([`AdoptedHandles`] lists the features). Everything that *can* be checked is:
//!   the API version, the physical device's requirements (as for morphray's own devices), and
//!   that the queue family can run compute.
//! - morphray never destroys adopted handles. Dropping the last morphray object waits for the
//!   adopted queue (not the whole device) and frees morphray's own objects and memory; the
//!   integrator destroys the device and instance afterwards.
//! - Profiles and kernel tuning apply as for a created device.

use super::adapter::describe_physical;
use super::device::{Device, DeviceParts};
use super::error::{GpuError, GpuResult};
use super::instance::Instance;
use super::profile::{DeviceProfile, KernelTuning};
use ash::vk;

/// Handles of an integrator's Vulkan objects.
///
/// The device must have been created with Vulkan 1.3 and these features enabled:
/// `shaderStorageImageWriteWithoutFormat` (1.0), `synchronization2` (1.3), and, for `--subgroup`
/// style tuning, `subgroupSizeControl` and `computeFullSubgroups` (1.3). If the physical device
/// supports VK_EXT_memory_budget, enabling it lets morphray see the driver's budget.
#[derive(Clone)]
pub struct AdoptedHandles {
    /// The loader the instance came from.
    pub entry: ash::Entry,
    /// The instance.
    pub instance: ash::Instance,
    /// The physical device the device was created on.
    pub physical: vk::PhysicalDevice,
    /// The device.
    pub device: ash::Device,
    /// A queue family with compute on which the device has a queue.
    pub queue_family: u32,
    /// Index of the queue within the family that morphray submits to.
    pub queue_index: u32,
    /// Profile to apply (None: the device as it is).
    pub profile: Option<DeviceProfile>,
    /// Workgroup and subgroup choices.
    pub tuning: KernelTuning,
}

impl Device {
    /// Works on an integrator's device instead of creating one.
    ///
    /// # Safety
    /// - every handle is valid, the device was created from `physical` of `instance` with the
    ///   features listed on [`AdoptedHandles`], and `queue_index` exists in `queue_family`;
    /// - the handles outlive every morphray object created from the returned device;
    /// - the integrator does not submit to that queue while a morphray call is running on another
    ///   thread (Vulkan requires external synchronization of a queue).
    pub unsafe fn adopt(handles: AdoptedHandles) -> GpuResult<Device> {
        let AdoptedHandles {
            entry,
            instance,
            physical,
            device,
            queue_family,
            queue_index,
            profile,
            tuning,
        } = handles;
        let instance = Instance::adopt(entry, instance);
        let mut adapter = describe_physical(&instance, physical)?;
        if !adapter.is_suitable() {
            return Err(GpuError::Unsupported(format!(
                "{} cannot run morphray: {}",
                adapter.name,
                adapter.rejections.join("; ")
            )));
        }
        // SAFETY: a query on a physical device of this instance.
        let families = unsafe {
            instance
                .raw
                .get_physical_device_queue_family_properties(physical)
        };
        let family = families.get(queue_family as usize).ok_or_else(|| {
            GpuError::InvalidRequest(format!(
                "queue family {queue_family} does not exist ({} families)",
                families.len()
            ))
        })?;
        if !family.queue_flags.contains(vk::QueueFlags::COMPUTE)
            || queue_index >= family.queue_count
        {
            return Err(GpuError::InvalidRequest(format!(
                "queue {queue_index} of family {queue_family} cannot run compute work ({:?}, {} queues)",
                family.queue_flags, family.queue_count
            )));
        }
        adapter.queue_family = queue_family;
        adapter.timestamp_valid_bits = family.timestamp_valid_bits;
        let adapter = match &profile {
            Some(p) => p.clamp(adapter),
            None => adapter,
        };
        let tuning = tuning.with_profile_defaults(profile.as_ref());
        if let Some(size) = tuning.subgroup_size {
            super::profile::check_subgroup_size(&adapter, size)?;
        }
        // SAFETY: the caller promises the queue exists (checked above against the family).
        let queue = unsafe { device.get_device_queue(queue_family, queue_index) };
        Device::assemble(DeviceParts {
            instance,
            physical,
            adapter,
            raw: device,
            queue,
            profile,
            tuning,
            owned: false,
            timings: Default::default(),
            pipeline_statistics: false,
        })
    }
}
