//! `lensblur bench-large`: the tiled renderer on a 4K-8K two-layer frame, mostly in focus and
//! fully defocused; prints time, tiles, peak memory (device and host) and taps per second.
use anyhow::{bail, Context};
use indicatif::{ProgressBar, ProgressStyle};
use lensblur::bench::large::{run_large_frame, Focus, LargeFrameResult};
use lensblur::vk::Context as GpuContext;

#[derive(clap::Args)]
#[command(after_help = "Examples:\n  lensblur bench-large\n  lensblur bench-large --size 3840x2160 --max-coc 40 --tile 1024 --json")]
pub struct Args {
    /// Frame size WIDTHxHEIGHT.
    #[arg(long, default_value = "7680x4320")]
    size: String,
    /// CoC radius in pixels of the most blurred layer.
    #[arg(long, default_value_t = 20.0)]
    max_coc: f32,
    /// Frame tile side (default: chosen from the device's limits).
    #[arg(long)]
    tile: Option<usize>,
    /// Print the results as JSON.
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let Some((w, h)) = args.size.split_once('x') else { bail!("--size must be WIDTHxHEIGHT, got '{}'", args.size) };
    let (width, height): (usize, usize) = (w.parse().context("--size width")?, h.parse().context("--size height")?);
    let ctx = GpuContext::from_env().context("opening the Vulkan device")?;
    let mut results = Vec::new();
    for focus in [Focus::MostlyInFocus, Focus::FullyDefocused] {
        let bar = ProgressBar::new(0).with_message(format!("{focus:?}"));
        bar.set_style(ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} tiles {elapsed}").unwrap_or_else(|_| ProgressStyle::default_bar()));
        let progress = |done: usize, total: usize| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        };
        let result = run_large_frame(&ctx, width, height, focus, args.max_coc, args.tile, Some(&progress))?;
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
    println!(
        "{:?} {}x{} {} layers, max CoC {} px on {device}: {:.2} s, {} tiles of {} px, peak device {:.0} MiB, peak host {} (stack f32 {:.0} MiB), {:.3e} taps, {:.3e} taps/s",
        r.focus,
        r.width,
        r.height,
        r.layers,
        r.max_coc_px,
        r.seconds,
        r.tiles,
        r.tile_size,
        mib(r.peak_device_bytes),
        r.peak_host_bytes.map(|b| format!("{:.0} MiB", mib(b))).unwrap_or_else(|| "n/a".into()),
        mib(r.stack_bytes),
        r.taps as f64,
        r.taps_per_second,
    );
}
