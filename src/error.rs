//! The library's one error type. The CLI adds `anyhow` context on top of it.
//!
//! A caller can match on what went wrong: the device ([`Error::Vulkan`], [`Error::NoVulkan`],
//! [`Error::OutOfDeviceMemory`], ...), a file ([`Error::Input`], [`Error::Io`], options that do not
//! fit its kind: [`Error::InputMismatch`]), a value it
//! passed ([`Error::InvalidParameter`] names which), data that cannot be used as handed over
//! ([`Error::Data`]: sizes that do not match, an empty stack), the camera
//! ([`Error::MissingCamera`], [`Error::InvalidCamera`]), an operation that does not apply
//! ([`Error::Unsupported`]), or a bug of ours ([`Error::Internal`]).
//!
//! A variant that wraps another error returns it from `source()` and leaves it out of its own
//! message: the CLI prints the whole chain (`{:#}`), so a cause named in both places would be
//! printed twice (`x.exr: No such file or directory: No such file or directory`).
use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A Vulkan call failed; `call` names the entry point so the message says what broke.
    #[error("Vulkan call {call} failed: {result:?}{}", vulkan_hint(*result))]
    Vulkan { call: &'static str, result: ash::vk::Result },
    #[error("Vulkan is not available: {0}")]
    NoVulkan(String),
    #[error("Vulkan validation reported {count} message(s); first: {first}")]
    Validation { count: usize, first: String },
    #[error("GPU memory allocation failed")]
    Allocation(#[from] gpu_allocator::AllocationError),
    /// Out of device memory with the smallest tiles: retrying smaller cannot help.
    #[error(
        "out of device memory even with {tile} px tiles, one per submission; free device memory \
         (close other programs using the GPU), choose a device with more memory (LENSBLUR_DEVICE, see \
         `lensblur devices`), or render on the CPU (`lensblur render --device cpu`)"
    )]
    OutOfDeviceMemory { tile: usize, source: Box<Error> },
    #[error("{path}: {message}")]
    Input { path: PathBuf, message: String },
    /// The input options do not fit the file's kind ([`InputMismatch`] says which): a caller
    /// that set them from its own flags can name the flag.
    #[error("{path}: {mismatch}")]
    InputMismatch { path: PathBuf, mismatch: InputMismatch },
    /// A value the caller passed is out of range or malformed; `parameter` names it (`aperture`,
    /// `frame range`, `vdslr settings`, ...) and the message says what is accepted.
    #[error("{message}")]
    InvalidParameter { parameter: &'static str, message: String },
    /// Data that cannot be used as handed over: sizes or lengths that do not match, an empty
    /// stack, non-finite depth, nothing visible to measure.
    #[error("{0}")]
    Data(String),
    /// A physical camera parameter that neither the caller, the file's header nor the shot's
    /// camera file gives; `parameter` is its key (`focal-length`, `fstop`, `focus-distance`).
    #[error(
        "no {parameter} (not given, and the file's header has no camera): give a physical camera \
         (focal length, f-stop, focus distance, optionally sensor width) or the normalised model \
         (CoC pixels per unit of disparity, focus disparity)"
    )]
    MissingCamera { parameter: &'static str },
    /// A physical camera parameter that is not a positive number (given or from the header).
    #[error("{parameter} must be a positive number, got {value} (given or from the file's header)")]
    InvalidCamera { parameter: &'static str, value: f32 },
    /// The operation does not apply to this input or method (the message says why).
    #[error("{0}")]
    Unsupported(String),
    /// A broken internal invariant (a shader's bindings, a buffer's size): a bug in lensblur,
    /// not in what the caller passed.
    #[error("internal error (a bug in lensblur; please report it): {0}")]
    Internal(String),
    /// The I/O error is the `source()`; the message names the file only (see the module note).
    #[error("{path}")]
    Io { path: PathBuf, source: std::io::Error },
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Which input option does not fit the file (`crate::input::InputOptions`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum InputMismatch {
    /// A PNG/JPEG input without `depth_image`.
    #[error("a PNG/JPEG input needs its depth image (a grey PNG)")]
    MissingDepthImage,
    /// `layers` selected in a PNG/JPEG input.
    #[error("is a single image: there are no layers to select")]
    LayersOfSingleImage,
    /// `depth_image` beside an EXR, which carries its depth in its channels.
    #[error("carries its depth in its channels: a separate depth image is for PNG/JPEG inputs")]
    DepthImageBesideStack,
}

/// What a Vulkan failure means for the user, where the bare result code does not say it.
fn vulkan_hint(result: ash::vk::Result) -> &'static str {
    match result {
        ash::vk::Result::ERROR_DEVICE_LOST => {
            " (the GPU device was lost: a driver reset, crash or timeout; nothing was written; \
             retry, try a smaller --tile, update the driver, or render with --device cpu)"
        }
        _ => "",
    }
}

impl Error {
    /// The message with every cause after it, on one line (`x.exr: No such file or directory`):
    /// for front ends that print no chain of their own (a JSON answer, a Python exception).
    pub fn with_causes(&self) -> String {
        let mut message = self.to_string();
        let mut source = std::error::Error::source(self);
        while let Some(cause) = source {
            message = format!("{message}: {cause}");
            source = cause.source();
        }
        message
    }

    pub fn invalid(parameter: &'static str, message: impl Into<String>) -> Self {
        Error::InvalidParameter { parameter, message: message.into() }
    }
    pub fn data(message: impl Into<String>) -> Self {
        Error::Data(message.into())
    }
    pub fn unsupported(message: impl Into<String>) -> Self {
        Error::Unsupported(message.into())
    }
    pub fn internal(message: impl Into<String>) -> Self {
        Error::Internal(message.into())
    }
    /// For `map_err`: an I/O error on `path`, which the message names.
    pub fn io<P: AsRef<std::path::Path> + ?Sized>(path: &P) -> impl Fn(std::io::Error) -> Self + Copy + '_ {
        move |source| Error::Io { path: path.as_ref().to_path_buf(), source }
    }
    pub fn input(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Error::Input { path: path.into(), message: message.into() }
    }

    /// The device was lost mid-work (`VK_ERROR_DEVICE_LOST`): the context is unusable.
    pub fn is_device_lost(&self) -> bool {
        matches!(self, Error::Vulkan { result: ash::vk::Result::ERROR_DEVICE_LOST, .. })
    }

    /// The device (or the driver's host side) ran out of memory: worth retrying smaller.
    pub fn is_out_of_memory(&self) -> bool {
        use ash::vk::Result as VkResult;
        match self {
            Error::Allocation(gpu_allocator::AllocationError::OutOfMemory) | Error::OutOfDeviceMemory { .. } => true,
            Error::Vulkan { result, .. } => {
                matches!(*result, VkResult::ERROR_OUT_OF_DEVICE_MEMORY | VkResult::ERROR_OUT_OF_HOST_MEMORY)
            }
            _ => false,
        }
    }
}

/// The message of `error` and of every error behind it, joined with ": " (what the CLI
/// prints through anyhow's `{:#}`), for callers that report a library error as one line.
pub fn full_message(error: &(dyn std::error::Error + 'static)) -> String {
    let mut message = error.to_string();
    let mut cause = error.source();
    while let Some(inner) = cause {
        message.push_str(": ");
        message.push_str(&inner.to_string());
        cause = inner.source();
    }
    message
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn io_errors_name_the_cause_once() {
        let missing = std::io::Error::new(std::io::ErrorKind::NotFound, "No such file or directory");
        let error = Error::Io { path: "nofile.exr".into(), source: missing };
        assert_eq!(full_message(&error), "nofile.exr: No such file or directory");
    }

    #[test]
    fn device_loss_says_what_happened_and_what_to_do() {
        let lost = Error::Vulkan { call: "vkQueueSubmit", result: ash::vk::Result::ERROR_DEVICE_LOST };
        let message = lost.to_string();
        assert!(lost.is_device_lost());
        for needle in ["vkQueueSubmit", "ERROR_DEVICE_LOST", "device was lost", "nothing was written", "--device cpu"] {
            assert!(message.contains(needle), "'{needle}' missing: {message}");
        }
        let other = Error::Vulkan { call: "vkCreateBuffer", result: ash::vk::Result::ERROR_OUT_OF_DEVICE_MEMORY };
        assert!(!other.is_device_lost());
        assert!(!other.to_string().contains("device was lost"));
    }

    /// A caller tells a bad value it passed from bad data and from a bug by the variant.
    #[test]
    fn callers_can_match_what_went_wrong() {
        let aperture = crate::camera::Aperture::parse("polygon:2").unwrap_err();
        assert!(matches!(aperture, Error::InvalidParameter { parameter: "aperture", .. }), "{aperture:?}");
        assert!(aperture.to_string().contains("3 to 16 blades"), "{aperture}");
        let frames = crate::sequence::parse_frames("5-x").unwrap_err();
        assert!(matches!(frames, Error::InvalidParameter { parameter: "frame range", .. }), "{frames:?}");
        let layer = crate::stack::Layer { name: "a".into(), rgba: crate::image::Image::new(4, 4), disparity: vec![0.5; 16] };
        let sizes = crate::stack::LayerStack::new(8, 4, vec![layer]).unwrap_err();
        assert!(matches!(sizes, Error::Data(_)), "{sizes:?}");
        assert!(Error::internal("x").to_string().contains("a bug in lensblur"));
    }
}
