//! `lensblur example -o DIR`: the whole product on a built-in scene, no input files needed.
//! Ray-traces the scene's true layers and its physically defocused ground truth, renders the
//! layers with Dr.Bokeh through the same file path `lensblur render` uses, renders the
//! single-image gather baseline for comparison, and reports PSNR against the ground truth.
use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context as _;
use indicatif::{ProgressBar, ProgressStyle};
use lensblur::camera::CameraHints;
use lensblur::metrics::compare;
use lensblur::raytrace::{builtin_scene, output, render_ground_truth, TraceOptions};
use lensblur::render::{Lens, Method};
use lensblur::stack::{
    read_stack, write_image, write_png_preview, ReadOptions, SampleType, WriteOptions,
};
use lensblur::vk::Context;

use super::camera_args::CameraArgs;

#[derive(clap::Args)]
#[command(
    after_help = "Examples:\n  lensblur example -o example-out\n  lensblur example -o out --scene fairy-lights --scale 1\n\n\
Writes the ray tracer's files (layers.exr with the camera in its header, pinhole.exr, defocused.exr,\n\
camera.json, previews) and render.exr / render.png (Dr.Bokeh) and gather.png (single-image baseline)."
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
        progress: Some(bar.clone()),
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
    lensblur::bench::write_png(&sheet, &path)?;
    println!("wrote {}", path.display());
    Ok(())
}
