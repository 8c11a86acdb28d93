//! `lensblur bench-perf`: the Dr.Bokeh forward renderer's fixed performance cases, optimised
//! kernel against the first straightforward one in the same run (wall and device time,
//! effective taps/s, peak memory, speed-up), with the machine's load average.
use anyhow::Context;
use lensblur::bench::perf::{load_average, perf_cases, run_perf_case, PerfRenderers, PerfResult};
use lensblur::vk::Context as GpuContext;

#[derive(clap::Args)]
#[command(after_help = "Examples:\n  lensblur bench-perf --quick\n  lensblur bench-perf --cases 1024-2l-coc32 --json perf.json\n  lensblur bench-perf --no-baseline")]
pub struct Args {
    /// Only the 1024x1024 cases.
    #[arg(long)]
    quick: bool,
    /// Comma-separated substrings; run the cases whose name contains one (e.g. 1024-2l-coc32).
    #[arg(long)]
    cases: Option<String>,
    /// Renders per kernel and case; the median is reported.
    #[arg(long, default_value_t = 3)]
    repeats: usize,
    /// Skip the baseline kernel (it is several times slower).
    #[arg(long)]
    no_baseline: bool,
    /// Also write the results as JSON to FILE.
    #[arg(long, value_name = "FILE")]
    json: Option<std::path::PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let filters: Vec<String> = args.cases.iter().flat_map(|c| c.split(',')).map(str::to_string).collect();
    let cases: Vec<_> = perf_cases(args.quick)
        .into_iter()
        .filter(|case| filters.is_empty() || filters.iter().any(|f| case.name.contains(f.as_str())))
        .collect();
    if cases.is_empty() {
        anyhow::bail!("no case matches --cases {}", args.cases.unwrap_or_default());
    }
    let ctx = GpuContext::from_env().context("opening the Vulkan device")?;
    let renderers = PerfRenderers::new(&ctx, !args.no_baseline).context("building the renderers")?;
    let load_before = load_average();
    println!("device: {}; load average before: {}", ctx.info().name, format_load(load_before));
    println!(
        "{:<28} {:>8} {:>8} {:>8} {:>10} {:>8} {:>8} {:>10} {:>8} {:>8} {:>7} {:>7}",
        "case", "wall s", "device s", "cpu s", "eff tap/s", "base s", "base cpu", "base tap/s", "speedup", "cpu x", "dev MiB", "hostMiB"
    );
    let mut results = Vec::new();
    for case in &cases {
        let result = run_perf_case(&renderers, case, args.repeats).with_context(|| format!("case {}", case.name))?;
        print_row(&result);
        results.push(result);
    }
    let load_after = load_average();
    println!("load average after: {}", format_load(load_after));
    if let Some(path) = &args.json {
        let report = serde_json::json!({
            "device": ctx.info().name,
            "repeats": args.repeats,
            "load_average_before": load_before,
            "load_average_after": load_after,
            "results": results,
        });
        std::fs::write(path, serde_json::to_string_pretty(&report)?).with_context(|| format!("writing {}", path.display()))?;
    }
    drop(renderers);
    ctx.finish()?;
    Ok(())
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
