//! Single-image gather baseline, like Blender's Defocus node and most compositing defocus:
//! each output pixel averages the neighbours inside its own CoC, where a neighbour counts only
//! if it also reaches back (`|x - y| <= min(r_x, r_y)`). The `min` keeps sharp pixels from
//! being smeared over by a blurred background (no halo onto focused subjects), but a blurred
//! foreground cannot spill over a sharp background either: the failure layers exist to fix.
//!
//! CPU reference written shader-shaped: one output pixel per iteration, an explicit tap loop.
//! Polygon apertures enter through the aperture gauge; a kernel image weighs each tap at its
//! offset scaled to the centre's CoC (the shape a Bokeh Blur node draws).
//! GPU path: `glsl/gather.comp` ([`Gather`]).
pub(crate) mod gpu;

pub use gpu::Gather;

use rayon::prelude::*;

use crate::camera::Aperture;
use crate::image::Image;
use crate::render::method::{single_image_baseline, InputKind, MethodSpec};
use crate::render::Lens;

/// The gather baseline in the registry.
pub const METHOD: MethodSpec = MethodSpec {
    name: "gather",
    label: "Gather",
    summary: "Single-image gather baseline, like the Defocus node (Vulkan)",
    input: InputKind::SingleImage,
    uses_gpu: true,
    settings: &[],
    prepare: |ctx| Ok(single_image_baseline(ctx.map(Gather::new).transpose()?, render_gather_cpu)),
    differentiable: None,
    fast_on_cpu: crate::render::method::never_fast_on_cpu,
};

/// Width in pixels of the anti-aliased rim of the acceptance test.
const EDGE_WIDTH: f32 = 1.0;

/// Renders `image` (linear, premultiplied) with per-pixel `disparity` through `lens`.
///
/// # Panics
/// If `disparity` does not hold one value per pixel (callers validate their inputs).
pub fn render_gather_cpu(image: &Image, disparity: &[f32], lens: &Lens) -> Image {
    assert_eq!(disparity.len(), image.pixels.len(), "one disparity per pixel");
    let radius: Vec<f32> = disparity.iter().map(|&d| lens.coc.radius(d)).collect();
    let mut out = Image::new(image.width, image.height);
    out.pixels.par_chunks_mut(image.width).enumerate().for_each(|(y, row)| {
        for (x, pixel) in row.iter_mut().enumerate() {
            *pixel = gather_pixel(image, disparity, &radius, lens, x as i64, y as i64);
        }
    });
    out
}

fn gather_pixel(image: &Image, disparity: &[f32], radius: &[f32], lens: &Lens, x: i64, y: i64) -> [f32; 4] {
    let (w, h) = (image.width as i64, image.height as i64);
    let centre = image.index(x as usize, y as usize);
    let r_x = radius[centre];
    let rel_x = lens.coc.relative_disparity(disparity[centre]);
    let reach = (r_x + 0.5 * EDGE_WIDTH).ceil() as i64;
    let (mut sum, mut weight) = ([0.0f32; 4], 0.0f32);
    for sy in (y - reach).max(0)..=(y + reach).min(h - 1) {
        for sx in (x - reach).max(0)..=(x + reach).min(w - 1) {
            let source = image.index(sx as usize, sy as usize);
            let (u, v) = Aperture::to_aperture_coords((x - sx) as f32, (y - sy) as f32, rel_x);
            let distance = lens.aperture.gauge(u, v);
            let reach_both = r_x.min(radius[source]);
            let mut k = ((reach_both - distance) / EDGE_WIDTH + 0.5).clamp(0.0, 1.0);
            if k > 0.0 {
                k *= lens.aperture.kernel_weight(u, v, r_x);
            }
            if k > 0.0 {
                let p = image.pixels[source];
                for c in 0..4 {
                    sum[c] += k * p[c];
                }
                weight += k;
            }
        }
    }
    // The centre tap has k >= 0.5, but a kernel image can block it (a ring's obstruction): a
    // pixel no tap reaches through the aperture keeps its own colour.
    if weight > 0.0 {
        sum.map(|s| s / weight)
    } else {
        image.pixels[centre]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::disk::{disk_blur_cpu, DiskKernel};

    use crate::render::test_inputs::{disk_lens as lens, texture};

    #[test]
    fn in_focus_pixels_are_unchanged() {
        let img = texture(23, 17);
        let disparity = vec![0.5; img.pixels.len()];
        // r = 0 admits the centre tap only (neighbours at distance >= 1 get weight 0): exact.
        assert_eq!(render_gather_cpu(&img, &disparity, &lens(30.0, 0.5)), img);
    }

    #[test]
    fn constant_image_stays_constant() {
        let img = Image::filled(29, 21, [0.2, 0.4, 0.8, 1.0]);
        let disparity: Vec<f32> = (0..img.pixels.len()).map(|i| (i % 13) as f32 / 12.0).collect();
        let out = render_gather_cpu(&img, &disparity, &lens(12.0, 0.3));
        for p in &out.pixels {
            for (got, want) in p.iter().zip(img.pixels[0]) {
                // A normalised average of equal values: exact up to f32 rounding.
                assert!((got - want).abs() < 1e-5);
            }
        }
    }

    #[test]
    fn single_radius_image_matches_the_disk_blur() {
        let img = texture(41, 37);
        let disparity = vec![0.0; img.pixels.len()];
        let lens = lens(5.0, 1.0); // r = 5 px everywhere
        let ours = render_gather_cpu(&img, &disparity, &lens);
        let disk = disk_blur_cpu(&img, &DiskKernel::new(5.0));
        let worst = ours.pixels.iter().zip(&disk.pixels).flat_map(|(a, b)| (0..4).map(move |c| (a[c] - b[c]).abs())).fold(0.0f32, f32::max);
        // Same disk; the rim differs (linear ramp in the centre distance vs exact pixel
        // coverage) on a texture of contrast 1; measured 0.003, bound 1% of the contrast.
        assert!(worst < 0.01, "max |gather - disk| = {worst}");
    }

    #[test]
    fn sharp_pixels_do_not_pick_up_a_blurred_background() {
        // A sharp white square on a blurred black background: the min-CoC rule keeps it white.
        let img = Image::from_fn(31, 31, |x, y| if (12..19).contains(&x) && (12..19).contains(&y) { [1.0; 4] } else { [0.0, 0.0, 0.0, 1.0] });
        let disparity: Vec<f32> = (0..31 * 31).map(|i| if img.pixels[i][0] > 0.5 { 0.5 } else { 0.0 }).collect();
        let out = render_gather_cpu(&img, &disparity, &lens(16.0, 0.5));
        assert_eq!(out.get(12, 12), [1.0; 4], "corner of the focused square stays exact");
    }
}
