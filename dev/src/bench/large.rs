//! The large-frame benchmark: a procedural two-layer stack at 4K-8K rendered by the tiled
//! Dr.Bokeh renderer, once mostly in focus and once fully defocused, with time, tiles, peak
//! device and host memory and effective gather taps per second; optionally through a real EXR
//! file (read, render, write), as `lensblur render` runs.
use std::path::PathBuf;
use std::time::Instant;

use lensblur::camera::{Aperture, CocModel};
use lensblur::image::Image;
use lensblur::render::drbokeh::{DrBokehGpu, Model, RenderOptions};
use lensblur::render::Lens;
use lensblur::stack::{
    read_stack, write_image, write_stack, DepthKind, Layer, LayerStack, ReadOptions, StackNaming, StackWriteOptions,
    WriteOptions,
};
use lensblur::vk::Context;
use lensblur::{Error, Result};

/// Which part of the frame is blurred.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Focus {
    /// Background (the whole frame) in focus; only a foreground disk of 1/10 of the area blurs.
    MostlyInFocus,
    /// Focus between the layers: everything is blurred.
    FullyDefocused,
}

impl Focus {
    /// The kebab-case name (as in JSON and on the command line).
    pub fn name(self) -> &'static str {
        match self {
            Focus::MostlyInFocus => "mostly-in-focus",
            Focus::FullyDefocused => "fully-defocused",
        }
    }
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct LargeFrameResult {
    pub focus: Focus,
    pub width: usize,
    pub height: usize,
    pub layers: usize,
    pub max_coc_px: f32,
    /// The normalised camera (`--blur`, `--focus-disparity` of `lensblur render`).
    pub k_px: f32,
    pub focus_disparity: f32,
    /// Wall time of the render alone.
    pub seconds: f64,
    pub tiles: usize,
    pub tile_size: usize,
    pub tiles_per_batch: usize,
    pub peak_device_bytes: u64,
    /// Peak resident memory during this case (VmHWM, reset per case), if the OS reports it.
    pub peak_host_bytes: Option<u64>,
    /// float32 size of the stack (RGBA + disparity per layer pixel): the host-memory yardstick.
    pub stack_bytes: u64,
    pub taps: u64,
    pub taps_per_second: f64,
    /// Through a file: where and how long reading and writing took.
    pub exr: Option<ExrRoundTrip>,
}

/// A textured far wall and a near disk covering a tenth of the frame; CoC radii scale with
/// the frame width so a 7680 px frame gets `max_coc_px` at its most blurred layer.
pub fn two_layer_stack(width: usize, height: usize, focus: Focus, max_coc_px: f32) -> Result<(LayerStack, Lens)> {
    layered_stack(width, height, 2, focus, max_coc_px)
}

/// [`two_layer_stack`] with `layers - 2` more disks (a tenth of the frame each) between the
/// near disk and the wall. Mostly in focus: the wall is in focus and the disks' CoC radii step
/// from `max_coc_px` (front) toward 0; fully defocused: every layer's CoC is between half the
/// largest and `max_coc_px`, the wall's at half.
pub fn layered_stack(
    width: usize,
    height: usize,
    layers: usize,
    focus: Focus,
    max_coc_px: f32,
) -> Result<(LayerStack, Lens)> {
    if layers < 2 {
        return Err(Error::invalid("layers", "the procedural stack needs at least two layers"));
    }
    let (near, far) = (1.0f32, 0.5f32);
    let (focus_disparity, k) = match focus {
        Focus::MostlyInFocus => (far, max_coc_px / (near - far)),
        // Focus in between, the near layer the most blurred (twice the far one's CoC).
        Focus::FullyDefocused => (far + (near - far) / 3.0, max_coc_px / ((near - far) * 2.0 / 3.0)),
    };
    let steps = (layers - 1) as f32;
    let disk_disparity = |i: usize| match focus {
        _ if i == 0 => near,
        Focus::MostlyInFocus => far + (near - far) * (1.0 - i as f32 / steps),
        Focus::FullyDefocused => focus_disparity + (near - focus_disparity) * (1.0 - 0.5 * i as f32 / steps),
    };
    let radius = ((width * height) as f32 / (10.0 * std::f32::consts::PI)).sqrt();
    let n = width * height;
    let mut stack_layers: Vec<Layer> = (0..layers - 1)
        .map(|i| {
            // Disk 0 is the two-layer stack's; later ones walk right and down.
            let t = i as f32 / steps;
            let (cx, cy) = (width as f32 * (0.4 + 0.3 * t), height as f32 * (0.5 - 0.2 * t));
            let colour = [0.9 - 0.5 * t, 0.3 + 0.5 * t, 0.2 + 0.3 * t];
            let rgba = Image::from_fn(width, height, |x, y| {
                let d = ((x as f32 - cx).powi(2) + (y as f32 - cy).powi(2)).sqrt();
                let a = (radius - d + 0.5).clamp(0.0, 1.0);
                [colour[0] * a, colour[1] * a, colour[2] * a, a]
            });
            let name = if i == 0 { "near".to_string() } else { format!("disk{i}") };
            Layer { name, rgba, disparity: vec![disk_disparity(i); n] }
        })
        .collect();
    let wall = Image::from_fn(width, height, |x, y| {
        let checker = if (x / 64 + y / 64) % 2 == 0 { 0.8 } else { 0.2 };
        let highlight = if x % 97 == 0 && y % 89 == 0 { 20.0 } else { 0.0 };
        [checker + highlight, checker * 0.9, 1.0 - checker, 1.0]
    });
    stack_layers.push(Layer { name: "far".into(), rgba: wall, disparity: vec![far; n] });
    let lens = Lens { coc: CocModel::new(k, focus_disparity)?, aperture: Aperture::Disk };
    Ok((LayerStack::new(width, height, stack_layers)?, lens))
}

/// How one case runs.
#[derive(Clone, Debug, Default)]
pub struct LargeFrameOptions {
    /// Frame tile side (None: chosen from the device's limits and memory budget).
    pub tile: Option<usize>,
    /// Tiles recorded into one submission (None: as many as the memory budget allows).
    pub tiles_per_batch: Option<usize>,
    /// Write the stack to `DIR/<case>.exr` and run the case through that file as `lensblur
    /// render` does: read it, render, write `DIR/<case>-render.exr` (the files are kept).
    pub exr_dir: Option<PathBuf>,
}

/// The file round trip of a case run with [`LargeFrameOptions::exr_dir`].
#[derive(Clone, Debug, serde::Serialize)]
pub struct ExrRoundTrip {
    pub stack: PathBuf,
    pub render: PathBuf,
    pub read_seconds: f64,
    pub write_seconds: f64,
}

/// Renders the two-layer stack once and measures it. The peak host memory is the case's own:
/// VmHWM is reset to the current resident size (`/proc/self/clear_refs`) once the procedural
/// stack exists (and, through a file, once it is written and dropped), so it holds the stack,
/// the render and, through a file, the read and the write.
pub fn run_large_frame(
    ctx: &Context,
    size: (usize, usize),
    focus: Focus,
    max_coc_px: f32,
    options: &LargeFrameOptions,
    progress: Option<&(dyn Fn(usize, usize) + Sync)>,
) -> Result<LargeFrameResult> {
    let (width, height) = size;
    let (stack, lens) = two_layer_stack(width, height, focus, max_coc_px)?;
    let layers = stack.layers.len();
    let renderer = DrBokehGpu::new(ctx)?;
    let render_options = RenderOptions {
        tile: options.tile,
        tiles_per_batch: options.tiles_per_batch,
        progress,
        ..RenderOptions::default()
    };
    let (seconds, stats, exr) = match &options.exr_dir {
        None => {
            reset_peak_resident();
            let start = Instant::now();
            let (_, stats) = renderer.render_with(&stack, &lens, Model::DrBokeh, &render_options)?;
            (start.elapsed().as_secs_f64(), stats, None)
        }
        Some(dir) => {
            let name = focus.name();
            let (stack_path, render_path) = (dir.join(format!("{name}.exr")), dir.join(format!("{name}-render.exr")));
            let naming = StackWriteOptions {
                naming: StackNaming::LayerDotChannel,
                depth_kind: DepthKind::Disparity,
                camera: None,
            };
            write_stack(&stack_path, &stack, &naming)?;
            drop(stack);
            reset_peak_resident();
            let start = Instant::now();
            let read = ReadOptions { depth_kind: DepthKind::Disparity, ..ReadOptions::default() };
            let file = read_stack(&stack_path, &read)?;
            let read_seconds = start.elapsed().as_secs_f64();
            let start = Instant::now();
            let (image, stats) = renderer.render_with(&file.stack, &lens, Model::DrBokeh, &render_options)?;
            let seconds = start.elapsed().as_secs_f64();
            drop(file);
            let start = Instant::now();
            write_image(&render_path, &image, &WriteOptions::default())?;
            let write_seconds = start.elapsed().as_secs_f64();
            (seconds, stats, Some(ExrRoundTrip { stack: stack_path, render: render_path, read_seconds, write_seconds }))
        }
    };
    Ok(LargeFrameResult {
        focus,
        width,
        height,
        layers,
        max_coc_px,
        k_px: lens.coc.k_px,
        focus_disparity: lens.coc.focus_disparity,
        seconds,
        tiles: stats.tiles,
        tile_size: stats.tile_size,
        tiles_per_batch: stats.tiles_per_batch,
        peak_device_bytes: stats.peak_device_bytes,
        peak_host_bytes: peak_resident_bytes(),
        stack_bytes: (layers * width * height * 20) as u64,
        taps: stats.taps,
        taps_per_second: stats.taps as f64 / seconds,
        exr,
    })
}

/// VmHWM from /proc/self/status (Linux); None elsewhere.
pub fn peak_resident_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Resets VmHWM to the current resident size (Linux: "5" to /proc/self/clear_refs), so
/// [`peak_resident_bytes`] measures from here on; false where that is not possible.
pub fn reset_peak_resident() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}
