//! Writes one synthetic frame twice, as true layers (a Blender-style multilayer EXR) and as a
//! deep EXR of the same layers (one sample per covered pixel per layer, ZIPS, half colour and
//! float Z), to time deep input against true layers (docs/book/src/deep.md):
//!
//! ```bash
//! cargo run --release --example deep_frame -- /tmp/frame 1920 1080
//! ```
//!
//! Three layers: a wall at 12 m covering the frame, a band of discs at 4 m and stripes at
//! 1.5 m covering about half of it each, so the deep file holds about 2 samples per pixel.
use std::path::PathBuf;

use lensblur::image::Image;
use lensblur::stack::deep::{write_deep, DeepImage, DeepWriteOptions};
use lensblur::stack::{write_stack, Layer, LayerStack, StackWriteOptions};

fn main() -> lensblur::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let stem = PathBuf::from(args.get(1).map_or("frame", String::as_str));
    let width: usize = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(1920);
    let height: usize = args.get(3).and_then(|a| a.parse().ok()).unwrap_or(1080);
    let wall = Image::from_fn(width, height, |x, y| {
        let v = 0.2 + 0.3 * (((x / 40) + (y / 40)) % 2) as f32;
        [v, 0.8 * v, 0.6 * v, 1.0]
    });
    let discs = Image::from_fn(width, height, |x, y| {
        let (cx, cy) = ((x % 160) as f32 - 80.0, (y % 160) as f32 - 80.0);
        let a = (72.0 - (cx * cx + cy * cy).sqrt()).clamp(0.0, 1.0);
        [2.0 * a, 1.5 * a, 0.3 * a, a]
    });
    let stripes = Image::from_fn(width, height, |x, y| {
        let a = if ((x + y / 3) / 48) % 2 == 0 { 1.0 } else { 0.0 };
        [0.1 * a, 0.3 * a, 0.9 * a, a]
    });
    let layer =
        |name: &str, rgba: Image, z: f32| Layer { name: name.into(), rgba, disparity: vec![1.0 / z; width * height] };
    let stack = LayerStack::new(
        width,
        height,
        vec![layer("stripes", stripes, 1.5), layer("discs", discs, 4.0), layer("wall", wall, 12.0)],
    )?;
    let layers_path = stem.with_extension("layers.exr");
    write_stack(&layers_path, &stack, &StackWriteOptions::default())?;
    let deep = DeepImage::from_stack(&stack);
    let deep_path = stem.with_extension("deep.exr");
    write_deep(
        &deep_path,
        &[(None, &deep)],
        &DeepWriteOptions { half_colour: true, zip: true, ..DeepWriteOptions::default() },
    )?;
    let per_pixel = deep.samples.len() as f64 / (width * height) as f64;
    println!(
        "{} and {}: {width}x{height}, {per_pixel:.2} deep samples per pixel",
        layers_path.display(),
        deep_path.display()
    );
    Ok(())
}
