//! The backward rows of the performance benchmark: Dr.Bokeh forward alone against forward +
//! backward ([`DrBokehGpuGrad::backward_with_stats`], which re-runs the forward in its batch)
//! on a two-layer stack, reported as the ratio of their medians. The goal on a real GPU is
//! backward within 3x forward.
use std::time::Instant;

use super::large::{layered_stack, peak_resident_bytes, Focus};
use super::perf::median;
use lensblur::image::Image;
use lensblur::render::drbokeh::{BackwardOptions, DrBokehGpu, DrBokehGpuGrad, Model, RenderOptions};
use lensblur::vk::Context;
use lensblur::Result;

/// The fixed backward cases: 256^2 and 1024^2, two layers, largest CoC 16 px, defocused.
pub fn backward_cases(quick: bool) -> Vec<BackwardCase> {
    let _ = quick; // both sides are small enough for --quick
    [256, 1024].into_iter().map(|side| BackwardCase::new(side, 2, 16.0)).collect()
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct BackwardCase {
    pub name: String,
    pub side: usize,
    pub layers: usize,
    pub max_coc_px: f32,
}

impl BackwardCase {
    pub fn new(side: usize, layers: usize, max_coc_px: f32) -> Self {
        Self { name: format!("backward-{side}-{layers}l-coc{max_coc_px}"), side, layers, max_coc_px }
    }
}

/// Medians over the repeats; "backward" is the whole forward + backward batch.
#[derive(Clone, Debug, serde::Serialize)]
pub struct BackwardResult {
    pub case: BackwardCase,
    pub forward_wall_seconds: f64,
    pub forward_device_seconds: Option<f64>,
    pub backward_wall_seconds: f64,
    pub backward_device_seconds: Option<f64>,
    /// Backward wall time over forward wall time.
    pub ratio: f64,
    /// The same on device time, if the queue has timestamps.
    pub device_ratio: Option<f64>,
    pub peak_host_bytes: Option<u64>,
}

/// The forward renderer and the gradient pipelines, compiled and warmed up once.
pub struct BackwardRenderers {
    forward: DrBokehGpu,
    grad: DrBokehGpuGrad,
}

impl BackwardRenderers {
    pub fn new(ctx: &Context) -> Result<Self> {
        let forward = DrBokehGpu::new(ctx)?;
        let grad = DrBokehGpuGrad::new(ctx, Model::DrBokeh, BackwardOptions::exact())?;
        // lavapipe compiles a shader at its first dispatch: keep that out of the timings.
        let (stack, lens) = layered_stack(48, 48, 2, Focus::FullyDefocused, 4.0)?;
        forward.render(&stack, &lens, Model::DrBokeh)?;
        grad.backward_with_stats(&stack, &lens, &ones(48))?;
        Ok(Self { forward, grad })
    }
}

/// dL/d(output) of L = the sum of every output channel: every pixel weighs in.
fn ones(side: usize) -> Image {
    Image::from_fn(side, side, |_, _| [1.0; 4])
}

pub fn run_backward_case(renderers: &BackwardRenderers, case: &BackwardCase, repeats: usize) -> Result<BackwardResult> {
    let (stack, lens) = layered_stack(case.side, case.side, case.layers, Focus::FullyDefocused, case.max_coc_px)?;
    let grad_output = ones(case.side);
    let (mut fw, mut fd, mut bw, mut bd) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for _ in 0..repeats.max(1) {
        let start = Instant::now();
        let (_, stats) = renderers.forward.render_with(&stack, &lens, Model::DrBokeh, &RenderOptions::default())?;
        fw.push(start.elapsed().as_secs_f64());
        fd.extend(stats.device_ns.map(|ns| ns * 1e-9));
        let start = Instant::now();
        let (_, stats) = renderers.grad.backward_with_stats(&stack, &lens, &grad_output)?;
        bw.push(start.elapsed().as_secs_f64());
        bd.extend(stats.device_ns.map(|ns| ns * 1e-9));
    }
    let all = |v: &mut Vec<f64>| (v.len() == fw.len()).then(|| median(v));
    let (forward_device_seconds, backward_device_seconds) = (all(&mut fd), all(&mut bd));
    let (forward_wall_seconds, backward_wall_seconds) = (median(&mut fw), median(&mut bw));
    Ok(BackwardResult {
        case: case.clone(),
        forward_wall_seconds,
        forward_device_seconds,
        backward_wall_seconds,
        backward_device_seconds,
        ratio: backward_wall_seconds / forward_wall_seconds,
        device_ratio: forward_device_seconds.zip(backward_device_seconds).map(|(f, b)| b / f),
        peak_host_bytes: peak_resident_bytes(),
    })
}
