//! Validation-layer messages: collected per instance by a debug-utils messenger and turned into
//! errors, so `LENSBLUR_VALIDATION=1` makes any warning or error a failure of the command.
use std::ffi::{c_void, CStr};
use std::sync::Mutex;

use ash::vk;

/// Messages that arrived while objects were being destroyed, when no call was left to return
/// them from. The CLI and the tests check this after dropping their context.
static UNREPORTED: Mutex<Vec<String>> = Mutex::new(Vec::new());

/// Where one instance's messenger stores its messages.
#[derive(Default)]
pub(crate) struct MessageLog {
    messages: Mutex<Vec<String>>,
}

impl MessageLog {
    fn push(&self, message: String) {
        self.messages.lock().unwrap_or_else(|e| e.into_inner()).push(message);
    }

    /// Returns an error naming the first message if any arrived since the last check.
    pub(crate) fn check(&self) -> crate::Result<()> {
        let mut messages = self.messages.lock().unwrap_or_else(|e| e.into_inner());
        if messages.is_empty() {
            return Ok(());
        }
        let taken = std::mem::take(&mut *messages);
        Err(crate::Error::Validation { count: taken.len(), first: taken[0].clone() })
    }

    /// Moves whatever is left into the process-wide list (called when the instance dies).
    pub(crate) fn flush_unreported(&self) {
        let mut messages = self.messages.lock().unwrap_or_else(|e| e.into_inner());
        UNREPORTED.lock().unwrap_or_else(|e| e.into_inner()).append(&mut messages);
    }
}

/// Fails if a validation message arrived while a context was torn down.
pub fn check_unreported() -> crate::Result<()> {
    let taken = std::mem::take(&mut *UNREPORTED.lock().unwrap_or_else(|e| e.into_inner()));
    match taken.first() {
        None => Ok(()),
        Some(first) => Err(crate::Error::Validation { count: taken.len(), first: first.clone() }),
    }
}

pub(crate) fn messenger_info(log: &MessageLog) -> vk::DebugUtilsMessengerCreateInfoEXT<'static> {
    vk::DebugUtilsMessengerCreateInfoEXT::default()
        .message_severity(vk::DebugUtilsMessageSeverityFlagsEXT::WARNING | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR)
        .message_type(
            vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
        )
        .pfn_user_callback(Some(on_message))
        .user_data(log as *const MessageLog as *mut c_void)
}

unsafe extern "system" fn on_message(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user_data: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: the layer passes a valid callback-data pointer for the duration of the call, and
    // `user_data` is the `MessageLog` owned by the `Instance`, which outlives the messenger.
    let (message, log) = unsafe {
        let text = data
            .as_ref()
            .and_then(|d| d.message_as_c_str())
            .map(CStr::to_string_lossy)
            .unwrap_or_default()
            .into_owned();
        (text, (user_data as *const MessageLog).as_ref())
    };
    let line = format!("[{severity:?}] {message}");
    log::warn!("validation: {line}");
    if let Some(log) = log {
        log.push(line);
    }
    vk::FALSE
}
