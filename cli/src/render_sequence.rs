//! `lensblur render IN.####.exr -o OUT.####.exr --frames RANGE`: a shot in one process. The
//! device opens once (its pipelines come from the cache it keeps), then each frame is read,
//! rendered and written atomically in turn. A frame that fails does not stop the others; the
//! command fails at the end, naming them.
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::bail;
use indicatif::ProgressBar;
use lensblur::camera::{CameraHints, PhysicalCamera};
use lensblur::job::{RenderJob, Rendered};
use lensblur::render::Method;
use lensblur::sequence::{CameraFile, FramePattern, Shot, ShotFrame};
use lensblur::stack::OutputFormat;
use lensblur::vk::Context;

use super::input_args::{check_output_paths, input_files};
use super::progress;
use super::render::{check_flags, load, ms, open_device, render_loaded, write_output, Args};
use super::words::job_error;

/// What `--json` prints for a sequence.
#[derive(serde::Serialize)]
struct ShotReport<'a> {
    input: &'a Path,
    output: &'a Path,
    /// `--frames` as given.
    frame_range: &'a str,
    method: Method,
    device: Option<String>,
    rendered: Vec<i64>,
    /// Outputs that existed (`--skip-existing`).
    skipped: Vec<i64>,
    failed: Vec<FailedFrame>,
    /// Frames rendered per second of rendering time (reading, rendering, writing; the device
    /// opened once before them).
    frames_per_second: f64,
    frames: Vec<FrameReport>,
    timings_ms: ShotTimings,
}

#[derive(serde::Serialize)]
struct FailedFrame {
    frame: i64,
    error: String,
}

#[derive(serde::Serialize)]
#[serde(rename_all = "lowercase")]
enum Status {
    Rendered,
    Skipped,
    Failed,
}

#[derive(serde::Serialize)]
struct FrameReport {
    frame: i64,
    input: PathBuf,
    output: PathBuf,
    status: Status,
    #[serde(skip_serializing_if = "Option::is_none")]
    error: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    camera: Option<PhysicalCamera>,
    /// The camera parameters taken from this frame's header, and from the camera file.
    camera_from_header: Vec<&'static str>,
    camera_from_file: Vec<&'static str>,
    timings_ms: FrameTimings,
    /// The device was lost: no later frame can render.
    #[serde(skip)]
    device_lost: bool,
}

#[derive(serde::Serialize, Default)]
struct FrameTimings {
    read: f64,
    render: f64,
    write: f64,
    total: f64,
}

#[derive(serde::Serialize)]
struct ShotTimings {
    device_open: f64,
    total: f64,
}

/// The flags every frame shares, resolved once: one render job for the whole shot.
struct ShotSetup {
    format: OutputFormat,
    job: RenderJob,
    camera_file: Option<CameraFile>,
    preview: Option<FramePattern>,
}

pub fn run(args: &Args, frames: &str) -> anyhow::Result<()> {
    let total = Instant::now();
    let shot = Shot::new(&args.input, &args.output, "-o", frames)?;
    let setup = check_shot(args, &shot)?;
    let spinner = progress::spinner(args.json);
    spinner.set_message("opening the device");
    let start = Instant::now();
    // Placed as a one-shot render of its first frame is (`RenderJob::place_frame`), so that
    // every frame has the bytes of its single render.
    let frame_size = shot.files().find_map(|file| lensblur::input::declared_frame_size(&file.input));
    let ctx = open_device(&setup.job, frame_size)?;
    let device_open = start.elapsed();
    let mut reports = Vec::new();
    let count = shot.frames.len();
    let mut files = shot.files().enumerate();
    for (index, file) in files.by_ref() {
        let position = format!("frame {} ({}/{count}): ", file.frame, index + 1);
        let report = if args.skip_existing && file.output.exists() {
            FrameReport::new(&file, Status::Skipped)
        } else {
            render_frame(args, ctx.as_ref(), &setup, &file, &spinner, &position)
        };
        spinner.suspend(|| eprintln!("lensblur: {position}{}", describe_frame(&report)));
        let device_lost = report.device_lost;
        reports.push(report);
        if device_lost {
            break;
        }
    }
    // After a lost device nothing more can render: the frames left are failed, not dropped.
    for (_, file) in files {
        let mut report = FrameReport::new(&file, Status::Failed);
        report.error = Some("not rendered: the device was lost on an earlier frame".into());
        reports.push(report);
    }
    spinner.finish_and_clear();
    let device = ctx.as_ref().map(|c| c.info().name.clone());
    // Teardown validation (leaks, destruction order) fails the command; every frame's own
    // device work was validated before its file appeared.
    if let Some(ctx) = ctx {
        ctx.finish()?;
    }
    let timings = ShotTimings { device_open: ms(device_open), total: ms(total.elapsed()) };
    let report = shot_report(args, frames, device, reports, timings);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_shot_summary(&report);
    }
    if !report.failed.is_empty() {
        let failed: Vec<String> = report.failed.iter().map(|f| format!("frame {}: {}", f.frame, f.error)).collect();
        bail!("{} of {count} frame(s) failed:\n  {}", report.failed.len(), failed.join("\n  "));
    }
    Ok(())
}

/// Everything checked before any work: the patterns, the flags that do not fit a sequence,
/// the camera file against the frame list, and every frame's output path.
fn check_shot(args: &Args, shot: &Shot) -> anyhow::Result<ShotSetup> {
    if args.character.debug_out.is_some() {
        bail!("--debug-out writes the debug views of one frame; render that frame alone (without --frames)");
    }
    let preview = match &args.preview {
        Some(path) => Some(FramePattern::parse(path).ok_or_else(|| {
            anyhow::anyhow!(
                "--preview {}: with --frames, name every frame's preview with a frame pattern (preview.####.png)",
                path.display()
            )
        })?),
        None => None,
    };
    let (format, job) = check_flags(args)?;
    let camera_file = args.camera_file.as_deref().map(CameraFile::read).transpose()?;
    if let Some(file) = &camera_file {
        file.check_covers(&shot.frames)?;
    }
    for file in shot.files() {
        let preview_path = preview.as_ref().map(|p| p.path(file.frame));
        let mut outputs = vec![("-o", file.output.as_path())];
        outputs.extend(preview_path.as_deref().map(|p| ("--preview", p)));
        let mut inputs = input_files(&file.input, &args.input_args, &args.camera);
        if let Some(path) = &args.camera_file {
            inputs.push(("the --camera-file", path));
        }
        check_output_paths(&outputs, &inputs)?;
    }
    Ok(ShotSetup { format, job, camera_file, preview })
}

/// Reads, renders and writes one frame; a failure is reported in the frame's report.
fn render_frame(
    args: &Args,
    ctx: Option<&Context>,
    setup: &ShotSetup,
    file: &ShotFrame,
    spinner: &ProgressBar,
    position: &str,
) -> FrameReport {
    let start = Instant::now();
    let mut report = FrameReport::new(file, Status::Rendered);
    if let Err(error) = try_render_frame(args, ctx, setup, file, spinner, position, &mut report) {
        report.status = Status::Failed;
        report.error = Some(format!("{error:#}"));
        report.device_lost =
            error.chain().any(|cause| cause.downcast_ref::<lensblur::Error>().is_some_and(lensblur::Error::is_device_lost));
    }
    report.timings_ms.total = ms(start.elapsed());
    report
}

fn try_render_frame(
    args: &Args,
    ctx: Option<&Context>,
    setup: &ShotSetup,
    file: &ShotFrame,
    spinner: &ProgressBar,
    position: &str,
    report: &mut FrameReport,
) -> anyhow::Result<()> {
    let from_file = match &setup.camera_file {
        Some(camera_file) => camera_file.hints(file.frame)?,
        None => CameraHints::default(),
    };
    spinner.set_message(format!("{position}reading {}", file.input.display()));
    let mut loaded = load(&setup.job, &file.input, &from_file)?;
    report.camera = loaded.camera.physical;
    report.camera_from_header = loaded.camera.from_header.clone();
    report.camera_from_file = loaded.camera.from_camera_file.clone();
    report.timings_ms.read = ms(loaded.read_time + loaded.layering_time);
    // A tilt or focal planes this frame cannot take fail here, before the render, in the flags' words
    // (the render resolves the same settings again: microseconds).
    setup.job.settings(&loaded).map_err(job_error)?;
    let rendered = render_loaded(&setup.job, ctx, &file.input, &loaded, spinner, position)?;
    report.timings_ms.render = ms(rendered.prepare_time + rendered.render_time);
    // This frame's device work is validated before its file appears.
    if let Some(ctx) = ctx {
        ctx.check_validation()?;
    }
    let start = Instant::now();
    let Rendered { image, prepared, .. } = rendered;
    drop(prepared);
    drop(std::mem::take(&mut loaded.stack.layers));
    spinner.set_message(format!("{position}writing {}", file.output.display()));
    let preview = setup.preview.as_ref().map(|p| p.path(file.frame));
    write_output(args, &setup.job, &file.output, preview.as_deref(), setup.format, &loaded, &image)?;
    report.timings_ms.write = ms(start.elapsed());
    Ok(())
}

impl FrameReport {
    fn new(file: &ShotFrame, status: Status) -> Self {
        Self {
            frame: file.frame,
            input: file.input.clone(),
            output: file.output.clone(),
            status,
            error: None,
            camera: None,
            camera_from_header: Vec::new(),
            camera_from_file: Vec::new(),
            timings_ms: FrameTimings::default(),
            device_lost: false,
        }
    }
}

/// The progress line of a finished frame.
fn describe_frame(report: &FrameReport) -> String {
    match report.status {
        Status::Rendered => format!(
            "{} -> {} ({:.0} ms{})",
            report.input.display(),
            report.output.display(),
            report.timings_ms.total,
            report.camera.map(|c| format!(", f/{} focus distance {}", c.fstop, c.focus_distance)).unwrap_or_default()
        ),
        Status::Skipped => format!("{} exists, skipped", report.output.display()),
        Status::Failed => format!("FAILED: {}", report.error.as_deref().unwrap_or_default()),
    }
}

fn shot_report<'a>(
    args: &'a Args,
    frame_range: &'a str,
    device: Option<String>,
    frames: Vec<FrameReport>,
    timings_ms: ShotTimings,
) -> ShotReport<'a> {
    let with = |status: fn(&Status) -> bool| frames.iter().filter(|f| status(&f.status)).map(|f| f.frame).collect();
    let rendered: Vec<i64> = with(|s| matches!(s, Status::Rendered));
    let rendering_ms: f64 =
        frames.iter().filter(|f| matches!(f.status, Status::Rendered)).map(|f| f.timings_ms.total).sum();
    let failed = frames
        .iter()
        .filter_map(|f| f.error.as_ref().map(|error| FailedFrame { frame: f.frame, error: error.clone() }))
        .collect();
    ShotReport {
        input: &args.input,
        output: &args.output,
        frame_range,
        method: args.method,
        device,
        frames_per_second: if rendering_ms > 0.0 { rendered.len() as f64 / (rendering_ms / 1e3) } else { 0.0 },
        rendered,
        skipped: with(|s| matches!(s, Status::Skipped)),
        failed,
        frames,
        timings_ms,
    }
}

fn print_shot_summary(report: &ShotReport) {
    let failed: Vec<String> = report.failed.iter().map(|f| f.frame.to_string()).collect();
    println!(
        "{} -> {}: {} frame(s) of {}: {} rendered, {} skipped (output exists), {} failed{}; {} {}; \
         device opened in {:.0} ms, {:.2} frames/s, total {:.1} s",
        report.input.display(),
        report.output.display(),
        report.frames.len(),
        report.frame_range,
        report.rendered.len(),
        report.skipped.len(),
        report.failed.len(),
        if failed.is_empty() { String::new() } else { format!(" ({})", failed.join(", ")) },
        report.method,
        report.device.as_deref().map(|d| format!("on {d}")).unwrap_or_else(|| "on the CPU".into()),
        report.timings_ms.device_open,
        report.frames_per_second,
        report.timings_ms.total / 1e3,
    );
}
