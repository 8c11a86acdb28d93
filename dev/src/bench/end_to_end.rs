//! End-to-end timing of `lensblur render`: whole processes of the current executable on a
//! procedural stack written to a temporary EXR, from spawn to exit (the output appears by
//! rename before the process exits, so exit is "file written"). Medians of the runs; one row
//! as is, one with Mesa's on-disk shader cache off (`MESA_SHADER_CACHE_DISABLE=true`: every
//! process compiles its shaders from scratch, what a first run on a fresh machine pays), and
//! one with our own Vulkan pipeline cache off as well (`LENSBLUR_PIPELINE_CACHE=off`).
//!
//! On lavapipe the last two rows agree: it compiles to machine code at the first dispatch and
//! keeps that in Mesa's cache, and its `vkGetPipelineCacheData` holds only the header. Drivers
//! that compile at pipeline creation (discrete GPUs) are what the pipeline cache is for.
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use super::large::{layered_stack, Focus};
use super::perf::median;
use lensblur::render::Lens;
use lensblur::stack::{write_stack, DepthKind, LayerStack, StackWriteOptions};
use lensblur::{Error, Result};

#[derive(Clone, Debug, serde::Serialize)]
pub struct EndToEndResult {
    pub name: String,
    pub side: usize,
    pub layers: usize,
    pub runs: usize,
    /// Whether Mesa's shader disk cache was left on (it is by default).
    pub driver_shader_cache: bool,
    /// Whether lensblur's own on-disk Vulkan pipeline cache was on (it is by default).
    pub pipeline_cache: bool,
    pub median_seconds: f64,
    pub min_seconds: f64,
    pub max_seconds: f64,
    /// The first run (it may fill a cold driver cache).
    pub first_seconds: f64,
}

/// Writes `stack` as a layered EXR with normalised disparity as depth.
pub fn write_disparity_stack(path: &Path, stack: &LayerStack) -> Result<()> {
    let options = StackWriteOptions { depth_kind: DepthKind::Disparity, ..StackWriteOptions::default() };
    write_stack(path, stack, &options)
}

/// The `lensblur render` arguments (after the input) that render a disparity stack with `lens`.
pub fn render_args(output: &Path, lens: &Lens) -> Vec<String> {
    vec![
        "-o".into(),
        output.display().to_string(),
        "--depth-kind".into(),
        "disparity".into(),
        "--blur".into(),
        lens.coc.k_px.to_string(),
        "--focus-disparity".into(),
        lens.coc.focus_disparity.to_string(),
    ]
}

/// One whole `lensblur render` process: its wall time, from spawn to exit, and its `--json`
/// report (the camera, the layers, and `timings_ms`: how long each step took inside).
pub struct RenderProcess {
    pub seconds: f64,
    pub report: serde_json::Value,
}

/// Runs `exe render INPUT ARGS --json` once (ARGS name the output, `output`); errors if it
/// fails, the output is missing or it prints no report.
pub fn run_render_process(exe: &Path, input: &Path, args: &[String], output: &Path, env: &[(&str, &str)]) -> Result<RenderProcess> {
    let _ = std::fs::remove_file(output);
    let start = Instant::now();
    let result = Command::new(exe).arg("render").arg(input).args(args).arg("--json").envs(env.iter().copied()).output();
    let seconds = start.elapsed().as_secs_f64();
    let out = result.map_err(|e| Error::input(exe, format!("cannot run: {e}")))?;
    if !out.status.success() || !output.exists() {
        let stderr = String::from_utf8_lossy(&out.stderr);
        return Err(Error::input(input, format!("lensblur render failed ({}): {}", out.status, stderr.trim())));
    }
    let report = serde_json::from_slice(&out.stdout)
        .map_err(|e| Error::input(input, format!("lensblur render printed no JSON report: {e}")))?;
    Ok(RenderProcess { seconds, report })
}

/// [`run_render_process`]'s wall time alone.
pub fn time_render_process(exe: &Path, input: &Path, args: &[String], output: &Path, env: &[(&str, &str)]) -> Result<f64> {
    Ok(run_render_process(exe, input, args, output, env)?.seconds)
}

/// The median over `reports` of each step of their `timings_ms` (read, layering, device_open,
/// ...), in the first report's order.
pub fn median_steps(reports: &[serde_json::Value]) -> serde_json::Map<String, serde_json::Value> {
    median_fields(reports, "timings_ms")
}

/// The median over `reports` of each number in their object `key` (`timings_ms`, or `process`:
/// peak resident memory and page faults), in the first report's order.
pub fn median_fields(reports: &[serde_json::Value], key: &str) -> serde_json::Map<String, serde_json::Value> {
    let fields = reports.first().and_then(|r| r[key].as_object()).map(|o| o.keys().cloned().collect::<Vec<_>>());
    fields
        .unwrap_or_default()
        .into_iter()
        .map(|field| {
            let mut values: Vec<f64> = reports.iter().filter_map(|r| r[key][&field].as_f64()).collect();
            (field, serde_json::Value::from(median(&mut values)))
        })
        .collect()
}

/// `runs` (at least 5) whole `lensblur render` processes of a `side`^2 two-layer stack: with
/// both caches, without Mesa's shader cache, without either. `dir` holds the input and output.
pub fn run_end_to_end(exe: &Path, dir: &Path, side: usize, runs: usize) -> Result<Vec<EndToEndResult>> {
    let layers = 2;
    let (stack, lens) = layered_stack(side, side, layers, Focus::FullyDefocused, 16.0)?;
    std::fs::create_dir_all(dir).map_err(|e| Error::input(dir, format!("cannot create: {e}")))?;
    let input = dir.join(format!("e2e-{side}-{layers}l.exr"));
    let output: PathBuf = dir.join(format!("e2e-{side}-{layers}l-out.exr"));
    write_disparity_stack(&input, &stack)?;
    let args = render_args(&output, &lens);
    let mut results = Vec::new();
    const MESA_OFF: (&str, &str) = ("MESA_SHADER_CACHE_DISABLE", "true");
    const PIPELINE_OFF: (&str, &str) = ("LENSBLUR_PIPELINE_CACHE", "off");
    let configs: [(&str, &[(&str, &str)]); 3] =
        [("", &[]), ("-mesa-cache-off", &[MESA_OFF]), ("-both-caches-off", &[MESA_OFF, PIPELINE_OFF])];
    for (suffix, env) in configs {
        let mut times = (0..runs.max(5)).map(|_| time_render_process(exe, &input, &args, &output, env)).collect::<Result<Vec<f64>>>()?;
        let first_seconds = times[0];
        let median_seconds = median(&mut times);
        results.push(EndToEndResult {
            name: format!("e2e-{side}-{layers}l{suffix}"),
            side,
            layers,
            runs: times.len(),
            driver_shader_cache: !env.contains(&MESA_OFF),
            pipeline_cache: !env.contains(&PIPELINE_OFF),
            median_seconds,
            min_seconds: times[0],
            max_seconds: times[times.len() - 1],
            first_seconds,
        });
    }
    let _ = std::fs::remove_file(&output);
    Ok(results)
}
