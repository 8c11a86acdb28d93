//! Which device a method renders on. Every caller (the command line, a pipeline script, a
//! farm job) wants the same rule: a method that needs no GPU never opens one; asked for the
//! CPU, the method's CPU reference runs; in [`DevicePreference::Auto`] a machine with no usable
//! Vulkan device falls back to the CPU, but a device named by `LENSBLUR_DEVICE` that fails to
//! open is an error (the caller asked for it by name).
//!
//! A one-shot render of a small frame ([`place_frame`]) is the exception to `Auto`: where the
//! method renders the lens fast on the CPU, it opens no device at all. Opening one costs more
//! than such a render: on lavapipe (2 cores) the loader, the driver and compiling four
//! pipelines take 130-140 ms of CPU against ~50 ms for the whole 256^2 render on the CPU; a
//! discrete GPU's driver takes about as long to open. A resident renderer (`serve`, a
//! `Session`) pays the opening once and keeps its device.
use crate::render::{Lens, Method};
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
    /// A one-shot render of a frame of at most [`SMALL_FRAME_PIXELS`] that the method renders
    /// fast on the CPU ([`place_frame`]).
    SmallFrame,
}

/// The largest frame (in pixels) a one-shot render in [`DevicePreference::Auto`] renders on the
/// CPU when its method renders the lens fast there: 512^2. Measured on this project's CI
/// machine (2 cores, lavapipe), see the book's performance chapter.
pub const SMALL_FRAME_PIXELS: usize = 512 * 512;

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

/// [`place`] for a one-shot render of one frame of `frame` pixels (width, height; None where
/// unknown) through `lens`: in [`DevicePreference::Auto`], with no device named, a frame of at
/// most [`SMALL_FRAME_PIXELS`] that the method renders fast on the CPU opens no device.
pub fn place_frame(method: Method, preference: DevicePreference, options: &ContextOptions, lens: &Lens, frame: Option<(usize, usize)>) -> Result<Placement> {
    if small_frame_on_cpu(method, preference, options, lens, frame) {
        return Ok(Placement::Cpu(CpuReason::SmallFrame));
    }
    place(method, preference, options)
}

/// [`place_frame`]'s exception to [`place`]: whether the frame renders on the CPU, opening no
/// device.
pub fn small_frame_on_cpu(method: Method, preference: DevicePreference, options: &ContextOptions, lens: &Lens, frame: Option<(usize, usize)>) -> bool {
    let small = frame.is_some_and(|(width, height)| width.saturating_mul(height) <= SMALL_FRAME_PIXELS);
    small && preference == DevicePreference::Auto && options.device.is_none() && method.uses_gpu() && method.fast_on_cpu(lens)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Aperture, CocModel};

    #[test]
    fn cpu_methods_and_the_cpu_preference_open_no_device() {
        // A named device that does not exist would fail to open: not opening it is the point.
        let options = ContextOptions { device: Some("no such device".into()), ..ContextOptions::from_env() };
        assert!(matches!(place(Method::Oracle, DevicePreference::Gpu, &options), Ok(Placement::Cpu(CpuReason::CpuMethod))));
        assert!(matches!(place(Method::DrBokeh, DevicePreference::Cpu, &options), Ok(Placement::Cpu(CpuReason::Asked))));
    }

    #[test]
    fn only_a_small_frame_the_method_renders_fast_on_the_cpu_skips_the_device() {
        let coc = CocModel::new(10.0, 0.5).unwrap();
        let disk = Lens { coc, aperture: Aperture::Disk };
        let hexagon = Lens { coc, aperture: Aperture::polygon(6, 0.0, 0.0).unwrap() };
        let unnamed = ContextOptions { device: None, ..ContextOptions::from_env() };
        let named = ContextOptions { device: Some("some GPU".into()), ..ContextOptions::from_env() };
        let (auto, gpu) = (DevicePreference::Auto, DevicePreference::Gpu);
        let small = Some((512, 512));
        assert!(small_frame_on_cpu(Method::DrBokeh, auto, &unnamed, &disk, small));
        assert!(small_frame_on_cpu(Method::DrBokeh, auto, &unnamed, &disk, Some((256, 192))));
        // A larger or unknown frame, a device asked for or named, a lens or a model the fast
        // path does not render: the device (or the reference, for the CPU preference).
        assert!(!small_frame_on_cpu(Method::DrBokeh, auto, &unnamed, &disk, Some((512, 513))));
        assert!(!small_frame_on_cpu(Method::DrBokeh, auto, &unnamed, &disk, None));
        assert!(!small_frame_on_cpu(Method::DrBokeh, gpu, &unnamed, &disk, small));
        assert!(!small_frame_on_cpu(Method::DrBokeh, DevicePreference::Cpu, &unnamed, &disk, small));
        assert!(!small_frame_on_cpu(Method::DrBokeh, auto, &named, &disk, small));
        assert!(!small_frame_on_cpu(Method::DrBokeh, auto, &unnamed, &hexagon, small));
        assert!(!small_frame_on_cpu(Method::DrBokehCompat, auto, &unnamed, &disk, small));
        assert!(!small_frame_on_cpu(Method::Gather, auto, &unnamed, &disk, small));
        assert!(matches!(place_frame(Method::DrBokeh, auto, &unnamed, &disk, small), Ok(Placement::Cpu(CpuReason::SmallFrame))));
    }

    #[test]
    fn a_named_device_that_fails_is_an_error_even_in_auto() {
        let options = ContextOptions { device: Some("no such device".into()), ..ContextOptions::from_env() };
        assert!(place(Method::DrBokeh, DevicePreference::Auto, &options).is_err());
        assert!(place(Method::DrBokeh, DevicePreference::Gpu, &options).is_err());
    }
}
