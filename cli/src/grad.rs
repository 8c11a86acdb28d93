//! `lensblur grad STACK.exr --grad-output DL_DB.exr -o GRADS.exr`: the backward pass on files.
//! The three files keep these names in the help, examples and errors (one name per file:
//! `--grad-output` is an input, dL/dB, despite its flag). GRADS has the channel names of STACK,
//! each holding dL/d(that channel as stored): colour and alpha directly (premultiplied, as stored), depth through the file's depth convention; channels
//! that do not reach the render (unselected layers, passes) are zero. The camera gradients are
//! printed (and in `--json`).
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context as _};
use lensblur::image::Image;
use lensblur::render::drbokeh::RenderOptions;
use lensblur::render::grad::{CameraGradients, Slope};
use lensblur::render::{InputKind, Method};
use lensblur::stack::{read_rgba, write_named_channels, OutputFormat};
use lensblur::vk::Context;

use super::camera_args::CameraArgs;
use super::input_args::{check_output_paths, input_files, InputArgs, LoadedInput};
use super::progress;

const EXAMPLES: &str = "\
Examples:
  lensblur grad shot.exr --grad-output dL_dB.exr -o grads.exr --focal-length 50 --fstop 2 --focus-distance 3
  lensblur grad shot.exr --grad-output dL_dB.exr -o grads.exr --blur 30 --focus-disparity 0.4 --leaky --json

STACK.exr is the layered input. DL_DB.exr (--grad-output, an input) holds dL/dB, the gradient of the
loss with respect to the rendered image B, in its R,G,B channels (same size as STACK.exr; alpha is not
differentiated). GRADS.exr (-o, the output) has STACK.exr's channel names: dL/dR,G,B,A of each layer as stored
(premultiplied), dL/dZ through the depth convention (--depth-kind), zero for channels that do not
reach the render (depth where alpha is 0 is filled from the covered pixels when the file is read, so
its gradient lands on those). Multi-part inputs are written single-part as <part>.<channel>.
Printed: dL/dK and dL/d(focus disparity); with a physical camera also dL/d(focus distance),
dL/d(f-stop) and dL/d(focal length).";

#[derive(clap::Args)]
#[command(after_help = EXAMPLES)]
pub struct Args {
    /// Layered EXR (the stack to differentiate).
    #[arg(value_name = "STACK.exr")]
    pub input: PathBuf,
    /// Input: EXR holding dL/dB, the loss gradient of the rendered image B, in R,G,B.
    #[arg(long, value_name = "DL_DB.exr")]
    pub grad_output: PathBuf,
    /// Output: EXR of gradients, named after STACK.exr's channels.
    #[arg(short, long, value_name = "GRADS.exr")]
    pub output: PathBuf,
    #[command(flatten)]
    pub input_args: InputArgs,
    #[command(flatten)]
    pub camera: CameraArgs,
    /// A method with a backward pass: drbokeh, drbokeh-compat or gausspsf (CPU).
    #[arg(long, default_value = "drbokeh")]
    pub method: Method,
    /// Leaky soft step: the scatter edge keeps a small slope so far-away sources still get
    /// depth gradients (for optimisation; off = the exact gradient of the render).
    #[arg(long)]
    pub leaky: bool,
    /// Frame tile side in pixels (default: the largest the device's limits and memory allow).
    #[arg(long, value_name = "N")]
    pub tile: Option<usize>,
    /// Most memory the backward may hold, host and device together: SIZE in bytes or with K,
    /// M, G (e.g. 512M, 2G). Default: as for `render`.
    #[arg(long, value_name = "SIZE", value_parser = super::render::parse_size)]
    pub max_memory: Option<u64>,
    /// Print a JSON report on stdout.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let start = Instant::now();
    let mut inputs = input_files(&args.input, &args.input_args, &args.camera);
    inputs.push(("the --grad-output input file (dL/dB)", &args.grad_output));
    // An output on an input is the graver mistake: said first.
    check_output_paths(&[("-o", &args.output)], &inputs)?;
    OutputFormat::for_output(&args.output, "-o", OutputFormat::EXR)?;
    // Refused before any work: a method without a backward pass.
    if !args.method.is_differentiable() {
        bail!("{}", args.method.differentiable_error());
    }
    let spinner = progress::spinner(args.json);
    spinner.set_message(format!("reading {}", args.input.display()));
    // No auto-layering: gradients must map back onto the file's own channels.
    args.input_args.require_channel_stack(&args.input, "grad writes its gradients")?;
    let loaded = args.input_args.load(&args.input, &args.camera, InputKind::SingleImage)?;
    let Some(info) = &loaded.info else { bail!("{}: grad needs an EXR stack", args.input.display()) };
    let grad_output = read_grad_output(&args.grad_output, &loaded, args.input_args.max_pixels)?;
    let ctx = Context::from_env().context("opening the Vulkan device")?;
    let renderer = args.method.differentiable(&ctx, if args.leaky { Slope::Leaky } else { Slope::Exact })?;
    let what = format!("differentiating {} layer(s) with {}", loaded.stack.layers.len(), args.method);
    let tile_progress = progress::tiles(&spinner, what, 1);
    let tiling = RenderOptions {
        tile: args.tile,
        max_memory: args.max_memory,
        progress: Some(&tile_progress),
        ..RenderOptions::default()
    };
    let (grads, stats) = renderer.backward_with(&loaded.stack, &loaded.camera.lens, &grad_output, &tiling)?;
    drop(renderer);
    // Teardown validated before the file appears: a validation error leaves no output.
    ctx.finish()?;
    spinner.set_message(format!("writing {}", args.output.display()));
    let channels = loaded.gradient_channels(&grads)?;
    let origin = (info.display_window.x, info.display_window.y);
    write_named_channels(&args.output, (loaded.stack.width, loaded.stack.height), origin, channels)
        .context("writing -o")?;
    spinner.finish_and_clear();
    let camera = CameraGradients::new(&grads, &loaded.camera.lens.coc, loaded.camera.physical.as_ref());
    if args.json {
        let report = serde_json::json!({
            "input": args.input, "output": args.output, "method": args.method, "leaky": args.leaky,
            "layers": loaded.stack.layers.iter().map(|l| &l.name).collect::<Vec<_>>(),
            "camera_gradients": camera, "seconds": start.elapsed().as_secs_f64(),
            "tiles": stats.tiles, "tile_size": stats.tile_size, "peak_device_bytes": stats.peak_device_bytes,
        });
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!("dL/dK = {:.6e}  dL/d(focus disparity) = {:.6e}", camera.k_px, camera.focus_disparity);
        if let (Some(d), Some(n), Some(f)) = (camera.focus_distance, camera.fstop, camera.focal_length_mm) {
            println!("dL/d(focus distance) = {d:.6e}  dL/d(f-stop) = {n:.6e}  dL/d(focal length mm) = {f:.6e}");
        }
        println!("wrote {} ({:.2} s)", args.output.display(), start.elapsed().as_secs_f64());
    }
    Ok(())
}

fn read_grad_output(path: &Path, loaded: &LoadedInput, max_pixels: u64) -> anyhow::Result<Image> {
    let mut g = read_rgba(path, None, max_pixels).context("--grad-output")?;
    if (g.width, g.height) != (loaded.stack.width, loaded.stack.height) {
        bail!(
            "{}: --grad-output (dL/dB) is {}x{} but the stack is {}x{}",
            path.display(),
            g.width,
            g.height,
            loaded.stack.width,
            loaded.stack.height
        );
    }
    for p in &mut g.pixels {
        p[3] = 0.0; // alpha of the render is not differentiated
    }
    Ok(g)
}
