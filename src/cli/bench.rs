//! `lensblur bench`: ray-traces the built-in scenes, renders each with every registered method
//! from the inputs it is entitled to, and scores it against the thin-lens ground truth.
use std::path::PathBuf;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use lensblur::bench::cycles::{cycles_truths, CyclesSettings, CYCLES_SCENES};
use lensblur::bench::{all_methods, contact_sheet, cpu_methods, run_single_image, run_with_progress, scenes, select_methods, write_png, HEAT_MAX, SINGLE_IMAGE_METHODS};
use lensblur::vk::Context as GpuContext;

#[derive(clap::Args)]
#[command(after_help = "Examples:\n  lensblur bench --quick\n  lensblur bench --methods oracle,scatter --scenes fence,branches\n  \
lensblur bench --json out/bench.json --sheet out/bench.png\n  lensblur bench --perf --quick --json perf.json\n\n\
Prints one table: a row per method, a column per metric, 'mean (worst scene)'. Metrics are computed on\n\
sRGB-encoded RGB composited over black and clipped to [0,1] (RMSE, scale-invariant RMSE, PSNR,\n\
SSIM 11x11 sigma 1.5 averaged over R,G,B, ZNCC); time is the render alone.\n\
The sheet has two rows per scene: pinhole input, ground truth and each method's render (PSNR in\n\
the corner); then the pinhole disparity (white = near), the error colour scale, and each method's\n\
absolute error (black = 0; the scale is printed on the legend tile).")]
pub struct Args {
    /// Half resolution and a looser ground-truth tolerance: ranks the methods in a few minutes
    /// with a cold cache, seconds with a warm one.
    #[arg(long)]
    quick: bool,
    /// Folder caching the ray-traced ground truths (keyed by scene and sampling options); by
    /// default in the user cache folder ($XDG_CACHE_HOME/lensblur, else ~/.cache/lensblur),
    /// whichever folder the command runs in.
    #[arg(long, value_name = "DIR", default_value_os_t = lensblur::cache_dir::cache_subdir("gt-cache"))]
    cache: PathBuf,
    /// Always ray-trace the ground truth; neither read nor write the cache.
    #[arg(long)]
    no_cache: bool,
    /// Comma-separated methods to run (default: all registered).
    #[arg(long, value_delimiter = ',')]
    methods: Vec<String>,
    /// Comma-separated built-in scenes (default: all; see `lensblur raytrace --list`).
    #[arg(long, value_delimiter = ',')]
    scenes: Vec<String>,
    /// Write the full report (every scene x method, summaries) as JSON.
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
    /// Write a labelled contact sheet of all renders and error maps as PNG.
    #[arg(long, value_name = "FILE.png")]
    sheet: Option<PathBuf>,
    /// Run the performance suite instead (the same as `lensblur bench-perf`): kernel,
    /// backward, end-to-end and Blender case groups; see --groups.
    #[arg(long)]
    perf: bool,
    /// The single-image table instead: the single-image scenes, drbokeh-auto, vdslr and gather
    /// beside the OpenDefocus peer (peers/opendefocus, run as a separate program), PSNR and
    /// seconds per scene.
    #[arg(long)]
    single_image: bool,
    /// With --single-image: also the Cycles scenes (src/bench/cycles_scenes.py, built and
    /// rendered by Blender headless, cached under the --cache folder; a cold cache takes
    /// Blender about half an hour on 2 cores). Fails if Blender is missing.
    #[arg(long, requires = "single_image")]
    cycles: bool,
    /// Side of the Cycles renders in pixels (the CoC radii scale with it).
    #[arg(long, value_name = "PX", default_value_t = CyclesSettings::BENCH.size, requires = "cycles")]
    cycles_size: usize,
    /// Samples per pixel of the Cycles thin-lens truth; the pinhole input gets a quarter, the
    /// per-group layers a 32nd (at least 1).
    #[arg(long, value_name = "SPP", default_value_t = CyclesSettings::BENCH.truth_spp, requires = "cycles")]
    cycles_spp: u32,
    #[command(flatten, next_help_heading = "Performance (with --perf)")]
    perf_flags: super::bench_perf::PerfFlags,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if args.perf {
        return super::bench_perf::run_suite(args.quick, args.json.as_deref(), &args.perf_flags);
    }
    // Refused before minutes of ray tracing, like render's outputs: the sheet is a PNG.
    if let Some(sheet) = &args.sheet {
        lensblur::stack::OutputFormat::for_output(sheet, "--sheet", &[lensblur::stack::OutputFormat::Png])?;
    }
    if args.single_image {
        return run_single_image_table(args);
    }
    let gpu = open_device_or_warn(&args.methods)?;
    let methods = select_methods(all_methods(gpu.as_ref())?, &args.methods)?;
    let tracing = bar("ray tracing {msg}", "rows")?;
    let truths = scenes::ground_truths(&args.scenes, args.quick, Some(tracing.clone()), (!args.no_cache).then_some(args.cache.as_path())).context("ray tracing the scenes")?;
    tracing.finish_and_clear();
    let progress = bar("{msg}", "renders")?;
    let report = run_with_progress(&truths, &methods, &progress)?;
    println!("{report}");
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&report)?;
        std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
        eprintln!("wrote {}", path.display());
    }
    if let Some(path) = &args.sheet {
        write_png(&contact_sheet(&truths, &report)?, path)?;
        eprintln!("wrote {} (error scale: 0 to {HEAT_MAX} in display values)", path.display());
    }
    drop(methods);
    if let Some(gpu) = gpu {
        gpu.finish()?;
    }
    Ok(())
}

fn run_single_image_table(args: Args) -> anyhow::Result<()> {
    let gpu = GpuContext::from_env().context("the single-image table needs a Vulkan device")?;
    let names: Vec<String> = if args.methods.is_empty() { SINGLE_IMAGE_METHODS.map(String::from).to_vec() } else { args.methods.clone() };
    let methods = select_methods(all_methods(Some(&gpu))?, &names)?;
    // --scenes may name scenes of both sets; a set none of whose scenes is named is left out.
    let (cycles_names, traced_names): (Vec<String>, Vec<String>) = args.scenes.iter().cloned().partition(|n| CYCLES_SCENES.contains(&n.as_str()));
    let mut truths = Vec::new();
    if args.scenes.is_empty() || !traced_names.is_empty() {
        let tracing = bar("ray tracing {msg}", "rows")?;
        truths = scenes::single_image_truths(&traced_names, args.quick, Some(tracing.clone()), (!args.no_cache).then_some(args.cache.as_path()))
            .context("ray tracing the single-image scenes")?;
        tracing.finish_and_clear();
    }
    if !cycles_names.is_empty() && !args.cycles {
        anyhow::bail!("scene '{}' is a Cycles scene: add --cycles", cycles_names[0]);
    }
    if args.cycles && (args.scenes.is_empty() || !cycles_names.is_empty()) {
        let cache = args.cache.join("cycles");
        let settings = CyclesSettings::with_truth_spp(args.cycles_size, args.cycles_spp);
        let rendered = cycles_truths(&cycles_names, &settings, &cache, &|name| eprintln!("Blender rendered {name}"))
            .context("rendering the Cycles scenes with Blender")?;
        truths.extend(rendered);
    }
    let progress = bar("{msg}", "renders")?;
    let table = run_single_image(&truths, &methods, &progress, true)?;
    println!("{table}");
    if let Some(path) = &args.json {
        std::fs::write(path, serde_json::to_string_pretty(&table.report)?).with_context(|| format!("writing {}", path.display()))?;
        eprintln!("wrote {}", path.display());
    }
    if let Some(path) = &args.sheet {
        write_png(&contact_sheet(&truths, &table.report)?, path)?;
        eprintln!("wrote {} (error scale: 0 to {HEAT_MAX} in display values)", path.display());
    }
    drop(methods);
    gpu.finish()?;
    Ok(())
}

/// The Vulkan device, or None (with a warning) when none opens and every requested method
/// has a CPU reference: the CPU references alone still rank against the ground truth.
fn open_device_or_warn(requested: &[String]) -> anyhow::Result<Option<GpuContext>> {
    let error = match GpuContext::from_env() {
        Ok(ctx) => return Ok(Some(ctx)),
        Err(error) => error,
    };
    let cpu: Vec<&str> = cpu_methods().iter().map(|m| m.name).collect();
    if let Some(name) = requested.iter().find(|n| !cpu.contains(&n.as_str())) {
        return Err(anyhow::Error::new(error)
            .context(format!("method '{name}' needs a Vulkan device (without one, only {} run)", cpu.join(", "))));
    }
    eprintln!("lensblur: warning: no Vulkan device ({error}); running only the CPU methods: {}", cpu.join(", "));
    Ok(None)
}

fn bar(prefix: &str, unit: &str) -> anyhow::Result<ProgressBar> {
    let template = format!("{{bar:30}} {{pos}}/{{len}} {unit} [{{elapsed}}] {prefix}");
    let style = ProgressStyle::with_template(&template).context("progress bar template")?;
    Ok(ProgressBar::new(0).with_style(style))
}
