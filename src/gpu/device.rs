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
use super::faults::FaultLog;
use super::instance::{Instance, Validation};
use super::memory::{self, MemoryLedger, TrackedAllocation};
use super::profile::{DeviceProfile, KernelTuning};
use super::recycler::{Recycler, RecyclerCounts};
use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};
use std::ffi::CStr;
use std::mem::ManuallyDrop;
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// How to create a device.
#[derive(Clone, Debug, Default)]
pub struct DeviceConfig {
    /// Which physical device.
    pub selector: DeviceSelector,
    /// Whether to load the validation layer.
    pub validation: Validation,
    /// Limits of a constrained device class to apply on top of the real device.
    pub profile: Option<DeviceProfile>,
    /// Workgroup and subgroup sizes of the tunable kernels.
    pub tuning: KernelTuning,
    /// Ask the driver for its compiler's statistics of every pipeline (enables
    /// VK_KHR_pipeline_executable_properties where the device has it; `morphray kernels`).
    pub pipeline_statistics: bool,
}

/// Host times of creating a device, milliseconds (all zero for an adopted device). The path to
/// the first pixel waits for all three, so they are measured separately.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct DeviceTimings {
    /// Opening the Vulkan loader and creating the instance (layers, extensions, messenger).
    pub instance_ms: f64,
    /// Part of `instance_ms`: opening the loader library and the layer and version queries
    /// before `vkCreateInstance`.
    pub loader_ms: f64,
    /// Enumerating the physical devices and describing each (properties, features, formats).
    pub adapter_ms: f64,
    /// `vkCreateDevice`, the queue and the memory allocator.
    pub device_ms: f64,
    /// Part of `device_ms`: the memory allocator (and the memory-property query).
    pub allocator_ms: f64,
}

/// A created or adopted device before its allocator exists.
pub(crate) struct DeviceParts {
    pub(crate) instance: Instance,
    pub(crate) physical: vk::PhysicalDevice,
    pub(crate) adapter: AdapterInfo,
    pub(crate) raw: ash::Device,
    pub(crate) queue: vk::Queue,
    pub(crate) profile: Option<DeviceProfile>,
    pub(crate) tuning: KernelTuning,
    pub(crate) owned: bool,
    pub(crate) timings: DeviceTimings,
    /// VK_KHR_pipeline_executable_properties was enabled (pipelines capture statistics).
    pub(crate) pipeline_statistics: bool,
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
    pub(crate) ledger: Arc<MemoryLedger>,
    pub(crate) profile: Option<DeviceProfile>,
    pub(crate) tuning: KernelTuning,
    pub(crate) timings: DeviceTimings,
    /// Command pools, fences, query pools and breadcrumb buffers reused across submissions.
    pub(crate) recycler: Recycler,
    /// Faults in destructors (failed frees, resets), reported here instead of skipped.
    pub(crate) faults: FaultLog,
    /// Object names and command labels (VK_EXT_debug_utils), when the instance has it.
    pub(crate) debug_utils: Option<ash::ext::debug_utils::Device>,
    /// How many objects were named (tests check that naming happens).
    pub(crate) names_set: std::sync::atomic::AtomicU64,
    /// The compiler-statistics entry points, when enabled ([`DeviceConfig::pipeline_statistics`]).
    pub(crate) executable_properties: Option<ash::khr::pipeline_executable_properties::Device>,
    // False for an integrator's device (`Device::adopt`): the integrator destroys it.
    pub(crate) owned: bool,
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
        let ms = |since: Instant| since.elapsed().as_secs_f64() * 1e3;
        let mut timings = DeviceTimings::default();
        let start = Instant::now();
        let span = crate::files::trace::span("vulkan instance", "gpu-setup");
        let instance = Instance::with_extensions(config.validation, surface_extensions)?;
        timings.instance_ms = ms(start);
        drop(span);
        timings.loader_ms = instance.loader_ms;
        let start = Instant::now();
        let selector = match &config.selector {
            DeviceSelector::Auto => DeviceSelector::from_env(),
            other => other.clone(),
        };
        let span = crate::files::trace::span("adapter choice", "gpu-setup");
        let (physical, adapter) = select(&instance, &selector)?;
        timings.adapter_ms = ms(start);
        drop(span);
        let _span = crate::files::trace::span("device and allocator", "gpu-setup");
        let start = Instant::now();
        // A profile clamps what the engine may use (never more than the device offers).
        let adapter = match &config.profile {
            Some(profile) => profile.clamp(adapter),
            None => adapter,
        };
        let tuning = config
            .tuning
            .clone()
            .with_profile_defaults(config.profile.as_ref());
        if let Some(size) = tuning.subgroup_size {
            super::profile::check_subgroup_size(&adapter, size)?;
        }
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
        let statistics = config.pipeline_statistics && adapter.has_pipeline_executable_properties;
        let mut executable_info =
            vk::PhysicalDevicePipelineExecutablePropertiesFeaturesKHR::default()
                .pipeline_executable_info(true);
        if statistics {
            extensions.push(ash::khr::pipeline_executable_properties::NAME.as_ptr());
        }
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
        let create_info = if statistics {
            create_info.push_next(&mut executable_info)
        } else {
            create_info
        };
        // SAFETY: physical comes from this instance; create_info points to locals alive here.
        let raw = unsafe { instance.raw.create_device(physical, &create_info, None) }
            .map_err(vk_err("vkCreateDevice"))?;
        // SAFETY: queue family and index 0 were requested above.
        let queue = unsafe { raw.get_device_queue(adapter.queue_family, 0) };
        let parts = DeviceParts {
            instance,
            physical,
            adapter,
            raw,
            queue,
            profile: config.profile.clone(),
            tuning,
            owned: true,
            timings,
            pipeline_statistics: statistics,
        };
        let before_allocator = Instant::now();
        let mut device = Self::assemble(parts)?;
        if let Some(shared) = Arc::get_mut(&mut device.shared) {
            shared.timings.device_ms = ms(start);
            shared.timings.allocator_ms = ms(before_allocator);
        }
        Ok(device)
    }

    /// The allocator and the shared state around a created (or adopted) device.
    pub(crate) fn assemble(parts: DeviceParts) -> GpuResult<Self> {
        let DeviceParts {
            instance,
            physical,
            adapter,
            raw,
            queue,
            profile,
            tuning,
            owned,
            timings,
            pipeline_statistics,
        } = parts;
        let debug_utils = instance
            .debug_utils
            .then(|| ash::ext::debug_utils::Device::new(&instance.raw, &raw));
        let executable_properties = pipeline_statistics
            .then(|| ash::khr::pipeline_executable_properties::Device::new(&instance.raw, &raw));
        // SAFETY: query on the physical device this device was created from.
        let memory_properties =
            unsafe { instance.raw.get_physical_device_memory_properties(physical) };
        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: instance.raw.clone(),
            device: raw.clone(),
            physical_device: physical,
            debug_settings: Default::default(),
            buffer_device_address: false,
            allocation_sizes: allocation_sizes(),
        });
        let allocator = match allocator {
            Ok(a) => a,
            Err(e) => {
                if owned {
                    // SAFETY: nothing was created on the device yet.
                    unsafe { raw.destroy_device(None) };
                }
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
                ledger: Arc::new(MemoryLedger::default()),
                profile,
                tuning,
                timings,
                recycler: Recycler::default(),
                faults: FaultLog::default(),
                executable_properties,
                debug_utils,
                names_set: Default::default(),
                owned,
                instance: ManuallyDrop::new(instance),
            }),
        })
    }

    /// What the chosen physical device offers.
    pub fn adapter(&self) -> &AdapterInfo {
        &self.shared.adapter
    }

    /// How long creating this device took (zero for an adopted device).
    pub fn creation_timings(&self) -> DeviceTimings {
        self.shared.timings
    }

    /// Validation messages so far (empty when validation is off).
    pub fn validation_log(&self) -> &Arc<ValidationLog> {
        self.shared.instance.validation_log()
    }

    /// True when the Khronos validation layer is active.
    pub fn validation_enabled(&self) -> bool {
        self.shared.instance.validation_enabled()
    }

    /// True when objects are named and passes labelled for capture tools (VK_EXT_debug_utils).
    pub fn debug_names_enabled(&self) -> bool {
        self.shared.debug_utils.is_some()
    }

    /// How many objects have been named so far (0 without VK_EXT_debug_utils).
    pub fn debug_names_set(&self) -> u64 {
        self.shared
            .names_set
            .load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Live allocations.
    pub fn ledger(&self) -> &Arc<MemoryLedger> {
        &self.shared.ledger
    }

    /// The physical device handle, for integrators.
    pub fn physical(&self) -> vk::PhysicalDevice {
        self.shared.physical
    }

    /// Bytes of device-local memory this process may still allocate: the driver's budget for the
    /// largest device-local heap (VK_EXT_memory_budget, which accounts for other processes) minus
    /// what it reports in use, or, without the extension, that heap's size minus what the
    /// engine's ledger holds.
    pub fn device_local_budget(&self) -> u64 {
        let shared = &self.shared;
        let heaps = &shared.memory_properties.memory_heaps
            [..shared.memory_properties.memory_heap_count as usize];
        let largest = heaps
            .iter()
            .enumerate()
            .filter(|(_, h)| h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL))
            .max_by_key(|(_, h)| h.size)
            .map(|(i, h)| (i, h.size));
        let Some((index, size)) = largest else {
            return 0;
        };
        if shared.adapter.has_memory_budget {
            let mut budget = vk::PhysicalDeviceMemoryBudgetPropertiesEXT::default();
            let mut props = vk::PhysicalDeviceMemoryProperties2::default().push_next(&mut budget);
            // SAFETY: a query on the physical device this device was created from, with the
            // extension enabled at device creation.
            unsafe {
                shared
                    .instance
                    .raw
                    .get_physical_device_memory_properties2(shared.physical, &mut props)
            };
            let available = budget.heap_budget[index].saturating_sub(budget.heap_usage[index]);
            return self.profile_cap(available);
        }
        self.profile_cap(size.saturating_sub(shared.ledger.total_bytes()))
    }

    /// `available` capped by the profile's heap (the modelled machine's, minus what the engine
    /// holds).
    fn profile_cap(&self, available: u64) -> u64 {
        let shared = &self.shared;
        match shared.profile.as_ref().and_then(|p| p.heap_bytes()) {
            Some(heap) => available.min(heap.saturating_sub(shared.ledger.total_bytes())),
            None => available,
        }
    }

    /// The profile applied to this device, if any.
    pub fn profile(&self) -> Option<&DeviceProfile> {
        self.shared.profile.as_ref()
    }

    /// The workgroup and subgroup sizes pipelines are created with.
    pub fn tuning(&self) -> &KernelTuning {
        &self.shared.tuning
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
            Err(_) => Err(GpuError::Internal(
                "the queue lock was poisoned by a panic on another thread".into(),
            )),
        }
    }

    /// Internal faults that happened where no caller could be given an error (destructors:
    /// failed frees or resets); empty when all is well. See `faults.rs`.
    pub fn internal_faults(&self) -> Vec<String> {
        self.shared.faults.all()
    }

    /// How often submissions created or reused their command pool, fence, query pool and
    /// breadcrumb buffer.
    pub fn recycler_counts(&self) -> RecyclerCounts {
        self.shared.recycler.counts()
    }
}

impl DeviceShared {
    /// Names `handle` for capture tools (RenderDoc, GPA, Nsight) and validation messages, when
    /// VK_EXT_debug_utils is enabled; a failure is recorded in the fault log (diagnostics must
    /// not fail the work they describe).
    pub(crate) fn name_object<H: vk::Handle>(&self, handle: H, name: &str) {
        let Some(utils) = &self.debug_utils else {
            return;
        };
        let Ok(name) = std::ffi::CString::new(name.replace('\0', " ")) else {
            return;
        };
        let info = vk::DebugUtilsObjectNameInfoEXT::default()
            .object_handle(handle)
            .object_name(&name);
        // SAFETY: a live handle of this device, a NUL-terminated name alive for the call.
        match unsafe { utils.set_debug_utils_object_name(&info) } {
            Ok(()) => {
                self.names_set
                    .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            }
            Err(e) => self
                .faults
                .record(&GpuError::from_vk("vkSetDebugUtilsObjectNameEXT", e)),
        }
    }

    /// Allocates memory for a resource with `requirements` and binds it with `bind` (given the
    /// memory and offset; `call` names the bind call in errors). On failure nothing stays
    /// allocated, and the caller destroys its still-unbound handle. The one sequence behind
    /// every buffer and image (`Buffer::new`, `Image::new`, the recycler's breadcrumbs).
    pub(crate) fn allocate_bound(
        &self,
        name: &str,
        requirements: vk::MemoryRequirements,
        intent: memory::MemoryIntent,
        linear: bool,
        call: &'static str,
        bind: impl FnOnce(vk::DeviceMemory, u64) -> Result<(), vk::Result>,
    ) -> GpuResult<TrackedAllocation> {
        let tracked = memory::allocate(
            &self.allocator,
            &self.ledger,
            &self.memory_properties,
            name,
            requirements,
            intent,
            linear,
        )?;
        // SAFETY: the allocation is live (its memory handle is valid until it is freed), and
        // memory and offset come from an allocation made for these requirements.
        let memory = unsafe { tracked.allocation.memory() };
        if let Err(e) = bind(memory, tracked.allocation.offset()) {
            self.free_memory(tracked);
            return Err(GpuError::from_vk(call, e));
        }
        Ok(tracked)
    }

    /// Frees device memory; a failure is recorded in the fault log (callers are destructors or
    /// error paths that already return another error).
    pub(crate) fn free_memory(&self, tracked: TrackedAllocation) {
        if let Err(e) = memory::free(&self.allocator, &self.ledger, tracked) {
            self.faults.record(&e);
        }
    }
}

/// Memory-block sizes of the allocator. Host-visible blocks start at 4 MiB and double up to the
/// default 64 MiB as more are needed; device-local blocks keep the default 256 MiB.
///
/// Why: on a discrete NVIDIA GPU every host-visible block is pinned system memory, and pinning
/// costs about 0.2-0.5 ms per MiB. With 64 MiB blocks, the engine's first readback buffer (a few
/// bytes of pass breadcrumbs) cost 12-14 ms and the volume's 25 MiB staging buffer 17-32 ms
/// (H200, driver 580, on the way to the first pixel). With 4 MiB first blocks the first
/// readback pins 4 MiB, and a buffer larger than a block gets a block of its own size. On
/// unified memory (lavapipe, integrated GPUs) allocation is plain host memory either way.
fn allocation_sizes() -> gpu_allocator::AllocationSizes {
    const MIB: u64 = 1 << 20;
    gpu_allocator::AllocationSizes::new(256 * MIB, 4 * MIB).with_max_host_memblock_size(64 * MIB)
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
            // A failed wait (a lost device) leaves nothing to wait for; destroying follows
            // either way, since no one is left to hand the error to.
            if self.owned {
                let _ = self.raw.device_wait_idle();
            } else {
                // Not the whole device: the integrator's other queues are not ours to wait on.
                // A poisoned lock still holds the queue handle.
                let queue = self.queue.lock().unwrap_or_else(|p| p.into_inner());
                let _ = self.raw.queue_wait_idle(*queue);
            }
            // The free leases' breadcrumb memory goes back to the allocator before it is dropped.
            self.recycler.destroy_all(self);
            ManuallyDrop::drop(&mut self.allocator);
            if self.owned {
                self.raw.destroy_device(None);
            }
            ManuallyDrop::drop(&mut self.instance);
        }
    }
}
