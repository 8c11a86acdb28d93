//! Assembling a [`GroundTruth`]: one pass over the image renders, per pixel, the thin-lens
//! image, the pinhole image, every surface alone (the true layers) and the depth maps.
use rayon::prelude::*;

use super::noise::scatter;
use super::scene::{Scene, ZPass};
use super::texture::Rgba;
use super::sampling::PixelSamples;
use super::trace::{over, pixel_samples, trace, Hits, TraceOptions, View};
use super::GroundTruth;
use crate::camera::CocModel;
use crate::image::Image;
use crate::stack::{Layer, LayerStack};
use crate::Result;

/// Depth written where a pixel's centre ray hits nothing opaque (Blender's convention).
pub const EMPTY_DEPTH: f32 = 1.0e10;

/// One row of every output; `layers[l]` in surface order (not yet front to back).
struct Row {
    defocused: Vec<Rgba>,
    pinhole: Vec<Rgba>,
    depth: Vec<f32>,
    layers: Vec<Vec<Rgba>>,
    disparity: Vec<Vec<f32>>,
}

/// Renders everything the benchmark needs for `scene` (see [`GroundTruth`]).
pub fn render_ground_truth(scene: &Scene, options: &TraceOptions) -> Result<GroundTruth> {
    scene.validate()?;
    options.validate()?;
    let (width, height) = scene.size(options.scale);
    let coc = CocModel::from_physical(&scene.camera, width)?;
    let view = View::new(scene, width, height);
    let finished = std::sync::atomic::AtomicUsize::new(0);
    if let Some(progress) = &options.progress {
        (progress.0)(0, height);
    }
    let rows: Vec<Row> = (0..height)
        .into_par_iter()
        .map(|y| {
            let row = render_row(scene, options, &view, y);
            if let Some(progress) = &options.progress {
                (progress.0)(finished.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1, height);
            }
            row
        })
        .collect();
    assemble(scene, coc, width, height, rows)
}

fn render_row(scene: &Scene, options: &TraceOptions, view: &View, y: usize) -> Row {
    let count = scene.surfaces.len();
    let mut row = Row {
        defocused: Vec::with_capacity(view.width),
        pinhole: Vec::with_capacity(view.width),
        depth: Vec::with_capacity(view.width),
        layers: vec![Vec::with_capacity(view.width); count],
        disparity: vec![Vec::with_capacity(view.width); count],
    };
    let mut layer_sum = vec![[0.0f32; 4]; count];
    for x in 0..view.width {
        // The rounds every pixel takes: the pinhole pass uses their pixel positions too, so an
        // in-focus pixel that stops after them sees exactly the points its pinhole pixel sees.
        let rounds: Vec<PixelSamples> = (0..options.first_rounds()).map(|r| pixel_samples(options, x, y, r)).collect();
        let offsets: Vec<[f32; 2]> = rounds.iter().flat_map(|r| r.pixel.iter().copied()).collect();
        let weight = 1.0 / offsets.len() as f32;
        let mut pinhole = [0.0f32; 4];
        layer_sum.iter_mut().for_each(|s| *s = [0.0; 4]);
        for offset in &offsets {
            accumulate(&mut pinhole, pinhole_sample(scene, view, x as f32 + offset[0], y as f32 + offset[1], &mut layer_sum), weight);
        }
        let defocused = defocus_pixel(scene, options, view, x, y, &rounds);
        row.pinhole.push(pinhole);
        row.defocused.push(defocused);
        for (l, sum) in layer_sum.iter().enumerate() {
            row.layers[l].push(sum.map(|c| c * weight));
        }
        let centre = view.slope(x as f32 + 0.5, y as f32 + 0.5);
        let z_at = match scene.z_pass {
            ZPass::PixelCentre => centre,
            ZPass::OneSample => {
                // One of the pixel's samples, picked per pixel: the strata come in a fixed
                // order, so always the first would sit in the pixel's top-left corner.
                let pick = (scatter(y as u32, x as u32) * offsets.len() as f32) as usize % offsets.len();
                view.slope(x as f32 + offsets[pick][0], y as f32 + offsets[pick][1])
            }
        };
        row.depth.push(centre_depth(scene, z_at));
        for (l, s) in scene.surfaces.iter().enumerate() {
            row.disparity[l].push(s.pinhole_disparity(centre));
        }
    }
    row
}

/// The thin-lens estimate of one pixel: rounds of `n x n` stratified pixel x lens rays, each
/// round an independent estimate, until the standard error of their mean, measured where the
/// metrics measure it (sRGB-encoded and clipped, see [`display_error`]), is below
/// `options.tolerance` in every channel, or `options.max_rounds` are spent. The spread of the
/// round means is the honest error of a stratified estimate (the per-ray variance would
/// overstate it many times on smooth content). Small bright discs far out of focus, fine
/// texture under a small CoC and cut-out edges are what take extra rounds.
fn defocus_pixel(scene: &Scene, options: &TraceOptions, view: &View, x: usize, y: usize, first: &[PixelSamples]) -> Rgba {
    let (mut sum, mut sum_sq, mut alpha) = ([0.0f64; 3], [0.0f64; 3], 0.0f64);
    let mut taken = 0usize;
    for round in 0..options.max_rounds {
        let fresh;
        let samples = match first.get(round) {
            Some(s) => s,
            None => {
                fresh = pixel_samples(options, x, y, round);
                &fresh
            }
        };
        let mut round_sum = [0.0f32; 4];
        for (offset, lens) in samples.pixel.iter().zip(&samples.lens) {
            let (origin, dir) = view.lens_ray(x as f32 + offset[0], y as f32 + offset[1], *lens);
            accumulate(&mut round_sum, trace(&scene.surfaces, origin, dir), 1.0);
        }
        let n = samples.pixel.len() as f64;
        for c in 0..3 {
            let mean = round_sum[c] as f64 / n;
            (sum[c], sum_sq[c]) = (sum[c] + mean, sum_sq[c] + mean * mean);
        }
        alpha += round_sum[3] as f64 / n;
        taken += 1;
        if taken >= first.len() && (0..3).all(|c| display_error(sum[c], sum_sq[c], taken) <= options.tolerance as f64) {
            break;
        }
    }
    let k = taken as f64;
    [(sum[0] / k) as f32, (sum[1] / k) as f32, (sum[2] / k) as f32, (alpha / k) as f32]
}

/// Standard error, in sRGB-encoded display units clipped to [0, 1], of the mean of `rounds`
/// independent round means with sum `sum` and sum of squares `sum_sq`: the linear error times
/// the encoding's slope at the mean. A value certainly above display white (three standard
/// errors) is exact after clipping. One round gives no estimate and counts as converged.
fn display_error(sum: f64, sum_sq: f64, rounds: usize) -> f64 {
    if rounds < 2 {
        return 0.0;
    }
    let k = rounds as f64;
    let mean = sum / k;
    let variance = ((sum_sq - k * mean * mean) / (k - 1.0)).max(0.0);
    let error = (variance / k).sqrt();
    if mean - 3.0 * error >= 1.0 {
        return 0.0;
    }
    let x = mean.clamp(0.0, 1.0);
    let slope = if x <= 0.003_130_8 { 12.92 } else { 1.055 / 2.4 * x.powf(1.0 / 2.4 - 1.0) };
    slope * error
}

/// One pinhole sample: every surface is evaluated (each layer needs its own colour), and the
/// composite over them, nearest first, is the all-in-focus image.
fn pinhole_sample(scene: &Scene, view: &View, px: f32, py: f32, layer_sum: &mut [Rgba]) -> Rgba {
    let t = view.slope(px, py);
    let mut acc = [0.0; 4];
    for &(_, i, u, v) in Hits::find(&scene.surfaces, [0.0, 0.0], [t[0], t[1], 1.0]).iter() {
        let c = scene.surfaces[i].texture.sample(u, v);
        accumulate(&mut layer_sum[i], c, 1.0);
        over(&mut acc, c);
    }
    acc
}

/// Planar depth of the first surface whose alpha exceeds 0.5 along the pinhole ray `t`.
fn centre_depth(scene: &Scene, t: [f32; 2]) -> f32 {
    Hits::find(&scene.surfaces, [0.0, 0.0], [t[0], t[1], 1.0])
        .iter()
        .find(|&&(_, i, u, v)| scene.surfaces[i].texture.sample(u, v)[3] > 0.5)
        .map_or(EMPTY_DEPTH, |&(z, ..)| z)
}

#[inline]
fn accumulate(sum: &mut Rgba, c: Rgba, weight: f32) {
    for (s, c) in sum.iter_mut().zip(c) {
        *s += c * weight;
    }
}

fn assemble(scene: &Scene, coc: CocModel, width: usize, height: usize, rows: Vec<Row>) -> Result<GroundTruth> {
    let mut gt_rows = (Vec::new(), Vec::new(), Vec::new());
    let count = scene.surfaces.len();
    let (mut layer_px, mut layer_disp) = (vec![Vec::new(); count], vec![Vec::new(); count]);
    for row in rows {
        gt_rows.0.extend(row.defocused);
        gt_rows.1.extend(row.pinhole);
        gt_rows.2.extend(row.depth);
        for (l, (px, d)) in row.layers.into_iter().zip(row.disparity).enumerate() {
            layer_px[l].extend(px);
            layer_disp[l].extend(d);
        }
    }
    // Front to back by the depth where each surface crosses the optical axis.
    let mut order: Vec<usize> = (0..count).collect();
    order.sort_by(|&a, &b| scene.surfaces[a].z0.total_cmp(&scene.surfaces[b].z0));
    let layers = order
        .into_iter()
        .map(|l| Layer {
            name: scene.surfaces[l].name.clone(),
            rgba: Image { width, height, pixels: std::mem::take(&mut layer_px[l]) },
            disparity: std::mem::take(&mut layer_disp[l]),
        })
        .collect();
    Ok(GroundTruth {
        name: scene.name.clone(),
        camera: scene.camera,
        coc,
        pinhole: Image { width, height, pixels: gt_rows.1 },
        pinhole_depth: gt_rows.2,
        layers: LayerStack::new(width, height, layers)?,
        defocused: Image { width, height, pixels: gt_rows.0 },
    })
}

#[cfg(test)]
mod tests {
    use super::display_error;

    /// Sum and sum of squares of round means.
    fn moments(means: &[f64]) -> (f64, f64) {
        (means.iter().sum(), means.iter().map(|m| m * m).sum())
    }

    #[test]
    fn display_error_follows_the_encoding_slope_and_clipping() {
        let (s, q) = moments(&[0.49, 0.51, 0.49, 0.51]);
        // Sample variance of the round means 0.0004 / 3, standard error sqrt(0.0004 / 3 / 4),
        // times the sRGB slope at 0.5 (1.055/2.4 * 0.5^(-7/12) = 0.6596).
        let expected = (0.0004f64 / 3.0 / 4.0).sqrt() * 0.6596;
        assert!((display_error(s, q, 4) - expected).abs() < 1e-4, "{}", display_error(s, q, 4));
        let (s, q) = moments(&[0.009, 0.011, 0.009, 0.011]);
        // A tenth of the spread at 0.01, where the slope is 6.45 (ten times 0.5's): about the
        // same display error, as the metrics would see it.
        let dark = (0.000004f64 / 3.0 / 4.0).sqrt() * 6.45;
        assert!((display_error(s, q, 4) - dark).abs() < 1e-5, "{}", display_error(s, q, 4));
        let (s, q) = moments(&[20.0, 30.0, 25.0, 26.0]);
        assert_eq!(display_error(s, q, 4), 0.0, "certainly above white: exact after clipping");
        assert_eq!(display_error(0.3, 0.09, 1), 0.0, "one round gives no estimate");
    }
}
