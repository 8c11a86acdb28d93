//! The device self-check: every Vulkan method's forward pass and every backward pass against its
//! CPU reference (same formulas; f64 for Dr.Bokeh), untiled and on frame tiles, for each aperture
//! path, on small scenes. One copy of these checks serves two callers: the test suite (lavapipe,
//! `tests/gpu_selfcheck.rs`) and the GPU kit (`lensblur self-check` on a lent GPU, `gpu-kit/`),
//! so a driver that differs from lavapipe (subgroup size, memory types, limits, precision of
//! transcendentals) fails the same comparison the tests pass here.
//!
//! Each check reports its measured difference beside its tolerance instead of panicking, so the
//! kit's report says how close every path came, not only the first that failed.
pub mod scenes;

use std::time::Instant;

use lensblur::camera::{Aperture, CocModel, KernelImage};
use lensblur::image::Image;
use lensblur::render::drbokeh::{backward_cpu, BackwardOptions, CpuGradients, DrBokehGpuGrad, Model, RenderOptions};
use lensblur::render::grad::StackGradients;
use lensblur::render::{Lens, Method, MethodSettings};
use lensblur::stack::LayerStack;
use lensblur::vk::Context;
use lensblur::Result;

/// One comparison of a device result with its CPU reference.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Check {
    /// What ran: pass, method, aperture, tiling.
    pub name: String,
    /// The measured difference (see [`Check::metric`]); `None` when the device run failed.
    pub difference: Option<f64>,
    pub tolerance: f64,
    /// How `difference` is measured.
    pub metric: &'static str,
    pub passed: bool,
    /// The error of a run that failed outright.
    pub error: Option<String>,
    pub seconds: f64,
}

/// Largest per-channel |device - cpu| / max(1, |cpu|): absolute below 1, relative above, so HDR
/// highlights (up to 40 in the scenes) are held to the same number of significant digits.
pub const IMAGE_METRIC: &str = "max |gpu - cpu| / max(1, |cpu|) over pixels and channels";
/// Largest |device - cpu| of a gradient family over the family's largest |cpu| entry.
pub const GRADIENT_METRIC: &str =
    "max |gpu - cpu| / max |cpu| per gradient family (layer rgba, layer disparity, K, focus)";

/// Forward tolerance of a method, from the f32-against-reference error measured on lavapipe and
/// on an NVIDIA H200 (docs/gpu/): Dr.Bokeh sums a few hundred f32 taps against f64 (<= 6e-6
/// on lavapipe, 1.6e-6 on the H200; 5e-5 leaves room for other drivers' tanh/exp/atan); the
/// lens-sampling renderers march rays whose f32 steps land on neighbouring texels (2e-4);
/// gather and scatter weigh every tap with a tanh, which NVIDIA's driver evaluates less
/// precisely than lavapipe's (scatter: 1.0e-6 on lavapipe, 1.8e-5 on the H200), so 1e-4.
pub fn forward_tolerance(method: Method) -> f64 {
    match method.name() {
        "vdslr" | "multiview" => 2e-4,
        "gather" | "scatter" => 1e-4,
        _ => 5e-5,
    }
}

/// Backward tolerance: f32 sums of a few hundred terms per entry (plus the 1/W^2 of the colour
/// ratio) come within ~1e-5 of the largest entry; 1e-4 leaves margin for cancellation.
pub const BACKWARD_TOLERANCE: f64 = 1e-4;

/// Tile sides the tiled checks use: Dr.Bokeh's 16 px search tiles, and 13 px (odd, not dividing
/// the frame) for the other methods, so every frame is cut into several tiles with halos.
pub const DRBOKEH_TILE: usize = 16;
pub const OTHER_TILE: usize = 13;

/// Every aperture path of the Dr.Bokeh shaders (the CLI's names): the disk, the gauge path
/// (polygons, rounded or not, and the ellipse), the ring's obstruction taps, the kernel image,
/// the cat's-eye gauge and the one-pass vignetted polygon.
pub fn apertures() -> Vec<(&'static str, Aperture)> {
    // Not point-symmetric: a near side's mirrored kernel differs from a far side's.
    let kernel = KernelImage::from_weights(
        4,
        vec![0.2, 1.0, 1.0, 0.6, 1.0, 0.5, 0.3, 1.0, 1.0, 0.8, 0.5, 1.0, 0.0, 1.0, 0.9, 0.4],
    )
    .expect("a valid 4x4 kernel");
    let hexagon = Aperture::polygon(6, 15.0, 0.0).expect("valid polygon");
    vec![
        ("disk", Aperture::Disk),
        ("polygon:6", hexagon.clone()),
        ("polygon:5:roundness=0.2", Aperture::polygon(5, 20.0, 0.2).expect("valid polygon")),
        ("anamorphic:1.7", Aperture::anamorphic(1.7, 25.0).expect("valid ellipse")),
        ("ring:0.5", Aperture::ring(0.5).expect("valid ring")),
        ("image:4x4", Aperture::Kernel(kernel)),
        ("cats-eye", Aperture::cats_eye([-0.7, 0.4]).expect("valid cat's-eye")),
        ("polygon:6 vignetted 0.6", Aperture::vignetted(&hexagon, 0.6).expect("straight blades vignette in one pass")),
    ]
}

/// Runs every check on `ctx`; `on_check` sees each as it finishes (progress).
pub fn run(ctx: &Context, mut on_check: impl FnMut(&Check)) -> Vec<Check> {
    let mut checks = Vec::new();
    let mut record = |check: Check| {
        on_check(&check);
        checks.push(check);
    };
    for check in forward_methods(ctx) {
        record(check);
    }
    for check in forward_apertures(ctx) {
        record(check);
    }
    for check in backward(ctx) {
        record(check);
    }
    checks
}

/// Times `body` and turns its outcome into a [`Check`]: its difference against `tolerance`, or
/// the error that kept it from measuring one (also for checks made outside this module, such as
/// the CLI's sequence check).
pub fn check<E: std::fmt::Display>(
    name: String,
    metric: &'static str,
    tolerance: f64,
    body: impl FnOnce() -> std::result::Result<f64, E>,
) -> Check {
    let start = Instant::now();
    let outcome = body();
    let seconds = start.elapsed().as_secs_f64();
    match outcome {
        // NaN never passes: `<=` is false for it.
        Ok(difference) => Check {
            name,
            passed: difference <= tolerance,
            difference: Some(difference),
            tolerance,
            metric,
            error: None,
            seconds,
        },
        Err(e) => {
            Check { name, difference: None, tolerance, metric, passed: false, error: Some(e.to_string()), seconds }
        }
    }
}

/// A CPU reference that could not run fails each check that compares with it.
fn reference_failed(e: &lensblur::Error) -> lensblur::Error {
    lensblur::Error::Data(format!("the CPU reference failed: {e}"))
}

/// See [`IMAGE_METRIC`].
pub fn image_difference(device: &Image, cpu: &Image) -> f64 {
    if (device.width, device.height) != (cpu.width, cpu.height) {
        return f64::INFINITY;
    }
    device
        .pixels
        .iter()
        .zip(&cpu.pixels)
        .flat_map(|(g, c)| (0..4).map(move |i| f64::from((g[i] - c[i]).abs() / c[i].abs().max(1.0))))
        .fold(0.0, |m, d| if d.is_nan() { f64::NAN } else { m.max(d) })
}

/// Every method that runs on the device, through the registry as `lensblur render` calls it,
/// untiled and on tiles, against the same method's CPU reference (the disk aperture).
fn forward_methods(ctx: &Context) -> Vec<Check> {
    let stack = scenes::forward(45, 37);
    let lens = Lens { coc: CocModel::new(25.0, 0.5).expect("valid CoC"), aperture: Aperture::Disk };
    let settings = scenes::few_samples();
    let mut checks = Vec::new();
    for &method in Method::ALL.iter().filter(|m| m.uses_gpu()) {
        let tile = if method.name().starts_with("drbokeh") { DRBOKEH_TILE } else { OTHER_TILE };
        checks.extend(forward_untiled_and_tiled(ctx, method, "disk", &stack, &lens, &settings, tile));
    }
    checks
}

/// `method` on the device, untiled and on `tile`-sided tiles, against its CPU reference.
fn forward_untiled_and_tiled(
    ctx: &Context,
    method: Method,
    aperture_name: &str,
    stack: &LayerStack,
    lens: &Lens,
    settings: &MethodSettings,
    tile: usize,
) -> Vec<Check> {
    let reference = method.render_with(None, stack, lens, &RenderOptions::default(), settings);
    [None, Some(tile)]
        .into_iter()
        .map(|tiled| {
            let name = match tiled {
                None => format!("forward {method} {aperture_name} untiled"),
                Some(t) => format!("forward {method} {aperture_name} tiles {t}"),
            };
            check(name, IMAGE_METRIC, forward_tolerance(method), || -> Result<f64> {
                let cpu = reference.as_ref().map_err(reference_failed)?;
                let options = RenderOptions { tile: tiled, ..RenderOptions::default() };
                let device = method.render_with(Some(ctx), stack, lens, &options, settings)?;
                Ok(image_difference(&device, cpu))
            })
        })
        .collect()
}

/// Dr.Bokeh (both models) through every aperture path, untiled and tiled.
fn forward_apertures(ctx: &Context) -> Vec<Check> {
    let stack = scenes::forward(45, 37);
    let settings = MethodSettings::default();
    let mut checks = Vec::new();
    for method in [Method::DrBokeh, Method::DrBokehCompat] {
        for (name, aperture) in apertures() {
            // The disk's comparison is in forward_methods already; a vignetted aperture renders
            // under the default model only (the compat model refuses it).
            if name == "disk" || (method == Method::DrBokehCompat && matches!(aperture, Aperture::Vignetted { .. })) {
                continue;
            }
            // K = 25: CoC up to ~12 px in front, ~10 px behind.
            let lens = Lens { coc: CocModel::new(25.0, 0.5).expect("valid CoC"), aperture };
            checks.extend(forward_untiled_and_tiled(ctx, method, name, &stack, &lens, &settings, DRBOKEH_TILE));
        }
    }
    checks
}

/// See [`GRADIENT_METRIC`].
pub fn gradient_difference(device: &StackGradients, cpu: &CpuGradients) -> f64 {
    fn family(device: impl Iterator<Item = f32>, cpu: impl Iterator<Item = f64>) -> f64 {
        let pairs: Vec<(f64, f64)> = device.map(f64::from).zip(cpu).collect();
        let scale = pairs.iter().fold(0.0f64, |m, p| m.max(p.1.abs()));
        pairs.iter().fold(0.0f64, |m, p| m.max((p.0 - p.1).abs())) / scale.max(f64::MIN_POSITIVE)
    }
    if device.layers.len() != cpu.layers.len() {
        return f64::INFINITY;
    }
    let mut worst = 0.0f64;
    for (g, c) in device.layers.iter().zip(&cpu.layers) {
        worst = worst.max(family(g.rgba.iter().flatten().copied(), c.rgba.iter().flatten().copied()));
        worst = worst.max(family(g.disparity.iter().copied(), c.disparity.iter().copied()));
    }
    // The scalars sum thousands of f32 shares of both signs: relative to max(1, |cpu|).
    worst = worst.max((device.k_px - cpu.k_px).abs() / cpu.k_px.abs().max(1.0));
    worst.max((device.focus_disparity - cpu.focus_disparity).abs() / cpu.focus_disparity.abs().max(1.0))
}

/// The backward pass of both models through every aperture it accepts (vignetted apertures
/// are refused by design), the exact and the leaky slope, untiled and on 16 px tiles.
fn backward(ctx: &Context) -> Vec<Check> {
    let (w, h) = (37, 29);
    let stack = scenes::backward(w, h, 0.83);
    let grad_output = scenes::grad_output(w, h);
    let mut checks = Vec::new();
    for model in [Model::DrBokeh, Model::Compat] {
        for (name, aperture) in
            apertures().into_iter().filter(|(_, a)| !matches!(a, Aperture::Vignetted { .. } | Aperture::CatsEye { .. }))
        {
            // The leak changes only dS/dr terms, the same code for every aperture: disk only.
            let slopes: &[(&str, BackwardOptions)] = if name == "disk" {
                &[("exact", BackwardOptions::exact()), ("leaky", BackwardOptions::leaky())]
            } else {
                &[("exact", BackwardOptions::exact())]
            };
            let lens = Lens { coc: CocModel::new(12.0, 0.5).expect("valid CoC"), aperture };
            for &(slope, options) in slopes {
                let reference = backward_cpu(&stack, &lens, model, options, &grad_output);
                for tiled in [None, Some(DRBOKEH_TILE)] {
                    let label = match tiled {
                        None => format!("backward {model:?} {name} {slope} untiled"),
                        Some(t) => format!("backward {model:?} {name} {slope} tiles {t}"),
                    };
                    checks.push(check(label, GRADIENT_METRIC, BACKWARD_TOLERANCE, || -> Result<f64> {
                        let cpu = reference.as_ref().map_err(reference_failed)?;
                        let renderer = DrBokehGpuGrad::new(ctx, model, options)?;
                        let render = RenderOptions { tile: tiled, ..RenderOptions::default() };
                        let (device, _) = renderer.backward_with(&stack, &lens, &grad_output, &render)?;
                        Ok(gradient_difference(&device, cpu))
                    }));
                }
            }
        }
    }
    checks
}

/// The stack the sequence check writes as its frames: the forward scene.
pub fn sequence_stack() -> LayerStack {
    scenes::forward(45, 37)
}
