//! Physical-device choice: what each device offers, what morphray requires, and why a device was
//! rejected.
//!
//! Decisions (after wgpu-hal's `PhysicalDeviceFeatures` and vk-bootstrap's detailed failure
//! reasons): every requirement is checked on every device and each miss becomes a readable
//! phrase, so "no suitable device" lists all reasons for all devices. The user can pick a device
//! by index or by a case-insensitive name fragment (`--device`, or `MORPHRAY_DEVICE`). Otherwise
//! the first device of the best type wins: discrete > integrated > virtual > CPU.

use super::error::{DeviceRejection, GpuError, GpuResult, vk_err};
use super::instance::Instance;
use ash::vk;

/// Formats the engine stores volumes and derived data in, with the features each must have.
pub(crate) const REQUIRED_FORMATS: &[(vk::Format, &str)] = &[
    (vk::Format::R16_UNORM, "R16_UNORM"),
    (vk::Format::R16_SFLOAT, "R16_SFLOAT"),
    (vk::Format::R16G16_SFLOAT, "R16G16_SFLOAT"),
    (vk::Format::R8G8B8A8_SNORM, "R8G8B8A8_SNORM"),
];

/// Which physical device to use.
#[derive(Clone, Debug, PartialEq, Eq, Default)]
pub enum DeviceSelector {
    /// The best suitable device (or `MORPHRAY_DEVICE` when set).
    #[default]
    Auto,
    /// The device at this index in Vulkan's enumeration order.
    Index(usize),
    /// The first device whose name contains this text (case-insensitive).
    Name(String),
}

impl DeviceSelector {
    /// Parses `3` as an index and anything else as a name fragment.
    pub fn parse(text: &str) -> Self {
        match text.trim().parse::<usize>() {
            Ok(index) => DeviceSelector::Index(index),
            Err(_) => DeviceSelector::Name(text.trim().to_string()),
        }
    }

    /// `Auto`, unless `MORPHRAY_DEVICE` is set.
    pub fn from_env() -> Self {
        match std::env::var("MORPHRAY_DEVICE") {
            Ok(text) if !text.trim().is_empty() => DeviceSelector::parse(&text),
            _ => DeviceSelector::Auto,
        }
    }
}

/// What the engine knows about one physical device.
#[derive(Clone, Debug)]
pub struct AdapterInfo {
    /// Index in the Vulkan enumeration order.
    pub index: usize,
    /// Device name.
    pub name: String,
    /// Discrete, integrated, virtual or CPU.
    pub device_type: vk::PhysicalDeviceType,
    /// Vulkan API version the device supports.
    pub api_version: u32,
    /// Driver name and version string (from VkPhysicalDeviceDriverProperties).
    pub driver: String,
    /// PCI vendor id.
    pub vendor_id: u32,
    /// Vendor's device id.
    pub device_id: u32,
    /// Driver version as the driver encodes it (keys the on-disk pipeline cache).
    pub driver_version: u32,
    /// Driver's pipeline-cache UUID (keys the on-disk pipeline cache).
    pub pipeline_cache_uuid: [u8; 16],
    /// Default subgroup size.
    pub subgroup_size: u32,
    /// Smallest and largest subgroup size (subgroup size control), if reported.
    pub subgroup_size_range: Option<(u32, u32)>,
    /// Queue family used for compute and transfer.
    pub queue_family: u32,
    /// Valid bits of timestamps on that queue (0: no timestamps).
    pub timestamp_valid_bits: u32,
    /// Nanoseconds per timestamp tick.
    pub timestamp_period_ns: f64,
    /// Largest 3D image side.
    pub max_image_dimension_3d: u32,
    /// Largest storage-buffer binding in bytes.
    pub max_storage_buffer_range: u32,
    /// Most texels a texel-buffer view may address.
    pub max_texel_buffer_elements: u32,
    /// Largest workgroup count along x.
    pub max_workgroup_count_x: u32,
    /// Largest workgroup size per axis.
    pub max_workgroup_size: [u32; 3],
    /// Most invocations in one workgroup.
    pub max_workgroup_invocations: u32,
    /// Most subgroups in one workgroup (subgroup size control).
    pub max_workgroup_subgroups: u32,
    /// Largest push-constant block in bytes.
    pub max_push_constants_size: u32,
    /// Whether VK_EXT_memory_budget is available.
    pub has_memory_budget: bool,
    /// Whether `subgroupSizeControl` and `computeFullSubgroups` are available.
    pub has_subgroup_size_control: bool,
    /// Whether the driver reports its compiler's statistics per pipeline
    /// (VK_KHR_pipeline_executable_properties).
    pub has_pipeline_executable_properties: bool,
    /// Memory heaps: (size in bytes, device-local).
    pub heaps: Vec<(u64, bool)>,
    /// True when every device-local heap is also reachable by host-visible memory types (CPU
    /// devices, integrated GPUs): uploads then skip the staging copy.
    pub unified_memory: bool,
    /// Size of the largest device-local heap that a HOST_VISIBLE memory type reaches (resizable
    /// BAR on a discrete GPU, all memory on unified devices); 0 when there is none.
    pub host_visible_device_bytes: u64,
    /// Reasons this device cannot run morphray (empty when suitable).
    pub rejections: Vec<String>,
    /// The device profile clamping these properties (`gen12`, a file's name), if any.
    pub profile: Option<String>,
    /// Whether the device has float atomic add on buffers or in shared memory
    /// (VK_EXT_shader_atomic_float; a profile of a device without them clears it). No shader
    /// needs them today; a module declaring them is refused where this is false.
    pub float_atomics: bool,
}

impl AdapterInfo {
    /// True when the device meets every requirement.
    pub fn is_suitable(&self) -> bool {
        self.rejections.is_empty()
    }

    /// Short type name (`discrete`, `integrated`, `virtual`, `cpu`, `other`).
    pub fn type_name(&self) -> &'static str {
        match self.device_type {
            vk::PhysicalDeviceType::DISCRETE_GPU => "discrete",
            vk::PhysicalDeviceType::INTEGRATED_GPU => "integrated",
            vk::PhysicalDeviceType::VIRTUAL_GPU => "virtual",
            vk::PhysicalDeviceType::CPU => "cpu",
            _ => "other",
        }
    }

    /// Whether per-sample table reads should go through texel buffers rather than storage
    /// buffers: on a CPU device (llvmpipe) a storage-buffer read at a per-lane index is a loop
    /// over the lanes with a bounds test in each, a texel fetch one vectorized gather (the
    /// shaded MNI152 frame 1.9x faster, BENCHMARKS.md "Per-sample tables as texel buffers");
    /// GPUs keep the storage buffers, which Intel's compiler schedules in fewer cycles.
    pub fn prefers_texel_lookups(&self) -> bool {
        self.device_type == vk::PhysicalDeviceType::CPU
    }

    fn type_rank(&self) -> u32 {
        match self.device_type {
            vk::PhysicalDeviceType::DISCRETE_GPU => 0,
            vk::PhysicalDeviceType::INTEGRATED_GPU => 1,
            vk::PhysicalDeviceType::VIRTUAL_GPU => 2,
            vk::PhysicalDeviceType::CPU => 3,
            _ => 4,
        }
    }
}

/// Lists every physical device with its properties and rejection reasons.
pub fn enumerate(instance: &Instance) -> GpuResult<Vec<(vk::PhysicalDevice, AdapterInfo)>> {
    // SAFETY: enumeration on a live instance.
    let devices = unsafe { instance.raw.enumerate_physical_devices() }
        .map_err(vk_err("vkEnumeratePhysicalDevices"))?;
    let mut out = Vec::with_capacity(devices.len());
    for (index, physical) in devices.into_iter().enumerate() {
        out.push((physical, describe(instance, physical, index)?));
    }
    Ok(out)
}

/// What the engine knows about `physical`, a device of `instance` (for adopted devices).
pub(crate) fn describe_physical(
    instance: &Instance,
    physical: vk::PhysicalDevice,
) -> GpuResult<AdapterInfo> {
    // SAFETY: enumeration on a live instance.
    let devices = unsafe { instance.raw.enumerate_physical_devices() }
        .map_err(vk_err("vkEnumeratePhysicalDevices"))?;
    let index = devices.iter().position(|&d| d == physical).ok_or_else(|| {
        GpuError::InvalidRequest("the physical device does not belong to the instance".into())
    })?;
    describe(instance, physical, index)
}

/// Picks a device per `selector`; errors list every device and why it was not usable.
pub fn select(
    instance: &Instance,
    selector: &DeviceSelector,
) -> GpuResult<(vk::PhysicalDevice, AdapterInfo)> {
    let adapters = enumerate(instance)?;
    if adapters.is_empty() {
        return Err(GpuError::NoDevices);
    }
    let summary = || {
        adapters
            .iter()
            .map(|(_, a)| {
                if a.is_suitable() {
                    format!("#{} {} (usable)", a.index, a.name)
                } else {
                    format!(
                        "#{} {} (rejected: {})",
                        a.index,
                        a.name,
                        a.rejections.join("; ")
                    )
                }
            })
            .collect::<Vec<_>>()
    };
    let pick = |found: Option<&(vk::PhysicalDevice, AdapterInfo)>, wanted: String| match found {
        Some((p, a)) if a.is_suitable() => Ok((*p, a.clone())),
        _ => Err(GpuError::DeviceNotFound {
            wanted,
            available: summary(),
        }),
    };
    match selector {
        DeviceSelector::Index(i) => pick(adapters.get(*i), format!("#{i}")),
        DeviceSelector::Name(name) => {
            let needle = name.to_lowercase();
            pick(
                adapters
                    .iter()
                    .find(|(_, a)| a.name.to_lowercase().contains(&needle)),
                name.clone(),
            )
        }
        DeviceSelector::Auto => {
            let best = adapters
                .iter()
                .filter(|(_, a)| a.is_suitable())
                .min_by_key(|(_, a)| (a.type_rank(), a.index));
            match best {
                Some((p, a)) => Ok((*p, a.clone())),
                None => Err(GpuError::NoSuitableDevice(
                    adapters
                        .iter()
                        .map(|(_, a)| DeviceRejection {
                            index: a.index,
                            name: a.name.clone(),
                            reasons: a.rejections.clone(),
                        })
                        .collect(),
                )),
            }
        }
    }
}

fn describe(
    instance: &Instance,
    physical: vk::PhysicalDevice,
    index: usize,
) -> GpuResult<AdapterInfo> {
    let raw = &instance.raw;
    let mut driver = vk::PhysicalDeviceDriverProperties::default();
    let mut subgroup = vk::PhysicalDeviceSubgroupProperties::default();
    let mut size_control = vk::PhysicalDeviceSubgroupSizeControlProperties::default();
    let mut properties2 = vk::PhysicalDeviceProperties2::default()
        .push_next(&mut driver)
        .push_next(&mut subgroup)
        .push_next(&mut size_control);
    // SAFETY: enumeration on a device of this instance.
    let extensions = unsafe { raw.enumerate_device_extension_properties(physical) }
        .map_err(vk_err("vkEnumerateDeviceExtensionProperties"))?;
    let has_atomic_float = extensions
        .iter()
        .any(|e| e.extension_name_as_c_str() == Ok(ash::ext::shader_atomic_float::NAME));
    let mut features13 = vk::PhysicalDeviceVulkan13Features::default();
    let mut atomic_float = vk::PhysicalDeviceShaderAtomicFloatFeaturesEXT::default();
    let mut features2 = vk::PhysicalDeviceFeatures2::default().push_next(&mut features13);
    if has_atomic_float {
        features2 = features2.push_next(&mut atomic_float);
    }
    // SAFETY: query calls on a device enumerated from this instance, with valid out-structs
    // (the atomic-float struct chained only when the device has its extension).
    let (queue_families, memory) = unsafe {
        raw.get_physical_device_properties2(physical, &mut properties2);
        raw.get_physical_device_features2(physical, &mut features2);
        (
            raw.get_physical_device_queue_family_properties(physical),
            raw.get_physical_device_memory_properties(physical),
        )
    };
    let properties = properties2.properties;
    let features = features2.features;
    // Float atomic add on buffers or in shared memory (what a float reduction would need).
    let float_atomics = has_atomic_float
        && (atomic_float.shader_buffer_float32_atomic_add == vk::TRUE
            || atomic_float.shader_shared_float32_atomic_add == vk::TRUE);
    let name = properties
        .device_name_as_c_str()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let driver_name = driver
        .driver_name_as_c_str()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let driver_info = driver
        .driver_info_as_c_str()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let has_extension = |wanted: &std::ffi::CStr| {
        extensions
            .iter()
            .any(|e| e.extension_name_as_c_str() == Ok(wanted))
    };

    let mut rejections = Vec::new();
    if properties.api_version < vk::API_VERSION_1_3 {
        rejections.push(format!(
            "supports Vulkan {}.{}, needs 1.3",
            vk::api_version_major(properties.api_version),
            vk::api_version_minor(properties.api_version)
        ));
    }
    let queue_family = queue_families
        .iter()
        .position(|q| q.queue_flags.contains(vk::QueueFlags::COMPUTE) && q.queue_count > 0);
    if queue_family.is_none() {
        rejections.push("has no compute queue".to_string());
    }
    if features.shader_storage_image_write_without_format == vk::FALSE {
        rejections.push("lacks shaderStorageImageWriteWithoutFormat".to_string());
    }
    if features13.synchronization2 == vk::FALSE {
        rejections.push("lacks synchronization2".to_string());
    }
    if !subgroup
        .supported_stages
        .contains(vk::ShaderStageFlags::COMPUTE)
    {
        rejections.push("has no subgroup operations in compute shaders".to_string());
    }
    let wanted_ops = vk::SubgroupFeatureFlags::BASIC
        | vk::SubgroupFeatureFlags::VOTE
        | vk::SubgroupFeatureFlags::ARITHMETIC
        | vk::SubgroupFeatureFlags::BALLOT;
    if !subgroup.supported_operations.contains(wanted_ops) {
        rejections.push(format!(
            "subgroup operations {:?} lack some of basic, vote, arithmetic, ballot",
            subgroup.supported_operations
        ));
    }
    for (format, format_name) in REQUIRED_FORMATS {
        // SAFETY: query on an enumerated device.
        let props = unsafe { raw.get_physical_device_format_properties(physical, *format) };
        let needed = vk::FormatFeatureFlags::SAMPLED_IMAGE
            | vk::FormatFeatureFlags::STORAGE_IMAGE
            | vk::FormatFeatureFlags::SAMPLED_IMAGE_FILTER_LINEAR;
        if !props.optimal_tiling_features.contains(needed) {
            rejections.push(format!(
                "{format_name} 3D images lack sampled+storage+linear-filter support"
            ));
        }
    }

    let family = queue_family.unwrap_or(0);
    let timestamp_valid_bits = queue_families
        .get(family)
        .map(|q| q.timestamp_valid_bits)
        .unwrap_or(0);
    let heaps: Vec<(u64, bool)> = memory.memory_heaps[..memory.memory_heap_count as usize]
        .iter()
        .map(|h| (h.size, h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL)))
        .collect();
    let types = &memory.memory_types[..memory.memory_type_count as usize];
    let unified_memory = heaps
        .iter()
        .enumerate()
        .filter(|(_, (_, local))| *local)
        .all(|(heap, _)| {
            types.iter().any(|t| {
                t.heap_index as usize == heap
                    && t.property_flags.contains(
                        vk::MemoryPropertyFlags::HOST_VISIBLE
                            | vk::MemoryPropertyFlags::DEVICE_LOCAL,
                    )
            })
        })
        && (properties.device_type == vk::PhysicalDeviceType::CPU
            || properties.device_type == vk::PhysicalDeviceType::INTEGRATED_GPU);
    let host_visible_device_bytes = types
        .iter()
        .filter(|t| {
            t.property_flags.contains(
                vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::DEVICE_LOCAL,
            )
        })
        .filter_map(|t| heaps.get(t.heap_index as usize).map(|h| h.0))
        .max()
        .unwrap_or(0);
    let has_subgroup_size_control = features13.subgroup_size_control == vk::TRUE
        && features13.compute_full_subgroups == vk::TRUE
        && size_control
            .required_subgroup_size_stages
            .contains(vk::ShaderStageFlags::COMPUTE);

    Ok(AdapterInfo {
        index,
        name,
        device_type: properties.device_type,
        api_version: properties.api_version,
        driver: format!("{driver_name} {driver_info}").trim().to_string(),
        vendor_id: properties.vendor_id,
        device_id: properties.device_id,
        driver_version: properties.driver_version,
        pipeline_cache_uuid: properties.pipeline_cache_uuid,
        subgroup_size: subgroup.subgroup_size,
        subgroup_size_range: has_subgroup_size_control.then_some((
            size_control.min_subgroup_size,
            size_control.max_subgroup_size,
        )),
        queue_family: family as u32,
        timestamp_valid_bits,
        timestamp_period_ns: properties.limits.timestamp_period as f64,
        max_image_dimension_3d: properties.limits.max_image_dimension3_d,
        max_storage_buffer_range: properties.limits.max_storage_buffer_range,
        max_texel_buffer_elements: properties.limits.max_texel_buffer_elements,
        max_workgroup_count_x: properties.limits.max_compute_work_group_count[0],
        max_workgroup_size: properties.limits.max_compute_work_group_size,
        max_workgroup_invocations: properties.limits.max_compute_work_group_invocations,
        max_workgroup_subgroups: size_control.max_compute_workgroup_subgroups,
        max_push_constants_size: properties.limits.max_push_constants_size,
        has_memory_budget: has_extension(ash::ext::memory_budget::NAME),
        has_pipeline_executable_properties: has_extension(
            ash::khr::pipeline_executable_properties::NAME,
        ),
        has_subgroup_size_control,
        heaps,
        unified_memory,
        host_visible_device_bytes,
        rejections,
        profile: None,
        float_atomics,
    })
}
