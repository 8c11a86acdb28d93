//! Device timings of the GPU kit (`lensblur gpu-timings`, `gpu-kit/run`): fixed procedural
//! cases from 256^2 to 8K, each renderer prepared once, one warm-up, then the median of the
//! repeats of the device time (timestamp queries around every pass, summed by the tiling
//! service) and of the wall time of the render call (inputs already in host memory; no file
//! I/O). Each case also reports effective taps per second and the share of the device's memory
//! bandwidth its compulsory traffic (read the stack once, write the output once) reaches.
use std::time::Instant;

use super::large::{layered_stack, Focus};
use super::perf::median;
use lensblur::camera::Aperture;
use lensblur::image::Image;
use lensblur::render::drbokeh::{BackwardOptions, DrBokehGpu, DrBokehGpuGrad, Model, RenderOptions, RenderStats, ResidentStack};
use lensblur::render::multiview::{Multiview, MultiviewParams};
use lensblur::render::vdslr::{Vdslr, VdslrParams};
use lensblur::render::Lens;
use crate::selfcheck::scenes::hash;
use lensblur::stack::LayerStack;
use lensblur::vk::Context;
use lensblur::Result;

/// What a case runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum TimedPass {
    /// Dr.Bokeh's forward pass.
    Forward,
    /// Dr.Bokeh's backward pass (`lensblur grad`) for a loss with noise as dL/d(output).
    Backward,
    /// Multiview's lens sampling over the layers.
    Multiview,
    /// Virtual DSLR on the flattened stack (one RGBA + depth image).
    Vdslr,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct TimingCase {
    pub name: String,
    pub pass: TimedPass,
    pub width: usize,
    pub height: usize,
    pub layers: usize,
    /// Largest CoC radius in pixels (the near layer; every layer is blurred).
    pub max_coc_px: f32,
    /// The aperture in the CLI's form.
    pub aperture: &'static str,
    /// Lens samples (multiview, vdslr).
    pub samples: Option<u32>,
    /// The goal for an H100, if it set one, and whether it bounds the wall time of
    /// the whole render call (else the device time).
    pub goal_ms: Option<f64>,
    pub goal_on_wall: bool,
}

impl TimingCase {
    fn new(
        pass: TimedPass,
        (width, height): (usize, usize),
        layers: usize,
        max_coc_px: f32,
        aperture: &'static str,
    ) -> Self {
        let pass_name = match pass {
            TimedPass::Forward => "forward",
            TimedPass::Backward => "grad",
            TimedPass::Multiview => "multiview",
            TimedPass::Vdslr => "vdslr",
        };
        let name = format!("{pass_name} {width}x{height} {layers}l coc{max_coc_px} {aperture}");
        Self {
            name,
            pass,
            width,
            height,
            layers,
            max_coc_px,
            aperture,
            samples: None,
            goal_ms: None,
            goal_on_wall: false,
        }
    }

    fn samples(mut self, samples: u32) -> Self {
        self.samples = Some(samples);
        self.name += &format!(" {samples}spp");
        self
    }

    /// A goal on the device time.
    fn goal(mut self, ms: f64) -> Self {
        self.goal_ms = Some(ms);
        self
    }

    /// A goal on the wall time of the render call (inputs and outputs in host memory).
    fn wall_goal(mut self, ms: f64) -> Self {
        self.goal_ms = Some(ms);
        self.goal_on_wall = true;
        self
    }

    /// Pixels x layers x pi r^2 with r the largest CoC radius: the work of a naive gather.
    pub fn effective_taps(&self) -> f64 {
        (self.width * self.height * self.layers) as f64 * std::f64::consts::PI * f64::from(self.max_coc_px).powi(2)
    }

    /// Compulsory traffic: every layer's RGBA + disparity read once (float32), the output
    /// RGBA written once (the backward pass writes a gradient of every input instead).
    pub fn compulsory_bytes(&self) -> u64 {
        let pixels = (self.width * self.height) as u64;
        let inputs = pixels * self.layers as u64 * 20;
        match self.pass {
            TimedPass::Backward => 2 * inputs + pixels * 16,
            _ => inputs + pixels * 16,
        }
    }
}

/// The kit's cases. `small`: the same kinds of case at sizes lavapipe runs in seconds (the
/// test suite's run of the kit).
pub fn timing_cases(small: bool) -> Vec<TimingCase> {
    use TimedPass::*;
    if small {
        return vec![
            TimingCase::new(Forward, (64, 64), 2, 5.0, "disk"),
            TimingCase::new(Forward, (128, 128), 5, 10.0, "disk"),
            TimingCase::new(Forward, (128, 128), 5, 10.0, "polygon:6"),
            TimingCase::new(Forward, (320, 180), 5, 10.0, "disk"),
            TimingCase::new(Backward, (128, 128), 5, 10.0, "disk"),
            TimingCase::new(Multiview, (96, 96), 5, 10.0, "disk").samples(16),
            TimingCase::new(Vdslr, (96, 96), 5, 10.0, "disk").samples(16),
        ];
    }
    // Goals of issue 34 (on an H100): the Dr.Bokeh paper's 256^2 takes 19 ms in CUDA.
    vec![
        TimingCase::new(Forward, (256, 256), 2, 21.0, "disk").goal(1.0),
        TimingCase::new(Forward, (1024, 1024), 5, 40.0, "disk"),
        TimingCase::new(Forward, (1024, 1024), 5, 40.0, "polygon:6"),
        TimingCase::new(Forward, (4096, 4096), 2, 32.0, "disk").goal(50.0),
        // "8K five layers < 1 s": the whole render, file I/O apart.
        TimingCase::new(Forward, (7680, 4320), 5, 40.0, "disk").wall_goal(1000.0),
        TimingCase::new(Backward, (1024, 1024), 5, 40.0, "disk"),
        TimingCase::new(Multiview, (1024, 1024), 5, 40.0, "disk").samples(512),
        TimingCase::new(Vdslr, (1024, 1024), 5, 40.0, "disk").samples(512),
    ]
}

/// One case's medians.
#[derive(Clone, Debug, serde::Serialize)]
pub struct CaseTiming {
    pub case: TimingCase,
    pub repeats: usize,
    /// Device time (timestamp queries), median; `None` where the queue has no timestamps.
    pub device_ms: Option<f64>,
    pub wall_ms: f64,
    /// Every repeat, in order (device, wall).
    pub device_ms_runs: Vec<f64>,
    pub wall_ms_runs: Vec<f64>,
    /// [`TimingCase::effective_taps`] per second of device time (wall time without timestamps).
    pub effective_taps_per_second: f64,
    /// [`TimingCase::compulsory_bytes`] per second of device time, in GB/s.
    pub compulsory_gb_per_second: f64,
    /// That over the device's peak memory bandwidth, where [`peak_bandwidth_gb_per_second`] knows it.
    pub bandwidth_share: Option<f64>,
    pub tiles: usize,
    pub tile_size: usize,
    /// Most device memory a timed render held, a resident stack's kept upload included.
    pub peak_device_bytes: u64,
    /// Where the wall time of the median run went on the host (ms): the method's preparation
    /// of the frame (wall less the tile loop), recording tiles (allocations, uploads), waiting
    /// for the device, reading results back.
    pub host_ms: HostBreakdown,
    /// Whether the case's goal holds: the median wall time for a wall goal, else the median
    /// device time (wall time without timestamps).
    pub meets_goal: Option<bool>,
}

#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct HostBreakdown {
    /// A forward case's pass over its stack's pixels (a [`ResidentStack`]'s scan): made once
    /// per stack and kept for the timed renders (a resident stack refocused), so it is in none
    /// of their walls. A one-shot render pays it on top of `prepare`. 0 for the others. The
    /// warm-up render also keeps the stack's upload when the frame is one tile, which the timed
    /// renders then bind instead of recording its copy.
    pub scan: f64,
    pub prepare: f64,
    pub record: f64,
    pub wait: f64,
    pub collect: f64,
}

/// Peak DRAM bandwidth of known GPUs, GB/s (the vendors' datasheets): the yardstick of
/// [`CaseTiming::bandwidth_share`]. `None` for devices not listed (lavapipe's is system memory).
pub fn peak_bandwidth_gb_per_second(device_name: &str) -> Option<f64> {
    let name = device_name.to_lowercase();
    let table: [(&str, f64); 6] = [
        ("h200", 4800.0),
        ("h100 pcie", 2000.0),
        ("h100 nvl", 3900.0),
        ("h100", 3350.0),
        ("a100", 2039.0),
        ("l40s", 864.0),
    ];
    table.iter().find(|(key, _)| name.contains(key)).map(|&(_, gb)| gb)
}

/// The whole timing report.
#[derive(Clone, Debug, serde::Serialize)]
pub struct TimingReport {
    pub device: String,
    pub driver: String,
    pub subgroup_size: u32,
    pub peak_bandwidth_gb_per_second: Option<f64>,
    pub cases: Vec<CaseTiming>,
    /// Backward over forward device time on the same frame (the goal is < 3).
    pub backward_over_forward: Option<f64>,
    /// Whole `lensblur render` processes, EXR to EXR ([`super::process_timings`]).
    pub processes: Vec<super::process_timings::ProcessTiming>,
}

/// A case's inputs and the renderer that times it, built outside the timings.
enum Prepared {
    /// The renderer, what its renders of the case's stack keep, and the scan's time (ms).
    Forward(DrBokehGpu, ResidentStack, f64),
    Backward(DrBokehGpuGrad, Image),
    Multiview(Multiview, MultiviewParams),
    Vdslr(Vdslr, VdslrParams, Image, Vec<f32>),
}

impl Prepared {
    fn new(ctx: &Context, case: &TimingCase, stack: &LayerStack, lens: &Lens) -> Result<Self> {
        let samples = case.samples.unwrap_or(512);
        Ok(match case.pass {
            TimedPass::Forward => {
                let start = Instant::now();
                let resident = ResidentStack::new(stack, lens.coc.focus_disparity);
                Prepared::Forward(DrBokehGpu::new(ctx)?, resident, start.elapsed().as_secs_f64() * 1e3)
            }
            TimedPass::Backward => {
                let (w, h) = (case.width, case.height);
                let grad_output = Image::from_fn(w, h, |x, y| std::array::from_fn(|c| hash((y * w + x) * 4 + c)));
                Prepared::Backward(DrBokehGpuGrad::new(ctx, Model::DrBokeh, BackwardOptions::exact())?, grad_output)
            }
            TimedPass::Multiview => {
                Prepared::Multiview(Multiview::new(ctx)?, MultiviewParams { samples, ..MultiviewParams::tuned() })
            }
            TimedPass::Vdslr => {
                let (image, disparity) = stack.flatten();
                Prepared::Vdslr(Vdslr::new(ctx)?, VdslrParams { samples, ..VdslrParams::tuned() }, image, disparity)
            }
        })
    }

    fn run(&self, stack: &LayerStack, lens: &Lens) -> Result<RenderStats> {
        let options = RenderOptions::default();
        Ok(match self {
            Prepared::Forward(renderer, resident, _) => renderer.render_resident(stack, resident, lens, Model::DrBokeh, &options)?.1,
            Prepared::Backward(renderer, grad_output) => renderer.backward_with(stack, lens, grad_output, &options)?.1,
            Prepared::Multiview(renderer, params) => renderer.run_with(stack, lens, params, &options)?.1,
            Prepared::Vdslr(renderer, params, image, disparity) => {
                renderer.run_with(image, disparity, lens, params, &options)?.1
            }
        })
    }
}

/// Times one case: one warm-up render (pipelines compiled, memory first touched), then
/// `repeats` timed ones. A forward case renders as a resident stack refocused does: its
/// stack's pass over the pixels is made once, timed on its own ([`HostBreakdown::scan`]).
pub fn time_case(ctx: &Context, case: &TimingCase, repeats: usize) -> Result<CaseTiming> {
    let (stack, mut lens) =
        layered_stack(case.width, case.height, case.layers, Focus::FullyDefocused, case.max_coc_px)?;
    lens.aperture = Aperture::parse(case.aperture)?;
    let prepared = Prepared::new(ctx, case, &stack, &lens)?;
    prepared.run(&stack, &lens)?;
    let (mut device_ms_runs, mut wall_ms_runs, mut runs) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..repeats.max(1) {
        let start = Instant::now();
        let stats = prepared.run(&stack, &lens)?;
        let wall = start.elapsed().as_secs_f64() * 1e3;
        wall_ms_runs.push(wall);
        device_ms_runs.extend(stats.device_ns.map(|ns| ns * 1e-6));
        runs.push((wall, stats));
    }
    let wall_ms = median(&mut wall_ms_runs.clone());
    // The run whose wall time is the median, for the breakdown and the tiling.
    let (median_wall, last) = runs.iter().copied().find(|(wall, _)| *wall == wall_ms).unwrap_or_default();
    let tile_loop = (last.host_record_ns + last.host_wait_ns + last.host_collect_ns) * 1e-6;
    let host_ms = HostBreakdown {
        scan: if let Prepared::Forward(_, _, scan_ms) = &prepared { *scan_ms } else { 0.0 },
        prepare: median_wall - tile_loop,
        record: last.host_record_ns * 1e-6,
        wait: last.host_wait_ns * 1e-6,
        collect: last.host_collect_ns * 1e-6,
    };
    let device_ms = (device_ms_runs.len() == wall_ms_runs.len()).then(|| median(&mut device_ms_runs.clone()));
    let seconds = device_ms.unwrap_or(wall_ms) * 1e-3;
    let compulsory_gb_per_second = case.compulsory_bytes() as f64 / seconds / 1e9;
    let peak = peak_bandwidth_gb_per_second(&ctx.info().name);
    Ok(CaseTiming {
        case: case.clone(),
        repeats: wall_ms_runs.len(),
        device_ms,
        wall_ms,
        device_ms_runs,
        wall_ms_runs,
        effective_taps_per_second: case.effective_taps() / seconds,
        compulsory_gb_per_second,
        bandwidth_share: peak.map(|peak| compulsory_gb_per_second / peak),
        tiles: last.tiles,
        tile_size: last.tile_size,
        // A resident stack's upload, kept from the warm-up render, is held by the timed ones too.
        peak_device_bytes: last.peak_device_bytes
            + if let Prepared::Forward(_, resident, _) = &prepared { resident.upload_bytes() } else { 0 },
        host_ms,
        meets_goal: case
            .goal_ms
            .map(|goal| if case.goal_on_wall { wall_ms } else { device_ms.unwrap_or(wall_ms) } <= goal),
    })
}

/// Times every case of `cases`; `on_case` sees each as it finishes (progress, a log line).
pub fn run_timings(
    ctx: &Context,
    cases: &[TimingCase],
    repeats: usize,
    mut on_case: impl FnMut(&CaseTiming),
) -> Result<TimingReport> {
    let mut timings = Vec::new();
    for case in cases {
        let timing = time_case(ctx, case, repeats)?;
        on_case(&timing);
        timings.push(timing);
    }
    // Backward against the forward pass of the same frame, aperture and CoC.
    let time_of = |pass: TimedPass, like: &TimingCase| {
        timings
            .iter()
            .find(|t| {
                let c = &t.case;
                c.pass == pass
                    && (c.width, c.height, c.layers, c.aperture)
                        == (like.width, like.height, like.layers, like.aperture)
            })
            .map(|t| t.device_ms.unwrap_or(t.wall_ms))
    };
    let backward_over_forward = timings
        .iter()
        .find(|t| t.case.pass == TimedPass::Backward)
        .and_then(|b| Some(time_of(TimedPass::Backward, &b.case)? / time_of(TimedPass::Forward, &b.case)?));
    let info = ctx.info();
    Ok(TimingReport {
        device: info.name.clone(),
        driver: info.driver.clone(),
        subgroup_size: info.subgroup_size,
        peak_bandwidth_gb_per_second: peak_bandwidth_gb_per_second(&info.name),
        cases: timings,
        backward_over_forward,
        processes: Vec::new(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_full_case_has_a_small_twin_of_the_same_kind() {
        let (full, small) = (timing_cases(false), timing_cases(true));
        for case in &full {
            assert!(
                small.iter().any(|s| s.pass == case.pass && s.aperture == case.aperture),
                "{}: no small case runs the same pass and aperture in the tests",
                case.name
            );
        }
        // The backward ratio needs a forward case on the backward case's frame, in both sets.
        for cases in [&full, &small] {
            let b = cases.iter().find(|c| c.pass == TimedPass::Backward).expect("a backward case");
            assert!(cases.iter().any(|c| c.pass == TimedPass::Forward
                && (c.width, c.height, c.layers, c.aperture) == (b.width, b.height, b.layers, b.aperture)));
        }
    }

    #[test]
    fn known_gpus_get_their_datasheet_bandwidth() {
        assert_eq!(peak_bandwidth_gb_per_second("NVIDIA H100 80GB HBM3"), Some(3350.0));
        assert_eq!(peak_bandwidth_gb_per_second("NVIDIA H100 PCIe"), Some(2000.0));
        assert_eq!(peak_bandwidth_gb_per_second("NVIDIA H200"), Some(4800.0));
        assert_eq!(peak_bandwidth_gb_per_second("llvmpipe (LLVM 15.0.6, 256 bits)"), None);
    }

    #[test]
    fn compulsory_traffic_counts_inputs_once_and_the_output_once() {
        let case = TimingCase::new(TimedPass::Forward, (10, 10), 2, 4.0, "disk");
        assert_eq!(case.compulsory_bytes(), 100 * 2 * 20 + 100 * 16);
        assert!((case.effective_taps() - 200.0 * std::f64::consts::PI * 16.0).abs() < 1e-9);
    }
}
