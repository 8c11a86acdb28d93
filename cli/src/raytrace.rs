//! `lensblur raytrace`: renders a built-in scene's ground truth (pinhole, true layers,
//! thin-lens defocus) and writes it as EXR + JSON + PNG previews.
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context};
use indicatif::{ProgressBar, ProgressStyle};
use lensblur::raytrace::{builtin_scene, builtin_scenes, output, render_ground_truth, Scene, TraceOptions};

use super::progress;

#[derive(clap::Args)]
#[command(after_help = "Examples:\n  lensblur raytrace --list\n  lensblur raytrace fence -o out/fence\n  lensblur raytrace all -o out/truth --samples 8 --scale 0.5\n\n\
Writes pinhole.exr (R,G,B,A,Z), layers.exr (<Layer>.Combined.R/G/B/A + <Layer>.Depth.Z, Z = 1e10 where empty),\n\
defocused.exr, camera.json and sRGB previews pinhole.png / defocused.png. Depth is planar Z in metres.")]
pub struct Args {
    /// Built-in scene name, or `all` (each scene goes to its own sub-folder of the output).
    scene: Option<String>,
    /// Output folder.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Samples per pixel axis: a round is N x N stratified pixel x lens rays per pixel.
    #[arg(long, default_value_t = 8)]
    samples: usize,
    /// Resolution scale of the scene's native size (CoC radii in pixels scale with it).
    #[arg(long, default_value_t = 1.0)]
    scale: f32,
    /// Seed of the per-pixel sample streams (equal seeds give identical images).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Rounds of N x N rays every pixel takes (the pinhole image and layers use them too).
    #[arg(long, default_value_t = 4)]
    min_rounds: usize,
    /// Most rounds a pixel may take while its error is above the tolerance (1 = one round).
    #[arg(long, default_value_t = 64)]
    max_rounds: usize,
    /// Target standard error of a defocused pixel, in sRGB display units (0.002 = half an 8-bit step).
    #[arg(long, default_value_t = 0.002)]
    tolerance: f32,
    /// List the built-in scenes with their size and CoC range, then exit.
    #[arg(long)]
    list: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if args.list {
        return list(args.scale);
    }
    let (Some(name), Some(output)) = (args.scene.as_deref(), args.output.as_ref()) else {
        bail!("give a scene name (or `all`) and -o DIR; see `lensblur raytrace --list`");
    };
    let scenes = if name == "all" { builtin_scenes() } else { vec![builtin_scene(name)?] };
    for scene in &scenes {
        let dir = if name == "all" { output.join(&scene.name) } else { output.clone() };
        render_one(scene, &args, dir)?;
    }
    Ok(())
}

fn render_one(scene: &Scene, args: &Args, dir: PathBuf) -> anyhow::Result<()> {
    let bar = ProgressBar::new(0).with_message(scene.name.clone());
    bar.set_style(ProgressStyle::with_template("{msg:>14} [{bar:40}] {pos}/{len} rows {elapsed}").unwrap_or_else(|_| ProgressStyle::default_bar()));
    let options = TraceOptions { samples_per_axis: args.samples, scale: args.scale, seed: args.seed, min_rounds: args.min_rounds, max_rounds: args.max_rounds, tolerance: args.tolerance, progress: Some(progress::rows(&bar)) };
    let start = Instant::now();
    let truth = render_ground_truth(scene, &options).with_context(|| format!("rendering scene '{}'", scene.name))?;
    bar.finish_and_clear();
    let files = output::write_ground_truth(&truth, &dir).with_context(|| format!("writing '{}'", dir.display()))?;
    println!(
        "{}: {}x{}, {} to {} rays/pixel, {:.2} s -> {} files in {}",
        scene.name,
        truth.pinhole.width,
        truth.pinhole.height,
        args.samples * args.samples * args.min_rounds.min(args.max_rounds),
        args.samples * args.samples * args.max_rounds,
        start.elapsed().as_secs_f64(),
        files.len(),
        dir.display()
    );
    Ok(())
}

fn list(scale: f32) -> anyhow::Result<()> {
    println!("{:<16} {:>9} {:>6} {:>13}  description", "scene", "size", "layers", "CoC px");
    for scene in builtin_scenes() {
        let (w, h) = scene.size(scale);
        let (lo, hi) = scene.coc_range_px(w, h)?;
        let size = format!("{w}x{h}");
        println!("{:<16} {:>9} {:>6} {:>5.1} - {:>5.1}  {}", scene.name, size, scene.surfaces.len(), lo, hi, scene.description);
    }
    Ok(())
}

