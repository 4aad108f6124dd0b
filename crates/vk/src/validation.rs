//! Validation-layer messages: routed through `log`, and collected so that a test can fail on them.

use std::ffi::{c_void, CStr};
use std::sync::Mutex;

use ash::vk;

/// Whether to load `VK_LAYER_KHRONOS_validation` (with synchronization validation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Validation {
    /// Never (release builds by default).
    Off,
    /// When the layer is installed; otherwise a warning (debug builds by default).
    IfAvailable,
    /// Always; a missing layer is an error (tests).
    Required,
}

impl Validation {
    /// `TILEGRAPH_VALIDATION=0|1|required` overrides; otherwise on in debug builds, off in release.
    pub fn from_env() -> Self {
        match std::env::var("TILEGRAPH_VALIDATION").ok().as_deref() {
            Some("0" | "off" | "false") => Validation::Off,
            Some("required") => Validation::Required,
            Some(_) => Validation::IfAvailable,
            None if cfg!(debug_assertions) => Validation::IfAvailable,
            None => Validation::Off,
        }
    }
}

/// Collects every warning and error the layer reports. Lives in a `Box` whose address is the
/// messenger's user data, so it must outlive the messenger (the `Instance` guarantees that).
#[derive(Debug, Default)]
pub struct ValidationSink {
    messages: Mutex<Vec<String>>,
}

impl ValidationSink {
    pub fn count(&self) -> usize {
        self.messages.lock().map(|m| m.len()).unwrap_or(0)
    }

    /// Returns and clears the collected messages.
    pub fn take(&self) -> Vec<String> {
        self.messages
            .lock()
            .map(|mut m| std::mem::take(&mut *m))
            .unwrap_or_default()
    }

    fn push(&self, message: String) {
        if let Ok(mut m) = self.messages.lock() {
            m.push(message);
        }
    }
}

/// The messenger callback. Warnings and errors are failures; info and verbose are only logged.
///
/// # Safety
/// Called by the loader with a valid callback-data pointer; `user_data` is the address of the
/// `ValidationSink` owned by the instance.
pub(crate) unsafe extern "system" fn debug_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user_data: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: the loader passes a valid pointer for the duration of the call.
    let Some(data) = (unsafe { data.as_ref() }) else {
        return vk::FALSE;
    };
    let text = |p: *const std::ffi::c_char| {
        if p.is_null() {
            String::new()
        } else {
            // SAFETY: non-null strings in the callback data are NUL-terminated (spec).
            unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
        }
    };
    let id = text(data.p_message_id_name);
    let message = format!("[{id}] {}", text(data.p_message));
    // GENERAL messages come from the loader about the machine (manifests of other drivers and
    // layers it could not load), not about this program's use of the API: logged, not failures.
    let failure = severity.intersects(
        vk::DebugUtilsMessageSeverityFlagsEXT::ERROR
            | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING,
    ) && !types.contains(vk::DebugUtilsMessageTypeFlagsEXT::GENERAL);
    if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
        log::error!(target: "vulkan", "{message}");
    } else if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::WARNING) {
        log::warn!(target: "vulkan", "{message}");
    } else if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::INFO) {
        log::debug!(target: "vulkan", "{message}");
    } else {
        log::trace!(target: "vulkan", "{message}");
    }
    if failure {
        // SAFETY: user_data is the Box<ValidationSink> address set at messenger creation; the
        // instance destroys the messenger before dropping the box.
        if let Some(sink) = unsafe { (user_data as *const ValidationSink).as_ref() } {
            sink.push(message);
        }
    }
    vk::FALSE
}
