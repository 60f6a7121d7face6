//! Typed errors of the gpu layer.
//!
//! Decision (after wgpu-hal's `map_host_device_oom_and_lost_err`): every Vulkan result is mapped at
//! its call site into a variant that says what failed and what the user can do. Out-of-memory and
//! device-lost are their own variants because callers react to them (pick a smaller plan, name the
//! pass that hung); everything else keeps the Vulkan call name and result code.
//!
//! Misuse and faults are separate variants (issue 13 item 6): [`GpuError::InvalidRequest`] is a
//! request the caller can correct (sizes, bindings, a scene the prepared volume cannot draw),
//! [`GpuError::Internal`] a fault that is not the caller's (a poisoned lock, a failed free, an
//! impossible state). Faults in destructors, where no caller gets a result, are recorded in the
//! device's fault log (`faults.rs`), never skipped.

use ash::vk;

/// Why one physical device was not chosen.
#[derive(Clone, Debug, PartialEq)]
pub struct DeviceRejection {
    /// Index in the Vulkan enumeration order.
    pub index: usize,
    /// Device name reported by the driver.
    pub name: String,
    /// Every unmet requirement, one short phrase each.
    pub reasons: Vec<String>,
}

impl std::fmt::Display for DeviceRejection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "#{} {}: {}",
            self.index,
            self.name,
            self.reasons.join("; ")
        )
    }
}

/// Errors of the gpu layer.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// The Vulkan loader library could not be opened.
    #[error(
        "no Vulkan loader found ({0}); install one (Debian: `apt-get install libvulkan1 mesa-vulkan-drivers` for a CPU device)"
    )]
    LoaderMissing(String),
    /// The loader found no physical device at all.
    #[error(
        "Vulkan found no device; install a driver (Debian: `apt-get install mesa-vulkan-drivers` provides the lavapipe CPU device)"
    )]
    NoDevices,
    /// Devices exist, but none meets the engine's requirements.
    #[error("no Vulkan device meets morphray's requirements: {}", list(.0))]
    NoSuitableDevice(Vec<DeviceRejection>),
    /// The device the user asked for does not exist or was rejected.
    #[error("Vulkan device `{wanted}` is not usable; devices: {}", .available.join(", "))]
    DeviceNotFound {
        /// What the user asked for (index or name).
        wanted: String,
        /// Every device with its status.
        available: Vec<String>,
    },
    /// Validation was requested but the Khronos layer is not installed.
    #[error(
        "the Khronos validation layer is not installed (Debian: `apt-get install vulkan-validationlayers`)"
    )]
    ValidationLayerMissing,
    /// Host memory ran out in a Vulkan call.
    #[error("out of host memory during {0}")]
    OutOfHostMemory(String),
    /// Device memory ran out (allocation or Vulkan call).
    #[error("out of GPU memory during {during}: {detail}")]
    OutOfDeviceMemory {
        /// What was being allocated or executed.
        during: String,
        /// Sizes involved, as far as known.
        detail: String,
    },
    /// The device was lost (driver crash, hang, or GPU reset).
    #[error("the GPU device was lost during {0}; the results of that work are gone")]
    DeviceLost(String),
    /// Waiting for the GPU took longer than the engine's limit.
    #[error("the GPU did not finish {0} within the time limit")]
    Timeout(String),
    /// A feature, format or limit the work needs is missing.
    #[error("unsupported on this device: {0}")]
    Unsupported(String),
    /// The caller's request does not fit the resource (sizes, bindings, specialization): the
    /// caller's misuse, which the caller can correct.
    #[error("invalid GPU request: {0}")]
    InvalidRequest(String),
    /// Input data the GPU work cannot use (a voxel spacing f32 cannot differentiate): the
    /// message says what is wrong with the data and how to fix it.
    #[error("{0}")]
    UnusableInput(String),
    /// A fault that is not the caller's: a lock poisoned by a panic on another thread, a failed
    /// free, an impossible state. Nothing the caller changes avoids it; it is a bug to report.
    #[error("internal fault in morphray's GPU layer (please report it): {0}")]
    Internal(String),
    /// Any other failed Vulkan call.
    #[error("Vulkan call {call} failed: {result:?}")]
    Vulkan {
        /// The Vulkan function.
        call: &'static str,
        /// Its result code.
        result: vk::Result,
    },
}

fn list(rejections: &[DeviceRejection]) -> String {
    rejections
        .iter()
        .map(|r| r.to_string())
        .collect::<Vec<_>>()
        .join(" | ")
}

impl GpuError {
    /// Maps a failed Vulkan call: out-of-memory and device-lost become their own variants.
    pub fn from_vk(call: &'static str, result: vk::Result) -> Self {
        match result {
            vk::Result::ERROR_OUT_OF_HOST_MEMORY => GpuError::OutOfHostMemory(call.to_string()),
            vk::Result::ERROR_OUT_OF_DEVICE_MEMORY => GpuError::OutOfDeviceMemory {
                during: call.to_string(),
                detail: "the driver refused the allocation".to_string(),
            },
            vk::Result::ERROR_DEVICE_LOST => GpuError::DeviceLost(call.to_string()),
            result => GpuError::Vulkan { call, result },
        }
    }

    /// True for out-of-memory of either kind (callers may retry with a smaller plan).
    pub fn is_out_of_memory(&self) -> bool {
        matches!(
            self,
            GpuError::OutOfHostMemory(_) | GpuError::OutOfDeviceMemory { .. }
        )
    }
}

/// Shorthand for results of the gpu layer.
pub type GpuResult<T> = Result<T, GpuError>;

/// Adds the call name to a raw Vulkan result: `unsafe { device.f(..) }.map_err(vk_err("vkF"))?`.
pub fn vk_err(call: &'static str) -> impl Fn(vk::Result) -> GpuError {
    move |result| GpuError::from_vk(call, result)
}
