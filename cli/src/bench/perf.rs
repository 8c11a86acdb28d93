//! `lensblur bench perf`: the Dr.Bokeh forward renderer's fixed performance cases, optimised
//! kernel against the first straightforward one in the same run (wall and device time,
//! effective taps/s, peak memory, speed-up), with the machine's load average.
use std::path::{Path, PathBuf};

use anyhow::Context;
use lensblur_dev::bench::apertures::{compare_apertures, ApertureTiming};
use lensblur_dev::bench::blender::{case_name, compare_with_blender, BlenderComparison, FRAME_SIDE};
use lensblur_dev::bench::end_to_end::{run_end_to_end, EndToEndResult};
use lensblur_dev::bench::large::Focus;
use lensblur_dev::bench::perf::{load_average, perf_cases, run_perf_case, PerfRenderers, PerfResult};
use lensblur_dev::bench::perf_backward::{backward_cases, run_backward_case, BackwardRenderers, BackwardResult};
use lensblur::vk::Context as GpuContext;

#[derive(clap::Args)]
#[command(after_help = "Examples:\n  lensblur bench perf --quick\n  lensblur bench perf --cases 1024-2l-coc32 --json perf.json\n  \
lensblur bench perf --no-baseline\n  lensblur bench perf --groups end-to-end\n  lensblur bench perf --groups blender --out blender-cmp\n  \
lensblur bench perf --groups apertures,blender")]
pub struct Args {
    /// Only the 1024x1024 kernel cases.
    #[arg(long)]
    pub quick: bool,
    /// Also write the results as JSON to FILE.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    #[command(flatten, next_help_heading = "Performance")]
    pub flags: PerfFlags,
}

/// The suite's case selection, timing and output flags (a struct of their own so that --help
/// lists them under one heading).
#[derive(clap::Args, Clone)]
pub struct PerfFlags {
    /// Case groups to run: kernel (optimised vs baseline forward kernel), backward (forward vs
    /// forward+backward), end-to-end (whole `lensblur render` processes), blender (Blender 3.4's
    /// and 5.0's Defocus nodes vs `lensblur render`, needs `blender` on PATH and the bpy 5.0
    /// virtualenv of .ci/setup), apertures (`lensblur render`
    /// of the Blender frame with every aperture kind against the disk; with blender also
    /// Blender's Defocus with the same shape where it has one).
    #[arg(long, value_enum, value_delimiter = ',', default_value = "kernel,backward,end-to-end")]
    pub groups: Vec<PerfGroup>,
    /// Comma-separated substrings; run the kernel, backward and aperture cases whose name
    /// contains one (e.g. 1024-2l-coc32, backward-256, polygon; the apertures' disk always runs).
    #[arg(long)]
    pub cases: Option<String>,
    /// Renders per kernel and case; the median is reported (end-to-end: processes, at least 5).
    #[arg(long, default_value_t = 3)]
    pub repeats: usize,
    /// Skip the baseline kernel (it is several times slower).
    #[arg(long)]
    pub no_baseline: bool,
    /// Folder for the end-to-end and Blender inputs and the Blender comparison's PNGs; by
    /// default in the user cache folder ($XDG_CACHE_HOME/lensblur, else ~/.cache/lensblur),
    /// whichever folder the command runs in.
    #[arg(long, value_name = "DIR", default_value_os_t = lensblur::cache_dir::cache_subdir("perf"))]
    pub out: PathBuf,
    /// Side of the blender group's square frame (its largest CoC scales with it: 40 px at
    /// 1024); smaller for a quick look, Blender 5.0's CPU Defocus takes minutes at 1024.
    #[arg(long, value_name = "PX", default_value_t = FRAME_SIDE)]
    pub blender_side: usize,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum PerfGroup {
    Kernel,
    Backward,
    EndToEnd,
    Blender,
    Apertures,
}

/// The whole suite.
pub fn run(args: Args) -> anyhow::Result<()> {
    let Args { quick, json, flags } = args;
    let (json, flags) = (json.as_deref(), &flags);
    let filters: Vec<String> = flags.cases.iter().flat_map(|c| c.split(',')).map(str::to_string).collect();
    let wanted = |name: &str| filters.is_empty() || filters.iter().any(|f| name.contains(f.as_str()));
    let group = |g: PerfGroup| flags.groups.contains(&g);
    let ctx = GpuContext::from_env().context("opening the Vulkan device")?;
    let load_before = load_average();
    println!("device: {}; load average before: {}", ctx.info().name, format_load(load_before));
    let mut report = serde_json::json!({ "device": ctx.info().name, "repeats": flags.repeats, "load_average_before": load_before });
    if group(PerfGroup::Kernel) {
        let cases: Vec<_> = perf_cases(quick).into_iter().filter(|c| wanted(&c.name)).collect();
        report["results"] = serde_json::to_value(kernel_group(&ctx, &cases, flags)?)?;
    }
    if group(PerfGroup::Backward) {
        let cases: Vec<_> = backward_cases(quick).into_iter().filter(|c| wanted(&c.name)).collect();
        report["backward"] = serde_json::to_value(backward_group(&ctx, &cases, flags.repeats)?)?;
    }
    if group(PerfGroup::EndToEnd) {
        report["end_to_end"] = serde_json::to_value(end_to_end_group(&flags.out, flags.repeats)?)?;
    }
    if group(PerfGroup::Blender) {
        let focuses: Vec<Focus> = [Focus::MostlyInFocus, Focus::FullyDefocused].into_iter().filter(|&f| wanted(&case_name(f, flags.blender_side))).collect();
        report["blender"] = serde_json::to_value(blender_group(&focuses, &flags.out, flags.blender_side, flags.repeats)?)?;
    }
    if group(PerfGroup::Apertures) {
        report["apertures"] = serde_json::to_value(apertures_group(&flags.out, flags.repeats, group(PerfGroup::Blender), &wanted)?)?;
    }
    let load_after = load_average();
    println!("load average after: {}", format_load(load_after));
    report["load_average_after"] = serde_json::to_value(load_after)?;
    if let Some(path) = json {
        std::fs::write(path, serde_json::to_string_pretty(&report)?).with_context(|| format!("writing {}", path.display()))?;
    }
    ctx.finish()?;
    Ok(())
}

fn kernel_group(ctx: &GpuContext, cases: &[lensblur_dev::bench::perf::PerfCase], flags: &PerfFlags) -> anyhow::Result<Vec<PerfResult>> {
    if cases.is_empty() {
        return Ok(Vec::new());
    }
    let renderers = PerfRenderers::new(ctx, !flags.no_baseline).context("building the renderers")?;
    println!(
        "{:<28} {:>8} {:>8} {:>8} {:>10} {:>8} {:>8} {:>10} {:>8} {:>8} {:>7} {:>7}",
        "case", "wall s", "device s", "cpu s", "eff tap/s", "base s", "base cpu", "base tap/s", "speedup", "cpu x", "dev MiB", "hostMiB"
    );
    let mut results = Vec::new();
    for case in cases {
        let result = run_perf_case(&renderers, case, flags.repeats).with_context(|| format!("case {}", case.name))?;
        print_row(&result);
        results.push(result);
    }
    Ok(results)
}

fn backward_group(ctx: &GpuContext, cases: &[lensblur_dev::bench::perf_backward::BackwardCase], repeats: usize) -> anyhow::Result<Vec<BackwardResult>> {
    if cases.is_empty() {
        return Ok(Vec::new());
    }
    let renderers = BackwardRenderers::new(ctx).context("building the backward pipelines")?;
    println!("{:<28} {:>9} {:>9} {:>9} {:>9} {:>8} {:>8}", "case", "fwd s", "fwd dev s", "bwd s", "bwd dev s", "bwd/fwd", "dev b/f");
    let mut results = Vec::new();
    for case in cases {
        let r = run_backward_case(&renderers, case, repeats).with_context(|| format!("case {}", case.name))?;
        let opt = |v: Option<f64>, digits: usize| v.map(|v| format!("{v:.digits$}")).unwrap_or_else(|| "-".into());
        println!(
            "{:<28} {:>9.3} {:>9} {:>9.3} {:>9} {:>7.2}x {:>8}",
            r.case.name,
            r.forward_wall_seconds,
            opt(r.forward_device_seconds, 3),
            r.backward_wall_seconds,
            opt(r.backward_device_seconds, 3),
            r.ratio,
            opt(r.device_ratio, 2)
        );
        results.push(r);
    }
    Ok(results)
}

fn end_to_end_group(out: &Path, repeats: usize) -> anyhow::Result<Vec<EndToEndResult>> {
    let exe = std::env::current_exe().context("finding the lensblur executable")?;
    let results = run_end_to_end(&exe, out, 256, repeats.max(5)).context("timing `lensblur render` processes")?;
    println!("{:<28} {:>5} {:>9} {:>9} {:>9} {:>9}", "end to end (process)", "runs", "median s", "min s", "max s", "first s");
    for r in &results {
        println!("{:<28} {:>5} {:>9.3} {:>9.3} {:>9.3} {:>9.3}", r.name, r.runs, r.median_seconds, r.min_seconds, r.max_seconds, r.first_seconds);
    }
    Ok(results)
}

fn blender_group(focuses: &[Focus], out: &Path, side: usize, repeats: usize) -> anyhow::Result<Vec<BlenderComparison>> {
    let exe = std::env::current_exe().context("finding the lensblur executable")?;
    let mut results = Vec::new();
    for &focus in focuses {
        let name = case_name(focus, side);
        let r = compare_with_blender(&exe, out, focus, side, repeats).with_context(|| format!("case {name}"))?;
        println!(
            "{}: lensblur render (process) median {:.3} s, of the flat RGB+Z {:.3} s; f-stop {:.3}, lens {} mm, sensor {} mm, focus {} m; {}",
            r.name,
            r.lensblur_median_seconds,
            r.flat_median_seconds,
            r.camera.fstop,
            r.camera.focal_length_mm,
            r.camera.sensor_width_mm,
            r.camera.focus_distance,
            r.lensblur_png.display()
        );
        for (what, steps) in [("layered", &r.lensblur_steps_ms), ("flat", &r.flat_steps_ms)] {
            // In the order a process takes them (the report's map is sorted by name).
            let order = ["read", "layering", "device_open", "warm_up", "prepare", "render", "device_close", "write", "total"];
            let mut names: Vec<&String> = steps.keys().collect();
            names.sort_by_key(|name| order.iter().position(|o| o == name).unwrap_or(order.len()));
            let steps: Vec<String> = names.iter().map(|&step| format!("{step} {:.1}", steps[step].as_f64().unwrap_or(f64::NAN))).collect();
            println!("  inside the {what} process, medians (ms; the device opens beside read and layering): {}", steps.join(", "));
        }
        let usage = |field: &str| r.flat_process.get(field).and_then(|v| v.as_f64()).unwrap_or(f64::NAN);
        println!(
            "  the flat process, medians: peak resident {:.1} MiB, page faults {:.0}",
            usage("peak_resident_mib"),
            usage("page_faults")
        );
        for b in &r.blenders {
            println!(
                "  Blender {} Defocus ({:?}) compositing median {:.3} s (process {:.1} s); ratio {:.3} (goal <= 0.5), \
                 flat {:.3} (goal <= 1.0 at 256^2); f-stop {:.3}, Z x {:.1}, focus {:.3}, blur_max {}; {}",
                b.version,
                b.blender.node,
                b.median_seconds,
                b.process_seconds,
                b.ratio,
                b.flat_ratio,
                b.blender.f_stop,
                b.blender.z_scale,
                b.blender.focus_distance,
                b.blender.blur_max,
                b.png.display()
            );
        }
        results.push(r);
    }
    Ok(results)
}

fn apertures_group(out: &Path, repeats: usize, blender: bool, wanted: &dyn Fn(&str) -> bool) -> anyhow::Result<Vec<ApertureTiming>> {
    let exe = std::env::current_exe().context("finding the lensblur executable")?;
    println!("apertures: `lensblur render` of the 1024^2 five-layer frame (CoC up to 40 px, defocused), medians of {} processes", repeats.max(1));
    // Names up to "cats-eye 0.6 (anamorphic:1.8)".
    println!("{:<30} {:>10} {:>8} {:>10} {:>11} {:>10}", "aperture", "lensblur s", "/ disk", "Blender", "Blender s", "/ Blender");
    let row = |t: &ApertureTiming| {
        let (bokeh, seconds, ratio) = match (t.blender_median_seconds, t.ratio_to_blender) {
            (Some(s), Some(r)) => (t.blender_bokeh.unwrap_or("-"), format!("{s:.3}"), format!("{r:.3}")),
            _ => ("-", "-".to_string(), "-".to_string()),
        };
        println!("{:<30} {:>10.3} {:>8.2} {:>10} {:>11} {:>10}", t.name, t.lensblur_median_seconds, t.ratio_to_disk, bokeh, seconds, ratio);
    };
    compare_apertures(&exe, out, repeats, blender, wanted, &row).context("timing the aperture cases")
}

fn print_row(r: &PerfResult) {
    let mib = |b: u64| b as f64 / (1024.0 * 1024.0);
    let o = &r.optimised;
    let opt = |v: Option<f64>, f: &dyn Fn(f64) -> String| v.map(f).unwrap_or_else(|| "-".into());
    let seconds = |s: f64| format!("{s:.3}");
    let base = r.baseline.as_ref();
    println!(
        "{:<28} {:>8.3} {:>8} {:>8} {:>10.3e} {:>8} {:>8} {:>10} {:>8} {:>8} {:>7.0} {:>7}",
        r.case.name,
        o.wall_seconds,
        opt(o.device_seconds, &seconds),
        opt(o.cpu_seconds, &seconds),
        o.effective_taps_per_second,
        opt(base.map(|b| b.wall_seconds), &seconds),
        opt(base.and_then(|b| b.cpu_seconds), &seconds),
        opt(base.map(|b| b.effective_taps_per_second), &|t| format!("{t:.3e}")),
        opt(r.speedup, &|s| format!("{s:.2}x")),
        opt(r.cpu_speedup, &|s| format!("{s:.2}x")),
        mib(o.peak_device_bytes),
        opt(o.peak_host_bytes.map(|b| b as f64), &|b| format!("{:.0}", b / (1024.0 * 1024.0))),
    );
}

fn format_load(load: Option<[f64; 3]>) -> String {
    load.map(|[a, b, c]| format!("{a:.2} {b:.2} {c:.2}")).unwrap_or_else(|| "n/a".into())
}
