//! `lensblur bench sequence`: what rendering a shot in one process saves. For each frame size,
//! a synthetic focus pull of N frames is rendered twice through the real binary: once as one
//! `lensblur render --frames` process, once as one `lensblur render` process per frame (what a
//! farm or a script looping over frames pays: process start, device and pipeline creation per
//! frame). Prints frames/s of both and the start-up cost per frame the sequence saves.
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use anyhow::{bail, Context as _};
use lensblur::camera::PhysicalCamera;
use lensblur::image::Image;
use lensblur::stack::{write_stack, Layer, LayerStack, StackWriteOptions};

const EXAMPLES: &str = "\
Examples:
  lensblur bench sequence                            24 frames at 256x256 and 1024x1024
  lensblur bench sequence --sizes 512 --frames 48 --method vdslr --json

Both ways render through files, as users do, with the device's pipeline cache warmed by one
untimed render first (LENSBLUR_PIPELINE_CACHE=off measures without it). The blur is the same
number of pixels at every size (the sensor scales with the frame), so a larger frame costs
more per frame only because it has more pixels.";

#[derive(clap::Args)]
#[command(after_help = EXAMPLES)]
pub struct Args {
    /// Square frame sizes in pixels, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "256,1024")]
    sizes: Vec<usize>,
    /// Frames in the shot.
    #[arg(long, default_value_t = 24)]
    frames: usize,
    /// Rendering method (any `lensblur render --method`).
    #[arg(long, default_value = "drbokeh")]
    method: String,
    /// Work folder for the frames (default: a fresh one in the system's temporary folder,
    /// removed afterwards).
    #[arg(long, value_name = "DIR")]
    dir: Option<PathBuf>,
    /// Print the results as JSON.
    #[arg(long)]
    json: bool,
}

#[derive(serde::Serialize)]
struct SizeResult {
    size: usize,
    frames: usize,
    method: String,
    /// One `lensblur render --frames` process.
    sequence_seconds: f64,
    sequence_frames_per_second: f64,
    /// One `lensblur render` process per frame, one after another.
    per_process_seconds: f64,
    per_process_frames_per_second: f64,
    speedup: f64,
    /// (per-process time - sequence time) / frames: the start-up cost saved per frame.
    saved_ms_per_frame: f64,
    /// From the sequence's report: opening the device once, and a frame's mean read, render
    /// and write times.
    device_open_ms: f64,
    mean_frame_ms: FrameMeans,
}

#[derive(serde::Serialize)]
struct FrameMeans {
    read: f64,
    render: f64,
    write: f64,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if args.frames == 0 || args.sizes.iter().any(|&s| s < 16) {
        bail!("--frames must be at least 1 and every --sizes entry at least 16 px");
    }
    let exe = std::env::current_exe().context("finding the lensblur binary to time")?;
    let (dir, remove) = match &args.dir {
        Some(dir) => (dir.clone(), false),
        None => (std::env::temp_dir().join(format!("lensblur-bench-sequence-{}", std::process::id())), true),
    };
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let results: anyhow::Result<Vec<SizeResult>> = args.sizes.iter().map(|&size| bench_size(&exe, &dir, size, &args)).collect();
    if remove {
        let _ = std::fs::remove_dir_all(&dir);
    }
    let results = results?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&results)?);
    } else {
        print_table(&results);
    }
    Ok(())
}

fn bench_size(exe: &Path, dir: &Path, size: usize, args: &Args) -> anyhow::Result<SizeResult> {
    let dir = dir.join(size.to_string());
    std::fs::create_dir_all(&dir)?;
    eprintln!("bench sequence: writing {} frames of {size}x{size}", args.frames);
    for index in 0..args.frames {
        let options = StackWriteOptions { camera: Some(pull_camera(size, index, args.frames)), ..StackWriteOptions::default() };
        write_stack(&frame_path(&dir, "shot", index + 1), &shot_stack(size), &options)?;
    }
    let method = args.method.as_str();
    // Warms the pipeline cache and the file cache for both ways alike.
    render(exe, &frame_path(&dir, "shot", 1), &dir.join("warm.exr"), &["--method", method])?;
    eprintln!("bench sequence: {size}x{size}, one process for {} frames", args.frames);
    let range = format!("1-{}", args.frames);
    let (input, output) = (dir.join("shot.####.exr"), dir.join("sequence.####.exr"));
    let start = Instant::now();
    let report = render(exe, &input, &output, &["--frames", &range, "--json", "--method", method])?;
    let report: serde_json::Value = serde_json::from_slice(&report)?;
    let sequence_seconds = start.elapsed().as_secs_f64();
    eprintln!("bench sequence: {size}x{size}, one process per frame");
    let start = Instant::now();
    for frame in 1..=args.frames {
        render(exe, &frame_path(&dir, "shot", frame), &frame_path(&dir, "single", frame), &["--method", method])?;
    }
    let per_process_seconds = start.elapsed().as_secs_f64();
    // Same frames both ways, or the comparison means nothing.
    for frame in 1..=args.frames {
        if std::fs::read(frame_path(&dir, "sequence", frame))? != std::fs::read(frame_path(&dir, "single", frame))? {
            bail!("frame {frame} at {size}x{size} differs between the sequence and its single render");
        }
    }
    std::fs::remove_dir_all(&dir)?;
    let n = args.frames as f64;
    let mean = |key: &str| {
        let frames = report["frames"].as_array().map(Vec::as_slice).unwrap_or_default();
        frames.iter().filter_map(|f| f["timings_ms"][key].as_f64()).sum::<f64>() / n
    };
    Ok(SizeResult {
        size,
        frames: args.frames,
        method: args.method.clone(),
        sequence_seconds,
        sequence_frames_per_second: n / sequence_seconds,
        per_process_seconds,
        per_process_frames_per_second: n / per_process_seconds,
        speedup: per_process_seconds / sequence_seconds,
        saved_ms_per_frame: (per_process_seconds - sequence_seconds) * 1e3 / n,
        device_open_ms: report["timings_ms"]["device_open"].as_f64().unwrap_or_default(),
        mean_frame_ms: FrameMeans { read: mean("read"), render: mean("render"), write: mean("write") },
    })
}

fn frame_path(dir: &Path, name: &str, frame: usize) -> PathBuf {
    dir.join(format!("{name}.{frame:04}.exr"))
}

/// Runs `lensblur render INPUT -o OUTPUT FLAGS...`; returns its stdout.
fn render(exe: &Path, input: &Path, output: &Path, flags: &[&str]) -> anyhow::Result<Vec<u8>> {
    let result = Command::new(exe).arg("render").arg(input).arg("-o").arg(output).args(flags).output()?;
    if !result.status.success() {
        bail!("lensblur render {} {}: {}", input.display(), flags.join(" "), String::from_utf8_lossy(&result.stderr));
    }
    Ok(result.stdout)
}

/// Frame `index` of `frames`: focus pulled from the subject (2 m) to the wall (4 m); the
/// sensor scales with the frame so that the blur is the same in pixels at every size
/// (K = 0.025 m * 50/3 mm * 256 = 107 px per unit disparity: up to 13 px CoC).
fn pull_camera(size: usize, index: usize, frames: usize) -> PhysicalCamera {
    let t = if frames > 1 { index as f32 / (frames - 1) as f32 } else { 0.0 };
    PhysicalCamera { focal_length_mm: 50.0, sensor_width_mm: 3.0 * size as f32 / 64.0, fstop: 1.0, focus_distance: 2.0 + 2.0 * t }
}

/// A subject 2 m away (a square in the middle, a third of the frame) before a checkered wall
/// at 4 m with a few highlights.
fn shot_stack(size: usize) -> LayerStack {
    let cell = (size / 32).max(1);
    let inside = |v: usize| (size / 3..2 * size / 3).contains(&v);
    let subject = Image::from_fn(size, size, |x, y| if inside(x) && inside(y) { [0.9, 0.3, 0.1, 1.0] } else { [0.0; 4] });
    let wall = Image::from_fn(size, size, |x, y| {
        let c = if (x / cell + y / cell) % 2 == 0 { 0.8 } else { 0.1 };
        let highlight = if (x * 13 + y * 7) % 211 == 0 { 8.0 } else { 0.0 };
        [c + highlight, c, 1.0 - c, 1.0]
    });
    let layers = vec![
        Layer { name: "subject".into(), rgba: subject, disparity: vec![0.5; size * size] },
        Layer { name: "wall".into(), rgba: wall, disparity: vec![0.25; size * size] },
    ];
    LayerStack::new(size, size, layers).expect("two layers of the same size")
}

fn print_table(results: &[SizeResult]) {
    println!("| frame | frames | one process (frames/s) | process per frame (frames/s) | speed-up | saved per frame | device open | frame read / render / write |");
    println!("|---|---|---|---|---|---|---|---|");
    for r in results {
        println!(
            "| {0}x{0} | {1} | {2:.2} s ({3:.2}) | {4:.2} s ({5:.2}) | {6:.2}x | {7:.0} ms | {8:.0} ms | {9:.0} / {10:.0} / {11:.0} ms |",
            r.size,
            r.frames,
            r.sequence_seconds,
            r.sequence_frames_per_second,
            r.per_process_seconds,
            r.per_process_frames_per_second,
            r.speedup,
            r.saved_ms_per_frame,
            r.device_open_ms,
            r.mean_frame_ms.read,
            r.mean_frame_ms.render,
            r.mean_frame_ms.write,
        );
    }
}
