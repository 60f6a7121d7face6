//! Validation-layer messages, collected so tests can fail on them.
//!
//! Decision: the debug-utils messenger records every validation message of severity ERROR (core and
//! synchronization validation report hazards as errors) into a shared [`ValidationLog`]; warnings
//! are kept separately for display. Nothing is printed from the callback, so library users decide
//! what to show, and a test asserts `errors()` is empty after its GPU work.

use ash::vk;
use std::ffi::CStr;
use std::sync::{Arc, Mutex};

/// Messages the validation layer reported, shared between the messenger and its readers.
#[derive(Debug, Default)]
pub struct ValidationLog {
    errors: Mutex<Vec<String>>,
    warnings: Mutex<Vec<String>>,
}

impl ValidationLog {
    /// All error messages so far.
    pub fn errors(&self) -> Vec<String> {
        // A poisoned list still holds every message (pushes cannot half-happen): recovered,
        // so a panic elsewhere never hides a validation error.
        self.errors
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .clone()
    }

    /// All warning messages so far.
    pub fn warnings(&self) -> Vec<String> {
        self.warnings
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .clone()
    }

    fn push(&self, severity: vk::DebugUtilsMessageSeverityFlagsEXT, message: String) {
        let list = if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
            &self.errors
        } else {
            &self.warnings
        };
        list.lock().unwrap_or_else(|p| p.into_inner()).push(message);
    }
}

/// The messenger callback. `user_data` is the `ValidationLog` owned by the instance (kept alive
/// for as long as the messenger exists).
pub(crate) unsafe extern "system" fn messenger_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    kinds: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user_data: *mut std::ffi::c_void,
) -> vk::Bool32 {
    if user_data.is_null() || data.is_null() {
        return vk::FALSE;
    }
    // SAFETY: user_data is the pointer registered in `Instance::new`, which points into an Arc it
    // keeps until after the messenger is destroyed; `data` is valid for this call per the spec.
    let (log, data) = unsafe { (&*(user_data as *const ValidationLog), &*data) };
    if !kinds.intersects(
        vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION | vk::DebugUtilsMessageTypeFlagsEXT::GENERAL,
    ) {
        return vk::FALSE;
    }
    let text = if data.p_message.is_null() {
        String::from("(no message)")
    } else {
        // SAFETY: non-null p_message is a NUL-terminated string per the spec.
        unsafe { CStr::from_ptr(data.p_message) }
            .to_string_lossy()
            .into_owned()
    };
    log.push(severity, text);
    vk::FALSE
}

/// Creates the shared log for a new instance.
pub(crate) fn new_log() -> Arc<ValidationLog> {
    Arc::new(ValidationLog::default())
}
