//! `lensblur bench single-image`: the single-image (RGB+Z) scenes, ray-traced and (with
//! --cycles) rendered by Blender Cycles, through drbokeh-auto, vdslr and gather beside the
//! OpenDefocus peer (dev/peers/opendefocus, run as a separate program): PSNR and seconds per scene.
use anyhow::Context;
use lensblur_dev::bench::cycles::{cycles_truths, is_cycles_scene, split_scenes, CyclesSettings};
use lensblur_dev::bench::{all_methods, run_single_image, scenes, select_methods, SINGLE_IMAGE_METHODS};
use lensblur::raytrace::GroundTruth;
use lensblur::vk::Context as GpuContext;

use super::bar;

#[derive(clap::Args)]
#[command(after_help = "Examples:\n  lensblur bench single-image --quick\n  lensblur bench single-image --cycles --cycles-size 128\n  \
lensblur bench single-image --scenes thin-near --sheet single.png\n  \
lensblur bench single-image --cycles --split dev --cycles-size 256 --cycles-spp 256 --without-blender")]
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
    /// Only the procedural Cycles scenes of one split (issue 46): `dev` to tune on, `test` to
    /// score a candidate one would ship (never while tuning).
    #[arg(long, value_name = "SPLIT", value_parser = ["dev", "test"], requires = "cycles", conflicts_with = "scenes")]
    split: Option<String>,
    /// How many scenes of --split (each family appears every 6 scenes).
    #[arg(long, value_name = "N", default_value_t = 24, requires = "split")]
    split_size: usize,
    /// Index of the first scene of --split; with --split-step 6, scenes of one family (the
    /// family is the index modulo 6: 2 for silhouettes), e.g. `--split dev --split-start 122
    /// --split-step 6 --split-size 20`, the silhouettes dev-122 to dev-236.
    #[arg(long, value_name = "N", default_value_t = 0, requires = "split")]
    split_start: usize,
    /// Step between the indices of --split's scenes.
    #[arg(long, value_name = "K", default_value_t = 1, value_parser = clap::value_parser!(u16).range(1..), requires = "split")]
    split_step: u16,
    /// Only render the scenes into the cache (no method runs, nothing scored): a test split can
    /// be rendered while tuning on the dev split without being looked at.
    #[arg(long)]
    render_only: bool,
    /// Leave out Blender's Defocus node columns (a Blender process per scene and node).
    #[arg(long)]
    without_blender: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let truth = &args.truth;
    truth.check_sheet()?;
    if args.render_only {
        // Rendering needs Blender only: no device, no method.
        let truths = truths(&args)?;
        eprintln!("{} scenes rendered into the cache; nothing scored (--render-only)", truths.len());
        return Ok(());
    }
    let gpu = GpuContext::from_env().context("the single-image table needs a Vulkan device")?;
    let names: Vec<String> = if truth.methods.is_empty() { SINGLE_IMAGE_METHODS.map(String::from).to_vec() } else { truth.methods.clone() };
    let methods = select_methods(all_methods(Some(&gpu))?, &names)?;
    let truths = truths(&args)?;
    let progress = bar("{msg}", "renders")?;
    let table = run_single_image(&truths, &methods, &progress, !args.without_blender)?;
    println!("{table}");
    truth.write_outputs(&truths, &table.report)?;
    drop(methods);
    gpu.finish()?;
    Ok(())
}

/// The scenes asked for: ray traced, and with --cycles rendered by Blender (both cached).
fn truths(args: &Args) -> anyhow::Result<Vec<GroundTruth>> {
    let truth = &args.truth;
    // --scenes may name scenes of both sets; a set none of whose scenes is named is left out.
    let (cycles_names, traced_names): (Vec<String>, Vec<String>) = match &args.split {
        Some(split) => (split_scenes(split, args.split_start, usize::from(args.split_step), args.split_size), Vec::new()),
        None => truth.scenes.iter().cloned().partition(|n| is_cycles_scene(n)),
    };
    let mut truths = Vec::new();
    if args.split.is_none() && (truth.scenes.is_empty() || !traced_names.is_empty()) {
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
    Ok(truths)
}
