//! Virtual DSLR (image-space pseudo ray tracing): GPU against the CPU reference, and the
//! properties the paper claims (no bleeding, tilt-shift, several focal planes).
mod common;

use common::{finish, gpu, max_abs_diff, pattern, square_band_ramp};
use lensblur::camera::{Aperture, CocModel};
use lensblur::image::Image;
use lensblur::render::vdslr::{render_vdslr_cpu, FocusField, Highlight, Vdslr, VdslrParams};
use lensblur::render::Lens;

fn lens(k: f32, focus: f32) -> Lens {
    Lens { coc: CocModel::new(k, focus).unwrap(), aperture: Aperture::Disk }
}

#[test]
fn gpu_matches_cpu_reference() {
    let ctx = gpu();
    let vdslr = Vdslr::new(&ctx).unwrap();
    let (w, h) = (45, 37);
    let image = pattern(w, h);
    let disparity = square_band_ramp(w, h);
    let variants = [
        (lens(14.0, 0.5), VdslrParams::default()),
        (lens(20.0, 0.3), VdslrParams { iterations: 1, samples: 30, highlight: Some(Highlight { sigma: 0.3, white: 1.0 }), ..Default::default() }),
        (lens(10.0, 0.5), VdslrParams { focus: FocusField::Tilt { gradient: [0.01, -0.02] }, seed: 7, ..Default::default() }),
        (lens(16.0, 0.0), VdslrParams { focus: FocusField::Planes(vec![0.2, 0.9]), bleeding_guard: false, ..Default::default() }),
        (Lens { aperture: Aperture::polygon(5, 10.0, 0.0).unwrap(), ..lens(12.0, 0.6) }, VdslrParams::default()),
        // The near square in focus: its outline's pixels are mixed edges (traced at the far depth).
        (lens(14.0, 0.9), VdslrParams::default()),
    ];
    for (i, (lens, params)) in variants.iter().enumerate() {
        let gpu_out = vdslr.run(&image, &disparity, lens, params).unwrap();
        let cpu_out = render_vdslr_cpu(&image, &disparity, lens, params).unwrap();
        // Both read the same pixels (unfused position math); only the f32 sums and exp()
        // differ by a few ulps, on values up to ~20: 1e-5 relative.
        let diff = max_abs_diff(&gpu_out, &cpu_out);
        assert!(diff <= 2e-4, "variant {i}: max |gpu - cpu| = {diff}");
    }
    drop(vdslr);
    finish(ctx);
}

#[test]
fn in_focus_image_is_unchanged() {
    let ctx = gpu();
    let image = pattern(32, 24);
    let disparity = vec![0.4; 32 * 24];
    let params = VdslrParams { highlight: Some(Highlight { sigma: 0.5, white: 1.0 }), ..Default::default() };
    let cpu_out = render_vdslr_cpu(&image, &disparity, &lens(30.0, 0.4), &params).unwrap();
    let gpu_out = Vdslr::new(&ctx).unwrap().run(&image, &disparity, &lens(30.0, 0.4), &params).unwrap();
    // Every ray hits its own pixel; a weighted mean of identical values: f32 rounding only.
    assert!(max_abs_diff(&cpu_out, &image) <= 2e-5 * 20.0);
    assert!(max_abs_diff(&gpu_out, &image) <= 2e-5 * 20.0);
    finish(ctx);
}

#[test]
fn constant_image_stays_constant() {
    let value = [0.3, 0.6, 2.5, 1.0];
    let image = Image::filled(40, 30, value);
    let params = VdslrParams { highlight: Some(Highlight { sigma: 0.2, white: 1.0 }), ..Default::default() };
    let out = render_vdslr_cpu(&image, &square_band_ramp(40, 30), &lens(25.0, 0.5), &params).unwrap();
    // Any choice of pixels averages the same value: f32 rounding of a mean of ~64 terms.
    assert!(max_abs_diff(&out, &image) <= 1e-5 * 2.5);
}

/// An in-focus dark square (0.5) on a bright, strongly blurred background (0.1), plus a near
/// blurred blob (0.9) so searches start in front of the square and can end on background.
fn bleeding_scene() -> (Image, Vec<f32>, Vec<bool>) {
    let (w, h) = (48, 48);
    let in_square = |x: usize, y: usize| (16..32).contains(&x) && (16..32).contains(&y);
    let image = Image::from_fn(w, h, |x, y| if in_square(x, y) { [0.02, 0.05, 0.2, 1.0] } else { [8.0, 6.0, 1.0, 1.0] });
    let disparity = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            if in_square(x, y) {
                0.5
            } else if x < 6 && y < 6 {
                0.9
            } else {
                0.1
            }
        })
        .collect();
    let mask = (0..w * h).map(|i| in_square(i % w, i / w)).collect();
    (image, disparity, mask)
}

fn worst_foreground_change(out: &Image, image: &Image, mask: &[bool]) -> f32 {
    out.pixels
        .iter()
        .zip(&image.pixels)
        .zip(mask)
        .filter(|(_, &m)| m)
        .flat_map(|((p, q), _)| (0..3).map(move |c| (p[c] - q[c]).abs()))
        .fold(0.0, f32::max)
}

#[test]
fn blurred_background_does_not_bleed_onto_in_focus_foreground() {
    let ctx = gpu();
    let (image, disparity, mask) = bleeding_scene();
    let lens = lens(30.0, 0.5); // background CoC 12 px
    let params = VdslrParams { iterations: 1, ..Default::default() };
    let gpu_out = Vdslr::new(&ctx).unwrap().run(&image, &disparity, &lens, &params).unwrap();
    let cpu_out = render_vdslr_cpu(&image, &disparity, &lens, &params).unwrap();
    // With the guard every foreground sample is the square's own colour: rounding only.
    assert!(worst_foreground_change(&gpu_out, &image, &mask) < 1e-5);
    assert!(worst_foreground_change(&cpu_out, &image, &mask) < 1e-5);
    // The guard is what prevents it: without it the bright background (8.0) leaks in.
    let unguarded = render_vdslr_cpu(&image, &disparity, &lens, &VdslrParams { bleeding_guard: false, ..params }).unwrap();
    assert!(worst_foreground_change(&unguarded, &image, &mask) > 0.1);
    finish(ctx);
}

/// Mean absolute difference between horizontally adjacent pixels (green) over rows `rows`.
fn row_contrast(image: &Image, rows: std::ops::Range<usize>) -> f32 {
    let mut sum = 0.0;
    let mut n = 0;
    for y in rows {
        for x in 4..image.width - 5 {
            sum += (image.get(x + 1, y)[1] - image.get(x, y)[1]).abs();
            n += 1;
        }
    }
    sum / n as f32
}

#[test]
fn tilt_shift_makes_focus_vary_across_the_frame() {
    let (w, h) = (40, 40);
    let image = Image::from_fn(w, h, |x, y| if (x / 2 + y / 2) % 2 == 0 { [0.0, 1.0, 0.0, 1.0] } else { [0.0, 0.0, 0.0, 1.0] });
    let disparity = vec![0.5; w * h];
    let g = 0.012;
    // d_f(y) = 0.5 - g y: in focus on the top row, 0.47 off at the bottom: CoC 0 -> 9 px.
    let lens = lens(20.0, 0.5 - g * (h as f32 - 1.0) * 0.5);
    let tilt = VdslrParams { focus: FocusField::Tilt { gradient: [0.0, -g] }, ..Default::default() };
    let out = render_vdslr_cpu(&image, &disparity, &lens, &tilt).unwrap();
    let original = row_contrast(&image, 0..3);
    let (top, bottom) = (row_contrast(&out, 0..3), row_contrast(&out, h - 4..h));
    // Top rows are in focus (rays hit their own pixel); the bottom is blurred over ~9 px,
    // which leaves well under a third of a 2-px checker's edge contrast.
    assert!(top > 0.99 * original, "top {top} vs {original}");
    assert!(bottom < 0.3 * original, "bottom {bottom} vs {original}");
}

#[test]
fn several_focal_planes_are_sharp_at_once() {
    let (w, h) = (40, 40);
    let image = Image::from_fn(w, h, |x, y| if (x + y) % 2 == 0 { [1.0, 1.0, 1.0, 1.0] } else { [0.0, 0.2, 0.0, 1.0] });
    // Left third at 0.2, middle at 0.5, right third at 0.8; planes at 0.2 and 0.8.
    let disparity: Vec<f32> = (0..w * h).map(|i| [0.2, 0.5, 0.8][(i % w) * 3 / w]).collect();
    let params = VdslrParams { focus: FocusField::Planes(vec![0.2, 0.8]), ..Default::default() };
    let out = render_vdslr_cpu(&image, &disparity, &lens(20.0, 0.0), &params).unwrap();
    let column_change = |x: usize| (0..h).map(|y| (out.get(x, y)[1] - image.get(x, y)[1]).abs()).fold(0.0, f32::max);
    // Away from the band edges (CoC of the middle band is 6 px) both outer thirds are exact.
    for x in (0..7).chain(w - 7..w) {
        assert!(column_change(x) < 1e-5, "column {x} changed by {}", column_change(x));
    }
    assert!(column_change(w / 2) > 0.2, "the band between the planes is blurred");
}

#[test]
fn thin_blurred_foreground_over_a_sharp_background_turns_transparent() {
    // A 1 px white bar at r = 3 px in front of an in-focus grey background: the lens sees
    // past the bar, so the bar fades to about 0.2 + 0.8 * (2 r) / (pi r^2) = 0.37 and spreads
    // sideways. (A guard that gives every failed ray the centre kept the bar at 1.0.)
    let (w, h) = (31, 21);
    let image = Image::from_fn(w, h, |x, _| if x == 15 { [1.0; 4] } else { [0.2, 0.2, 0.2, 1.0] });
    let disparity: Vec<f32> = (0..w * h).map(|i| if i % w == 15 { 0.8 } else { 0.5 }).collect();
    let out = render_vdslr_cpu(&image, &disparity, &lens(10.0, 0.5), &VdslrParams { samples: 256, ..Default::default() }).unwrap();
    let (bar, beside) = (out.get(15, 10)[0], out.get(17, 10)[0]);
    // Bounds allow for the 256-sample estimate and the pixel-rounded search (~0.1).
    assert!(bar < 0.55, "the bar must fade: {bar}");
    assert!(beside > 0.25, "the bar must spread 2 px sideways: {beside}");
}
