//! What the multiview trace reads, built once on the host and shared by the CPU reference
//! and the GPU path: per-layer disparity bounds, height fields, mip pyramids of the
//! premultiplied RGBA (coverage in alpha), culling masks and the lens sample sets.
use crate::render::lens_samples::LensSamples;
use crate::render::Lens;
use crate::stack::LayerStack;
use crate::{Error, Result};

use super::MultiviewParams;

pub(super) struct Prepared {
    pub width: usize,
    pub height: usize,
    /// Pixels per layer plane (`width * height`).
    pub plane: usize,
    pub layers: usize,
    pub k: f32,
    pub focus: f32,
    /// Cone diameter in pixels per unit of |relative disparity|.
    pub cone: f32,
    pub steps: u32,
    pub cull: bool,
    pub samples: LensSamples,
    /// Per layer `[far disparity, near disparity, 1 if it has coverage, 0]`.
    pub bounds: Vec<[f32; 4]>,
    /// Per layer, a plane of `occupancy_words` words holding one bit per pixel (bit `i % 32`
    /// of word `i / 32`): set when some covered pixel is within reach of the pixel's rays.
    /// Bits, not words: the mask is read once per pixel and layer, and 32x smaller.
    pub occupancy: Vec<u32>,
    pub occupancy_words: usize,
    /// Per mip level `[offset in a layer's pyramid, width, height, 0]`.
    pub levels: Vec<[u32; 4]>,
    /// Texels of one layer's pyramid; layer `l` starts at `l * pyramid_len`.
    pub pyramid_len: usize,
    /// Per layer plane: disparity, empty pixels at the layer's far bound
    /// ([`Prepared::height_texels`]). Held only by the CPU reference ([`Prepared::with_planes`]):
    /// the GPU path streams the texels into device memory instead of holding a host copy.
    pub heights: Vec<f32>,
    /// Every layer's pyramid ([`Prepared::pyramid_texels`]); CPU reference only, as `heights`.
    pub pyramid: Vec<[f32; 4]>,
}

impl Prepared {
    /// Everything but the height fields and pyramids, which the caller streams from `stack`
    /// where it needs them ([`Self::height_texels`], [`Self::pyramid_texels`]).
    pub fn new(stack: &LayerStack, lens: &Lens, params: &MultiviewParams) -> Result<Self> {
        params.validate()?;
        let (width, height) = (stack.width, stack.height);
        if width == 0 || height == 0 || stack.layers.is_empty() {
            return Err(Error::data("multiview needs a non-empty stack with at least one layer"));
        }
        let samples = LensSamples::new(&lens.aperture, params.samples, params.patterns, params.seed)?;
        let (k, focus) = (lens.coc.k_px, lens.coc.focus_disparity);
        let cone = samples.spacing * params.cone_scale * k;
        let levels = mip_levels(width, height);
        let pyramid_len = levels.last().map_or(0, |l| (l[0] + l[1] * l[2]) as usize);
        let mut pr = Prepared {
            width,
            height,
            plane: width * height,
            layers: stack.layers.len(),
            k,
            focus,
            cone,
            steps: params.steps,
            cull: params.cull,
            samples,
            bounds: Vec::new(),
            occupancy: Vec::new(),
            occupancy_words: (width * height).div_ceil(32),
            levels,
            pyramid_len,
            heights: Vec::new(),
            pyramid: Vec::new(),
        };
        for layer in &stack.layers {
            let covered: Vec<bool> = layer.rgba.pixels.iter().map(is_covered).collect();
            let (lo, hi) = covered.iter().zip(&layer.disparity).filter(|(&c, _)| c).fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), (_, &d)| (lo.min(d), hi.max(d)));
            let active = lo.is_finite() && hi.is_finite();
            if !active && covered.iter().any(|&c| c) {
                return Err(Error::data(format!("layer '{}' has non-finite disparity", layer.name)));
            }
            let (lo, hi) = if active { (lo, hi) } else { (0.0, 0.0) };
            pr.bounds.push([lo, hi, if active { 1.0 } else { 0.0 }, 0.0]);
            let reach = pr.reach(lo, hi);
            pr.occupancy.extend(dilate(&covered, width, height, reach));
        }
        Ok(pr)
    }

    /// [`Self::new`] with the height fields and pyramids held on the host (the CPU reference).
    pub fn with_planes(stack: &LayerStack, lens: &Lens, params: &MultiviewParams) -> Result<Self> {
        let mut pr = Self::new(stack, lens, params)?;
        pr.heights = pr.height_texels(stack).collect();
        pr.pyramid = pr.pyramid_texels(stack).collect();
        Ok(pr)
    }

    /// Every layer's height field in order (`layers * plane` texels): the disparity, empty
    /// pixels at the layer's far bound so that rays pass through holes.
    pub fn height_texels<'a>(&'a self, stack: &'a LayerStack) -> impl Iterator<Item = f32> + 'a {
        stack.layers.iter().zip(&self.bounds).flat_map(|(layer, &[far, ..])| {
            layer.rgba.pixels.iter().zip(&layer.disparity).map(move |(p, &d)| if is_covered(p) { d } else { far })
        })
    }

    /// Every layer's pyramid in order (`layers * pyramid_len` texels), built level by level
    /// as it is consumed ([`PyramidTexels`]).
    pub fn pyramid_texels<'a>(&'a self, stack: &'a LayerStack) -> impl Iterator<Item = [f32; 4]> + 'a {
        stack.layers.iter().flat_map(|layer| PyramidTexels::new(&layer.rgba.pixels, &self.levels))
    }

    /// Whether layer `l` has coverage within reach of `pixel`'s rays (the culling mask).
    pub fn occupied(&self, l: usize, pixel: usize) -> bool {
        bit(&self.occupancy[l * self.occupancy_words..], pixel)
    }

    /// Pixels from `x` within which a ray of `x` can read layer texels with disparity in
    /// [lo, hi]: the largest CoC, plus the widest cone's trilinear footprint, plus a bilinear tap.
    fn reach(&self, lo: f32, hi: f32) -> usize {
        let rel = (lo - self.focus).abs().max((hi - self.focus).abs());
        let level = self.level_for(self.cone * rel).ceil();
        (self.k * rel + 2.0f32.powf(level + 1.0) + 1.0).ceil() as usize
    }

    /// Mip level of a cone `diameter` pixels wide (level 0 below one pixel).
    pub fn level_for(&self, diameter: f32) -> f32 {
        diameter.max(1.0).log2().min(self.levels.len() as f32 - 1.0)
    }

    /// The layer's height at the ray's position for disparity `t` (nearest texel, edge clamped).
    pub fn height(&self, l: usize, p: [f32; 2], u: [f32; 2], t: f32) -> f32 {
        let rel = t - self.focus;
        let x = nearest(p[0] + u[0] * rel, self.width);
        let y = nearest(p[1] + u[1] * rel, self.height);
        self.heights[l * self.plane + y * self.width + x]
    }

    /// Trilinear read of layer `l`'s pyramid at level-0 position `pos` for a cone `diameter`.
    pub fn sample_cone(&self, l: usize, pos: [f32; 2], diameter: f32) -> [f32; 4] {
        let level = self.level_for(diameter);
        let l0 = level.floor();
        let frac = level - l0;
        let l0 = l0 as usize;
        let l1 = (l0 + 1).min(self.levels.len() - 1);
        let a = self.bilinear(l, l0, pos);
        let b = self.bilinear(l, l1, pos);
        [0, 1, 2, 3].map(|c| a[c] + (b[c] - a[c]) * frac)
    }

    fn bilinear(&self, l: usize, level: usize, pos: [f32; 2]) -> [f32; 4] {
        let [offset, w, h, _] = self.levels[level];
        let scale = 1.0 / (1u32 << level) as f32;
        let cx = (pos[0] + 0.5) * scale - 0.5;
        let cy = (pos[1] + 0.5) * scale - 0.5;
        let (x0, y0) = (cx.floor(), cy.floor());
        let (fx, fy) = (cx - x0, cy - y0);
        let base = l * self.pyramid_len + offset as usize;
        let texel = |x: f32, y: f32| {
            let xi = x.clamp(0.0, w as f32 - 1.0) as usize;
            let yi = y.clamp(0.0, h as f32 - 1.0) as usize;
            self.pyramid[base + yi * w as usize + xi]
        };
        let (t00, t10, t01, t11) = (texel(x0, y0), texel(x0 + 1.0, y0), texel(x0, y0 + 1.0), texel(x0 + 1.0, y0 + 1.0));
        [0, 1, 2, 3].map(|c| {
            let top = t00[c] + (t10[c] - t00[c]) * fx;
            let bottom = t01[c] + (t11[c] - t01[c]) * fx;
            top + (bottom - top) * fy
        })
    }
}

/// Nearest pixel centre, clamped (edge extension); `floor(x + 0.5)` as in the shader.
#[inline]
fn nearest(x: f32, size: usize) -> usize {
    (x + 0.5).floor().clamp(0.0, size as f32 - 1.0) as usize
}

/// Mip chain down to 1x1: `[offset, width, height, 0]`, each level half the previous (ceil).
fn mip_levels(width: usize, height: usize) -> Vec<[u32; 4]> {
    let (mut w, mut h, mut offset) = (width, height, 0usize);
    let mut levels = vec![[0, w as u32, h as u32, 0]];
    while w > 1 || h > 1 {
        offset += w * h;
        w = w.div_ceil(2);
        h = h.div_ceil(2);
        levels.push([offset as u32, w as u32, h as u32, 0]);
    }
    levels
}

/// Box-filtered pyramid: each texel is the mean of its (up to four) existing children, so
/// alpha at level L is the coverage of its 2^L x 2^L footprint.
#[cfg(test)]
fn build_pyramid(base: &[[f32; 4]], levels: &[[u32; 4]]) -> Vec<[f32; 4]> {
    PyramidTexels::new(base, levels).collect()
}

/// The texels of a box-filtered pyramid (each texel the mean of its up to four existing
/// children; alpha at level L is the coverage of its 2^L x 2^L footprint), level after level,
/// each level computed from the previous one when the iterator reaches it. Only that previous
/// level is held (a quarter of the base at most): a device buffer fills from this with no host
/// copy of the pyramid beside it.
struct PyramidTexels<'a> {
    base: &'a [[f32; 4]],
    levels: &'a [[u32; 4]],
    /// Index in `levels` of the level being yielded.
    level: usize,
    /// That level's texels, once past level 0 (which is `base`).
    texels: Vec<[f32; 4]>,
    /// The next texel of that level to yield.
    next: usize,
}

impl<'a> PyramidTexels<'a> {
    fn new(base: &'a [[f32; 4]], levels: &'a [[u32; 4]]) -> Self {
        Self { base, levels, level: 0, texels: Vec::new(), next: 0 }
    }
}

impl Iterator for PyramidTexels<'_> {
    type Item = [f32; 4];

    fn next(&mut self) -> Option<[f32; 4]> {
        loop {
            let current = if self.level == 0 { self.base } else { &self.texels };
            if let Some(&texel) = current.get(self.next) {
                self.next += 1;
                return Some(texel);
            }
            let &[_, w, h, _] = self.levels.get(self.level + 1)?;
            let [_, pw, ph, _] = self.levels[self.level];
            self.texels = downsample(current, pw as usize, ph as usize, w as usize, h as usize);
            (self.level, self.next) = (self.level + 1, 0);
        }
    }
}

/// The `w x h` level above a `pw x ph` one: each texel the mean of its existing children.
fn downsample(previous: &[[f32; 4]], pw: usize, ph: usize, w: usize, h: usize) -> Vec<[f32; 4]> {
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let (mut sum, mut n) = ([0.0f32; 4], 0.0f32);
            for (cx, cy) in [(2 * x, 2 * y), (2 * x + 1, 2 * y), (2 * x, 2 * y + 1), (2 * x + 1, 2 * y + 1)] {
                if cx < pw && cy < ph {
                    let t = previous[cy * pw + cx];
                    (0..4).for_each(|c| sum[c] += t[c]);
                    n += 1.0;
                }
            }
            out.push(sum.map(|s| s / n));
        }
    }
    out
}

/// A pixel with any coverage: it sets the layer's disparity bounds and its height field.
fn is_covered(pixel: &[f32; 4]) -> bool {
    pixel[3] > 0.0
}

/// Bit `i` of a bit plane (bit `i % 32` of word `i / 32`), as the shader reads it.
fn bit(words: &[u32], i: usize) -> bool {
    (words[i / 32] >> (i % 32)) & 1 == 1
}

/// Bit plane ([`bit`]): set where some covered pixel lies in the square of half-size `reach`
/// (summed-area table).
fn dilate(covered: &[bool], width: usize, height: usize, reach: usize) -> Vec<u32> {
    let stride = width + 1;
    let mut table = vec![0u32; stride * (height + 1)];
    for y in 0..height {
        for x in 0..width {
            table[(y + 1) * stride + x + 1] =
                u32::from(covered[y * width + x]) + table[y * stride + x + 1] + table[(y + 1) * stride + x] - table[y * stride + x];
        }
    }
    let mut out = vec![0u32; (width * height).div_ceil(32)];
    for y in 0..height {
        let (y0, y1) = (y.saturating_sub(reach), (y + reach + 1).min(height));
        for x in 0..width {
            let (x0, x1) = (x.saturating_sub(reach), (x + reach + 1).min(width));
            let count = table[y1 * stride + x1] + table[y0 * stride + x0] - table[y0 * stride + x1] - table[y1 * stride + x0];
            let i = y * width + x;
            out[i / 32] |= u32::from(count > 0) << (i % 32);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pyramid_alpha_is_coverage() {
        // A 5x3 layer, left 2 columns covered: level 1 (3x2) has coverage 1, 0, 0 per row.
        let base: Vec<[f32; 4]> = (0..15).map(|i| if i % 5 < 2 { [1.0, 0.5, 0.0, 1.0] } else { [0.0; 4] }).collect();
        let levels = mip_levels(5, 3);
        assert_eq!(levels.iter().map(|l| (l[1], l[2])).collect::<Vec<_>>(), vec![(5, 3), (3, 2), (2, 1), (1, 1)]);
        let pyramid = build_pyramid(&base, &levels);
        let level1: Vec<f32> = pyramid[15..21].iter().map(|t| t[3]).collect();
        assert_eq!(level1, vec![1.0, 0.0, 0.0, 1.0, 0.0, 0.0]);
        assert!((pyramid[21][3] - 1.0 / 2.0).abs() < 1e-6 && pyramid[22][3] == 0.0);
        // Odd sizes: a texel averages the children that exist, unweighted (0.5 and 0 -> 0.25).
        assert!((pyramid.last().unwrap()[3] - 0.25).abs() < 1e-6);
    }

    /// The packed mask has exactly the bits of a brute-force square search, across word
    /// boundaries and on a plane whose size is no multiple of 32 (13 x 7 = 91 pixels).
    #[test]
    fn dilation_reaches_exactly_the_square() {
        let (w, h) = (13usize, 7usize);
        let points = [(4usize, 4usize), (12, 0)];
        let mut covered = vec![false; w * h];
        points.iter().for_each(|&(x, y)| covered[y * w + x] = true);
        let mask = dilate(&covered, w, h, 2);
        assert_eq!(mask.len(), 3);
        assert_eq!(mask[2] >> (w * h - 64), 0, "no bit past the plane");
        for y in 0..h {
            for x in 0..w {
                let inside = points.iter().any(|&(px, py)| x.abs_diff(px) <= 2 && y.abs_diff(py) <= 2);
                assert_eq!(bit(&mask, y * w + x), inside, "({x}, {y})");
            }
        }
    }

    /// The streamed pyramid is the eager one: every level downsampled from the whole previous
    /// level (the eager construction, written out here), in the same texel order.
    #[test]
    fn streamed_pyramid_equals_the_levels_built_one_by_one() {
        let (w, h) = (11usize, 6usize);
        let base: Vec<[f32; 4]> = (0..w * h).map(|i| [i as f32, (i * 7 % 5) as f32, 0.25, (i % 3) as f32 / 2.0]).collect();
        let levels = mip_levels(w, h);
        let mut eager = base.clone();
        let mut previous = base.clone();
        for pair in levels.windows(2) {
            let next = downsample(&previous, pair[0][1] as usize, pair[0][2] as usize, pair[1][1] as usize, pair[1][2] as usize);
            assert_eq!(eager.len(), pair[1][0] as usize, "level offsets");
            eager.extend_from_slice(&next);
            previous = next;
        }
        let streamed: Vec<[f32; 4]> = PyramidTexels::new(&base, &levels).collect();
        assert_eq!(streamed.len(), levels.last().map(|l| (l[0] + l[1] * l[2]) as usize).unwrap());
        assert_eq!(bits_of(&streamed), bits_of(&eager));
    }

    fn bits_of(texels: &[[f32; 4]]) -> Vec<u32> {
        texels.iter().flatten().map(|v| v.to_bits()).collect()
    }
}
