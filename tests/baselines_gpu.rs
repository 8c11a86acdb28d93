//! The single-image baselines on Vulkan (`glsl/gather.comp`, `glsl/scatter.comp`) against
//! their CPU references, for disk, polygon and kernel-image apertures (ring, anamorphic),
//! foreground and background focus.
mod common;

use common::{finish, gpu, max_abs_diff, pattern, square_band_ramp};
use lensblur::camera::{Aperture, CocModel};
use lensblur::image::Image;
use lensblur::render::gather::{render_gather_cpu, Gather};
use lensblur::render::scatter::{render_scatter_cpu, Scatter};
use lensblur::render::{Lens, SingleImageGpu};

fn lens(k: f32, focus: f32, aperture: Aperture) -> Lens {
    Lens { coc: CocModel::new(k, focus).unwrap(), aperture }
}

fn lenses() -> Vec<Lens> {
    vec![
        lens(14.0, 0.5, Aperture::Disk),
        lens(20.0, 0.1, Aperture::Disk),
        lens(12.0, 0.9, Aperture::polygon(5, 10.0, 0.0).unwrap()),
        lens(12.0, 0.55, Aperture::polygon(6, 0.0, 0.3).unwrap()),
        lens(16.0, 0.5, Aperture::parse("ring:0.6").unwrap()),
        lens(10.0, 0.2, Aperture::parse("anamorphic:2:rotation=30").unwrap()),
    ]
}

/// Largest difference relative to the image's own scale (the pattern has HDR values of 20).
fn relative_diff(a: &Image, b: &Image) -> f32 {
    let scale = b.pixels.iter().flat_map(|p| p.iter().map(|c| c.abs())).fold(1.0f32, f32::max);
    max_abs_diff(a, b) / scale
}

#[test]
fn gather_gpu_matches_cpu_reference() {
    let ctx = gpu();
    let gather = Gather::new(&ctx).unwrap();
    let (w, h) = (45, 37);
    let (image, disparity) = (pattern(w, h), square_band_ramp(w, h));
    for (i, lens) in lenses().iter().enumerate() {
        let gpu_out = gather.run(&image, &disparity, lens).unwrap();
        let cpu_out = render_gather_cpu(&image, &disparity, lens);
        // Same taps in the same order; only FMA contraction, atan (polygon gauge) and the
        // bilinear kernel sample differ by ulps, over at most ~600 taps: 1e-5 of the image's
        // largest value.
        let diff = relative_diff(&gpu_out, &cpu_out);
        assert!(diff <= 1e-5, "lens {i}: relative max |gpu - cpu| = {diff}");
    }
    drop(gather);
    finish(ctx);
}

#[test]
fn scatter_gpu_matches_cpu_reference() {
    let ctx = gpu();
    let scatter = Scatter::new(&ctx).unwrap();
    let (w, h) = (45, 37);
    let (image, disparity) = (pattern(w, h), square_band_ramp(w, h));
    for (i, lens) in lenses().iter().enumerate() {
        let gpu_out = scatter.run(&image, &disparity, lens).unwrap();
        let cpu_out = render_scatter_cpu(&image, &disparity, lens);
        // Same taps in the same order; tanh, atan and FMA contraction differ by ulps, over up
        // to 33^2 taps: 1e-5 of the image's largest value.
        let diff = relative_diff(&gpu_out, &cpu_out);
        assert!(diff <= 1e-5, "lens {i}: relative max |gpu - cpu| = {diff}");
    }
    drop(scatter);
    finish(ctx);
}

#[test]
fn gpu_baselines_keep_a_constant_image_constant() {
    let ctx = gpu();
    let (gather, scatter) = (Gather::new(&ctx).unwrap(), Scatter::new(&ctx).unwrap());
    let image = Image::filled(40, 30, [0.2, 0.4, 3.0, 1.0]);
    let disparity = square_band_ramp(40, 30);
    let lens = lens(16.0, 0.3, Aperture::Disk);
    for out in [gather.run(&image, &disparity, &lens).unwrap(), scatter.run(&image, &disparity, &lens).unwrap()] {
        // Normalised averages of equal values: exact up to f32 rounding of the sums.
        assert!(max_abs_diff(&out, &image) < 1e-5 * 3.0, "{}", max_abs_diff(&out, &image));
    }
    drop((gather, scatter));
    finish(ctx);
}

#[test]
fn gpu_baselines_reject_a_mismatched_disparity_map() {
    let ctx = gpu();
    let gather = Gather::new(&ctx).unwrap();
    let scatter = Scatter::new(&ctx).unwrap();
    let image = Image::filled(8, 8, [1.0; 4]);
    let lens = lens(10.0, 0.5, Aperture::Disk);
    assert!(gather.run(&image, &[0.5; 63], &lens).is_err());
    assert!(scatter.run(&image, &[f32::NAN; 64], &lens).is_err());
    drop((gather, scatter));
    finish(ctx);
}
