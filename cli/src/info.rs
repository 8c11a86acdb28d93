//! `lensblur info FILE`: what a stack file holds and how lensblur will interpret it.
use std::path::PathBuf;

use lensblur::input::SourceKind;
use lensblur::stack::{ldr_size, read_ldr, read_parts, read_stack, DepthKind, ReadOptions, StackInfo};

use super::input_args::input_flag_error;

#[derive(clap::Args)]
#[command(after_help = "Examples:\n  lensblur info shot.exr                      layers, channels, data windows, depth ranges, camera\n  lensblur info beauty.png --depth depth.png  a PNG/JPEG with its depth image\n  lensblur info shot.exr --json               the same as JSON (for scripts)")]
pub struct InfoArgs {
    /// EXR stack, or PNG/JPEG image (with --depth) to describe.
    pub file: PathBuf,
    /// Depth image of a PNG/JPEG FILE (PNG, 8/16-bit grey), as `render --depth` takes it.
    #[arg(long, value_name = "FILE")]
    pub depth: Option<PathBuf>,
    /// How depth is stored: z (planar, 1e10/inf = far), disparity (normalised, 1 = near) or
    /// inverse-z (1/z, 0 = far). [default: z for EXR, disparity for a --depth image]
    #[arg(long, value_name = "KIND")]
    pub depth_kind: Option<DepthKind>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Deep files: refuse one holding more samples than this.
    #[arg(long, value_name = "N", default_value_t = lensblur::stack::deep::DEFAULT_MAX_SAMPLES)]
    pub max_samples: u64,
}

pub fn run(args: InfoArgs) -> anyhow::Result<()> {
    match SourceKind::of_path(&args.file, false) {
        SourceKind::Image => return ldr_info(&args),
        SourceKind::Deep => return deep_info(&args),
        SourceKind::Exr => {}
    }
    if args.depth.is_some() {
        let mismatch = lensblur::InputMismatch::DepthImageBesideStack;
        return Err(input_flag_error(lensblur::Error::InputMismatch { path: args.file.clone(), mismatch }));
    }
    let options = ReadOptions { depth_kind: args.depth_kind.unwrap_or(DepthKind::Z), ..ReadOptions::default() };
    // The library's errors name the file already: no "reading FILE" context on top.
    let (parts, camera) = read_parts(&args.file, options.max_pixels)?;
    // A file that is not a usable stack is still described; the reason is reported.
    let stack = read_stack(&args.file, &options).map(|f| f.info);
    if args.json {
        let value = match &stack {
            Ok(info) => serde_json::to_value(info)?,
            Err(e) => {
                let error = lensblur::error::full_message(e);
                serde_json::json!({ "path": args.file, "parts": parts, "camera": camera, "stack_error": error })
            }
        };
        println!("{}", serde_json::to_string_pretty(&value)?);
        return Ok(());
    }
    println!("{}", args.file.display());
    for (i, part) in parts.iter().enumerate() {
        let w = part.data_window;
        let name = part.name.as_deref().unwrap_or("-");
        println!("part {i} '{name}': data window ({}, {}) {}x{}, {}", w.x, w.y, w.width, w.height, part.compression);
        for c in &part.channels {
            println!("  {:<32} {:?}", c.name, c.sample_type);
        }
    }
    match stack {
        Ok(info) => print_stack(&info),
        Err(e) => println!("not a usable layer stack: {}", lensblur::error::full_message(&e)),
    }
    for (key, value) in &camera {
        println!("camera attribute {key} = {value}");
    }
    Ok(())
}

/// A PNG/JPEG: its size and, with `--depth`, the disparity range its depth image gives.
fn ldr_info(args: &InfoArgs) -> anyhow::Result<()> {
    let max_pixels = lensblur::stack::DEFAULT_MAX_PIXELS;
    let (w, h) = ldr_size(&args.file, max_pixels)?;
    let kind = args.depth_kind.unwrap_or(DepthKind::Disparity);
    let disparity = match &args.depth {
        Some(depth) => {
            let ldr = read_ldr(&args.file, depth, kind, max_pixels)?;
            let (lo, hi) = ldr.disparity.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &d| (lo.min(d), hi.max(d)));
            Some((depth, [lo, hi]))
        }
        None => None,
    };
    if args.json {
        let value = serde_json::json!({
            "path": args.file, "width": w, "height": h, "depth": disparity.map(|(p, _)| p),
            "depth_kind": kind, "disparity_range": disparity.map(|(_, r)| r),
        });
        println!("{}", serde_json::to_string_pretty(&value)?);
        return Ok(());
    }
    println!("{}: PNG/JPEG image {w}x{h}, 8-bit sRGB colour, one layer (auto-layered before rendering)", args.file.display());
    match disparity {
        Some((depth, [lo, hi])) => println!("depth {} read as {}: disparity {lo}..{hi}", depth.display(), kind.name()),
        None => println!("no depth: give its depth image with --depth DEPTH.png (here and to `lensblur render`)"),
    }
    Ok(())
}

/// A deep file: every part with its sample counts and depth range.
fn deep_info(args: &InfoArgs) -> anyhow::Result<()> {
    let options = lensblur::stack::deep::DeepReadOptions { max_samples: args.max_samples, ..Default::default() };
    let info = lensblur::stack::deep::deep_info(&args.file, &options)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&info)?);
        return Ok(());
    }
    println!("{}: deep OpenEXR, {} part(s)", args.file.display(), info.parts.len());
    for part in &info.parts {
        let [x0, y0, x1, y1] = part.data_window;
        let [dx0, dy0, dx1, dy1] = part.display_window;
        let (w, h) = (i64::from(x1) - i64::from(x0) + 1, i64::from(y1) - i64::from(y0) + 1);
        println!(
            "part {} '{}': {}, {}; data window ({x0}, {y0}) {w}x{h} of display ({dx0}, {dy0}) {}x{}",
            part.index,
            part.name.as_deref().unwrap_or("-"),
            part.storage,
            part.compression,
            i64::from(dx1) - i64::from(dx0) + 1,
            i64::from(dy1) - i64::from(dy0) + 1,
        );
        println!("  channels: {}", part.channels.join(", "));
        let pixels = (w * h).max(1) as f64;
        println!(
            "  {} samples ({:.2} per pixel of the data window, at most {}), {} of {} pixels covered, {} volumetric",
            part.samples,
            part.samples as f64 / pixels,
            part.max_samples_per_pixel,
            part.covered_pixels,
            w * h,
            part.volumetric_samples
        );
        match part.depth_range {
            Some([lo, hi]) => println!("  depth {lo}..{hi} (scene units)"),
            None => println!("  no samples"),
        }
    }
    for (key, value) in &info.attributes {
        if lensblur::stack::deep::is_reported_attribute(key) {
            println!("attribute {key} = {value}");
        }
    }
    Ok(())
}

fn print_stack(info: &StackInfo) {
    let d = info.display_window;
    println!("display window ({}, {}) {}x{}; depth kind {:?}", d.x, d.y, d.width, d.height, info.depth_kind);
    println!("layers, front to back:");
    for layer in &info.layers {
        let ch = &layer.channels;
        let names = [&ch.red, &ch.green, &ch.blue, &ch.alpha, &ch.depth].map(|c| c.as_deref().unwrap_or("(none)"));
        let depth = layer.stored_depth_range.map_or("empty".to_string(), |(lo, hi)| format!("{lo}..{hi}"));
        println!(
            "  '{}' [{:?}] R={} G={} B={} A={} depth={}; stored depth {depth}; disparity {}..{}",
            layer.name,
            layer.convention,
            names[0],
            names[1],
            names[2],
            names[3],
            names[4],
            layer.disparity_range.0,
            layer.disparity_range.1
        );
    }
    if info.single_image {
        println!("single image: it will be auto-layered before rendering");
    }
    if !info.extra_channels.is_empty() {
        let names: Vec<&str> = info.extra_channels.iter().map(|c| c.name.as_str()).collect();
        println!("not rendered (kept with --keep-channels): {}", names.join(", "));
    }
}
