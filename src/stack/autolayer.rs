//! Auto-layering of one flat RGB+Z image (DESIGN.md, "Layer stacks").
//!
//! 1. Slices uniformly spaced in signed CoC (Lee, Eisemann, Seidel 2009, Eq. 4: a constant
//!    CoC growth `delta` per layer), each boundary moved to the emptiest depth bin within
//!    half a slice, so cuts fall at depth discontinuities rather than through surfaces.
//! 2. Depth is not anti-aliased but colour is: pixels within `band_px` of a cut whose CoC
//!    jumps by at least `discontinuity_px` mix both sides. There alpha is estimated by
//!    projecting the colour onto the line between the local foreground and background
//!    colours; the front layer gets `c - (1 - alpha) B`, the back layer `B`, so "over"
//!    reproduces the input exactly while a blurred foreground can become transparent.
//! 3. Every farther layer is filled under every nearer one by push-pull from its own pixels
//!    only (so no nearer colour can leak in), weighted towards the far side of its slice as
//!    disocclusion fills prefer background.
use super::fill::push_pull;
use super::{Layer, LayerStack};
use crate::camera::CocModel;
use crate::image::Image;

#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AutoLayerOptions {
    /// CoC growth between consecutive layers in pixels (`delta` of Lee et al.; they use 3-10).
    pub coc_spacing_px: f32,
    pub max_layers: usize,
    /// Width of the soft band on each side of a cut (1-2 px).
    pub band_px: usize,
    /// Smallest CoC jump (pixels) between neighbours that counts as a depth discontinuity;
    /// smaller jumps are seams inside one surface and stay hard.
    pub discontinuity_px: f32,
}

impl Default for AutoLayerOptions {
    fn default() -> Self {
        Self { coc_spacing_px: 4.0, max_layers: 16, band_px: 1, discontinuity_px: 1.0 }
    }
}

/// Slice boundaries in signed CoC, descending (nearest first).
fn boundaries(coc: &[f32], options: &AutoLayerOptions) -> Vec<f32> {
    let (lo, hi) = coc.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &s| (lo.min(s), hi.max(s)));
    let spacing = options.coc_spacing_px.max(1e-3);
    if lo.is_nan() || hi.is_nan() || hi - lo <= 1e-6 {
        return Vec::new();
    }
    let slices = (((hi - lo) / spacing).ceil() as usize).clamp(1, options.max_layers.max(1));
    let step = (hi - lo) / slices as f32;
    const BINS_PER_SLICE: usize = 8;
    let bin = step / BINS_PER_SLICE as f32;
    let bins = slices * BINS_PER_SLICE;
    let mut histogram = vec![0usize; bins];
    for &s in coc {
        histogram[(((s - lo) / bin) as usize).min(bins - 1)] += 1;
    }
    let mut out: Vec<f32> = Vec::new();
    for i in 1..slices {
        let target = hi - i as f32 * step;
        let centre = |b: usize| lo + (b as f32 + 0.5) * bin;
        let first = ((target - 0.5 * step - lo) / bin).floor().max(0.0) as usize;
        let last = (((target + 0.5 * step - lo) / bin).ceil() as usize).min(bins - 1);
        let best = (first..=last).min_by(|&a, &b| {
            (histogram[a], (centre(a) - target).abs())
                .partial_cmp(&(histogram[b], (centre(b) - target).abs()))
                .unwrap_or(std::cmp::Ordering::Equal)
        });
        if let Some(b) = best {
            if !out.iter().any(|&x| (x - centre(b)).abs() < 0.5 * bin) {
                out.push(centre(b));
            }
        }
    }
    out.sort_by(|a, b| b.total_cmp(a));
    out
}

/// Layer index per pixel (0 = nearest), with empty slices removed; returns (labels, count).
fn labels(coc: &[f32], options: &AutoLayerOptions) -> (Vec<usize>, usize) {
    let cuts = boundaries(coc, options);
    let raw: Vec<usize> = coc.iter().map(|&s| cuts.iter().filter(|&&b| s < b).count()).collect();
    let mut used = vec![false; cuts.len() + 1];
    raw.iter().for_each(|&l| used[l] = true);
    let mut remap = vec![0usize; used.len()];
    let mut count = 0;
    for (l, &u) in used.iter().enumerate() {
        remap[l] = count;
        count += u as usize;
    }
    (raw.into_iter().map(|l| remap[l]).collect(), count)
}

/// A pixel at a depth discontinuity: colour mixes layer `front` and layer `back`.
#[derive(Clone, Copy, Debug)]
struct Band {
    front: usize,
    back: usize,
    /// Front layer's premultiplied colour and the hidden background colour here.
    front_rgba: [f32; 4],
    back_rgba: [f32; 4],
}

fn sub_scaled(a: [f32; 4], b: [f32; 4], s: f32) -> [f32; 4] {
    [a[0] - s * b[0], a[1] - s * b[1], a[2] - s * b[2], a[3] - s * b[3]]
}

fn dot(a: [f32; 4], b: [f32; 4]) -> f32 {
    a.iter().zip(&b).map(|(x, y)| x * y).sum()
}

/// For each pixel: the nearest and farthest other layer across a discontinuity within
/// `band_px` (the two candidates its colour may be mixed with).
fn band_pairs(
    w: usize,
    h: usize,
    label: &[usize],
    coc: &[f32],
    options: &AutoLayerOptions,
) -> Vec<Option<(usize, usize)>> {
    let r = options.band_px as i64;
    let mut out = vec![None; w * h];
    for y in 0..h as i64 {
        for x in 0..w as i64 {
            let p = (y as usize) * w + x as usize;
            let (mut near, mut far) = (usize::MAX, 0usize);
            for qy in (y - r).max(0)..=(y + r).min(h as i64 - 1) {
                for qx in (x - r).max(0)..=(x + r).min(w as i64 - 1) {
                    let q = qy as usize * w + qx as usize;
                    if label[q] != label[p] && (coc[q] - coc[p]).abs() >= options.discontinuity_px {
                        near = near.min(label[q]);
                        far = far.max(label[q]);
                    }
                }
            }
            if near != usize::MAX {
                out[p] = Some((near, far));
            }
        }
    }
    out
}

/// Mean colour of non-band pixels of layer `l` around (x, y), searching wider if needed.
fn local_colour(
    image: &Image,
    label: &[usize],
    pairs: &[Option<(usize, usize)>],
    l: usize,
    x: usize,
    y: usize,
    r0: usize,
) -> Option<[f32; 4]> {
    let (w, h) = (image.width as i64, image.height as i64);
    for r in [r0, 2 * r0, 4 * r0] {
        let r = r as i64;
        let (mut sum, mut n) = ([0.0f32; 4], 0usize);
        for qy in (y as i64 - r).max(0)..=(y as i64 + r).min(h - 1) {
            for qx in (x as i64 - r).max(0)..=(x as i64 + r).min(w - 1) {
                let q = qy as usize * image.width + qx as usize;
                if label[q] == l && pairs[q].is_none() {
                    let c = image.pixels[q];
                    (0..4).for_each(|k| sum[k] += c[k]);
                    n += 1;
                }
            }
        }
        if n > 0 {
            return Some(sum.map(|s| s / n as f32));
        }
    }
    None
}

/// Splits a band pixel's colour `c` between foreground `f` and background `b`; returns
/// (front colour, back colour, squared residual of the two-colour model).
fn split_colour(c: [f32; 4], f: [f32; 4], b: [f32; 4], hard_alpha: f32) -> ([f32; 4], [f32; 4], f32) {
    let fb = sub_scaled(f, b, 1.0);
    let norm = dot(fb, fb);
    // Indistinguishable colours carry no alpha information: keep the depth map's decision.
    let alpha = if norm > 1e-6 { (dot(sub_scaled(c, b, 1.0), fb) / norm).clamp(0.0, 1.0) } else { hard_alpha };
    let model = sub_scaled(sub_scaled(c, b, 1.0 - alpha), f, alpha);
    let front = sub_scaled(c, b, 1.0 - alpha).map(|v| v.max(0.0));
    (front, b, dot(model, model))
}

/// The split of pixel `p` against another layer `other`, if both sides have local colour.
fn band_with(
    image: &Image,
    label: &[usize],
    pairs: &[Option<(usize, usize)>],
    p: usize,
    other: usize,
    radius: usize,
) -> Option<(Band, f32)> {
    let (x, y) = (p % image.width, p / image.width);
    let (front, back) = (label[p].min(other), label[p].max(other));
    let f = local_colour(image, label, pairs, front, x, y, radius)?;
    let b = local_colour(image, label, pairs, back, x, y, radius)?;
    let hard = if label[p] == front { 1.0 } else { 0.0 };
    let (front_rgba, back_rgba, residual) = split_colour(image.pixels[p], f, b, hard);
    Some((Band { front, back, front_rgba, back_rgba }, residual))
}

fn bands(
    image: &Image,
    label: &[usize],
    pairs: &[Option<(usize, usize)>],
    options: &AutoLayerOptions,
) -> Vec<Option<Band>> {
    let radius = options.band_px + 2;
    (0..pairs.len())
        .map(|p| {
            // Mixed with whichever neighbouring layer explains the colour best.
            let (near, far) = pairs[p]?;
            let a = band_with(image, label, pairs, p, near, radius);
            let b = if far != near { band_with(image, label, pairs, p, far, radius) } else { None };
            match (a, b) {
                (Some(a), Some(b)) => Some(if b.1 < a.1 { b.0 } else { a.0 }),
                (a, b) => a.or(b).map(|(band, _)| band),
            }
        })
        .collect()
}

/// What layer `k` holds at one pixel.
enum Cell {
    Own([f32; 4]),
    Partial([f32; 4]),
    Hidden,
    Empty,
}

fn cell(k: usize, p: usize, image: &Image, label: &[usize], bands: &[Option<Band>]) -> Cell {
    match bands[p] {
        Some(b) if k == b.front => Cell::Partial(b.front_rgba),
        Some(b) if k == b.back => Cell::Own(b.back_rgba),
        Some(b) if k > b.back => Cell::Hidden,
        Some(_) => Cell::Empty,
        None if label[p] == k => Cell::Own(image.pixels[p]),
        None if label[p] < k => Cell::Hidden,
        None => Cell::Empty,
    }
}

fn build_layer(k: usize, image: &Image, disparity: &[f32], label: &[usize], bands: &[Option<Band>]) -> Layer {
    let (w, h, n) = (image.width, image.height, image.pixels.len());
    let own_disp = (0..n).filter(|&p| label[p] == k).map(|p| disparity[p]);
    let (d_far, d_near) = own_disp.fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), d| (lo.min(d), hi.max(d)));
    let guide = |d: f32| (-2.0 * (d - d_far) / (d_near - d_far).max(1e-6)).exp();
    let mut rgba = vec![[0.0f32; 4]; n];
    let mut colour_weight = vec![0.0f32; n];
    let mut hidden = vec![false; n];
    for p in 0..n {
        match cell(k, p, image, label, bands) {
            Cell::Own(c) => {
                rgba[p] = c;
                colour_weight[p] = guide(disparity[p]);
            }
            Cell::Partial(c) => rgba[p] = c,
            Cell::Hidden => hidden[p] = true,
            Cell::Empty => {}
        }
    }
    let mut filled = rgba.clone();
    push_pull(w, h, &mut filled, &colour_weight);
    for p in (0..n).filter(|&p| hidden[p]) {
        rgba[p] = filled[p];
    }
    let mut layer_disparity: Vec<[f32; 1]> = disparity.iter().map(|&d| [d]).collect();
    let depth_weight: Vec<f32> = label.iter().map(|&l| if l == k { 1.0 } else { 0.0 }).collect();
    push_pull(w, h, &mut layer_disparity, &depth_weight);
    Layer {
        name: format!("auto{k:02}"),
        rgba: Image { width: w, height: h, pixels: rgba },
        disparity: layer_disparity.into_iter().map(|d| d[0]).collect(),
    }
}

/// Splits one flat image with per-pixel disparity into a front-to-back layer stack whose
/// "over" composite reproduces the input (see module docs).
///
/// # Panics
/// If `disparity` does not have one value per pixel (readers guarantee it).
pub fn split_into_layers(image: &Image, disparity: &[f32], coc: &CocModel, options: &AutoLayerOptions) -> LayerStack {
    assert_eq!(disparity.len(), image.pixels.len(), "one disparity per pixel");
    let signed: Vec<f32> = disparity.iter().map(|&d| coc.signed_radius(d)).collect();
    let (label, count) = labels(&signed, options);
    let pairs = band_pairs(image.width, image.height, &label, &signed, options);
    let bands = bands(image, &label, &pairs, options);
    let layers = (0..count).map(|k| build_layer(k, image, disparity, &label, &bands)).collect();
    LayerStack { width: image.width, height: image.height, layers }
}

impl super::StackFile {
    /// Auto-layers a single-image file (`info.single_image`); other files are returned as is.
    pub fn into_layered(mut self, coc: &CocModel, options: &AutoLayerOptions) -> Self {
        if !self.info.single_image || self.stack.layers.len() != 1 {
            return self;
        }
        let source = &self.stack.layers[0];
        let stack = split_into_layers(&source.rgba, &source.disparity, coc, options);
        if let Some(template) = self.info.layers.first().cloned() {
            self.info.layers = stack
                .layers
                .iter()
                .map(|l| {
                    let range = l
                        .disparity
                        .iter()
                        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &d| (lo.min(d), hi.max(d)));
                    super::LayerInfo {
                        name: l.name.clone(),
                        disparity_range: range,
                        depth_weights: Vec::new(),
                        ..template.clone()
                    }
                })
                .collect();
        }
        self.stack = stack;
        self
    }
}
