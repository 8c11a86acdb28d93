//! Timing of the single-image path at 1024^2 (issue 22: within 1.5x of its time before the
//! depth-structure layers and matting): the five-planes scene's pinhole image and depth from
//! the ground-truth cache, upscaled 4x (nearest), the lens scaled with it; split into layers,
//! then Dr.Bokeh. A benchmark that prints numbers (medians of 3 runs), not a test:
//! `cargo run --release --example single_image_speed` (ray traces the scene on first use, then
//! reads it from the bench's ground-truth cache, `~/.cache/lensblur/gt-cache`).
use std::time::Instant;

use lensblur_dev::bench::{scenes::single_image_truths, BenchCase};
use lensblur::camera::{Aperture, CocModel};
use lensblur::image::Image;
use lensblur::render::drbokeh::{DrBokehGpu, Model};
use lensblur::render::Lens;
use lensblur::stack::{split_into_layers, AutoLayerOptions};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let cache = lensblur::cache_dir::user_cache_dir().map(|dir| dir.join("gt-cache"));
    let truths = single_image_truths(&["five-planes".into()], false, None, cache.as_deref())?;
    let truth = &truths[0];
    let (w, h, s) = (truth.pinhole.width, truth.pinhole.height, 4usize);
    let image = Image::from_fn(w * s, h * s, |x, y| truth.pinhole.get(x / s, y / s));
    let small = BenchCase::disparity_of(truth);
    let disparity: Vec<f32> = (0..w * s * h * s).map(|i| small[(i / (w * s) / s) * w + (i % (w * s)) / s]).collect();
    let coc = CocModel::new(truth.coc.k_px * s as f32, truth.coc.focus_disparity).unwrap();
    let lens = Lens { coc, aperture: Aperture::Disk };
    let ctx = lensblur::vk::Context::from_env()?;
    let drbokeh = DrBokehGpu::new(&ctx)?;
    let (mut split, mut render, mut layers) = (Vec::new(), Vec::new(), 0);
    for _ in 0..3 {
        let start = Instant::now();
        let stack = split_into_layers(&image, &disparity, &coc, &AutoLayerOptions::default());
        split.push(start.elapsed().as_secs_f64());
        layers = stack.layers.len();
        let start = Instant::now();
        drbokeh.render(&stack, &lens, Model::DrBokeh)?;
        render.push(start.elapsed().as_secs_f64());
    }
    let (split, render) = (median(split), median(render));
    println!("1024^2 five-planes: {layers} layers, split {split:.2} s, Dr.Bokeh {render:.2} s, total {:.2} s (medians of 3)", split + render);
    drop(drbokeh);
    ctx.finish()?;
    Ok(())
}
