//! Timing of the single-image path at 1024^2 (issue 22: within 1.5x of its time before the
//! depth-structure layers and matting): the five-planes scene's pinhole image and depth from
//! the ground-truth cache, upscaled 4x (nearest), the lens scaled with it; split into layers,
//! then Dr.Bokeh. Ignored by default (minutes on lavapipe): `cargo test --release --test
//! single_image_speed -- --ignored --nocapture`. Prints medians of 3 runs.
mod common;

use std::time::Instant;

use lensblur::bench::{scenes::single_image_truths, BenchCase};
use lensblur::camera::{Aperture, CocModel};
use lensblur::image::Image;
use lensblur::render::drbokeh::{DrBokehGpu, Model};
use lensblur::render::Lens;
use lensblur::stack::{split_into_layers, AutoLayerOptions};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
#[ignore]
fn five_planes_at_1024_renders_in_time() {
    let cache = std::path::Path::new("target/lensblur-gt-cache");
    let truths = single_image_truths(&["five-planes".into()], false, None, Some(cache)).expect("traced or cached");
    let truth = &truths[0];
    let (w, h, s) = (truth.pinhole.width, truth.pinhole.height, 4usize);
    let image = Image::from_fn(w * s, h * s, |x, y| truth.pinhole.get(x / s, y / s));
    let small = BenchCase::disparity_of(truth);
    let disparity: Vec<f32> = (0..w * s * h * s).map(|i| small[(i / (w * s) / s) * w + (i % (w * s)) / s]).collect();
    let coc = CocModel::new(truth.coc.k_px * s as f32, truth.coc.focus_disparity).unwrap();
    let lens = Lens { coc, aperture: Aperture::Disk };
    let ctx = common::gpu();
    let drbokeh = DrBokehGpu::new(&ctx).expect("pipelines");
    let (mut split, mut render, mut layers) = (Vec::new(), Vec::new(), 0);
    for _ in 0..3 {
        let start = Instant::now();
        let stack = split_into_layers(&image, &disparity, &coc, &AutoLayerOptions::default());
        split.push(start.elapsed().as_secs_f64());
        layers = stack.layers.len();
        let start = Instant::now();
        drbokeh.render(&stack, &lens, Model::DrBokeh).expect("renders");
        render.push(start.elapsed().as_secs_f64());
    }
    let (split, render) = (median(split), median(render));
    eprintln!("1024^2 five-planes: {layers} layers, split {split:.2} s, Dr.Bokeh {render:.2} s, total {:.2} s (medians of 3)", split + render);
    drop(drbokeh);
    common::finish(ctx);
}
