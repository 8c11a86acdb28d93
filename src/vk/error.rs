//! Mapping `vk::Result` into the library error, naming the Vulkan entry point that failed.
use ash::vk;

use crate::Error;

/// `.call("vkCreateBuffer")` turns an ash result into [`Error::Vulkan`] carrying the call name,
/// so a failure message says which step broke (allocation, submission, device loss, ...).
pub(crate) trait VkCall<T> {
    fn call(self, name: &'static str) -> crate::Result<T>;
}

impl<T> VkCall<T> for Result<T, vk::Result> {
    fn call(self, name: &'static str) -> crate::Result<T> {
        self.map_err(|result| Error::Vulkan { call: name, result })
    }
}
