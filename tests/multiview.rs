//! Multiview synthesis (lens rays through layered height fields): GPU against the CPU
//! reference, convergence to the exact disk blur, and true partial occlusion.
mod common;

use common::{finish, gpu, max_abs_diff, pattern};
use lensblur::camera::{Aperture, CocModel};
use lensblur::image::Image;
use lensblur::render::disk::{disk_blur_cpu, DiskKernel};
use lensblur::render::multiview::{render_multiview_cpu, Multiview, MultiviewParams};
use lensblur::render::Lens;
use lensblur::stack::{Layer, LayerStack};

fn lens(k: f32, focus: f32) -> Lens {
    Lens { coc: CocModel::new(k, focus).unwrap(), aperture: Aperture::Disk }
}

fn layer(name: &str, rgba: Image, disparity: impl Fn(usize, usize) -> f32) -> Layer {
    let w = rgba.width;
    let disparity = (0..rgba.pixels.len()).map(|i| disparity(i % w, i / w)).collect();
    Layer { name: name.into(), rgba, disparity }
}

/// A soft-edged near disk, a slanted partial middle layer and a textured opaque back.
fn three_layer_stack(w: usize, h: usize) -> LayerStack {
    let front = Image::from_fn(w, h, |x, y| {
        let r = ((x as f32 - 12.0).powi(2) + (y as f32 - 10.0).powi(2)).sqrt();
        let a = (7.0 - r).clamp(0.0, 1.0);
        [a * 3.0, a * 0.2, a * 0.1, a]
    });
    let middle = Image::from_fn(w, h, |x, y| if x > 20 && y > 12 { [0.1, 0.8, 0.3, 1.0] } else { [0.0; 4] });
    let back = pattern(w, h).pixels.iter().map(|p| [p[0], p[1], p[2], 1.0]).collect();
    LayerStack::new(
        w,
        h,
        vec![
            layer("front", front, |_, _| 0.9),
            layer("middle", middle, |x, _| 0.4 + 0.2 * x as f32 / w as f32),
            layer("back", Image { width: w, height: h, pixels: back }, |_, y| 0.1 + 0.1 * y as f32 / h as f32),
        ],
    )
    .unwrap()
}

#[test]
fn gpu_matches_cpu_reference() {
    let ctx = gpu();
    let mv = Multiview::new(&ctx).unwrap();
    let stack = three_layer_stack(41, 35);
    let variants = [
        (lens(20.0, 0.5), MultiviewParams { samples: 32, ..Default::default() }),
        (lens(12.0, 0.15), MultiviewParams { samples: 20, cull: false, steps: 5, seed: 3, ..Default::default() }),
        (Lens { aperture: Aperture::polygon(6, 15.0, 0.0).unwrap(), ..lens(25.0, 0.9) }, MultiviewParams { samples: 40, cone_scale: 2.0, ..Default::default() }),
    ];
    for (i, (lens, params)) in variants.iter().enumerate() {
        let gpu_out = mv.run(&stack, lens, params).unwrap();
        let cpu_out = render_multiview_cpu(&stack, lens, params).unwrap();
        // Same texels read (unfused positions); bilinear/trilinear weights and log2 differ
        // by ulps on values up to ~20: 1e-5 relative.
        let diff = max_abs_diff(&gpu_out, &cpu_out);
        assert!(diff <= 2e-4, "variant {i}: max |gpu - cpu| = {diff}");
    }
    drop(mv);
    finish(ctx);
}

#[test]
fn in_focus_stack_is_the_over_composite_of_its_layers() {
    let ctx = gpu();
    let stack = three_layer_stack(32, 24);
    let flat = LayerStack::new(32, 24, stack.layers.iter().map(|l| Layer { disparity: vec![0.5; 32 * 24], ..l.clone() }).collect()).unwrap();
    let expected = Image::from_fn(32, 24, |x, y| {
        let mut acc = [0.0f32; 4];
        let mut t = 1.0f32;
        for l in &flat.layers {
            let c = l.rgba.get(x, y);
            (0..4).for_each(|k| acc[k] += t * c[k]);
            t *= 1.0 - c[3];
        }
        acc
    });
    let params = MultiviewParams::default();
    let cpu_out = render_multiview_cpu(&flat, &lens(30.0, 0.5), &params).unwrap();
    let gpu_out = Multiview::new(&ctx).unwrap().run(&flat, &lens(30.0, 0.5), &params).unwrap();
    // Every ray reads its own pixel at level 0 in every layer: rounding of a mean of ~64.
    assert!(max_abs_diff(&cpu_out, &expected) <= 1e-5 * 20.0);
    assert!(max_abs_diff(&gpu_out, &expected) <= 1e-5 * 20.0);
    finish(ctx);
}

#[test]
fn constant_image_stays_constant() {
    let value = [0.3, 0.6, 2.5, 1.0];
    let stack = LayerStack::new(30, 30, vec![layer("only", Image::filled(30, 30, value), |x, y| 0.1 + 0.02 * (x + y) as f32)]).unwrap();
    let out = render_multiview_cpu(&stack, &lens(20.0, 0.6), &MultiviewParams::default()).unwrap();
    // Every read (any texel, level, weight) is the same value: rounding only.
    assert!(max_abs_diff(&out, &Image::filled(30, 30, value)) <= 1e-5 * 2.5);
}

/// Mean and max |a - b| over pixels at least `margin` from the border (RGB).
fn interior_error(a: &Image, b: &Image, margin: usize) -> (f32, f32) {
    let (mut sum, mut max, mut n) = (0.0f32, 0.0f32, 0);
    for y in margin..a.height - margin {
        for x in margin..a.width - margin {
            for c in 0..3 {
                let d = (a.get(x, y)[c] - b.get(x, y)[c]).abs();
                sum += d;
                max = max.max(d);
                n += 1;
            }
        }
    }
    (sum / n as f32, max)
}

#[test]
fn single_opaque_layer_converges_to_the_disk_blur_of_its_coc() {
    let ctx = gpu();
    let (w, h) = (48, 48);
    // Texture in [0, 1] with hard edges: blocks plus a diagonal ramp.
    let image = Image::from_fn(w, h, |x, y| {
        let block = if (x / 6 + y / 5) % 2 == 0 { 1.0 } else { 0.2 };
        [block, (x + y) as f32 / (w + h) as f32, 1.0 - block * 0.5, 1.0]
    });
    let stack = LayerStack::new(w, h, vec![layer("plane", image.clone(), |_, _| 0.2)]).unwrap();
    let lens = lens(20.0, 0.5); // CoC radius 6 px
    let truth = disk_blur_cpu(&image, &DiskKernel::new(6.0));
    let margin = 8; // rays read edge-extended texels near the border; the disk blur renormalises
    let coarse = render_multiview_cpu(&stack, &lens, &MultiviewParams { samples: 9, ..Default::default() }).unwrap();
    let params = MultiviewParams { samples: 256, ..Default::default() };
    let fine = render_multiview_cpu(&stack, &lens, &params).unwrap();
    let fine_gpu = Multiview::new(&ctx).unwrap().run(&stack, &lens, &params).unwrap();
    let (coarse_mean, _) = interior_error(&coarse, &truth, margin);
    let (fine_mean, fine_max) = interior_error(&fine, &truth, margin);
    let (gpu_mean, _) = interior_error(&fine_gpu, &truth, margin);
    eprintln!("mean |err| 9 samples {coarse_mean}, 256 samples {fine_mean} (max {fine_max}), gpu {gpu_mean}");
    assert!(fine_mean < 0.5 * coarse_mean, "more samples must converge: {fine_mean} vs {coarse_mean}");
    // 256 stratified samples over a 6 px disk (~113 px): noise ~1/256 of the 0.8 contrast per
    // stratum edge plus the sub-pixel cone pre-filter; 0.01 mean and 0.06 worst case.
    assert!(fine_mean < 0.01 && fine_max < 0.06, "mean {fine_mean}, max {fine_max}");
    assert!(gpu_mean < 0.01, "{gpu_mean}");
    finish(ctx);
}

/// Fraction of the unit disk with `u < a`.
fn disk_fraction_below(a: f32) -> f32 {
    let a = a.clamp(-1.0, 1.0);
    1.0 - (a.acos() - a * (1.0 - a * a).sqrt()) / std::f32::consts::PI
}

#[test]
fn blurred_foreground_partially_occludes_a_sharp_background() {
    let (w, h) = (64, 24);
    let edge = 23.5; // the red foreground covers pixel centres 0..=23
    let front = Image::from_fn(w, h, |x, _| if x <= 23 { [1.0, 0.0, 0.0, 1.0] } else { [0.0; 4] });
    let back = Image::from_fn(w, h, |x, _| [0.0, if x % 2 == 0 { 1.0 } else { 0.4 }, 0.0, 1.0]);
    let stack = LayerStack::new(w, h, vec![layer("front", front, |_, _| 0.8), layer("back", back.clone(), |_, _| 0.3)]).unwrap();
    let r = 10.0; // K (0.8 - 0.3)
    let out = render_multiview_cpu(&stack, &lens(20.0, 0.3), &MultiviewParams { samples: 256, ..Default::default() }).unwrap();
    let column_mean = |x: usize, c: usize| (4..h - 4).map(|y| out.get(x, y)[c]).sum::<f32>() / (h - 8) as f32;
    for x in 8..w - 8 {
        // Pixel x sees the foreground through the lens samples with x + u r < edge.
        let expected = disk_fraction_below((edge - x as f32) / r);
        let red = column_mean(x, 0);
        // Stratified 256-sample estimate averaged over 16 rows, bilinear edge: 0.04.
        assert!((red - expected).abs() < 0.04, "x={x}: red coverage {red}, expected {expected}");
        // The background shows through sharp (in focus, read at the pixel itself), weighted
        // by what the foreground leaves: 1 - coverage. Same 0.04 estimate error.
        let transmitted = |x: usize| (1.0 - disk_fraction_below((edge - x as f32) / r)) * back.get(x, 0)[1];
        let green = column_mean(x, 1);
        assert!((green - transmitted(x)).abs() < 0.04, "x={x}: green {green} vs {}", transmitted(x));
        if (x as f32 - edge).abs() < 3.0 {
            // At the edge half the background's 0.6 checker contrast is still visible.
            let contrast = (column_mean(x, 1) - column_mean(x + 1, 1)).abs();
            assert!(contrast > 0.2, "x={x}: background contrast {contrast}");
        }
    }
}

#[test]
fn culling_never_changes_the_result() {
    let stack = three_layer_stack(40, 32);
    let lens = lens(18.0, 0.45);
    let culled = render_multiview_cpu(&stack, &lens, &MultiviewParams::default()).unwrap();
    let full = render_multiview_cpu(&stack, &lens, &MultiviewParams { cull: false, ..Default::default() }).unwrap();
    // Culled layers would have contributed exact zeros: identical sums.
    assert_eq!(max_abs_diff(&culled, &full), 0.0);
}
