//! The Dr.Bokeh backward shaders against finite differences of the GPU forward, for determinism
//! and on tiles. Their comparison with the f64 CPU reference is in the self-check (dev/src/selfcheck).
mod common;

use common::{finish, gpu};
use lensblur::camera::{Aperture, CocModel};
use lensblur::image::Image;
use lensblur::render::drbokeh::{BackwardOptions, DrBokehGpu, DrBokehGpuGrad, Model};
use lensblur::render::grad::{Differentiable, StackGradients};
use lensblur::render::Lens;
use lensblur::stack::LayerStack;

use lensblur_dev::selfcheck::scenes::{backward as scene, grad_output, hash};

fn lens(aperture: Aperture) -> Lens {
    Lens { coc: CocModel::new(12.0, 0.5).unwrap(), aperture }
}

// The comparison with the f64 CPU reference for both models and every aperture, untiled and
// tiled, is a self-check (dev/src/selfcheck, run by tests/gpu_kit.rs and by the GPU kit).

fn projected(renderer: &DrBokehGpu, stack: &LayerStack, lens: &Lens, model: Model, u: &Image) -> f64 {
    let out = renderer.render(stack, lens, model).unwrap();
    out.pixels.iter().zip(&u.pixels).map(|(o, g)| (0..4).map(|c| o[c] as f64 * g[c] as f64).sum::<f64>()).sum()
}

/// `stack + t v` for the direction v: colour, alpha (where it stays inside (0, 1]) and, with
/// `depth`, disparity (weight `depth` per unit of direction).
fn moved(stack: &LayerStack, t: f32, depth: f32) -> LayerStack {
    let mut s = stack.clone();
    for (l, layer) in s.layers.iter_mut().enumerate() {
        let n = layer.disparity.len();
        for (i, p) in layer.rgba.pixels.iter_mut().enumerate() {
            let j = (l * n + i) * 6;
            for (c, v) in p.iter_mut().enumerate().take(3) {
                *v += t * hash(j + c);
            }
            if p[3] > 0.1 && p[3] < 0.9 {
                p[3] += t * hash(j + 3);
            }
            layer.disparity[i] += t * hash(j + 4) * depth;
        }
    }
    s
}

/// `v . grad` for the direction of [`moved`].
fn directional(stack: &LayerStack, grads: &StackGradients, depth: f32) -> f64 {
    let mut sum = 0.0f64;
    for (l, (layer, g)) in stack.layers.iter().zip(&grads.layers).enumerate() {
        let n = layer.disparity.len();
        for i in 0..n {
            let j = (l * n + i) * 6;
            for c in 0..3 {
                sum += hash(j + c) as f64 * g.rgba[i][c] as f64;
            }
            let a = layer.rgba.pixels[i][3];
            if a > 0.1 && a < 0.9 {
                sum += hash(j + 3) as f64 * g.rgba[i][3] as f64;
            }
            sum += hash(j + 4) as f64 * depth as f64 * g.disparity[i] as f64;
        }
    }
    sum
}

#[test]
fn gpu_backward_matches_directional_finite_difference_of_gpu_forward() {
    let ctx = gpu();
    let (w, h) = (96, 64);
    // Near layer at d ~ 0.83: CoC up to 12 * 0.35 ~ 4 px; far up to 12 * 0.29 ~ 3.5; at 1.15, ~8 px.
    let stack = scene(w, h, 1.15);
    let u = grad_output(w, h);
    // The compat visibility box int((r + 1) / 2) jumps as radii cross odd integers: a step in
    // disparity crosses dozens of them over the image, so compat moves colour and alpha only
    // (its disparity gradient is checked against finite differences on the CPU, kinks excluded).
    for (model, depth) in [(Model::DrBokeh, 0.5f32), (Model::Compat, 0.0)] {
        let lens = lens(Aperture::Disk);
        let grad = DrBokehGpuGrad::new(&ctx, model, BackwardOptions::exact()).unwrap();
        let forward = DrBokehGpu::new(&ctx).unwrap();
        let analytic = directional(&stack, &grad.backward(&stack, &lens, &u).unwrap(), depth);
        // t = 1e-3 moves radii by <= 6e-3 px. The difference quotient is then limited by the
        // forward's curvature, not f32: the f64 CPU forward at this step differs from the
        // backward by 6e-4 as well (1e-4 steps get to 6e-5 in f64, but f32 inputs cannot
        // take them exactly). Smaller steps would measure f32 rounding of the inputs instead.
        let t = 1e-3;
        let up = projected(&forward, &moved(&stack, t, depth), &lens, model, &u);
        let down = projected(&forward, &moved(&stack, -t, depth), &lens, model, &u);
        let numeric = (up - down) / (2.0 * t as f64);
        let rel = (analytic - numeric).abs() / numeric.abs();
        eprintln!("{model:?}: <u, J v> backward {analytic:e}, FD {numeric:e}, rel {rel:e}");
        assert!(rel < 1e-3, "{model:?}: backward {analytic} vs FD {numeric}");
    }
    finish(ctx);
}

#[test]
fn gpu_backward_is_deterministic() {
    let ctx = gpu();
    let (w, h) = (40, 33);
    let stack = scene(w, h, 0.95);
    let gout = grad_output(w, h);
    let renderer = DrBokehGpuGrad::new(&ctx, Model::DrBokeh, BackwardOptions::leaky()).unwrap();
    let first = renderer.backward(&stack, &lens(Aperture::Disk), &gout).unwrap();
    let second = renderer.backward(&stack, &lens(Aperture::Disk), &gout).unwrap();
    // Gathers only, host sums in a fixed order: bit-identical, not merely close.
    assert!(first.layers.iter().zip(&second.layers).all(|(a, b)| {
        a.rgba.iter().flatten().zip(b.rgba.iter().flatten()).all(|(x, y)| x.to_bits() == y.to_bits())
            && a.disparity.iter().zip(&b.disparity).all(|(x, y)| x.to_bits() == y.to_bits())
    }));
    assert_eq!(first.k_px.to_bits(), second.k_px.to_bits());
    assert_eq!(first.focus_disparity.to_bits(), second.focus_disparity.to_bits());
    assert!(first.k_px != 0.0 && first.layers[0].disparity.iter().any(|&g| g != 0.0));
    assert!(renderer.backward(&stack, &lens(Aperture::Disk), &grad_output(w, h + 1)).is_err());
    finish(ctx);
}

/// Gradients as bits, for exact comparison: per layer rgba and disparity, then K and focus.
fn bits(g: &StackGradients) -> (Vec<u32>, Vec<u32>, u64, u64) {
    let rgba = g.layers.iter().flat_map(|l| l.rgba.iter().flatten().map(|v| v.to_bits())).collect();
    let disparity = g.layers.iter().flat_map(|l| l.disparity.iter().map(|v| v.to_bits())).collect();
    (rgba, disparity, g.k_px.to_bits(), g.focus_disparity.to_bits())
}

/// The tiling tests' frame: 75x53 is divisible by none of the tile sides (16, 32, 48); K = 16
/// with the near layer at d ~ 1.15 gives CoCs up to 10.5 px, so a tile's receivers and their
/// sources reach well into its neighbours (two tiles away for the 16 px ones).
fn tiling_case() -> (usize, usize, LayerStack, Image, Lens) {
    let (w, h) = (75, 53);
    let lens = Lens { coc: CocModel::new(16.0, 0.5).unwrap(), aperture: Aperture::Disk };
    (w, h, scene(w, h, 1.15), grad_output(w, h), lens)
}

#[test]
fn gradients_are_bit_identical_whatever_the_tile_size_and_batch_size() {
    use lensblur::render::drbokeh::RenderOptions;
    use std::sync::Mutex;
    let ctx = gpu();
    // Batches of 1, 3 (which divides neither 20 nor 6 tiles) and as many as the budget allows
    // (8 at most) share submissions.
    let (w, h, stack, gout, lens) = tiling_case();
    for options in [BackwardOptions::exact(), BackwardOptions::leaky()] {
        let renderer = DrBokehGpuGrad::new(&ctx, Model::DrBokeh, options).unwrap();
        let (whole, whole_stats) = renderer.backward_with_stats(&stack, &lens, &gout).unwrap();
        assert_eq!(whole_stats.tiles, 1, "a small frame is one tile");
        let want = bits(&whole);
        for tile in [16, 24, 40] {
            let mut one_per_batch_peak = 0;
            for tiles_per_batch in [Some(1), Some(3), None] {
                let calls = Mutex::new(Vec::new());
                let progress = |finished: usize, total: usize| calls.lock().unwrap().push((finished, total));
                let tiled_options = RenderOptions {
                    tile: Some(tile),
                    tiles_per_batch,
                    progress: Some(&progress),
                    ..RenderOptions::default()
                };
                let (tiled, stats) = renderer.backward_with(&stack, &lens, &gout, &tiled_options).unwrap();
                let side = tile.div_ceil(16) * 16;
                assert_eq!(stats.tiles, w.div_ceil(side) * h.div_ceil(side));
                let label = format!("leak {}, tile {tile}, {tiles_per_batch:?} per batch", options.leaky_slope);
                let expected: Vec<(usize, usize)> = (1..=stats.tiles).map(|done| (done, stats.tiles)).collect();
                assert_eq!(*calls.lock().unwrap(), expected, "{label}: progress once per tile, in order");
                match tiles_per_batch {
                    Some(1) => {
                        // Smaller tiles hold less on the device (the point of tiling).
                        assert!(
                            stats.peak_device_bytes < whole_stats.peak_device_bytes,
                            "{label}: {} vs {} bytes",
                            stats.peak_device_bytes,
                            whole_stats.peak_device_bytes
                        );
                        one_per_batch_peak = stats.peak_device_bytes;
                    }
                    // A batch holds its tiles' buffers and no more: at most that many of the largest.
                    _ => assert!(
                        stats.peak_device_bytes <= stats.tiles_per_batch as u64 * one_per_batch_peak,
                        "{label}: {} bytes",
                        stats.peak_device_bytes
                    ),
                }
                if let Some(n) = tiles_per_batch {
                    assert_eq!(stats.tiles_per_batch, n.min(stats.tiles), "{label}");
                }
                let got = bits(&tiled);
                let differing = |a: &[u32], b: &[u32]| a.iter().zip(b).filter(|(x, y)| x != y).count();
                assert_eq!(differing(&got.0, &want.0), 0, "{label}: rgba gradients differ from the untiled ones");
                assert_eq!(differing(&got.1, &want.1), 0, "{label}: disparity gradients differ from the untiled ones");
                assert_eq!(
                    (got.2, got.3),
                    (want.2, want.3),
                    "{label}: K / focus gradients differ from the untiled ones"
                );
            }
        }
        assert!(whole.k_px != 0.0 && whole.layers[0].disparity.iter().any(|&g| g != 0.0));
    }
    finish(ctx);
}

#[test]
fn backward_out_of_device_memory_retries_with_smaller_tiles_and_the_same_gradients() {
    use lensblur::render::drbokeh::RenderOptions;
    let ctx = gpu();
    let (_, _, stack, gout, lens) = tiling_case();
    let renderer = DrBokehGpuGrad::new(&ctx, Model::DrBokeh, BackwardOptions::exact()).unwrap();
    let (whole, whole_stats) = renderer.backward_with_stats(&stack, &lens, &gout).unwrap();
    // What 32 px tiles, one per batch, hold: less than the one-tile frame (on this small frame a
    // tile's receivers and halo span most of it, so no fixed fraction is safe), so the first
    // attempt runs out of memory and the retries must reach a plan that fits.
    let small = RenderOptions { tile: Some(32), tiles_per_batch: Some(1), ..RenderOptions::default() };
    let limit = renderer.backward_with(&stack, &lens, &gout, &small).unwrap().1.peak_device_bytes;
    assert!(limit < whole_stats.peak_device_bytes, "{limit} vs {whole_stats:?}");
    let options = RenderOptions { device_memory_limit: Some(limit), ..RenderOptions::default() };
    let (retried, stats) = renderer.backward_with(&stack, &lens, &gout, &options).unwrap();
    assert!(
        stats.tile_size < whole_stats.tile_size && stats.peak_device_bytes <= limit,
        "{stats:?} within {limit} bytes"
    );
    assert_eq!(bits(&retried), bits(&whole), "gradients of the retried, smaller tiles are the untiled ones");
    drop(renderer);
    finish(ctx);
}
