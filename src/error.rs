//! The library's one error type. The CLI adds `anyhow` context on top of it.
use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A Vulkan call failed; `call` names the entry point so the message says what broke.
    #[error("Vulkan call {call} failed: {result:?}")]
    Vulkan { call: &'static str, result: ash::vk::Result },
    #[error("Vulkan is not available: {0}")]
    NoVulkan(String),
    #[error("Vulkan validation reported {count} message(s); first: {first}")]
    Validation { count: usize, first: String },
    #[error("GPU memory allocation failed: {0}")]
    Allocation(#[from] gpu_allocator::AllocationError),
    #[error("{path}: {message}")]
    Input { path: PathBuf, message: String },
    #[error("invalid parameter: {0}")]
    Parameter(String),
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    pub fn param(message: impl Into<String>) -> Self {
        Error::Parameter(message.into())
    }
    pub fn input(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Error::Input { path: path.into(), message: message.into() }
    }

    /// The device (or the driver's host side) ran out of memory: worth retrying smaller.
    pub fn is_out_of_memory(&self) -> bool {
        use ash::vk::Result as VkResult;
        match self {
            Error::Allocation(gpu_allocator::AllocationError::OutOfMemory) => true,
            Error::Vulkan { result, .. } => {
                matches!(*result, VkResult::ERROR_OUT_OF_DEVICE_MEMORY | VkResult::ERROR_OUT_OF_HOST_MEMORY)
            }
            _ => false,
        }
    }
}
