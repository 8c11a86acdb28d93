//! Assembling a [`GroundTruth`]: one pass over the image renders, per pixel, the thin-lens
//! image, the pinhole image, every surface alone (the true layers) and the depth maps.
use rayon::prelude::*;

use super::scene::Scene;
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
    if let Some(bar) = &options.progress {
        bar.set_length(height as u64);
    }
    let rows: Vec<Row> = (0..height)
        .into_par_iter()
        .map(|y| {
            let row = render_row(scene, options, &view, y);
            if let Some(bar) = &options.progress {
                bar.inc(1);
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
        let samples = pixel_samples(options, x, y, 0);
        let weight = 1.0 / samples.pixel.len() as f32;
        let mut pinhole = [0.0f32; 4];
        layer_sum.iter_mut().for_each(|s| *s = [0.0; 4]);
        for offset in &samples.pixel {
            accumulate(&mut pinhole, pinhole_sample(scene, view, x as f32 + offset[0], y as f32 + offset[1], &mut layer_sum), weight);
        }
        let defocused = defocus_pixel(scene, options, view, x, y, &samples);
        row.pinhole.push(pinhole);
        row.defocused.push(defocused);
        for (l, sum) in layer_sum.iter().enumerate() {
            row.layers[l].push(sum.map(|c| c * weight));
        }
        let centre = view.slope(x as f32 + 0.5, y as f32 + 0.5);
        row.depth.push(centre_depth(scene, centre));
        for (l, s) in scene.surfaces.iter().enumerate() {
            row.disparity[l].push(s.pinhole_disparity(centre));
        }
    }
    row
}

/// Relative standard error a pixel seeing HDR highlights must reach before it stops taking
/// extra rounds; 2% keeps bokeh balls visibly smooth.
const HIGHLIGHT_TOLERANCE: f32 = 0.02;

/// The thin-lens estimate of one pixel. A small, very bright disc far out of focus is seen
/// through a small part of the lens, so one round of 256 stratified rays leaves bokeh balls
/// grainy; pixels whose samples saw HDR values (luminance > 1) and whose standard error
/// (per-sample variance / count, an over-estimate for stratified samples) exceeds
/// [`HIGHLIGHT_TOLERANCE`] of their mean take more rounds, up to `options.max_rounds`.
fn defocus_pixel(scene: &Scene, options: &TraceOptions, view: &View, x: usize, y: usize, first: &PixelSamples) -> Rgba {
    let (mut sum, mut lum_sum, mut lum_sq, mut count, mut brightest) = ([0.0f32; 4], 0.0f64, 0.0f64, 0usize, 0.0f32);
    for round in 0..options.max_rounds {
        let fresh;
        let samples = if round == 0 { first } else { fresh = pixel_samples(options, x, y, round); &fresh };
        for (offset, lens) in samples.pixel.iter().zip(&samples.lens) {
            let (origin, dir) = view.lens_ray(x as f32 + offset[0], y as f32 + offset[1], *lens);
            let c = trace(&scene.surfaces, origin, dir);
            let lum = 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
            accumulate(&mut sum, c, 1.0);
            (lum_sum, lum_sq, brightest) = (lum_sum + lum as f64, lum_sq + (lum * lum) as f64, brightest.max(lum));
        }
        count += samples.pixel.len();
        let mean = lum_sum / count as f64;
        let std_error = ((lum_sq / count as f64 - mean * mean).max(0.0) / count as f64).sqrt();
        if brightest <= 1.0 || std_error <= HIGHLIGHT_TOLERANCE as f64 * mean {
            break;
        }
    }
    sum.map(|c| c / count as f32)
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

/// Planar depth of the first surface whose alpha exceeds 0.5 along the centre ray.
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
