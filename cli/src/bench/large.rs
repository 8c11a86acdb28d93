//! `lensblur bench large`: the tiled renderer on a 4K-8K two-layer frame, mostly in focus and
//! fully defocused; prints time, tiles, peak memory (device and host) and taps per second.
use std::path::PathBuf;

use anyhow::{bail, Context};
use indicatif::{ProgressBar, ProgressStyle};
use lensblur_dev::bench::large::{run_large_frame, Focus, LargeFrameOptions, LargeFrameResult};
use lensblur::vk::Context as GpuContext;

const EXAMPLES: &str = "\
Examples:
  lensblur bench large
  lensblur bench large --size 3840x2160 --max-coc 40 --tile 1024 --json
  lensblur bench large --coc 64 --case fully-defocused --tiles-per-batch 1
  lensblur bench large --case mostly-in-focus --exr /tmp/large      (through real EXR files)

Peak host memory is per case: VmHWM is reset (/proc/self/clear_refs) when a case starts, with
its stack already in memory (--exr: written to disk and dropped, so the read counts).";

#[derive(clap::Args)]
#[command(after_help = EXAMPLES)]
pub struct Args {
    /// Frame size WIDTHxHEIGHT.
    #[arg(long, default_value = "7680x4320")]
    size: String,
    /// CoC radius in pixels of the most blurred layer.
    #[arg(long, visible_alias = "coc", default_value_t = 20.0)]
    max_coc: f32,
    /// Frame tile side (default: chosen from the device's limits and memory budget).
    #[arg(long)]
    tile: Option<usize>,
    /// Tiles recorded into one submission (default: as many as the memory budget allows).
    #[arg(long, value_name = "N")]
    tiles_per_batch: Option<usize>,
    /// Run only these cases (default: both).
    #[arg(long, value_enum, value_delimiter = ',')]
    case: Vec<CaseArg>,
    /// Write each case's stack to DIR/<case>.exr and run it through the file as `lensblur render`
    /// does: read, render, write DIR/<case>-render.exr (kept, with the command that reruns it).
    #[arg(long, value_name = "DIR")]
    exr: Option<PathBuf>,
    /// Print the results as JSON.
    #[arg(long)]
    json: bool,
}

/// `--case`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum CaseArg {
    MostlyInFocus,
    FullyDefocused,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let Some((w, h)) = args.size.split_once('x') else { bail!("--size must be WIDTHxHEIGHT, got '{}'", args.size) };
    let (width, height): (usize, usize) = (w.parse().context("--size width")?, h.parse().context("--size height")?);
    if let Some(dir) = &args.exr {
        if !dir.is_dir() {
            bail!("--exr {}: not a directory; create it first", dir.display());
        }
    }
    let ctx = GpuContext::from_env().context("opening the Vulkan device")?;
    let options =
        LargeFrameOptions { tile: args.tile, tiles_per_batch: args.tiles_per_batch, exr_dir: args.exr.clone() };
    let focuses = [(CaseArg::MostlyInFocus, Focus::MostlyInFocus), (CaseArg::FullyDefocused, Focus::FullyDefocused)];
    let mut results = Vec::new();
    for (_, focus) in focuses.into_iter().filter(|(case, _)| args.case.is_empty() || args.case.contains(case)) {
        let bar = ProgressBar::new(0).with_message(focus.name());
        bar.set_style(
            ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} tiles {elapsed}")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        let progress = |done: usize, total: usize| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        };
        let result = run_large_frame(&ctx, (width, height), focus, args.max_coc, &options, Some(&progress))
            .with_context(|| format!("case {}", focus.name()))?;
        bar.finish_and_clear();
        if !args.json {
            print_result(&result, ctx.info().name.as_str());
        }
        results.push(result);
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&results)?);
    } else if let [in_focus, defocused] = results.as_slice() {
        println!("fully defocused / mostly in focus: {:.2}x the time", defocused.seconds / in_focus.seconds);
    }
    ctx.finish()?;
    Ok(())
}

fn print_result(r: &LargeFrameResult, device: &str) {
    let mib = |b: u64| b as f64 / (1024.0 * 1024.0);
    let host = match r.peak_host_bytes {
        Some(b) => format!(
            "{:.0} MiB = {:.2}x the stack's f32 {:.0} MiB",
            mib(b),
            b as f64 / r.stack_bytes as f64,
            mib(r.stack_bytes)
        ),
        None => format!("n/a (stack f32 {:.0} MiB)", mib(r.stack_bytes)),
    };
    println!(
        "{} {}x{} {} layers, max CoC {} px on {device}: render {:.2} s, {} tiles of {} px ({} per batch), peak device {:.0} MiB, peak host {host}, {:.3e} taps, {:.3e} taps/s",
        r.focus.name(),
        r.width,
        r.height,
        r.layers,
        r.max_coc_px,
        r.seconds,
        r.tiles,
        r.tile_size,
        r.tiles_per_batch,
        mib(r.peak_device_bytes),
        r.taps as f64,
        r.taps_per_second,
    );
    if let Some(exr) = &r.exr {
        println!(
            "  through {}: read {:.2} s, write {:.2} s to {}; rerun: lensblur render {} -o OUT.exr --depth-kind disparity --blur {} --focus-disparity {}",
            exr.stack.display(),
            exr.read_seconds,
            exr.write_seconds,
            exr.render.display(),
            exr.stack.display(),
            r.k_px,
            r.focus_disparity,
        );
    }
}
