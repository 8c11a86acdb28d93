//! Single-image scatter baseline: BokehMe's classical renderer (Peng et al. 2022). Every source
//! pixel y spreads its colour over its own CoC with the weight
//! `(0.5 + 0.5 tanh(4 (r_y - |x - y|))) / (r_y^2 + 0.2)`: a soft disk with its energy divided
//! by its area, normalised at the end by the accumulated weight. Blurred pixels do spill over
//! sharp ones (foreground over background) but, with one image, also bleed background colour
//! onto focused edges, and nothing hidden can appear behind a blurred foreground.
//!
//! Written as a gather over sources (one output pixel per iteration, explicit tap loop over the
//! largest CoC), the form a compute shader uses to avoid atomics. Sources are mirrored for
//! polygon apertures as a lens does; a kernel image, scaled to the source's CoC, multiplies
//! the weight (the area term stays BokehMe's `r^2`, as for polygons).
//! GPU path: `glsl/scatter.comp` ([`Scatter`]).
mod gpu;

pub use gpu::Scatter;

use rayon::prelude::*;

use crate::camera::Aperture;
use crate::image::Image;
use crate::render::method::{single_image_baseline, InputKind, MethodSpec};
use crate::render::Lens;

/// The scatter baseline in the registry.
pub const METHOD: MethodSpec = MethodSpec {
    name: "scatter",
    label: "Scatter",
    summary: "Single-image scatter baseline (BokehMe's classical renderer, Vulkan)",
    input: InputKind::SingleImage,
    uses_gpu: true,
    settings: &[],
    prepare: |ctx| Ok(single_image_baseline(ctx.map(Scatter::new).transpose()?, render_scatter_cpu)),
    differentiable: None,
    fast_on_cpu: crate::render::method::never_fast_on_cpu,
};

/// Sharpness of the soft disk edge (BokehMe's constant): the weight falls from 0.98 to 0.02
/// over about one pixel.
const EDGE_SHARPNESS: f32 = 4.0;
/// Keeps the area normalisation finite for in-focus sources (BokehMe's constant).
const AREA_EPSILON: f32 = 0.2;
/// Extra window beyond the largest CoC: at 2 px past the rim tanh(-8) leaves 1e-7 of a tap.
const WINDOW_MARGIN: i64 = 2;

/// Renders `image` (linear, premultiplied) with per-pixel `disparity` through `lens`.
///
/// # Panics
/// If `disparity` does not hold one value per pixel (callers validate their inputs).
pub fn render_scatter_cpu(image: &Image, disparity: &[f32], lens: &Lens) -> Image {
    assert_eq!(disparity.len(), image.pixels.len(), "one disparity per pixel");
    let radius: Vec<f32> = disparity.iter().map(|&d| lens.coc.radius(d)).collect();
    let reach = radius.iter().cloned().fold(0.0f32, f32::max).ceil() as i64 + WINDOW_MARGIN;
    let mut out = Image::new(image.width, image.height);
    out.pixels.par_chunks_mut(image.width).enumerate().for_each(|(y, row)| {
        for (x, pixel) in row.iter_mut().enumerate() {
            *pixel = scatter_pixel(image, disparity, &radius, lens, reach, x as i64, y as i64);
        }
    });
    out
}

/// The weight source `y` (CoC radius `r_y`) gives a pixel at aperture distance `distance`.
#[inline]
pub fn scatter_weight(r_y: f32, distance: f32) -> f32 {
    (0.5 + 0.5 * (EDGE_SHARPNESS * (r_y - distance)).tanh()) / (r_y * r_y + AREA_EPSILON)
}

fn scatter_pixel(image: &Image, disparity: &[f32], radius: &[f32], lens: &Lens, reach: i64, x: i64, y: i64) -> [f32; 4] {
    let (w, h) = (image.width as i64, image.height as i64);
    let (mut sum, mut weight) = ([0.0f32; 4], 0.0f32);
    for sy in (y - reach).max(0)..=(y + reach).min(h - 1) {
        for sx in (x - reach).max(0)..=(x + reach).min(w - 1) {
            let source = image.index(sx as usize, sy as usize);
            let rel_y = lens.coc.relative_disparity(disparity[source]);
            let (u, v) = Aperture::to_aperture_coords((x - sx) as f32, (y - sy) as f32, rel_y);
            let r_y = radius[source];
            let k = scatter_weight(r_y, lens.aperture.gauge(u, v)) * lens.aperture.kernel_weight(u, v, r_y);
            let p = image.pixels[source];
            for c in 0..4 {
                sum[c] += k * p[c];
            }
            weight += k;
        }
    }
    // The pixel's own tap weighs at least 0.5 / (r^2 + 0.2) > 0 unless a kernel image blocks
    // it (a ring's obstruction): a pixel no source reaches keeps its own colour.
    if weight > 0.0 {
        sum.map(|s| s / weight)
    } else {
        image.pixels[image.index(x as usize, y as usize)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::disk::{disk_blur_cpu, DiskKernel};

    use crate::render::test_inputs::{disk_lens as lens, texture};

    fn max_abs_diff(a: &Image, b: &Image) -> f32 {
        a.pixels.iter().zip(&b.pixels).flat_map(|(p, q)| (0..4).map(move |c| (p[c] - q[c]).abs())).fold(0.0, f32::max)
    }

    #[test]
    fn in_focus_pixels_are_unchanged_up_to_the_kernel_tail() {
        let img = texture(23, 17);
        let disparity = vec![0.5; img.pixels.len()];
        let out = render_scatter_cpu(&img, &disparity, &lens(30.0, 0.5));
        // With r = 0 the 8 neighbours keep (0.5 + 0.5 tanh(-4 d)) of a tap against 0.5 for the
        // centre: a share of at most 4 (3.4e-4 + 1.2e-5) / 0.5 = 0.28%, times contrast 1.
        let tail = 4.0 * (scatter_weight(0.0, 1.0) + scatter_weight(0.0, 2f32.sqrt())) / scatter_weight(0.0, 0.0);
        assert!(tail < 0.003);
        assert!(max_abs_diff(&out, &img) <= tail, "{} > {tail}", max_abs_diff(&out, &img));
    }

    #[test]
    fn constant_image_stays_constant() {
        let img = Image::filled(29, 21, [0.2, 0.4, 0.8, 1.0]);
        let disparity: Vec<f32> = (0..img.pixels.len()).map(|i| (i % 13) as f32 / 12.0).collect();
        let out = render_scatter_cpu(&img, &disparity, &lens(8.0, 0.3));
        // A normalised average of equal values: exact up to f32 rounding.
        assert!(max_abs_diff(&out, &img) < 1e-5);
    }

    #[test]
    fn single_radius_image_matches_the_disk_blur() {
        let img = texture(41, 37);
        let disparity = vec![0.0; img.pixels.len()];
        let ours = render_scatter_cpu(&img, &disparity, &lens(5.0, 1.0)); // r = 5 px everywhere
        let disk = disk_blur_cpu(&img, &DiskKernel::new(5.0));
        let worst = max_abs_diff(&ours, &disk);
        // Same disk; the tanh rim (about 1 px wide, with a tail) differs from exact pixel
        // coverage; texture contrast 1, measured 0.0012, bound 1% of the contrast.
        assert!(worst < 0.01, "max |scatter - disk| = {worst}");
    }

    #[test]
    fn blurred_foreground_spills_over_a_sharp_background() {
        // What separates scatter from gather: a blurred white square reaches sharp black pixels.
        let img = Image::from_fn(31, 31, |x, y| if (12..19).contains(&x) && (12..19).contains(&y) { [1.0; 4] } else { [0.0, 0.0, 0.0, 1.0] });
        let disparity: Vec<f32> = (0..31 * 31).map(|i| if img.pixels[i][0] > 0.5 { 1.0 } else { 0.5 }).collect();
        let out = render_scatter_cpu(&img, &disparity, &lens(8.0, 0.5)); // square r = 4, rest sharp
        assert!(out.get(10, 15)[0] > 0.05, "{:?}", out.get(10, 15));
    }
}
