//! Which device a method renders on. Every caller (the command line, a pipeline script, a
//! farm job) wants the same rule: a method that needs no GPU never opens one; asked for the
//! CPU, the method's CPU reference runs; in [`DevicePreference::Auto`] a machine with no usable
//! Vulkan device falls back to the CPU, but a device named by `LENSBLUR_DEVICE` that fails to
//! open is an error (the caller asked for it by name).
use crate::render::Method;
use crate::vk::{Context, ContextOptions};
use crate::{Error, Result};

/// What the caller asks for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DevicePreference {
    /// The GPU if one opens, else the CPU (unless a device was named).
    #[default]
    Auto,
    /// The GPU or an error.
    Gpu,
    /// The CPU reference path.
    Cpu,
}

/// Where a render runs.
pub enum Placement {
    Gpu(Context),
    Cpu(CpuReason),
}

/// Why a render runs on the CPU, so the caller can say so (the CPU path is slow).
#[derive(Debug)]
pub enum CpuReason {
    /// The method has no GPU path: nothing to warn about.
    CpuMethod,
    /// The caller asked for the CPU.
    Asked,
    /// No usable Vulkan device opened (the error says why).
    NoDevice(Error),
}

impl Placement {
    pub fn context(&self) -> Option<&Context> {
        match self {
            Placement::Gpu(ctx) => Some(ctx),
            Placement::Cpu(_) => None,
        }
    }

    pub fn into_context(self) -> Option<Context> {
        match self {
            Placement::Gpu(ctx) => Some(ctx),
            Placement::Cpu(_) => None,
        }
    }
}

/// Opens the device `method` renders on under `preference`, with `options` (usually
/// [`ContextOptions::from_env`]). Errors only when a device was required (`Gpu`) or named
/// (`options.device`) and did not open.
pub fn place(method: Method, preference: DevicePreference, options: &ContextOptions) -> Result<Placement> {
    if !method.uses_gpu() {
        return Ok(Placement::Cpu(CpuReason::CpuMethod));
    }
    if preference == DevicePreference::Cpu {
        return Ok(Placement::Cpu(CpuReason::Asked));
    }
    match Context::new(options) {
        Ok(ctx) => Ok(Placement::Gpu(ctx)),
        Err(error @ (Error::NoVulkan(_) | Error::Vulkan { .. }))
            if preference == DevicePreference::Auto && options.device.is_none() =>
        {
            Ok(Placement::Cpu(CpuReason::NoDevice(error)))
        }
        Err(error) => Err(error),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cpu_methods_and_the_cpu_preference_open_no_device() {
        // A named device that does not exist would fail to open: not opening it is the point.
        let options = ContextOptions { device: Some("no such device".into()), ..ContextOptions::from_env() };
        assert!(matches!(place(Method::Oracle, DevicePreference::Gpu, &options), Ok(Placement::Cpu(CpuReason::CpuMethod))));
        assert!(matches!(place(Method::DrBokeh, DevicePreference::Cpu, &options), Ok(Placement::Cpu(CpuReason::Asked))));
    }

    #[test]
    fn a_named_device_that_fails_is_an_error_even_in_auto() {
        let options = ContextOptions { device: Some("no such device".into()), ..ContextOptions::from_env() };
        assert!(place(Method::DrBokeh, DevicePreference::Auto, &options).is_err());
        assert!(place(Method::DrBokeh, DevicePreference::Gpu, &options).is_err());
    }
}
