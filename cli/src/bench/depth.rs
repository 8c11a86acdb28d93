//! `lensblur bench depth`: depth from defocus on the benchmark scenes (Dr.Bokeh paper Tables
//! 2-3): from a flat depth, fit each scene's true layers to its ray-traced defocused image with
//! each differentiable renderer, and report depth error and re-render PSNR before and after.
use anyhow::{bail, Context as _};
use lensblur::optim::{experiment_truths, format_results, run_experiment, ExperimentOptions, FitOptions};
use lensblur::render::drbokeh::{BackwardOptions, DrBokehGpuGrad, Model};
use lensblur::render::gausspsf::GaussPsf;
use lensblur::render::grad::Differentiable;
use lensblur::vk::Context as GpuContext;

#[derive(clap::Args)]
#[command(after_help = "Examples:\n  lensblur bench depth --scenes portrait-night,letters --iters 100\n  lensblur bench depth --renderers drbokeh,gausspsf --scale 0.5 --json out.json")]
pub struct Args {
    /// Differentiable renderers to compare: drbokeh, drbokeh-compat, gausspsf.
    #[arg(long, value_delimiter = ',', default_value = "drbokeh,gausspsf")]
    renderers: Vec<String>,
    /// Built-in scenes (default: all).
    #[arg(long, value_delimiter = ',')]
    scenes: Vec<String>,
    /// Adam iterations per scene.
    #[arg(long, default_value_t = 150)]
    iters: usize,
    /// Resolution scale of the scenes' native 256x192.
    #[arg(long, default_value_t = 0.5)]
    scale: f32,
    /// Write every scene's result as JSON.
    #[arg(long, value_name = "FILE")]
    json: Option<std::path::PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let ctx = GpuContext::from_env().context("opening the Vulkan device")?;
    let fit = FitOptions { iterations: args.iters, ..FitOptions::default() };
    let options = ExperimentOptions { scale: args.scale, fit, ..ExperimentOptions::default() };
    let truths = experiment_truths(&args.scenes, &options).context("ray tracing the scenes")?;
    let mut all = serde_json::Map::new();
    for name in &args.renderers {
        let renderer: Box<dyn Differentiable> = match name.as_str() {
            "drbokeh" => Box::new(DrBokehGpuGrad::new(&ctx, Model::DrBokeh, BackwardOptions::leaky())?),
            "drbokeh-compat" => Box::new(DrBokehGpuGrad::new(&ctx, Model::Compat, BackwardOptions::leaky())?),
            "gausspsf" => Box::new(GaussPsf::default()),
            other => bail!("unknown renderer '{other}' (drbokeh, drbokeh-compat, gausspsf)"),
        };
        let results = run_experiment(renderer.as_ref(), &truths, &options.fit, |scene, i, loss| {
            if i % 50 == 0 {
                eprintln!("{name} {scene} {i:4} loss {loss:.5}");
            }
        })?;
        println!("renderer: {name}");
        print!("{}", format_results(&results));
        let mean = |f: &dyn Fn(&lensblur::optim::SceneResult) -> f64| results.iter().map(f).sum::<f64>() / results.len().max(1) as f64;
        println!(
            "mean: |dd| {:.4} -> {:.4}, scale-invariant {:.4} -> {:.4}, CoC px {:.2} -> {:.2}, PSNR {:.2} -> {:.2} dB\n",
            mean(&|r| r.depth_before.mean_abs),
            mean(&|r| r.depth_after.mean_abs),
            mean(&|r| r.depth_before.scale_invariant),
            mean(&|r| r.depth_after.scale_invariant),
            mean(&|r| r.coc_px_before),
            mean(&|r| r.coc_px_after),
            mean(&|r| r.psnr_before),
            mean(&|r| r.psnr_after),
        );
        all.insert(name.clone(), serde_json::to_value(&results)?);
    }
    if let Some(path) = &args.json {
        std::fs::write(path, serde_json::to_string_pretty(&all)?).with_context(|| format!("writing {}", path.display()))?;
    }
    ctx.finish()?;
    Ok(())
}
