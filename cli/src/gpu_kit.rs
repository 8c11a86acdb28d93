//! The GPU kit's two hidden subcommands (`gpu-kit/run` calls them; see docs/book/src/gpu-kit.md):
//! `lensblur self-check` compares every device pass with its CPU reference (the library's
//! [`lensblur_dev::selfcheck`], which the tests run too) and the sequence path of this binary;
//! `lensblur gpu-timings` times the fixed cases of [`lensblur_dev::bench::device_timings`].
use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{bail, Context as _};
use lensblur_dev::bench::device_timings::{run_timings, timing_cases, CaseTiming};
use lensblur_dev::bench::process_timings::{process_cases, time_process_case};
use lensblur::camera::{Aperture, CocModel};
use lensblur::render::{Lens, Method};
use lensblur_dev::selfcheck::{self, image_difference, Check, IMAGE_METRIC};
use lensblur::stack::{read_rgba, read_stack, write_stack, DepthKind, ReadOptions, StackWriteOptions};
use lensblur::vk::{Context, ContextOptions};

#[derive(clap::Args)]
#[command(after_help = "Examples:\n  lensblur self-check                                           every device pass against its CPU reference\n  LENSBLUR_VALIDATION=1 lensblur self-check --json checks.json  the same under the validation layer, each check as JSON")]
pub struct SelfCheckArgs {
    /// Write every check (name, difference, tolerance, verdict) as JSON here.
    #[arg(long, value_name = "FILE.json")]
    json: Option<PathBuf>,
}

#[derive(clap::Args)]
#[command(after_help = "Examples:\n  lensblur gpu-timings --small                                           every case at CPU-device sizes\n  lensblur gpu-timings --case process --json t.json                      the whole-process cases only\n  LENSBLUR_PROFILE=1 lensblur gpu-timings --small --case \"grad 128x128\"  device time per shader")]
pub struct TimingsArgs {
    /// Write the timings as JSON here.
    #[arg(long, value_name = "FILE.json")]
    json: Option<PathBuf>,
    /// The same kinds of case at sizes a CPU device runs in seconds (the tests' run of the kit).
    #[arg(long)]
    small: bool,
    /// Timed renders per case after the warm-up (the report gives their median).
    #[arg(long, default_value_t = 5)]
    repeats: usize,
    /// Only the cases whose name contains this (repeatable): one case of the full set runs in
    /// seconds on a CPU device, the whole set in many minutes.
    #[arg(long, value_name = "NAME")]
    case: Vec<String>,
}

pub fn self_check(args: SelfCheckArgs) -> anyhow::Result<()> {
    let ctx = Context::new(&ContextOptions::from_env()).context("opening the Vulkan device for the self-check")?;
    let info = ctx.info().clone();
    eprintln!(
        "self-check on {} ({}), validation {}",
        info.name,
        info.driver,
        if ctx.validation_enabled() { "on" } else { "off" }
    );
    let print = |c: &Check| {
        let verdict = if c.passed { "ok  " } else { "FAIL" };
        let difference = c.difference.map_or_else(|| "-".to_string(), |d| format!("{d:.2e}"));
        eprintln!(
            "{verdict} {:<52} {difference:>9} <= {:.0e}  {:.2} s{}",
            c.name,
            c.tolerance,
            c.seconds,
            c.error.as_ref().map_or(String::new(), |e| format!("  {e}"))
        );
    };
    let mut checks = selfcheck::run(&ctx, print);
    let sequence = sequence_check(&ctx);
    print(&sequence);
    checks.push(sequence);
    // Validation messages fail the self-check like a difference does.
    let validation = ctx.finish().err().map(|e| e.to_string());
    let failed: Vec<&str> = checks.iter().filter(|c| !c.passed).map(|c| c.name.as_str()).collect();
    if let Some(path) = &args.json {
        let report = serde_json::json!({
            "device": info,
            "checks": checks,
            "passed": failed.is_empty() && validation.is_none(),
            "validation_error": validation,
        });
        write_json(path, &report)?;
    }
    eprintln!("self-check: {} of {} checks passed", checks.len() - failed.len(), checks.len());
    if let Some(message) = validation {
        bail!("validation: {message}");
    }
    if !failed.is_empty() {
        bail!("{} check(s) failed: {}", failed.len(), failed.join("; "));
    }
    Ok(())
}

/// The sequence path: three frames rendered by `lensblur render IN.####.exr --frames 1-3` (this
/// very binary, one process, the device opened once) against the CPU reference of the frame.
fn sequence_check(ctx: &Context) -> Check {
    let name = "sequence drbokeh disk --frames 1-3".to_string();
    selfcheck::check(name, IMAGE_METRIC, selfcheck::forward_tolerance(Method::DrBokeh), || {
        sequence_difference(ctx).map_err(|e| format!("{e:#}"))
    })
}

/// The largest [`image_difference`] of the three frames from their CPU reference.
fn sequence_difference(ctx: &Context) -> anyhow::Result<f64> {
    let dir = tempdir()?;
    let stack = selfcheck::sequence_stack();
    let options = StackWriteOptions { depth_kind: DepthKind::Disparity, ..StackWriteOptions::default() };
    for frame in 1..=3 {
        write_stack(&dir.join(format!("shot.{frame:04}.exr")), &stack, &options)?;
    }
    let exe = std::env::current_exe().context("locating this binary")?;
    let output = Command::new(exe)
        .args([
            "render",
            "--device",
            "gpu",
            "--frames",
            "1-3",
            "--depth-kind",
            "disparity",
            "--blur",
            "25",
            "--focus-disparity",
            "0.5",
        ])
        .arg(dir.join("shot.####.exr"))
        .arg("-o")
        .arg(dir.join("out.####.exr"))
        .envs(ctx.validation_enabled().then_some(("LENSBLUR_VALIDATION", "1")))
        .output()
        .context("running `lensblur render --frames`")?;
    if !output.status.success() {
        bail!("`lensblur render --frames 1-3` failed: {}", String::from_utf8_lossy(&output.stderr).trim());
    }
    // The reference renders the stack as the file holds it (the writer stores its own depth
    // under fully transparent pixels).
    let read = ReadOptions { depth_kind: DepthKind::Disparity, ..ReadOptions::default() };
    let stored = read_stack(&dir.join("shot.0001.exr"), &read)?.stack;
    let lens = Lens { coc: CocModel::new(25.0, 0.5)?, aperture: Aperture::Disk };
    let cpu = Method::DrBokeh.render(None, &stored, &lens)?;
    let mut worst = 0.0f64;
    for frame in 1..=3 {
        let path = dir.join(format!("out.{frame:04}.exr"));
        let image = read_rgba(&path, None, u64::MAX).with_context(|| format!("reading {}", path.display()))?;
        worst = worst.max(image_difference(&image, &cpu));
    }
    std::fs::remove_dir_all(&dir).ok();
    Ok(worst)
}

fn tempdir() -> anyhow::Result<PathBuf> {
    let dir = std::env::temp_dir().join(format!("lensblur-self-check-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    Ok(dir)
}

pub fn timings(args: TimingsArgs) -> anyhow::Result<()> {
    let ctx = Context::new(&ContextOptions::from_env()).context("opening the Vulkan device for the timings")?;
    let mut cases = timing_cases(args.small);
    let mut processes = process_cases(args.small);
    if !args.case.is_empty() {
        let wanted = |name: &str| args.case.iter().any(|w| name.contains(w.as_str()));
        cases.retain(|c| wanted(&c.name));
        processes.retain(|c| wanted(&c.name));
        if cases.is_empty() && processes.is_empty() {
            bail!("no timing case's name contains any of {:?}", args.case);
        }
    }
    eprintln!("timings on {}: {} cases, median of {} after one warm-up", ctx.info().name, cases.len(), args.repeats);
    let print = |t: &CaseTiming| {
        let device = t.device_ms.map_or_else(|| "-".to_string(), |ms| format!("{ms:.2}"));
        let share = t.bandwidth_share.map_or_else(|| "-".to_string(), |s| format!("{:.1}%", 100.0 * s));
        eprintln!(
            "{:<44} device {device:>9} ms  wall {:>9.2} ms ({}prepare {:.1}, record {:.1}, wait {:.1}, collect {:.1})  {:>8.1} Gtaps/s  {share:>6} of bandwidth  {} tile(s){}",
            t.case.name,
            t.wall_ms,
            // A forward case's stack is scanned once, by its first render (see HostBreakdown::scan).
            if t.host_ms.scan > 0.0 { format!("scan once {:.1}, then ", t.host_ms.scan) } else { String::new() },
            t.host_ms.prepare,
            t.host_ms.record,
            t.host_ms.wait,
            t.host_ms.collect,
            t.effective_taps_per_second / 1e9,
            t.tiles,
            t.meets_goal.map_or(String::new(), |ok| format!(
                "  goal {} ms ({}) {}",
                t.case.goal_ms.unwrap_or(0.0),
                if t.case.goal_on_wall { "wall" } else { "device" },
                if ok { "met" } else { "MISSED" }
            ))
        );
    };
    let mut report = run_timings(&ctx, &cases, args.repeats, print)?;
    if let Some(ratio) = report.backward_over_forward {
        eprintln!("backward / forward on the same frame: {ratio:.2} (goal < 3)");
    }
    // Whole processes, EXR to EXR: this binary, each run opening the device itself.
    let exe = std::env::current_exe().context("locating this binary")?;
    let dir = tempdir()?;
    for case in &processes {
        let timing = time_process_case(&exe, &dir, case, args.repeats.min(3)).with_context(|| case.name.clone())?;
        let steps: Vec<String> = timing.steps_ms.iter().map(|(k, v)| format!("{k} {:.1}", v.as_f64().unwrap_or_default())).collect();
        eprintln!(
            "{:<44} wall {:>9.2} ms ({}); peak device {} ({} the stack){}",
            case.name,
            timing.wall_ms,
            steps.join(", "),
            timing.peak_device_bytes.map_or("-".into(), |b| format!("{:.1} MiB", b as f64 / 1048576.0)),
            timing.peak_over_stack.map_or("-".into(), |r| format!("{r:.2}x")),
            timing.meets_goal.map_or(String::new(), |ok| format!(
                "  goal {} ms (wall) {}",
                case.goal_ms.unwrap_or(0.0),
                if ok { "met" } else { "MISSED" }
            ))
        );
        report.processes.push(timing);
    }
    std::fs::remove_dir_all(&dir).ok();
    if let Some(path) = &args.json {
        write_json(path, &report)?;
    }
    ctx.finish()?;
    Ok(())
}

fn write_json(path: &Path, value: &impl serde::Serialize) -> anyhow::Result<()> {
    let text = serde_json::to_string_pretty(value)?;
    lensblur::atomic_file::write_atomically(path, |file| {
        use std::io::Write;
        file.write_all(text.as_bytes()).map_err(lensblur::Error::io(path))
    })
    .with_context(|| format!("writing {}", path.display()))
}
