//! `lensblur info FILE`: what a stack file holds and how lensblur will interpret it.
use std::path::PathBuf;

use anyhow::Context;
use lensblur::stack::{read_parts, read_stack, DepthKind, ReadOptions, StackInfo};

#[derive(clap::Args)]
pub struct InfoArgs {
    /// EXR file to describe.
    pub file: PathBuf,
    /// How the file's depth channel is encoded: z (planar, 1e10/inf = far), disparity
    /// (normalised, 1 = near) or inverse-z (1/z, 0 = far).
    #[arg(long, default_value = "z")]
    pub depth_kind: DepthKind,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: InfoArgs) -> anyhow::Result<()> {
    let options = ReadOptions { depth_kind: args.depth_kind, ..ReadOptions::default() };
    let (parts, camera) =
        read_parts(&args.file, options.max_pixels).with_context(|| format!("reading {}", args.file.display()))?;
    // A file that is not a usable stack is still described; the reason is reported.
    let stack = read_stack(&args.file, &options).map(|f| f.info);
    if args.json {
        let value = match &stack {
            Ok(info) => serde_json::to_value(info)?,
            Err(e) => {
                serde_json::json!({ "path": args.file, "parts": parts, "camera": camera, "stack_error": e.to_string() })
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
        Err(e) => println!("not a usable layer stack: {e}"),
    }
    for (key, value) in &camera {
        println!("camera attribute {key} = {value}");
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
