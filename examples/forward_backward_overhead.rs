//! The Rust side of the Python package's per-call overhead measurement: a 256^2 two-layer
//! stack rendered forward and backward (Dr.Bokeh, exact gradient) with the device opened once,
//! medians over repeats. It first writes the stack to STACK.exr (camera in the header) so the
//! Python side (`examples/python/overhead.py`) times the very same input.
//!
//! ```text
//! cargo run --release --example forward_backward_overhead -- STACK.exr [REPEATS]
//! ```
//!
//! Prints one JSON line: median milliseconds of the forward, the backward and both, and
//! every repeat's (`samples`).
use std::path::Path;
use std::time::Instant;

use lensblur::camera::{Aperture, CocModel, PhysicalCamera};
use lensblur::image::Image;
use lensblur::render::grad::Slope;
use lensblur::render::tiler::RenderOptions;
use lensblur::render::{Lens, Method, MethodSettings};
use lensblur::stack::{write_stack, DepthKind, Layer, LayerStack, StackWriteOptions};
use lensblur::vk::Context;

const SIZE: usize = 256;
const USAGE: &str = "usage: forward_backward_overhead STACK.exr [REPEATS]";

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let repeats = match args.get(1).map(|r| r.parse::<usize>()) {
        None => 15,
        Some(Ok(n)) if n > 0 => n,
        Some(_) => {
            eprintln!("REPEATS must be a positive whole number; {USAGE}");
            std::process::exit(2);
        }
    };
    let Some(path) = args.first() else {
        eprintln!("{USAGE}");
        std::process::exit(2);
    };
    if let Err(error) = run(Path::new(path), repeats) {
        eprintln!("forward_backward_overhead: {error}");
        std::process::exit(1);
    }
}

/// A soft-edged textured card at 1.5 m, in focus, in front of a textured wall at 6 m.
fn stack() -> lensblur::Result<LayerStack> {
    let card = Image::from_fn(SIZE, SIZE, |x, y| {
        let r = ((x as f32 - 100.0).powi(2) + (y as f32 - 128.0).powi(2)).sqrt();
        let a = (1.0 - (r - 60.0) / 8.0).clamp(0.0, 1.0);
        let c = if (x / 16 + y / 16) % 2 == 0 { 0.9 } else { 0.2 };
        [c * a, 0.5 * a, (1.0 - c) * a, a]
    });
    let wall = Image::from_fn(SIZE, SIZE, |x, y| {
        let stripes = 0.5 + 0.4 * ((x as f32) * 0.3).sin() * ((y as f32) * 0.11).cos();
        [stripes, 0.3, 1.0 - stripes, 1.0]
    });
    let layer = |name: &str, rgba, z: f32| Layer { name: name.into(), rgba, disparity: vec![1.0 / z; SIZE * SIZE] };
    LayerStack::new(SIZE, SIZE, vec![layer("card", card, 1.5), layer("wall", wall, 6.0)])
}

fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

fn run(path: &Path, repeats: usize) -> Result<(), Box<dyn std::error::Error>> {
    let stack = stack()?;
    let camera = PhysicalCamera { focal_length_mm: 85.0, sensor_width_mm: 36.0, fstop: 1.4, focus_distance: 1.5 };
    let options = StackWriteOptions { depth_kind: DepthKind::Z, camera: Some(camera), ..StackWriteOptions::default() };
    write_stack(path, &stack, &options)?;
    let lens = Lens { coc: CocModel::from_physical(&camera, SIZE)?, aperture: Aperture::default() };
    let ctx = Context::from_env()?;
    let method = Method::default();
    let renderer = method.prepare(Some(&ctx))?;
    let differentiable = method.differentiable(&ctx, Slope::Exact)?;
    let (mut forward, mut backward, mut total) = (Vec::new(), Vec::new(), Vec::new());
    // One untimed round first: pipeline creation and first-touch allocations.
    for round in 0..=repeats {
        let start = Instant::now();
        let image = method.render_prepared(
            renderer.as_ref(),
            &stack,
            &lens,
            &RenderOptions::default(),
            &MethodSettings::default(),
        )?;
        let rendered = start.elapsed().as_secs_f64() * 1e3;
        let grad_output = Image::from_fn(SIZE, SIZE, |x, y| {
            let p = image.get(x, y);
            [p[0], p[1], p[2], 0.0]
        });
        let start_backward = Instant::now();
        let grads = differentiable.backward(&stack, &lens, &grad_output)?;
        let differentiated = start_backward.elapsed().as_secs_f64() * 1e3;
        assert_eq!(grads.layers.len(), 2);
        if round > 0 {
            forward.push(rendered);
            backward.push(differentiated);
            total.push(rendered + differentiated);
        }
    }
    drop((renderer, differentiable));
    ctx.finish()?;
    let report = serde_json::json!({
        "forward_ms": median(forward.clone()), "backward_ms": median(backward.clone()), "total_ms": median(total.clone()),
        "repeats": repeats, "samples": { "forward_ms": forward, "backward_ms": backward, "total_ms": total },
    });
    println!("{report}");
    Ok(())
}
