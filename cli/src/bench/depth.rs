//! `lensblur bench depth`: depth from defocus on the benchmark scenes (Dr.Bokeh paper Tables
//! 2-3): from a flat depth, fit each scene's true layers to its ray-traced defocused image with
//! each differentiable renderer, and report depth error and re-render PSNR before and after.
use anyhow::{bail, Context as _};
use lensblur::optim::{experiment_truths, format_results, run_experiment, ExperimentOptions, FitOptions};
use lensblur::render::grad::Slope;
use lensblur::render::Method;
use lensblur::vk::Context as GpuContext;

#[derive(clap::Args)]
#[command(after_help = "Examples:\n  lensblur bench depth --scenes portrait-night,letters --iters 100\n  lensblur bench depth --renderers drbokeh,gausspsf --scale 0.5 --json out.json")]
pub struct Args {
    /// Differentiable renderers to compare (methods with a backward pass, leaky soft steps as
    /// in fit-depth): drbokeh, drbokeh-compat, gausspsf.
    #[arg(long, value_delimiter = ',', default_value = "drbokeh,gausspsf")]
    renderers: Vec<Method>,
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
    if let Some(method) = args.renderers.iter().find(|m| !m.is_differentiable()) {
        bail!("{}", method.differentiable_error());
    }
    let ctx = GpuContext::from_env().context("opening the Vulkan device")?;
    let fit = FitOptions { iterations: args.iters, ..FitOptions::default() };
    let options = ExperimentOptions { scale: args.scale, fit, ..ExperimentOptions::default() };
    let truths = experiment_truths(&args.scenes, &options).context("ray tracing the scenes")?;
    let mut all = serde_json::Map::new();
    for method in &args.renderers {
        let (name, renderer) = (method.name(), method.differentiable(&ctx, Slope::Leaky)?);
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
        all.insert(name.to_string(), serde_json::to_value(&results)?);
    }
    if let Some(path) = &args.json {
        std::fs::write(path, serde_json::to_string_pretty(&all)?).with_context(|| format!("writing {}", path.display()))?;
    }
    ctx.finish()?;
    Ok(())
}
