//! `lensblur example -o DIR`: the whole product on a built-in scene, no input files needed.
//! Ray-traces the scene's true layers and its physically defocused ground truth, renders the
//! layers with Dr.Bokeh through the same file path `lensblur render` uses, renders the
//! single-image gather baseline for comparison, and reports PSNR against the ground truth.
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context as _;
use indicatif::{ProgressBar, ProgressStyle};
use lensblur::camera::{CameraHints, PhysicalCamera};
use lensblur::metrics::compare;
use lensblur::raytrace::{builtin_scene, output, render_ground_truth, TraceOptions};
use lensblur::render::{Lens, Method};
use lensblur::sequence::CameraFile;
use lensblur::stack::{
    read_stack, write_image, write_png_preview, write_stack, Layer, LayerStack, ReadOptions, SampleType,
    StackWriteOptions, WriteOptions,
};
use lensblur::vk::Context;

use super::camera_args::CameraArgs;
use super::progress;

#[derive(clap::Args)]
#[command(
    after_help = "Examples:\n  lensblur example -o example-out\n  lensblur example -o out --scene fairy-lights --scale 1\n\n\
Writes the ray tracer's files (layers.exr with the camera in its header, pinhole.exr, defocused.exr,\n\
camera.json, previews) and render.exr / render.png (Dr.Bokeh) and gather.png (single-image baseline),\n\
and a focus-pull shot: shot/layers.1001-1006.exr with shot/camera.json (lensblur render --frames)."
)]
pub struct Args {
    /// Output folder.
    #[arg(short, long)]
    output: PathBuf,
    /// Built-in scene (see `lensblur raytrace --list`).
    #[arg(long, default_value = "branches")]
    scene: String,
    /// Resolution scale of the scene's native 256x192 (CoC radii scale with it).
    #[arg(long, default_value_t = 1.0)]
    scale: f32,
    /// Ground-truth rays per pixel axis (N x N per round).
    #[arg(long, default_value_t = 8)]
    samples: usize,
    /// Instead: write the lens-character contact sheet (each aperture and artist control on a
    /// procedural bokeh scene) as DIR/lens-character.png.
    #[arg(long)]
    lens_character: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if args.lens_character {
        return lens_character(&args.output);
    }
    let scene = builtin_scene(&args.scene)?;
    let bar = ProgressBar::new(0).with_message(format!("ray-tracing {}", scene.name));
    bar.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} rows {elapsed}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let options = TraceOptions {
        samples_per_axis: args.samples,
        scale: args.scale,
        progress: Some(progress::rows(&bar)),
        ..TraceOptions::default()
    };
    let start = Instant::now();
    let truth = render_ground_truth(&scene, &options)
        .with_context(|| format!("ray-tracing scene '{}'", scene.name))?;
    bar.finish_and_clear();
    output::write_ground_truth(&truth, &args.output)
        .context("writing the scene's files")?;
    println!(
        "ray-traced '{}' ({}x{}) in {:.1} s -> {}",
        scene.name,
        truth.pinhole.width,
        truth.pinhole.height,
        start.elapsed().as_secs_f64(),
        args.output.display()
    );

    // Read the stack back from the file, camera from its header: the path a user's file takes.
    let layers_path = args.output.join("layers.exr");
    let file = read_stack(&layers_path, &ReadOptions::default())?;
    let hints = CameraHints::from_attributes(&file.info.camera);
    let camera = CameraArgs::default().resolve(file.stack.width, &hints)?;
    let ctx = Context::from_env().context("opening the Vulkan device")?;
    println!("device: {}", ctx.info().name);
    let render_path = args.output.join("render.exr");
    let mut renders = Vec::new();
    for (method, png) in [(Method::DrBokeh, "render.png"), (Method::Gather, "gather.png")] {
        let start = Instant::now();
        let image = method.render(Some(&ctx), &file.stack, &camera.lens)?;
        renders.push((method, png, image, start.elapsed().as_secs_f64()));
    }
    // Teardown validated before the renders are written: a validation error leaves none.
    ctx.finish()?;
    for (method, png, image, seconds) in renders {
        if method == Method::DrBokeh {
            let options = WriteOptions {
                sample_type: SampleType::Float,
                camera: camera.physical,
                ..WriteOptions::default()
            };
            write_image(&render_path, &image, &options)?;
        }
        write_png_preview(&args.output.join(png), &image)?;
        let metrics = compare(&image, &truth.defocused)?;
        println!(
            "{:<8} {:>6.2} dB PSNR, SSIM {:.4} vs ground truth ({:.2} s) -> {png}",
            method.name(),
            metrics.psnr,
            metrics.ssim,
            seconds
        );
    }
    report_lens(&camera.lens);
    if let Some(physical) = &camera.physical {
        write_focus_pull(&args.output.join("shot"), &file.stack, physical).context("writing the focus-pull shot")?;
    }
    // Named as this process was started (`target/release/lensblur` under `cargo run`, `lensblur`
    // once installed), so the line runs as printed wherever lensblur is not on PATH yet.
    let program = std::env::args().next().unwrap_or_else(|| "lensblur".into());
    println!(
        "same render from the command line: {program} render {} -o {}",
        layers_path.display(),
        render_path.display()
    );
    Ok(())
}

/// Frames of the focus pull the README renders as a shot.
const PULL_FRAMES: std::ops::RangeInclusive<i64> = 1001..=1006;

/// A focus pull on the example, for the book's shots page: the layers as frames
/// 1001-1006 of `dir/layers.####.exr` with no camera in their headers (a locked-off shot), and
/// `dir/camera.json`, the camera file pulling focus from the front layer to the back one.
fn write_focus_pull(dir: &Path, stack: &LayerStack, camera: &PhysicalCamera) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    // Mean covered disparity (1/z) of a layer, as a distance.
    let distance = |layer: &Layer| {
        let covered = layer.rgba.pixels.iter().zip(&layer.disparity).filter(|(p, &d)| p[3] > 0.5 && d > 0.0);
        let (sum, count) = covered.fold((0.0f64, 0usize), |(s, n), (_, &d)| (s + f64::from(d), n + 1));
        if count == 0 { camera.focus_distance } else { (count as f64 / sum) as f32 }
    };
    let (near, far) = match (stack.layers.first(), stack.layers.last()) {
        (Some(front), Some(back)) => (distance(front), distance(back)),
        _ => (camera.focus_distance, camera.focus_distance),
    };
    let last = (PULL_FRAMES.end() - PULL_FRAMES.start()) as f32;
    let mut cameras = Vec::new();
    for frame in PULL_FRAMES {
        let t = (frame - PULL_FRAMES.start()) as f32 / last;
        // Even steps in 1/z, as a focus puller's marks look in defocus.
        let focus_distance = 1.0 / ((1.0 - t) / near + t / far);
        cameras.push((frame, PhysicalCamera { focus_distance, ..*camera }));
        write_stack(&dir.join(format!("layers.{frame}.exr")), stack, &StackWriteOptions::default())?;
    }
    CameraFile::write(&dir.join("camera.json"), &cameras)?;
    Ok(())
}

fn report_lens(lens: &Lens) {
    println!(
        "lens: K = {:.1} px per unit disparity, focus disparity {:.3}",
        lens.coc.k_px, lens.coc.focus_disparity
    );
}

fn lens_character(dir: &std::path::Path) -> anyhow::Result<()> {
    let ctx = Context::from_env().context("opening the Vulkan device")?;
    let sheet = lensblur::character::sheet::character_sheet(&ctx)?;
    ctx.finish()?;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let path = dir.join("lens-character.png");
    lensblur_dev::bench::write_png(&sheet, &path)?;
    println!("wrote {}", path.display());
    Ok(())
}
