//! The large-frame benchmark: a procedural two-layer stack at 4K-8K rendered by the tiled
//! Dr.Bokeh renderer, once mostly in focus and once fully defocused, with time, tiles, peak
//! device and host memory and effective gather taps per second.
use std::time::Instant;

use crate::camera::{Aperture, CocModel};
use crate::image::Image;
use crate::render::drbokeh::{DrBokehGpu, Model, RenderOptions};
use crate::render::Lens;
use crate::stack::{Layer, LayerStack};
use crate::vk::Context;
use crate::{Error, Result};

/// Which part of the frame is blurred.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Focus {
    /// Background (the whole frame) in focus; only a foreground disk of 1/10 of the area blurs.
    MostlyInFocus,
    /// Focus between the layers: everything is blurred.
    FullyDefocused,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct LargeFrameResult {
    pub focus: Focus,
    pub width: usize,
    pub height: usize,
    pub layers: usize,
    pub max_coc_px: f32,
    pub seconds: f64,
    pub tiles: usize,
    pub tile_size: usize,
    pub peak_device_bytes: u64,
    /// Peak resident memory of the whole process so far (VmHWM), if the OS reports it.
    pub peak_host_bytes: Option<u64>,
    /// float32 size of the stack (RGBA + disparity per layer pixel): the host-memory yardstick.
    pub stack_bytes: u64,
    pub taps: u64,
    pub taps_per_second: f64,
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
pub fn layered_stack(width: usize, height: usize, layers: usize, focus: Focus, max_coc_px: f32) -> Result<(LayerStack, Lens)> {
    if layers < 2 {
        return Err(Error::param("the procedural stack needs at least two layers"));
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

/// Renders the two-layer stack once and measures it.
pub fn run_large_frame(ctx: &Context, width: usize, height: usize, focus: Focus, max_coc_px: f32, tile: Option<usize>, progress: Option<&(dyn Fn(usize, usize) + Sync)>) -> Result<LargeFrameResult> {
    let (stack, lens) = two_layer_stack(width, height, focus, max_coc_px)?;
    let renderer = DrBokehGpu::new(ctx)?;
    let start = Instant::now();
    let (_, stats) = renderer.render_with(&stack, &lens, Model::DrBokeh, &RenderOptions { tile, progress, ..RenderOptions::default() })?;
    let seconds = start.elapsed().as_secs_f64();
    Ok(LargeFrameResult {
        focus,
        width,
        height,
        layers: stack.layers.len(),
        max_coc_px,
        seconds,
        tiles: stats.tiles,
        tile_size: stats.tile_size,
        peak_device_bytes: stats.peak_device_bytes,
        peak_host_bytes: peak_resident_bytes(),
        stack_bytes: (stack.layers.len() * width * height * 20) as u64,
        taps: stats.taps,
        taps_per_second: stats.taps as f64 / seconds,
    })
}

/// VmHWM from /proc/self/status (Linux); None elsewhere.
pub fn peak_resident_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}
