//! The Vulkan instance: loader, optional Khronos validation (core + synchronization), messenger.
//!
//! Decisions:
//! - The loader is opened at run time (`ash::Entry::load`), so a machine without Vulkan gets a
//!   typed error naming the package to install instead of a link failure.
//! - Validation is a test oracle (every GPU test fails on a validation error):
//!   [`Validation::Required`] fails if the layer is missing, [`Validation::IfAvailable`] (debug
//!   builds) uses it when installed, [`Validation::Off`] (release) never loads it. Synchronization
//!   validation is switched on through VK_EXT_validation_features whenever the layer is on.
//! - API version 1.3: synchronization2, subgroup size control and maintenance4 are core there, and
//!   every target (lavapipe, NVIDIA, Intel ANV on Gen12) has it.

use super::debug::{ValidationLog, messenger_callback, new_log};
use super::error::{GpuError, GpuResult, vk_err};
use ash::{ext, vk};
use std::ffi::{CStr, c_char};
use std::sync::Arc;

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

/// Whether to load the Khronos validation layer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Validation {
    /// Never load it (release builds, benchmarks).
    Off,
    /// Load it when installed (the default in debug builds).
    #[default]
    IfAvailable,
    /// Fail if it is not installed (tests).
    Required,
}

impl Validation {
    /// `IfAvailable` in debug builds, `Off` in release builds;
    /// `MORPHRAY_VALIDATION=required|on|off` overrides.
    pub fn from_build_and_env() -> Self {
        match std::env::var("MORPHRAY_VALIDATION").as_deref() {
            Ok("required") => Validation::Required,
            Ok("on") | Ok("1") => Validation::IfAvailable,
            Ok("off") | Ok("0") => Validation::Off,
            _ if cfg!(debug_assertions) => Validation::IfAvailable,
            _ => Validation::Off,
        }
    }
}

/// A Vulkan instance with its loader and (optionally) a validation messenger.
pub struct Instance {
    // Holds the loaded libvulkan; dropping it would unload the loader under the instance.
    entry: ash::Entry,
    pub(crate) raw: ash::Instance,
    messenger: Option<(ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    log: Arc<ValidationLog>,
    validation_enabled: bool,
    // VK_EXT_debug_utils is enabled: objects get names and passes labels (capture tools).
    pub(crate) debug_utils: bool,
    // False for an integrator's instance (see `Instance::adopt`): the integrator destroys it.
    owned: bool,
    // Opening the loader and the layer and version queries before vkCreateInstance (ms).
    pub(crate) loader_ms: f64,
}

impl Instance {
    /// Opens the loader and creates an instance.
    pub fn new(validation: Validation) -> GpuResult<Self> {
        Self::with_extensions(validation, &[])
    }

    /// Like [`Instance::new`], with extra instance extensions enabled (the window system's
    /// surface extensions, for the viewer); one the loader lacks is a typed error naming it.
    pub fn with_extensions(validation: Validation, extra: &[&CStr]) -> GpuResult<Self> {
        let start = std::time::Instant::now();
        // SAFETY: loading the system Vulkan loader; ash checks the symbols it needs.
        let entry =
            unsafe { ash::Entry::load() }.map_err(|e| GpuError::LoaderMissing(e.to_string()))?;
        // SAFETY: plain enumeration calls on a loaded entry.
        let layers = unsafe { entry.enumerate_instance_layer_properties() }
            .map_err(vk_err("vkEnumerateInstanceLayerProperties"))?;
        let has_layer = layers
            .iter()
            .any(|l| l.layer_name_as_c_str() == Ok(VALIDATION_LAYER));
        let use_validation = match validation {
            Validation::Off => false,
            Validation::IfAvailable => has_layer,
            Validation::Required if !has_layer => return Err(GpuError::ValidationLayerMissing),
            Validation::Required => true,
        };
        // SAFETY: as above.
        let version = unsafe { entry.try_enumerate_instance_version() }
            .map_err(vk_err("vkEnumerateInstanceVersion"))?
            .unwrap_or(vk::API_VERSION_1_0);
        if version < vk::API_VERSION_1_3 {
            return Err(GpuError::Unsupported(format!(
                "the Vulkan loader supports API {}.{}, morphray needs 1.3",
                vk::api_version_major(version),
                vk::api_version_minor(version)
            )));
        }

        let loader_ms = start.elapsed().as_secs_f64() * 1e3;
        let app_info = vk::ApplicationInfo::default()
            .application_name(c"morphray")
            .application_version(0)
            .engine_name(c"morphray")
            .api_version(vk::API_VERSION_1_3);
        let mut layer_names: Vec<*const c_char> = Vec::new();
        let mut extension_names: Vec<*const c_char> = Vec::new();
        // SAFETY: plain enumeration call on a loaded entry.
        let available = unsafe { entry.enumerate_instance_extension_properties(None) }
            .map_err(vk_err("vkEnumerateInstanceExtensionProperties"))?;
        // Object names and pass labels for RenderDoc, GPA and Nsight whenever the loader offers
        // the extension (it costs nothing at run time without a capture tool attached).
        let debug_utils = use_validation
            || available
                .iter()
                .any(|e| e.extension_name_as_c_str() == Ok(ext::debug_utils::NAME));
        if debug_utils {
            extension_names.push(ext::debug_utils::NAME.as_ptr());
        }
        if !extra.is_empty() {
            for wanted in extra {
                if !available
                    .iter()
                    .any(|e| e.extension_name_as_c_str() == Ok(*wanted))
                {
                    return Err(GpuError::Unsupported(format!(
                        "the Vulkan loader lacks the instance extension {}, needed to show a window",
                        wanted.to_string_lossy()
                    )));
                }
                extension_names.push(wanted.as_ptr());
            }
        }
        if use_validation {
            layer_names.push(VALIDATION_LAYER.as_ptr());
            extension_names.push(ext::validation_features::NAME.as_ptr());
        }
        let enabled_features = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
        let mut validation_features =
            vk::ValidationFeaturesEXT::default().enabled_validation_features(&enabled_features);
        let log = new_log();
        let mut messenger_info = messenger_create_info(&log);
        let mut create_info = vk::InstanceCreateInfo::default()
            .application_info(&app_info)
            .enabled_layer_names(&layer_names)
            .enabled_extension_names(&extension_names);
        if use_validation {
            // The chained messenger also reports problems inside vkCreateInstance itself.
            create_info = create_info
                .push_next(&mut validation_features)
                .push_next(&mut messenger_info);
        }
        // SAFETY: every pointer in create_info refers to locals alive for this call.
        let raw = unsafe { entry.create_instance(&create_info, None) }
            .map_err(vk_err("vkCreateInstance"))?;

        let messenger = if use_validation {
            let loader = ext::debug_utils::Instance::new(&entry, &raw);
            // SAFETY: the callback's user data points into `log`, which this Instance keeps alive
            // until after the messenger is destroyed in Drop.
            match unsafe { loader.create_debug_utils_messenger(&messenger_create_info(&log), None) }
            {
                Ok(m) => Some((loader, m)),
                Err(e) => {
                    // SAFETY: nothing else was created from this instance yet.
                    unsafe { raw.destroy_instance(None) };
                    return Err(GpuError::from_vk("vkCreateDebugUtilsMessengerEXT", e));
                }
            }
        } else {
            None
        };
        Ok(Instance {
            entry,
            raw,
            messenger,
            log,
            validation_enabled: use_validation,
            debug_utils,
            owned: true,
            loader_ms,
        })
    }

    /// Wraps an instance the integrator created and will destroy (after every morphray object
    /// made from it is dropped). Its validation messages, if any, go to the integrator's own
    /// messenger; morphray's log stays empty.
    pub fn adopt(entry: ash::Entry, raw: ash::Instance) -> Instance {
        Instance {
            entry,
            raw,
            messenger: None,
            log: new_log(),
            validation_enabled: false,
            debug_utils: false,
            owned: false,
            loader_ms: 0.0,
        }
    }

    /// True when the Khronos validation layer is active.
    pub fn validation_enabled(&self) -> bool {
        self.validation_enabled
    }

    /// The messages the validation layer reported so far (empty when it is off).
    pub fn validation_log(&self) -> &Arc<ValidationLog> {
        &self.log
    }

    /// The raw ash instance, for integrators who need it.
    pub fn raw(&self) -> &ash::Instance {
        &self.raw
    }

    /// The loaded Vulkan entry points (surface creation needs them).
    pub fn entry(&self) -> &ash::Entry {
        &self.entry
    }
}

fn messenger_create_info(
    log: &Arc<ValidationLog>,
) -> vk::DebugUtilsMessengerCreateInfoEXT<'static> {
    vk::DebugUtilsMessengerCreateInfoEXT::default()
        .message_severity(
            vk::DebugUtilsMessageSeverityFlagsEXT::ERROR
                | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING,
        )
        .message_type(
            vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                | vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
        )
        .pfn_user_callback(Some(messenger_callback))
        .user_data(Arc::as_ptr(log) as *mut std::ffi::c_void)
}

impl Drop for Instance {
    fn drop(&mut self) {
        // SAFETY: the device (which holds this instance) is destroyed before the instance is
        // dropped; the messenger is destroyed before the instance and before `log` is released.
        unsafe {
            if let Some((loader, messenger)) = self.messenger.take() {
                loader.destroy_debug_utils_messenger(messenger, None);
            }
            if self.owned {
                self.raw.destroy_instance(None);
            }
        }
    }
}
