//! `lensblur bench single-image`: the single-image (RGB+Z) scenes, ray-traced and (with
//! --cycles) rendered by Blender Cycles, through drbokeh-auto, vdslr and gather beside the
//! OpenDefocus peer (dev/peers/opendefocus, run as a separate program): PSNR and seconds per scene.
use anyhow::Context;
use lensblur_dev::bench::cycles::{cycles_truths, CyclesSettings, CYCLES_SCENES};
use lensblur_dev::bench::{all_methods, run_single_image, scenes, select_methods, SINGLE_IMAGE_METHODS};
use lensblur::vk::Context as GpuContext;

use super::bar;

#[derive(clap::Args)]
#[command(after_help = "Examples:\n  lensblur bench single-image --quick\n  lensblur bench single-image --cycles --cycles-size 128\n  \
lensblur bench single-image --scenes thin-near --sheet single.png")]
pub struct Args {
    #[command(flatten)]
    truth: super::TruthArgs,
    /// Also the Cycles scenes (dev/scripts/cycles_scenes.py, built and rendered by Blender
    /// headless, cached under the --cache folder; a cold cache takes Blender about half an hour
    /// on 2 cores). Fails if Blender is missing.
    #[arg(long)]
    cycles: bool,
    /// Side of the Cycles renders in pixels (the CoC radii scale with it).
    #[arg(long, value_name = "PX", default_value_t = CyclesSettings::BENCH.size, requires = "cycles")]
    cycles_size: usize,
    /// Samples per pixel of the Cycles thin-lens truth; the pinhole input gets a quarter, the
    /// per-group layers a 32nd (at least 1).
    #[arg(long, value_name = "SPP", default_value_t = CyclesSettings::BENCH.truth_spp, requires = "cycles")]
    cycles_spp: u32,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let truth = &args.truth;
    truth.check_sheet()?;
    let gpu = GpuContext::from_env().context("the single-image table needs a Vulkan device")?;
    let names: Vec<String> = if truth.methods.is_empty() { SINGLE_IMAGE_METHODS.map(String::from).to_vec() } else { truth.methods.clone() };
    let methods = select_methods(all_methods(Some(&gpu))?, &names)?;
    // --scenes may name scenes of both sets; a set none of whose scenes is named is left out.
    let (cycles_names, traced_names): (Vec<String>, Vec<String>) = truth.scenes.iter().cloned().partition(|n| CYCLES_SCENES.contains(&n.as_str()));
    let mut truths = Vec::new();
    if truth.scenes.is_empty() || !traced_names.is_empty() {
        let tracing = bar("ray tracing {msg}", "rows")?;
        truths = scenes::single_image_truths(&traced_names, truth.quick, Some(tracing.clone()), truth.cache())
            .context("ray tracing the single-image scenes")?;
        tracing.finish_and_clear();
    }
    if !cycles_names.is_empty() && !args.cycles {
        anyhow::bail!("scene '{}' is a Cycles scene: add --cycles", cycles_names[0]);
    }
    if args.cycles && (truth.scenes.is_empty() || !cycles_names.is_empty()) {
        let cache = truth.cache.join("cycles");
        let settings = CyclesSettings::with_truth_spp(args.cycles_size, args.cycles_spp);
        let rendered = cycles_truths(&cycles_names, &settings, &cache, &|name| eprintln!("Blender rendered {name}"))
            .context("rendering the Cycles scenes with Blender")?;
        truths.extend(rendered);
    }
    let progress = bar("{msg}", "renders")?;
    let table = run_single_image(&truths, &methods, &progress, true)?;
    println!("{table}");
    truth.write_outputs(&truths, &table.report)?;
    drop(methods);
    gpu.finish()?;
    Ok(())
}
