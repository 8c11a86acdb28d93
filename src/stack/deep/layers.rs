//! Deep pixels to a layer stack (DESIGN.md, "Deep images"). The layers are the depth clusters
//! of all samples across the frame, found in signed CoC as auto-layering finds them in one
//! image: an empty gap of `discontinuity_px` of CoC between samples is a cut, so surfaces
//! blurred differently never share a layer. A cluster where some pixel holds two samples
//! farther apart than that (one surface seen through another of the same depth range) is
//! sliced every `coc_spacing_px`, so what is behind keeps a layer of its own; a cluster with
//! one sample per pixel is one surface and stays whole, however slanted, so no seam is cut
//! into it. Each sample keeps its own alpha: a layer's pixel is its samples composited front
//! to back with "over"; a volumetric sample (Z < ZBack) cut by a layer boundary is split per
//! OpenEXR's "Interpreting Deep Pixels" (alpha `1 - (1 - a)^t` for a fraction `t` of its
//! thickness, colour in proportion). Pixels with no sample in a layer are empty (alpha 0); the
//! layer's disparity is continued under them from its own samples.
use super::{DeepImage, DeepSample};
use crate::camera::{disparity_from_z, CocModel};
use crate::image::Image;
use crate::stack::autolayer::runs_between_gaps;
use crate::stack::fill::push_pull;
use crate::stack::{Layer, LayerStack};
use crate::Result;

#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DeepLayerOptions {
    /// Smallest empty CoC gap (pixels) between samples that separates two layers.
    pub discontinuity_px: f32,
    /// Slice thickness (CoC pixels) of a cluster where surfaces overlap in depth.
    pub coc_spacing_px: f32,
    pub max_layers: usize,
}

impl Default for DeepLayerOptions {
    fn default() -> Self {
        Self { discontinuity_px: 1.0, coc_spacing_px: 4.0, max_layers: 16 }
    }
}

/// Histogram resolution of the signed CoC when looking for clusters (as auto-layering).
const BIN_PX: f32 = 0.25;

/// The layer stack of `image` for a lens of CoC model `coc` (depths in the same scene units).
pub fn deep_to_layers(image: &DeepImage, coc: &CocModel, options: &DeepLayerOptions) -> Result<LayerStack> {
    let (width, height) = (image.width, image.height);
    let n = width * height;
    // A lens without blur still needs depth order: cluster by disparity at 1 px per unit.
    let k = if coc.k_px > 1e-6 { coc.k_px } else { 1.0 };
    let signed = |z: f32| k * (disparity_from_z(z) - coc.focus_disparity);
    let mut sorted: Vec<DeepSample> = image.samples.clone();
    for i in 0..n {
        let range = image.offsets[i] as usize..image.offsets[i + 1] as usize;
        sorted[range].sort_by(|a, b| a.z.total_cmp(&b.z).then(a.z_back.total_cmp(&b.z_back)));
    }
    let pixel = |i: usize| &sorted[image.offsets[i] as usize..image.offsets[i + 1] as usize];
    let cuts = cuts(n, &pixel, &signed, options);
    let count = cuts.len() + 1;
    // Layer of a signed CoC: the number of cuts at or above it (cuts descend, nearest first).
    let layer_of = |s: f32| cuts.iter().take_while(|&&c| c >= s).count();
    let mut rgba = vec![vec![[0.0f32; 4]; n]; count];
    // Per layer and pixel: alpha-weighted disparity sum, its weight, and whether any sample fell there.
    let mut disparity_sum = vec![vec![[0.0f32; 2]; n]; count];
    let mut covered = vec![vec![0.0f32; n]; count];
    let z_of_coc = |s: f32| {
        let d = s / k + coc.focus_disparity;
        if d > 0.0 {
            1.0 / d
        } else {
            f32::INFINITY
        }
    };
    for i in 0..n {
        for s in pixel(i) {
            let (front, back) = (signed(s.z), signed(s.z_back));
            let (first, last) = (layer_of(front), layer_of(back));
            if first == last || !(s.z_back > s.z) || !s.z_back.is_finite() {
                add(
                    &mut rgba[first][i],
                    &mut disparity_sum[first][i],
                    &mut covered[first][i],
                    s.rgba,
                    disparity_from_z(s.z),
                );
                continue;
            }
            // A volume cut by layer boundaries: one piece per layer it crosses, front first.
            let alpha = s.rgba[3].clamp(0.0, 1.0);
            let thickness = s.z_back - s.z;
            let mut start = s.z;
            for layer in first..=last {
                let end = if layer == last { s.z_back } else { z_of_coc(cuts[layer]).clamp(start, s.z_back) };
                let t = (end - start) / thickness;
                let piece_alpha = 1.0 - (1.0 - alpha).powf(t);
                let scale = if alpha > 0.0 { piece_alpha / alpha } else { t };
                let piece = [s.rgba[0] * scale, s.rgba[1] * scale, s.rgba[2] * scale, piece_alpha];
                let middle = disparity_from_z(0.5 * (start + end));
                add(&mut rgba[layer][i], &mut disparity_sum[layer][i], &mut covered[layer][i], piece, middle);
                start = end;
            }
        }
    }
    let mut layers = Vec::with_capacity(count);
    for (index, ((colour, sums), cover)) in rgba.into_iter().zip(disparity_sum).zip(covered).enumerate() {
        let mut disparity: Vec<[f32; 1]> =
            sums.iter().map(|&[sum, weight]| [if weight > 0.0 { sum / weight } else { 0.0 }]).collect();
        push_pull(width, height, &mut disparity, &cover);
        let mut layer_image = Image::new(width, height);
        layer_image.pixels = colour;
        layers.push(Layer {
            name: format!("deep{index}"),
            rgba: layer_image,
            disparity: disparity.into_iter().map(|[d]| d).collect(),
        });
    }
    // Layers no sample reached (a cut that only a volume's piece crossed) carry nothing.
    layers.retain(|l| l.rgba.pixels.iter().any(|p| p[3] > 0.0 || p[0] != 0.0 || p[1] != 0.0 || p[2] != 0.0));
    if layers.is_empty() {
        layers.push(Layer { name: "deep0".into(), rgba: Image::new(width, height), disparity: vec![0.0; n] });
    }
    LayerStack::new(width, height, layers)
}

/// Composites a sample behind what the layer's pixel holds and adds its disparity, weighted
/// by the alpha it contributes (a little weight for a transparent emitter, so it still counts).
fn add(rgba: &mut [f32; 4], disparity: &mut [f32; 2], covered: &mut f32, sample: [f32; 4], d: f32) {
    let transmitted = 1.0 - rgba[3].clamp(0.0, 1.0);
    for c in 0..4 {
        rgba[c] += transmitted * sample[c];
    }
    let weight = transmitted * sample[3].max(0.0) + 1e-6;
    disparity[0] += weight * d;
    disparity[1] += weight;
    *covered = 1.0;
}

/// Layer boundaries in signed CoC, descending (nearest first).
fn cuts<'a>(
    n: usize,
    pixel: &dyn Fn(usize) -> &'a [DeepSample],
    signed: &dyn Fn(f32) -> f32,
    options: &DeepLayerOptions,
) -> Vec<f32> {
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for i in 0..n {
        for s in pixel(i) {
            for v in [signed(s.z), signed(s.z_back)] {
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
    }
    if !(hi - lo > 1e-6) {
        return Vec::new();
    }
    let bin = BIN_PX.max((hi - lo) / (1 << 20) as f32);
    let bins = ((hi - lo) / bin).floor() as usize + 1;
    let bin_of = |v: f32| (((v - lo) / bin) as usize).min(bins - 1);
    let mut histogram = vec![0usize; bins];
    for i in 0..n {
        for s in pixel(i) {
            let (a, b) = (bin_of(signed(s.z_back)), bin_of(signed(s.z)));
            // A volume occupies every bin it spans.
            for h in &mut histogram[a.min(b)..=a.max(b)] {
                *h += 1;
            }
        }
    }
    // Runs of occupied bins separated by gaps of at least the discontinuity.
    let min_gap = ((options.discontinuity_px / bin).round() - 1.0).max(1.0) as usize;
    let runs = runs_between_gaps(&histogram, min_gap);
    let gaps = runs.windows(2).map(|w| (lo + 0.5 * (w[0].1 + w[1].0) as f32 * bin, (w[1].0 - w[0].1) as f32));
    // Runs where some pixel has two samples apart by the discontinuity: surfaces overlap in
    // depth there, so they are sliced.
    let mut overlapping = vec![false; runs.len()];
    let run_of = |v: f32| {
        let b = bin_of(v);
        runs.iter().position(|&(s, e)| b >= s && b < e)
    };
    for i in 0..n {
        let samples = pixel(i);
        for pair in samples.windows(2) {
            let (a, b) = (signed(pair[0].z), signed(pair[1].z));
            if (a - b).abs() >= options.discontinuity_px {
                if let (Some(ra), Some(rb)) = (run_of(a), run_of(b)) {
                    if ra == rb {
                        overlapping[ra] = true;
                    }
                }
            }
        }
    }
    let mut cuts: Vec<(f32, f32)> = gaps.collect();
    for (&(start, end), _) in runs.iter().zip(&overlapping).filter(|(_, &o)| o) {
        let width = (end - start) as f32 * bin;
        // No more slices than layers can be kept: a forged depth (Z of 1e-40) spans a CoC range
        // so wide that uncapped slicing would allocate without bound (found by the fuzzer).
        let slices = ((width / options.coc_spacing_px.max(1e-3)).ceil() as usize).min(options.max_layers.max(1));
        for s in 1..slices {
            cuts.push((lo + start as f32 * bin + width * s as f32 / slices as f32, 0.0));
        }
    }
    // Beyond the most layers: the slices go first, then the narrowest gaps.
    cuts.sort_by(|a, b| b.1.total_cmp(&a.1));
    cuts.truncate(options.max_layers.max(1) - 1);
    let mut out: Vec<f32> = cuts.into_iter().map(|c| c.0).collect();
    out.sort_by(|a, b| b.total_cmp(a));
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    fn image(width: usize, height: usize, pixels: Vec<Vec<DeepSample>>) -> DeepImage {
        let mut offsets = vec![0u64];
        for p in &pixels {
            offsets.push(offsets.last().unwrap() + p.len() as u64);
        }
        DeepImage { width, height, origin: [0, 0], offsets, samples: pixels.concat(), attributes: BTreeMap::new() }
    }

    fn point(rgba: [f32; 4], z: f32) -> DeepSample {
        DeepSample { rgba, z, z_back: z }
    }

    #[test]
    fn separate_depths_become_separate_layers_with_their_own_alpha() {
        let coc = CocModel::new(20.0, 0.5).unwrap();
        let near = point([0.5, 0.0, 0.0, 0.5], 1.0);
        let far = point([0.0, 0.0, 1.0, 1.0], 10.0);
        let deep = image(2, 1, vec![vec![far, near], vec![far]]);
        let stack = deep_to_layers(&deep, &coc, &DeepLayerOptions::default()).unwrap();
        assert_eq!(stack.layers.len(), 2);
        assert_eq!(stack.layers[0].rgba.pixels, vec![[0.5, 0.0, 0.0, 0.5], [0.0; 4]]);
        assert_eq!(stack.layers[1].rgba.pixels, vec![[0.0, 0.0, 1.0, 1.0]; 2]);
        assert!((stack.layers[0].disparity[1] - 1.0).abs() < 1e-6, "continued under the empty pixel");
        // Flattening the stack is flattening the deep pixels.
        assert_eq!(stack.flatten().0.pixels, deep.flatten().pixels);
    }

    #[test]
    fn a_volume_cut_by_a_boundary_splits_its_alpha_by_thickness() {
        let coc = CocModel::new(20.0, 0.0).unwrap();
        // A volume from z 1.5 to 3 (CoC 13.3 to 6.7 px) with a surface at z 2.5 behind it in the
        // same pixel: the cluster is sliced, and the volume with it.
        let volume = DeepSample { rgba: [0.4, 0.4, 0.4, 0.8], z: 1.5, z_back: 3.0 };
        let behind = point([0.0, 1.0, 0.0, 1.0], 2.5);
        let deep = image(2, 1, vec![vec![behind, volume], vec![point([1.0, 0.0, 0.0, 1.0], 1.0)]]);
        let stack = deep_to_layers(&deep, &coc, &DeepLayerOptions::default()).unwrap();
        let pieces: Vec<[f32; 4]> = stack.layers.iter().map(|l| l.rgba.pixels[0]).filter(|p| p[3] > 0.0).collect();
        assert!(pieces.len() >= 2, "{pieces:?}");
        assert!(pieces[0][3] < 0.8, "the front piece has part of the alpha: {pieces:?}");
        // The pieces composite back to the deep pixel.
        let (flat, deep_flat) = (stack.flatten().0, deep.flatten());
        for c in 0..4 {
            assert!(
                (flat.pixels[0][c] - deep_flat.pixels[0][c]).abs() < 1e-4,
                "{:?} vs {:?}",
                flat.pixels[0],
                deep_flat.pixels[0]
            );
        }
    }
}
