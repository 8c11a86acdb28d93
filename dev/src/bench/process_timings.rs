//! The GPU kit's "process" cases: whole `lensblur render` processes, EXR to EXR, as a farm
//! node or a compositing node pays them (issue 44). The kit writes each case's stack on the
//! machine it runs on, then times the binary rendering it on the device: start-up, reading,
//! the render, writing. Each run's `--json` report gives the steps and the peak device memory
//! of the render's buffers.
use std::path::Path;

use super::end_to_end::{median_steps, run_render_process};
use super::large::{layered_stack, Focus};
use super::perf::median;
use lensblur::stack::{write_stack, DepthKind, StackWriteOptions};
use lensblur::{Error, Result};

/// One whole-process case: a procedural stack of `layers` at `width` x `height`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ProcessCase {
    pub name: String,
    pub width: usize,
    pub height: usize,
    pub layers: usize,
    pub max_coc_px: f32,
    /// The goal for the median wall time of the process, where it sets one.
    pub goal_ms: Option<f64>,
}

impl ProcessCase {
    fn new(width: usize, height: usize, layers: usize, max_coc_px: f32, goal_ms: Option<f64>) -> Self {
        let name = format!("process {width}x{height} {layers}l coc{max_coc_px:.0} disk");
        Self { name, width, height, layers, max_coc_px, goal_ms }
    }

    /// Bytes of the stack as float32 (RGBA and disparity per layer): what "peak device memory
    /// <= 3x the stack" measures against.
    pub fn stack_bytes(&self) -> u64 {
        (self.width * self.height * self.layers * 5 * 4) as u64
    }
}

/// The kit's process cases (issue 44's goals: 1024^2 five layers <= 0.5 s, 8K five layers
/// <= 5 s); `small`: the same kind at sizes lavapipe runs in seconds.
pub fn process_cases(small: bool) -> Vec<ProcessCase> {
    if small {
        return vec![ProcessCase::new(128, 128, 5, 10.0, None), ProcessCase::new(320, 180, 5, 10.0, None)];
    }
    vec![ProcessCase::new(1024, 1024, 5, 40.0, Some(500.0)), ProcessCase::new(7680, 4320, 5, 40.0, Some(5000.0))]
}

/// One process case's medians.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ProcessTiming {
    pub case: ProcessCase,
    pub repeats: usize,
    pub wall_ms: f64,
    pub wall_ms_runs: Vec<f64>,
    /// The median of each step of the reports' `timings_ms` (read, layering, device_open, ...).
    pub steps_ms: serde_json::Map<String, serde_json::Value>,
    /// The most device memory the render's buffers held (the largest over the runs).
    pub peak_device_bytes: Option<u64>,
    /// That over [`ProcessCase::stack_bytes`] (the goal: at most 3).
    pub peak_over_stack: Option<f64>,
    pub meets_goal: Option<bool>,
}

/// Writes the case's stack into `dir`, then times `exe render` on it: one warm-up, then
/// `repeats` runs (at least one).
pub fn time_process_case(exe: &Path, dir: &Path, case: &ProcessCase, repeats: usize) -> Result<ProcessTiming> {
    let (stack, lens) = layered_stack(case.width, case.height, case.layers, Focus::FullyDefocused, case.max_coc_px)?;
    std::fs::create_dir_all(dir).map_err(|e| Error::input(dir, format!("cannot create: {e}")))?;
    let stem = case.name.replace(' ', "-");
    let (input, output) = (dir.join(format!("{stem}.exr")), dir.join(format!("{stem}-out.exr")));
    write_stack(&input, &stack, &StackWriteOptions { depth_kind: DepthKind::Disparity, ..StackWriteOptions::default() })?;
    drop(stack);
    let args: Vec<String> = [
        "-o", &output.display().to_string(), "--device", "gpu", "--depth-kind", "disparity", "--blur",
        &lens.coc.k_px.to_string(), "--focus-disparity", &lens.coc.focus_disparity.to_string(),
    ]
    .map(String::from)
    .to_vec();
    run_render_process(exe, &input, &args, &output, &[])?;
    let mut walls = Vec::new();
    let mut reports = Vec::new();
    for _ in 0..repeats.max(1) {
        let run = run_render_process(exe, &input, &args, &output, &[])?;
        walls.push(run.seconds * 1e3);
        reports.push(run.report);
    }
    let _ = std::fs::remove_file(&input);
    let _ = std::fs::remove_file(&output);
    let steps_ms = median_steps(&reports);
    let peak_device_bytes = reports.iter().filter_map(|r| r["device_peak_bytes"].as_u64()).max();
    let wall_ms_runs = walls.clone();
    let wall_ms = median(&mut walls);
    Ok(ProcessTiming {
        case: case.clone(),
        repeats: repeats.max(1),
        wall_ms,
        wall_ms_runs,
        steps_ms,
        peak_device_bytes,
        peak_over_stack: peak_device_bytes.map(|peak| peak as f64 / case.stack_bytes() as f64),
        meets_goal: case.goal_ms.map(|goal| wall_ms <= goal),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_full_process_case_has_a_small_twin_and_a_goal() {
        let (full, small) = (process_cases(false), process_cases(true));
        assert_eq!(full.len(), small.len());
        assert!(full.iter().all(|c| c.goal_ms.is_some() && c.name.starts_with("process ")));
        assert!(small.iter().all(|c| c.name.starts_with("process ")));
        assert_eq!(full[1].stack_bytes(), 7680 * 4320 * 5 * 20);
    }
}
