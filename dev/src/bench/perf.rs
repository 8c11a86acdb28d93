//! The performance benchmark of the Dr.Bokeh forward renderer (issue 11): fixed procedural
//! cases (1024^2 and 4096^2, 2 and 5 layers, largest CoC 16/32/64 px, mostly in focus and
//! fully defocused), each rendered by the optimised layer kernel and by the first
//! straightforward one ([`LayerKernel::Baseline`]) in the same run; medians of `repeats`.
use std::time::Instant;

use super::large::{layered_stack, peak_resident_bytes, Focus};
use lensblur::render::drbokeh::{DrBokehGpu, LayerKernel, Model, RenderOptions};
use lensblur::vk::Context;
use lensblur::Result;

#[derive(Clone, Debug, serde::Serialize)]
pub struct PerfCase {
    pub name: String,
    pub side: usize,
    pub layers: usize,
    pub max_coc_px: f32,
    pub focus: Focus,
}

impl PerfCase {
    pub fn new(side: usize, layers: usize, max_coc_px: f32, focus: Focus) -> Self {
        let focus_name = match focus {
            Focus::MostlyInFocus => "focused",
            Focus::FullyDefocused => "defocused",
        };
        let name = format!("{side}-{layers}l-coc{max_coc_px}-{focus_name}");
        Self { name, side, layers, max_coc_px, focus }
    }

    /// The yardstick: pixels x layers x pi r^2 with r the largest CoC radius.
    pub fn effective_taps(&self) -> f64 {
        (self.side * self.side * self.layers) as f64 * std::f64::consts::PI * (self.max_coc_px as f64).powi(2)
    }
}

/// Every fixed case, 1024^2 first; `quick` keeps only the 1024^2 ones.
pub fn perf_cases(quick: bool) -> Vec<PerfCase> {
    let sides: &[usize] = if quick { &[1024] } else { &[1024, 4096] };
    let mut cases = Vec::new();
    for &side in sides {
        for layers in [2, 5] {
            for coc in [16.0, 32.0, 64.0] {
                for focus in [Focus::FullyDefocused, Focus::MostlyInFocus] {
                    cases.push(PerfCase::new(side, layers, coc, focus));
                }
            }
        }
    }
    cases
}

/// One kernel on one case: medians over the repeats.
#[derive(Clone, Debug, serde::Serialize)]
pub struct KernelTiming {
    pub wall_seconds: f64,
    pub device_seconds: Option<f64>,
    /// CPU time of the whole process (user + system, all threads): on a CPU device such as
    /// lavapipe this is the work, less sensitive than wall time to other load on the machine.
    pub cpu_seconds: Option<f64>,
    /// [`PerfCase::effective_taps`] per wall second.
    pub effective_taps_per_second: f64,
    /// Taps the search windows bound (square windows, `RenderStats::taps`).
    pub window_taps: u64,
    pub tiles: usize,
    pub peak_device_bytes: u64,
    /// Peak resident memory of the process so far (VmHWM), if the OS reports it.
    pub peak_host_bytes: Option<u64>,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct PerfResult {
    pub case: PerfCase,
    pub optimised: KernelTiming,
    pub baseline: Option<KernelTiming>,
    /// Baseline wall time over optimised wall time.
    pub speedup: Option<f64>,
    /// Baseline process CPU time over optimised process CPU time.
    pub cpu_speedup: Option<f64>,
}

/// The optimised and (optionally) the baseline renderer, each compiled and warmed up once.
pub struct PerfRenderers {
    optimised: DrBokehGpu,
    baseline: Option<DrBokehGpu>,
}

impl PerfRenderers {
    pub fn new(ctx: &Context, with_baseline: bool) -> Result<Self> {
        let optimised = DrBokehGpu::with_kernel(ctx, LayerKernel::Optimised)?;
        let baseline = if with_baseline { Some(DrBokehGpu::with_kernel(ctx, LayerKernel::Baseline)?) } else { None };
        // lavapipe compiles a shader at its first dispatch: keep that out of the timings.
        let (stack, lens) = layered_stack(48, 48, 2, Focus::FullyDefocused, 4.0)?;
        for renderer in std::iter::once(&optimised).chain(baseline.as_ref()) {
            renderer.render(&stack, &lens, Model::DrBokeh)?;
        }
        Ok(Self { optimised, baseline })
    }
}

/// Runs one case `repeats` times per kernel (the stack is built once, outside the timings).
pub fn run_perf_case(renderers: &PerfRenderers, case: &PerfCase, repeats: usize) -> Result<PerfResult> {
    let (stack, lens) = layered_stack(case.side, case.side, case.layers, case.focus, case.max_coc_px)?;
    let time = |renderer: &DrBokehGpu| -> Result<KernelTiming> {
        let mut walls = Vec::new();
        let mut devices = Vec::new();
        let mut cpus = Vec::new();
        let mut last = None;
        for _ in 0..repeats.max(1) {
            let (start, cpu_start) = (Instant::now(), process_cpu_seconds());
            let (_, stats) = renderer.render_with(&stack, &lens, Model::DrBokeh, &RenderOptions::default())?;
            walls.push(start.elapsed().as_secs_f64());
            cpus.extend(cpu_start.zip(process_cpu_seconds()).map(|(a, b)| b - a));
            devices.extend(stats.device_ns.map(|ns| ns * 1e-9));
            last = Some(stats);
        }
        let stats = last.unwrap_or_default();
        let wall_seconds = median(&mut walls);
        Ok(KernelTiming {
            wall_seconds,
            device_seconds: (devices.len() == walls.len()).then(|| median(&mut devices)),
            cpu_seconds: (cpus.len() == walls.len()).then(|| median(&mut cpus)),
            effective_taps_per_second: case.effective_taps() / wall_seconds,
            window_taps: stats.taps,
            tiles: stats.tiles,
            peak_device_bytes: stats.peak_device_bytes,
            peak_host_bytes: peak_resident_bytes(),
        })
    };
    let optimised = time(&renderers.optimised)?;
    let baseline = renderers.baseline.as_ref().map(time).transpose()?;
    let speedup = baseline.as_ref().map(|b| b.wall_seconds / optimised.wall_seconds);
    let cpu_speedup = baseline.as_ref().and_then(|b| Some(b.cpu_seconds? / optimised.cpu_seconds?));
    Ok(PerfResult { case: case.clone(), optimised, baseline, speedup, cpu_speedup })
}

pub(crate) fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

/// The 1, 5 and 15 minute load averages (/proc/loadavg), if the OS reports them: the machine
/// may be shared, and timings only compare within one run.
pub fn load_average() -> Option<[f64; 3]> {
    let text = std::fs::read_to_string("/proc/loadavg").ok()?;
    let mut fields = text.split_whitespace().map(|f| f.parse::<f64>().ok());
    Some([fields.next()??, fields.next()??, fields.next()??])
}

/// User + system CPU seconds of this process, all threads (/proc/self/stat fields 14 and 15,
/// in USER_HZ = 100 ticks per second on Linux).
pub fn process_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // The command name (field 2) may hold spaces; fields after its closing parenthesis don't.
    let rest = &stat[stat.rfind(')')? + 1..];
    let mut fields = rest.split_whitespace().skip(11);
    let user: u64 = fields.next()?.parse().ok()?;
    let system: u64 = fields.next()?.parse().ok()?;
    Some((user + system) as f64 / 100.0)
}
