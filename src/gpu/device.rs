//! The logical device: one compute queue, the allocator, the memory ledger, and the instance it
//! came from, shared by every resource created on it.
//!
//! Decisions:
//! - Resources hold an `Arc<DeviceShared>`, so the device outlives everything created on it and
//!   drop order is never a question (screen-13's RAII model).
//! - `vkDeviceWaitIdle` runs only in `Drop`, at shutdown; everything else waits on fences.
//! - Enabled features are exactly the ones the shaders need (see `adapter.rs` for the checks):
//!   storage-image writes without format, synchronization2, and subgroup size control where the
//!   device has it (for profiling variants).

use super::adapter::{AdapterInfo, DeviceSelector, select};
use super::debug::ValidationLog;
use super::error::{GpuError, GpuResult, vk_err};
use super::instance::{Instance, Validation};
use super::memory::MemoryLedger;
use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};
use std::ffi::CStr;
use std::mem::ManuallyDrop;
use std::sync::{Arc, Mutex};

/// How to create a device.
#[derive(Clone, Debug, Default)]
pub struct DeviceConfig {
    /// Which physical device.
    pub selector: DeviceSelector,
    /// Whether to load the validation layer.
    pub validation: Validation,
}

/// What a device needs beyond compute to draw an interface and show it in a window (the
/// viewer): graphics on the queue, dynamic rendering, and for a window the surface and
/// swapchain extensions. Commands that only compute never ask for these.
#[derive(Clone, Debug, Default)]
pub struct Presentation {
    /// Instance extensions of the window system's surface (from ash-window); empty offscreen.
    pub surface_extensions: Vec<&'static CStr>,
    /// Enable VK_KHR_swapchain (a window); false for an offscreen interface.
    pub swapchain: bool,
}

/// State shared by the device and every resource created on it.
pub struct DeviceShared {
    pub(crate) raw: ash::Device,
    pub(crate) physical: vk::PhysicalDevice,
    pub(crate) adapter: AdapterInfo,
    pub(crate) memory_properties: vk::PhysicalDeviceMemoryProperties,
    pub(crate) queue: Mutex<vk::Queue>,
    pub(crate) allocator: ManuallyDrop<Mutex<Allocator>>,
    pub(crate) ledger: MemoryLedger,
    // Dropped last: the instance must outlive the device.
    pub(crate) instance: ManuallyDrop<Instance>,
}

/// A Vulkan device ready for compute work. Cheap to clone.
#[derive(Clone)]
pub struct Device {
    pub(crate) shared: Arc<DeviceShared>,
}

impl Device {
    /// Creates instance and device per `config`.
    pub fn new(config: &DeviceConfig) -> GpuResult<Self> {
        Self::create(config, None)
    }

    /// Creates a device that can also draw an interface (graphics queue, dynamic rendering) and,
    /// with `presentation.swapchain`, present to a window surface. Fails with a typed error when
    /// the chosen device's queue cannot draw or the swapchain extension is missing.
    pub fn with_presentation(
        config: &DeviceConfig,
        presentation: &Presentation,
    ) -> GpuResult<Self> {
        Self::create(config, Some(presentation))
    }

    fn create(config: &DeviceConfig, presentation: Option<&Presentation>) -> GpuResult<Self> {
        let surface_extensions = presentation
            .map(|p| p.surface_extensions.as_slice())
            .unwrap_or(&[]);
        let instance = Instance::with_extensions(config.validation, surface_extensions)?;
        let selector = match &config.selector {
            DeviceSelector::Auto => DeviceSelector::from_env(),
            other => other.clone(),
        };
        let (physical, adapter) = select(&instance, &selector)?;
        let priorities = [1.0f32];
        let queue_info = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(adapter.queue_family)
            .queue_priorities(&priorities)];
        let features =
            vk::PhysicalDeviceFeatures::default().shader_storage_image_write_without_format(true);
        let mut features13 = vk::PhysicalDeviceVulkan13Features::default()
            .synchronization2(true)
            .subgroup_size_control(adapter.has_subgroup_size_control)
            .compute_full_subgroups(adapter.has_subgroup_size_control)
            // Dynamic rendering (core and required in 1.3) only for the viewer's interface.
            .dynamic_rendering(presentation.is_some());
        let mut extensions = Vec::new();
        if adapter.has_memory_budget {
            extensions.push(ash::ext::memory_budget::NAME.as_ptr());
        }
        if let Some(p) = presentation {
            check_presentation(&instance, physical, &adapter, p)?;
            if p.swapchain {
                extensions.push(ash::khr::swapchain::NAME.as_ptr());
            }
        }
        let create_info = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queue_info)
            .enabled_features(&features)
            .enabled_extension_names(&extensions)
            .push_next(&mut features13);
        // SAFETY: physical comes from this instance; create_info points to locals alive here.
        let raw = unsafe { instance.raw.create_device(physical, &create_info, None) }
            .map_err(vk_err("vkCreateDevice"))?;
        // SAFETY: queue family and index 0 were requested above.
        let queue = unsafe { raw.get_device_queue(adapter.queue_family, 0) };
        // SAFETY: query on the physical device this device was created from.
        let memory_properties =
            unsafe { instance.raw.get_physical_device_memory_properties(physical) };
        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: instance.raw.clone(),
            device: raw.clone(),
            physical_device: physical,
            debug_settings: Default::default(),
            buffer_device_address: false,
            allocation_sizes: Default::default(),
        });
        let allocator = match allocator {
            Ok(a) => a,
            Err(e) => {
                // SAFETY: nothing was created on the device yet.
                unsafe { raw.destroy_device(None) };
                return Err(GpuError::OutOfDeviceMemory {
                    during: "creating the memory allocator".into(),
                    detail: e.to_string(),
                });
            }
        };
        Ok(Device {
            shared: Arc::new(DeviceShared {
                raw,
                physical,
                adapter,
                memory_properties,
                queue: Mutex::new(queue),
                allocator: ManuallyDrop::new(Mutex::new(allocator)),
                ledger: MemoryLedger::default(),
                instance: ManuallyDrop::new(instance),
            }),
        })
    }

    /// What the chosen physical device offers.
    pub fn adapter(&self) -> &AdapterInfo {
        &self.shared.adapter
    }

    /// Validation messages so far (empty when validation is off).
    pub fn validation_log(&self) -> &Arc<ValidationLog> {
        self.shared.instance.validation_log()
    }

    /// True when the Khronos validation layer is active.
    pub fn validation_enabled(&self) -> bool {
        self.shared.instance.validation_enabled()
    }

    /// Live allocations.
    pub fn ledger(&self) -> &MemoryLedger {
        &self.shared.ledger
    }

    /// The physical device handle, for integrators.
    pub fn physical(&self) -> vk::PhysicalDevice {
        self.shared.physical
    }

    /// True when `format` has all of `features` for optimally tiled images on this device.
    pub fn supports_format(&self, format: vk::Format, features: vk::FormatFeatureFlags) -> bool {
        // SAFETY: a query on the physical device this device was created from.
        let props = unsafe {
            self.shared
                .instance
                .raw
                .get_physical_device_format_properties(self.shared.physical, format)
        };
        props.optimal_tiling_features.contains(features)
    }

    /// The raw ash device, for integrators.
    pub fn raw(&self) -> &ash::Device {
        &self.shared.raw
    }

    /// The instance this device was created from (surface creation needs it).
    pub fn instance(&self) -> &Instance {
        &self.shared.instance
    }

    /// Runs `f` with the device's one queue, holding its lock (Vulkan requires external
    /// synchronization of queue calls such as vkQueuePresentKHR and third-party uploads).
    pub fn with_queue<R>(&self, f: impl FnOnce(vk::Queue) -> R) -> GpuResult<R> {
        match self.shared.queue.lock() {
            Ok(queue) => Ok(f(*queue)),
            Err(_) => Err(GpuError::InvalidRequest(
                "the queue lock was poisoned by a panic on another thread".into(),
            )),
        }
    }
}

/// The viewer's needs that `adapter::select` does not check (compute commands never need them).
fn check_presentation(
    instance: &Instance,
    physical: vk::PhysicalDevice,
    adapter: &AdapterInfo,
    presentation: &Presentation,
) -> GpuResult<()> {
    // SAFETY: queries on a physical device of this instance.
    let families = unsafe {
        instance
            .raw
            .get_physical_device_queue_family_properties(physical)
    };
    let graphics = families
        .get(adapter.queue_family as usize)
        .is_some_and(|f| f.queue_flags.contains(vk::QueueFlags::GRAPHICS));
    if !graphics {
        return Err(GpuError::Unsupported(format!(
            "{}: the compute queue cannot draw graphics, which the viewer's interface needs",
            adapter.name
        )));
    }
    if presentation.swapchain {
        // SAFETY: as above.
        let extensions = unsafe { instance.raw.enumerate_device_extension_properties(physical) }
            .map_err(vk_err("vkEnumerateDeviceExtensionProperties"))?;
        if !extensions
            .iter()
            .any(|e| e.extension_name_as_c_str() == Ok(ash::khr::swapchain::NAME))
        {
            return Err(GpuError::Unsupported(format!(
                "{} has no VK_KHR_swapchain, so it cannot show a window (try --offscreen)",
                adapter.name
            )));
        }
    }
    Ok(())
}

impl Drop for DeviceShared {
    fn drop(&mut self) {
        // SAFETY: this runs when the last resource holding the device has been dropped, so
        // nothing else uses the device. Waiting for idle here (shutdown) covers work that was
        // submitted but never waited for. The allocator frees its blocks through the device, so
        // it goes first; the instance goes last.
        unsafe {
            let _ = self.raw.device_wait_idle();
            ManuallyDrop::drop(&mut self.allocator);
            self.raw.destroy_device(None);
            ManuallyDrop::drop(&mut self.instance);
        }
    }
}
