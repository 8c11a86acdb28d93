//! `lensblur bench quality`: ray-traces the built-in scenes, renders each with every registered method
//! from the inputs it is entitled to, and scores it against the thin-lens ground truth.
use anyhow::Context;
use lensblur_dev::bench::{all_methods, cpu_methods, run_with_progress, scenes, select_methods};
use lensblur::vk::Context as GpuContext;

use super::bar;

#[derive(clap::Args)]
#[command(after_help = "Examples:\n  lensblur bench quality --quick\n  lensblur bench quality --methods oracle,scatter --scenes fence,branches\n  \
lensblur bench quality --json out/bench.json --sheet out/bench.png\n\n\
Prints one table: a row per method, a column per metric, 'mean (worst scene)'. Metrics are computed on\n\
sRGB-encoded RGB composited over black and clipped to [0,1] (RMSE, scale-invariant RMSE, PSNR,\n\
SSIM 11x11 sigma 1.5 averaged over R,G,B, ZNCC); time is the render alone.\n\
The sheet has two rows per scene: pinhole input, ground truth and each method's render (PSNR in\n\
the corner); then the pinhole disparity (white = near), the error colour scale, and each method's\n\
absolute error (black = 0; the scale is printed on the legend tile).")]
pub struct Args {
    #[command(flatten)]
    pub truth: super::TruthArgs,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let args = &args.truth;
    args.check_sheet()?;
    let gpu = open_device_or_warn(&args.methods)?;
    let methods = select_methods(all_methods(gpu.as_ref())?, &args.methods)?;
    let tracing = bar("ray tracing {msg}", "rows")?;
    let truths = scenes::ground_truths(&args.scenes, args.quick, Some(tracing.clone()), args.cache()).context("ray tracing the scenes")?;
    tracing.finish_and_clear();
    let progress = bar("{msg}", "renders")?;
    let report = run_with_progress(&truths, &methods, &progress)?;
    println!("{report}");
    args.write_outputs(&truths, &report)?;
    drop(methods);
    if let Some(gpu) = gpu {
        gpu.finish()?;
    }
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
