//! `lensblur render FILE -o OUT`: read a stack, render it with one method, write the result.
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use indicatif::ProgressBar;
use lensblur::camera::CameraHints;
use lensblur::image::Image;
use lensblur::input::SourceKind;
use lensblur::job::{JobSpec, RenderJob, Rendered};
use lensblur::render::{Lens, Method};
use lensblur::sequence::FramePattern;
use lensblur::stack::{
    write_image, write_ldr, LayerStack, OutputFormat, SampleType, StackNaming, WriteOptions,
};
use lensblur::render::placement::{CpuReason, DevicePreference, Placement};
use lensblur::vk::{Context, ContextOptions};

use super::camera_args::CameraArgs;
use super::character_args::CharacterArgs;
use super::input_args::{check_output_collisions, check_output_paths, input_files, warn, InputArgs, LoadedInput};
use super::method_args::MethodArgs;
use super::progress;
use super::words::job_error;

const EXAMPLES: &str = "\
Examples:
  lensblur render shot.exr -o blurred.exr --focal-length 50 --fstop 1.4 --focus-distance 3
  lensblur render shot.exr -o blurred.exr --layers 'fg*,bg' --aperture polygon:6:rotation=15
  lensblur render shot.exr -o comp.exr --output-layer Defocus --keep-channels --half
  lensblur render photo.jpg --depth depth.png -o out.jpg --blur 40 --focus-disparity 0.7
  lensblur render shot.exr -o tilt.exr --method vdslr --tilt-shift 0,-8 --samples 512
  lensblur render shot.exr -o two.exr --method vdslr --focal-length 50 --fstop 2 --focal-planes 1.5,6
  lensblur render example-out/layers.exr -o out.exr --json      (camera read from the header)
  lensblur render shot.####.exr -o out/defocus.####.exr --frames 1001-1100 --camera-file shot.json
  lensblur render shot.%04d.exr -o out/defocus.%04d.exr --frames 1-99:2,100 --skip-existing

Input: Blender multilayer EXR (<ViewLayer>.Combined.RGBA + <ViewLayer>.Depth.Z), OpenEXR/OIIO/Nuke
layer.R,G,B,A,Z, multi-part (one layer per part), plain R,G,B,A,Z; or PNG/JPEG + --depth. A file
holding one image is split into layers automatically for layered methods (one layer picked out of a
stack with --layers is not). Output: EXR (plain R,G,B,A, linear, premultiplied, on the input's display
window; --output-layer names it in the input's convention) or, for .png/.jpg/.jpeg, 8-bit sRGB; the
extension picks the format and any other is refused. Files appear atomically; the input is never
overwritten.

Sequences: with --frames (an Open Job Description range expression: 1001-1100, 1-99:2, 1,5,9 or a
comma-separated mix, as a farm hands a chunk to a task), the input and -o are frame patterns (#### or
%04d: the frame number, zero-padded to the width) and one process renders every frame on one device.
Each frame's camera comes from the flags, else its EXR header, else --camera-file. A frame that fails
does not stop the others; the exit status is 1 if any failed, and the failed frames are named.";

#[derive(clap::Args)]
#[command(after_help = EXAMPLES)]
pub struct Args {
    /// Layered EXR, or PNG/JPEG with --depth; with --frames, a frame pattern (shot.####.exr).
    pub input: PathBuf,
    /// Output file: .exr (linear float) or .png/.jpg/.jpeg (8-bit sRGB), by its extension;
    /// any other extension is refused. With --frames, a frame pattern (out.####.exr).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Render a sequence: these frames of the input pattern (1001-1100, 1-99:2, 1,5,9, ...).
    #[arg(long, value_name = "RANGE", help_heading = "Sequence")]
    pub frames: Option<String>,
    /// Per-frame camera of the shot, for frames whose header has none:
    /// {"frames": {"1001": {"focal_length_mm": 85, "sensor_width_mm": 36, "fstop": 1.8,
    /// "focus_distance": 1.2}, ...}}. Flags still win; a frame it lacks is an error.
    #[arg(long, value_name = "FILE.json", requires = "frames", help_heading = "Sequence")]
    pub camera_file: Option<PathBuf>,
    /// Leave frames whose output exists alone (resumes an interrupted chunk: every output
    /// appears whole, so an existing one is complete).
    #[arg(long, requires = "frames", help_heading = "Sequence")]
    pub skip_existing: bool,
    #[command(flatten)]
    pub input_args: InputArgs,
    #[command(flatten)]
    pub camera: CameraArgs,
    #[command(flatten)]
    pub character: CharacterArgs,
    #[command(flatten)]
    pub method_args: MethodArgs,
    #[arg(long, default_value = "drbokeh", help_heading = "Method", help = super::methods::method_help())]
    pub method: Method,
    /// Write colour as a layer NAME in the input's convention: NAME.Combined.R,G,B,A for
    /// Blender multilayer, plain and PNG/JPEG inputs (what Blender's Image node reads as a
    /// layer), NAME.R,G,B,A for layer.R inputs, a part NAME for multi-part inputs.
    #[arg(long, value_name = "NAME", help_heading = "Output")]
    pub output_layer: Option<String>,
    /// Write colour as half floats (default: 32-bit float).
    #[arg(long, help_heading = "Output")]
    pub half: bool,
    /// Copy the input's other channels (cryptomatte, passes) to the output, unblurred (EXR
    /// input only).
    #[arg(long, help_heading = "Output")]
    pub keep_channels: bool,
    /// The input was rendered with PX extra pixels on every side (overscan), so that light from
    /// outside the frame blurs into it as a real lens sees it: they are read and blurred, then
    /// cut from the output (and the preview). The camera describes the whole overscanned image
    /// (its sensor width spans it).
    #[arg(long, value_name = "PX", default_value_t = 0, help_heading = "Output")]
    pub overscan: usize,
    /// Also write an 8-bit sRGB preview: .png (with alpha) or .jpg/.jpeg (over black).
    #[arg(long, value_name = "FILE.png", help_heading = "Output")]
    pub preview: Option<PathBuf>,
    /// Frame tile side in pixels, for every method on the Vulkan device (default: the largest
    /// the device's limits and the memory cap allow). The output is the same for every tile size.
    #[arg(long, value_name = "N", help_heading = "Output")]
    pub tile: Option<usize>,
    /// Most memory the render may hold, host and device together (inputs, output and tiles):
    /// SIZE in bytes or with K, M, G (e.g. 512M, 2G). Default: on a CPU Vulkan device (lavapipe)
    /// 3x the stack's float32 size, on a GPU what its driver's budget leaves.
    #[arg(long, value_name = "SIZE", value_parser = parse_size, help_heading = "Output")]
    pub max_memory: Option<u64>,
    /// Where Vulkan methods run: auto (the Vulkan device; the CPU, with a warning, if none can
    /// be opened; a frame of at most 512x512 pixels that drbokeh renders through a plain disk,
    /// with no lens character or tiling, on the CPU: opening a device costs more than that
    /// render), gpu (fail without one), cpu (the CPU paths: drbokeh's disk fast, the other
    /// references slow, for checking).
    #[arg(long, value_enum, default_value = "auto", help_heading = "Output")]
    pub device: DeviceChoice,
    /// Print a JSON report (camera and aperture, layers and their order, CoC range, timings,
    /// the process's peak memory and page faults) on stdout.
    #[arg(long, help_heading = "Output")]
    pub json: bool,
}

/// What `--json` prints.
#[derive(serde::Serialize)]
struct Report<'a> {
    input: &'a Path,
    output: &'a Path,
    method: Method,
    device: Option<String>,
    /// The most device memory the render's buffers held at once (None on the CPU path).
    device_peak_bytes: Option<u64>,
    width: usize,
    height: usize,
    k_px: f32,
    focus_disparity: f32,
    camera: Option<lensblur::camera::PhysicalCamera>,
    /// The camera parameters taken from the input's header (the rest came from flags).
    camera_from_header: Vec<&'static str>,
    /// `--aperture` as given.
    aperture: &'a str,
    depth_kind: lensblur::stack::DepthKind,
    /// What one unit of depth and focus distance is, and whether the header said so.
    scene_unit: lensblur::camera::SceneUnit,
    scene_unit_from_header: bool,
    /// Deep samples read (all merged files), for a deep input.
    deep_samples: Option<u64>,
    auto_layered: bool,
    /// Front to back.
    layers: Vec<LayerReport>,
    coc_range_px: [f32; 2],
    timings_ms: Timings,
    /// The process's peak resident memory and page faults when the report was made.
    process: Option<crate::memory::ProcessUsage>,
}

#[derive(serde::Serialize)]
struct LayerReport {
    name: String,
    disparity_range: [f32; 2],
    coc_range_px: [f32; 2],
}

#[derive(serde::Serialize)]
struct Timings {
    read: f64,
    layering: f64,
    /// Opening the Vulkan device (0 on the CPU path), while the input is read and layered.
    device_open: f64,
    /// Compiling the method's pipelines on the device, after it opened and still beside the
    /// reading and layering (0 on the CPU path).
    warm_up: f64,
    /// Preparing the method (the pipelines the warm-up did not compile are compiled in `render`).
    prepare: f64,
    render: f64,
    /// Closing the device and checking its teardown.
    device_close: f64,
    write: f64,
    total: f64,
}

/// Renders one file (`render_sequence::run` renders a frame range with the same steps).
/// `declared_frame`: the input's frame size from its header (`input::declared_frame_size`), as
/// `main` read it.
pub fn run(args: Args, declared_frame: Option<(usize, usize)>) -> anyhow::Result<()> {
    refuse_frame_pattern_without_frames(&args.input)?;
    let total = Instant::now();
    let inputs = input_files(&args.input, &args.input_args, &args.camera);
    let mut outputs = vec![("-o", args.output.as_path())];
    outputs.extend(args.preview.as_deref().map(|p| ("--preview", p)));
    // An output on an input is the graver mistake: said before the format.
    check_output_paths(&outputs, &inputs)?;
    let (format, job) = check_flags(&args)?;
    let spinner = progress::spinner(args.json);
    spinner.set_message(format!("reading {}", args.input.display()));
    // The device opens, and the method's pipelines compile on it, while the file is read and
    // layered (neither needs the other): on a preview-sized frame, opening the device is a
    // fifth of the whole process and compiling its pipelines (lavapipe) a sixth.
    let (loaded, opened) = std::thread::scope(|scope| {
        let opening = scope.spawn(|| {
            let start = Instant::now();
            // A small frame may render on the CPU without a device (`RenderJob::place_frame`).
            let ctx = open_device(&job, declared_frame);
            let device_open = start.elapsed();
            if let Ok(Some(ctx)) = &ctx {
                // A failure here is the render's to report, in its own words: it compiles
                // whatever is not compiled yet.
                let _ = job.warm_up(ctx);
            }
            (ctx, device_open, start.elapsed() - device_open)
        });
        let loaded = load(&job, &args.input, &CameraHints::default());
        (loaded, opening.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic)))
    });
    let mut loaded = loaded?;
    let (ctx, device_open, warm_up) = opened;
    // The debug views are named after the layers, so they are checked once the stack is read.
    let debug_views = args.character.debug_view_paths(&loaded.stack);
    let debug_outputs: Vec<(&str, &Path)> = debug_views.iter().map(|p| ("--debug-out", p.as_path())).collect();
    check_output_collisions(&[outputs.as_slice(), debug_outputs.as_slice()].concat(), &inputs)?;
    // A tilt or focal planes this frame cannot take fail here, before the render, in the flags' words
    // (the render resolves the same settings again: microseconds).
    job.settings(&loaded).map_err(job_error)?;
    let ctx = ctx?;
    let rendered = render_loaded(&job, ctx.as_ref(), &args.input, &loaded, &spinner, "")?;
    let (prepare_time, render_time) = (rendered.prepare_time, rendered.render_time);
    let device = ctx.as_ref().map(|c| c.info().name.clone());
    let device_peak_bytes = ctx.as_ref().map(|c| c.buffer_pool_counts().peak_bytes);
    // The device is closed and its teardown validated before any file appears: a validation
    // error fails the command with nothing written.
    let closing = Instant::now();
    if let Some(ctx) = ctx {
        ctx.finish()?;
    }
    let device_close = closing.elapsed();
    let start = Instant::now();
    // As rendered: after --near-blur/--far-blur/--max-blur, which remap the disparity.
    let layers = layer_reports(&rendered.prepared, &rendered.lens);
    args.character.write_debug_views(&rendered, loaded.frame_margin)?;
    // The stack is done with: free it before the write copies the image into EXR channels,
    // so the host never holds the stack, the image and the channels at once.
    let Rendered { image, lens, prepared, .. } = rendered;
    drop(prepared);
    drop(std::mem::take(&mut loaded.stack.layers));
    spinner.set_message(format!("writing {}", args.output.display()));
    write_output(&args, &job, &args.output, args.preview.as_deref(), format, &loaded, &image)?;
    let write_time = start.elapsed();
    spinner.finish_and_clear();
    let timings = Timings {
        read: ms(loaded.read_time),
        layering: ms(loaded.layering_time),
        device_open: ms(device_open),
        warm_up: ms(warm_up),
        prepare: ms(prepare_time),
        render: ms(render_time),
        device_close: ms(device_close),
        write: ms(write_time),
        total: ms(total.elapsed()),
    };
    let report = report(&args, &loaded, &lens, layers, (device, device_peak_bytes), timings);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_summary(&report);
    }
    Ok(())
}

/// A frame pattern given as a single file is a forgotten --frames (unless such a file exists).
fn refuse_frame_pattern_without_frames(input: &Path) -> anyhow::Result<()> {
    if FramePattern::parse(input).is_some() && !input.exists() {
        anyhow::bail!(
            "{} is a frame pattern: say which frames to render with --frames (e.g. --frames 1001-1100)",
            input.display()
        );
    }
    Ok(())
}

/// What needs no input file, checked before any work: the output formats, --keep-channels on
/// an EXR, and the render job the flags describe (the library checks it). Returns the output
/// format and the job.
pub(super) fn check_flags(args: &Args) -> anyhow::Result<(OutputFormat, RenderJob)> {
    let format = OutputFormat::for_output(&args.output, "-o", OutputFormat::ALL)?;
    if let Some(preview) = &args.preview {
        OutputFormat::for_output(preview, "--preview", OutputFormat::LDR)?;
    }
    if args.keep_channels && SourceKind::of_path(&args.input, false) == SourceKind::Image {
        anyhow::bail!(
            "--keep-channels copies the other channels of an EXR input; {} is a PNG/JPEG and has none \
             (drop the flag)",
            args.input.display()
        );
    }
    if args.overscan > 0 && args.keep_channels {
        anyhow::bail!(
            "--keep-channels copies the input's other channels unblurred at its size; with --overscan they would \
             not line up with the cut output (drop one of them)"
        );
    }
    Ok((format, args.job()?))
}

impl Args {
    /// The library's render job these flags describe, checked (its refusals in flag words).
    pub(super) fn job(&self) -> anyhow::Result<RenderJob> {
        let method_options = self.method_args.options()?;
        // First, before the camera flags: a setting given to the wrong method is what the user
        // hears about (the job checks it again with the rest).
        method_options.check(self.method).map_err(job_error)?;
        let mut camera = self.camera.clone();
        self.method_args.apply_to_camera(&mut camera)?;
        let spec = JobSpec {
            method: self.method,
            camera: camera.request()?,
            input: self.input_args.options(),
            method_options,
            character: self.character.character()?,
            overscan: self.overscan,
            tile: self.tile,
            max_memory: self.max_memory,
            device: self.device.preference(),
        };
        RenderJob::new(spec).map_err(job_error)
    }
}

/// Reads `path` for `job` (`camera_file`: a shot's camera for the frame), rewording the
/// library's refusals with the flags and printing the file's warnings.
pub(super) fn load(job: &RenderJob, path: &Path, camera_file: &CameraHints) -> anyhow::Result<LoadedInput> {
    // The library's errors name the file already: no "reading FILE" context on top.
    Ok(warn(job.load(path, camera_file).map_err(job_error)?))
}

/// `--max-memory SIZE`: bytes, or a number with K, M, G or T (binary units, an optional B or
/// iB after it).
pub(super) fn parse_size(text: &str) -> Result<u64, String> {
    let upper = text.trim().to_ascii_uppercase();
    let number = upper.trim_end_matches("IB").trim_end_matches('B');
    let (digits, shift) = match number.chars().last() {
        Some('K') => (&number[..number.len() - 1], 10),
        Some('M') => (&number[..number.len() - 1], 20),
        Some('G') => (&number[..number.len() - 1], 30),
        Some('T') => (&number[..number.len() - 1], 40),
        _ => (number, 0),
    };
    match digits.trim().parse::<f64>() {
        Ok(value) if value.is_finite() && value > 0.0 => Ok((value * (1u64 << shift) as f64) as u64),
        _ => Err(format!("expected a size such as 512M or 2G, got '{text}'")),
    }
}

/// Renders `loaded` (read from `input`) as `job` says, showing the tiles on `spinner` after
/// `what_prefix`.
pub(super) fn render_loaded<'a>(
    job: &RenderJob,
    ctx: Option<&Context>,
    input: &Path,
    loaded: &'a LoadedInput,
    spinner: &ProgressBar,
    what_prefix: &str,
) -> anyhow::Result<Rendered<'a>> {
    let layer_count = loaded.stack.layers.len();
    let method = job.method();
    let what = format!("{what_prefix}rendering {layer_count} layer(s) with {method}");
    let tile_progress = progress::tiles(spinner, what, job.render_count(loaded));
    job.render(ctx, loaded, Some(&tile_progress))
        .map_err(job_error)
        .with_context(|| format!("rendering {} with {method}", input.display()))
}

/// `--device`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum DeviceChoice {
    Auto,
    Gpu,
    Cpu,
}

impl DeviceChoice {
    pub(super) fn preference(self) -> DevicePreference {
        match self {
            DeviceChoice::Auto => DevicePreference::Auto,
            DeviceChoice::Gpu => DevicePreference::Gpu,
            DeviceChoice::Cpu => DevicePreference::Cpu,
        }
    }
}

/// The Vulkan context `job` runs on, or None for the CPU path (the library's policy:
/// [`RenderJob::place`]), saying on stderr why the CPU path runs when the user may not expect it.
/// `frame`: the size of the frames rendered (None where no header says).
pub(super) fn open_device(job: &RenderJob, frame: Option<(usize, usize)>) -> anyhow::Result<Option<Context>> {
    let method = job.method();
    let named = ContextOptions::from_env().device.is_some();
    let placement = job.place_frame(frame).with_context(|| {
        if named {
            "opening the Vulkan device named by LENSBLUR_DEVICE (see `lensblur devices`; unset it, or --device cpu)"
        } else {
            "opening the Vulkan device (see `lensblur devices`; --device cpu renders without one)"
        }
    })?;
    match &placement {
        Placement::Cpu(CpuReason::Asked) => {
            eprintln!("lensblur: warning: rendering {method} on the CPU (--device cpu: slow but for drbokeh through a disk)");
        }
        Placement::Cpu(CpuReason::NoDevice(error)) => eprintln!(
            "lensblur: warning: no usable Vulkan device ({error}); rendering {method} on the CPU \
             (slow); --device cpu says so explicitly, --device gpu makes this an error"
        ),
        Placement::Gpu(_) | Placement::Cpu(CpuReason::CpuMethod | CpuReason::SmallFrame) => {}
    }
    Ok(placement.into_context())
}

/// Writes `image` to `output` (and `preview`) as the flags say; `loaded` is the input it came
/// from, whose naming and display window the output takes.
pub(super) fn write_output(
    args: &Args,
    job: &RenderJob,
    output: &Path,
    preview: Option<&Path>,
    format: OutputFormat,
    loaded: &LoadedInput,
    image: &Image,
) -> anyhow::Result<()> {
    let image = job.output(image, loaded).map_err(job_error)?;
    let image = image.as_ref();
    if format != OutputFormat::Exr {
        if args.output_layer.is_some() || args.keep_channels || args.half {
            anyhow::bail!(
                "--output-layer, --keep-channels and --half apply to EXR output; {} is 8-bit",
                output.display()
            );
        }
        write_ldr(output, image)?;
    } else {
        let extra_channels = match (&loaded.info, args.keep_channels) {
            (Some(info), true) => info.extra_channels.clone(),
            _ => Vec::new(),
        };
        // Named like the input, on its display window, so the output lines up with it.
        let (layer_naming, display_origin) = match &loaded.info {
            Some(info) => (info.output_naming(), (info.display_window.x, info.display_window.y)),
            None => (StackNaming::default(), (0, 0)),
        };
        let options = WriteOptions {
            output_layer: args.output_layer.clone(),
            layer_naming,
            display_origin,
            sample_type: if args.half { SampleType::Half } else { SampleType::Float },
            extra_channels,
            camera: loaded.camera.physical,
        };
        write_image(output, image, &options).context("writing -o")?;
    }
    if let Some(preview) = preview {
        write_ldr(preview, image).context("writing --preview")?;
    }
    Ok(())
}

fn report<'a>(
    args: &'a Args,
    loaded: &LoadedInput,
    lens: &Lens,
    layers: Vec<LayerReport>,
    (device, device_peak_bytes): (Option<String>, Option<u64>),
    timings_ms: Timings,
) -> Report<'a> {
    let coc_range_px = layers
        .iter()
        .fold([f32::INFINITY, 0.0f32], |[lo, hi], l| [lo.min(l.coc_range_px[0]), hi.max(l.coc_range_px[1])]);
    Report {
        input: &args.input,
        output: &args.output,
        method: args.method,
        device,
        device_peak_bytes,
        width: loaded.frame_size().0,
        height: loaded.frame_size().1,
        k_px: lens.coc.k_px,
        focus_disparity: lens.coc.focus_disparity,
        camera: loaded.camera.physical,
        camera_from_header: loaded.camera.from_header.clone(),
        aperture: &args.camera.aperture,
        depth_kind: loaded.depth_kind,
        scene_unit: loaded.camera.scene_unit.clone(),
        scene_unit_from_header: loaded.camera.scene_unit_from_header,
        deep_samples: loaded.deep_samples,
        auto_layered: loaded.auto_layered.is_some(),
        layers,
        coc_range_px: if coc_range_px[0].is_finite() { coc_range_px } else { [0.0, 0.0] },
        timings_ms,
        process: crate::memory::usage(),
    }
}

/// Disparity and CoC ranges over each layer's covered pixels (alpha > 0), the layers side by
/// side: a pass over every pixel of the stack, on the process's path after the render (1.7 ms on
/// one core for five 278^2 layers).
fn layer_reports(stack: &LayerStack, lens: &Lens) -> Vec<LayerReport> {
    use rayon::prelude::*;
    stack
        .layers
        .par_iter()
        .map(|layer| {
            // Branch-free, so the loop vectorises: an uncovered pixel adds the fold's identity.
            let (lo, hi) = layer.rgba.pixels.iter().zip(&layer.disparity).fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), (p, &d)| {
                let covered = p[3] > 0.0;
                (lo.min(if covered { d } else { f32::INFINITY }), hi.max(if covered { d } else { f32::NEG_INFINITY }))
            });
            let (lo, hi) = if lo.is_finite() { (lo, hi) } else { (0.0, 0.0) };
            let (r_lo, r_hi) = (lens.coc.radius(lo), lens.coc.radius(hi));
            // |d - df| is smallest inside the range when the focus plane crosses the layer.
            let crosses = (lo..=hi).contains(&lens.coc.focus_disparity);
            let min_radius = if crosses { 0.0 } else { r_lo.min(r_hi) };
            LayerReport {
                name: layer.name.clone(),
                disparity_range: [lo, hi],
                coc_range_px: [min_radius, r_lo.max(r_hi)],
            }
        })
        .collect()
}

fn print_summary(report: &Report) {
    let layers: Vec<String> = report
        .layers
        .iter()
        .map(|l| format!("{} ({:.1}-{:.1} px)", l.name, l.coc_range_px[0], l.coc_range_px[1]))
        .collect();
    println!(
        "{} -> {}: {}x{}, {} {}, {} layer(s) front to back: {}; render {:.0} ms, total {:.0} ms{}",
        report.input.display(),
        report.output.display(),
        report.width,
        report.height,
        report.method,
        report.device.as_deref().map(|d| format!("on {d}")).unwrap_or_else(|| "on the CPU".into()),
        report.layers.len(),
        layers.join(", "),
        report.timings_ms.render,
        report.timings_ms.total,
        match (report.auto_layered, report.deep_samples) {
            (true, _) => " (auto-layered from one image)".to_string(),
            (false, Some(samples)) => format!(" (from {samples} deep samples)"),
            (false, None) => String::new(),
        },
    );
    println!("{}", describe_camera(report));
}

/// The lens the render used, and where its values came from: flags, or the input's header
/// (a stamped file renders without camera flags, and the user should see what it held).
fn describe_camera(report: &Report) -> String {
    let lens = match &report.camera {
        Some(c) => format!(
            "camera {} mm, f/{}, focus distance {}, sensor width {} mm",
            c.focal_length_mm, c.fstop, c.focus_distance, c.sensor_width_mm
        ),
        None => format!("normalised model: K = {} px, focus disparity {}", report.k_px, report.focus_disparity),
    };
    let source = match report.camera_from_header.as_slice() {
        [] => String::new(),
        names => format!(" ({} from {}'s header)", names.join(", "), report.input.display()),
    };
    let unit = if report.scene_unit_from_header { " (from the header)" } else { "" };
    format!("{lens}, aperture {}{source}; scene unit {}{unit}", report.aperture, report.scene_unit)
}

/// Milliseconds to the microsecond: `as_secs_f64() * 1e3` prints binary noise such as
/// `0.00009999999999999999`.
pub(super) fn ms(d: Duration) -> f64 {
    d.as_micros() as f64 / 1e3
}
