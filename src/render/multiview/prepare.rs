//! What the multiview trace reads, built on the host and shared by the CPU reference and the
//! GPU path: per-layer disparity bounds, culling masks and the lens sample sets for the frame,
//! and, per window (a tile's reach; the whole frame for the CPU reference), the height fields
//! and mip pyramids of the premultiplied RGBA (coverage in alpha).
//!
//! Windows keep tiles bit-identical to the whole frame: a window's origin is a multiple of
//! 2^top (the highest mip level a ray reads) and it ends on such a multiple or at the frame's
//! edge, so each of its levels up to `top` holds, texel for texel, the whole frame's level
//! there (each texel the box filter of the same existing children). Reads clamp to the frame's
//! edges and then index the window.
use crate::render::lens_samples::LensSamples;
use rayon::prelude::*;

use crate::render::tiler::crop_rows;
use crate::render::Lens;
use crate::stack::LayerStack;
use crate::tile_grid::Rect;
use crate::{Error, Result};

use super::MultiviewParams;

pub(super) struct Prepared {
    pub width: usize,
    pub height: usize,
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
    /// Mip levels of the whole frame (down to 1x1): the cone's level clamp.
    pub level_count: usize,
    /// The highest mip level any ray reads: windows align to 2^top_level.
    pub top_level: usize,
    /// Pixels from a pixel within which its rays read heights and pyramid texels (any layer).
    pub margin: usize,
    /// The CPU reference's window, the whole frame ([`Prepared::with_planes`]), and its
    /// height fields and pyramids; the GPU path streams each tile's into device memory instead.
    pub window: Window,
    pub heights: Vec<f32>,
    pub pyramid: Vec<[f32; 4]>,
}

/// The part of the layers that a tile's rays read: `rect` (frame pixels) and its mip levels up
/// to the top level read, `[offset in a layer's pyramid, width, height, 0]` each.
pub(super) struct Window {
    pub rect: Rect,
    pub levels: Vec<[u32; 4]>,
    /// Texels of one layer's pyramid of the window; layer `l` starts at `l * pyramid_len`.
    pub pyramid_len: usize,
}

impl Window {
    fn new(rect: Rect, level_count: usize) -> Self {
        let levels = level_sizes(rect.width(), rect.height(), level_count);
        let pyramid_len = levels.last().map_or(0, |l| (l[0] + l[1] * l[2]) as usize);
        Self { rect, levels, pyramid_len }
    }
}

impl Prepared {
    /// Everything but the height fields and pyramids, which the caller makes from `stack`
    /// per window ([`Self::window_heights`], [`Self::window_pyramids`]).
    pub fn new(stack: &LayerStack, lens: &Lens, params: &MultiviewParams) -> Result<Self> {
        params.validate()?;
        let (width, height) = (stack.width, stack.height);
        if width == 0 || height == 0 || stack.layers.is_empty() {
            return Err(Error::data("multiview needs a non-empty stack with at least one layer"));
        }
        let samples = LensSamples::new(&lens.aperture, params.samples, params.patterns, params.seed)?;
        let (k, focus) = (lens.coc.k_px, lens.coc.focus_disparity);
        let cone = samples.spacing * params.cone_scale * k;
        let level_count = mip_level_count(width, height);
        let mut pr = Prepared {
            width,
            height,
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
            level_count,
            top_level: 0,
            margin: 0,
            window: Window::new(Rect { x0: 0, y0: 0, x1: width, y1: height }, level_count),
            heights: Vec::new(),
            pyramid: Vec::new(),
        };
        // Each layer's bounds and culling mask, the layers side by side (one after another,
        // they were most of a 1024^2 frame's preparation on a 16-core GPU machine).
        let per_layer: Vec<Result<([f32; 4], Vec<u32>)>> = stack
            .layers
            .par_iter()
            .map(|layer| {
                let covered: Vec<bool> = layer.rgba.pixels.iter().map(is_covered).collect();
                let (lo, hi) = covered.iter().zip(&layer.disparity).filter(|(&c, _)| c).fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), (_, &d)| (lo.min(d), hi.max(d)));
                let active = lo.is_finite() && hi.is_finite();
                if !active && covered.iter().any(|&c| c) {
                    return Err(Error::data(format!("layer '{}' has non-finite disparity", layer.name)));
                }
                let (lo, hi) = if active { (lo, hi) } else { (0.0, 0.0) };
                let mask = dilate(&covered, width, height, pr.reach(lo, hi));
                Ok(([lo, hi, if active { 1.0 } else { 0.0 }, 0.0], mask))
            })
            .collect();
        let mut widest = 0.0f32;
        for layer in per_layer {
            let (bounds, mask) = layer?;
            let [lo, hi, active, _] = bounds;
            // Inactive layers are never traced, so their (zero) bounds widen nothing.
            if active > 0.0 {
                widest = widest.max(pr.relative_reach(lo, hi));
            }
            pr.bounds.push(bounds);
            pr.occupancy.extend(mask);
        }
        (pr.top_level, pr.margin) = pr.read_extent(widest);
        Ok(pr)
    }

    /// [`Self::new`] with the whole frame's height fields and pyramids on the host (the CPU
    /// reference), read through the same window indexing as a GPU tile's.
    pub fn with_planes(stack: &LayerStack, lens: &Lens, params: &MultiviewParams) -> Result<Self> {
        let mut pr = Self::new(stack, lens, params)?;
        pr.heights = pr.window_heights(stack, &pr.window);
        let upper = pr.window_upper_levels(stack, &pr.window);
        pr.pyramid = pr.window_pyramids(stack, &pr.window, &upper).flatten().copied().collect();
        Ok(pr)
    }

    /// The window a tile with this `core` reads: the core grown by [`Self::margin`], then out
    /// to multiples of 2^top_level (or the frame's edge), with levels up to the top level.
    pub fn window(&self, core: Rect) -> Window {
        let grown = core.grown(self.margin, self.width, self.height);
        let align = 1usize << self.top_level;
        let rect = Rect {
            x0: grown.x0 / align * align,
            y0: grown.y0 / align * align,
            x1: (grown.x1.div_ceil(align) * align).min(self.width),
            y1: (grown.y1.div_ceil(align) * align).min(self.height),
        };
        Window::new(rect, self.top_level + 1)
    }

    /// Bound of how far a window reaches past its core: the margin, plus the alignment.
    pub fn window_halo(&self) -> usize {
        self.margin + (1 << self.top_level) - 1
    }

    /// The largest window of a `tile`-sided core (for the tile's memory footprint).
    pub fn largest_window(&self, tile: usize) -> Window {
        let side = |size: usize| (tile + 2 * self.window_halo()).min(size);
        Window::new(Rect { x0: 0, y0: 0, x1: side(self.width), y1: side(self.height) }, self.top_level + 1)
    }

    /// Every layer's height field over `window`, in order (`layers * area` texels): the
    /// disparity, empty pixels at the layer's far bound so that rays pass through holes. Rows
    /// on every core.
    pub fn window_heights(&self, stack: &LayerStack, window: &Window) -> Vec<f32> {
        let rect = window.rect;
        let mut heights = vec![0.0f32; stack.layers.len() * rect.area()];
        heights.par_chunks_mut(rect.width().max(1)).enumerate().for_each(|(row, out)| {
            let (l, y) = (row / rect.height(), rect.y0 + row % rect.height());
            let (layer, far) = (&stack.layers[l], self.bounds[l][0]);
            let span = y * self.width + rect.x0..y * self.width + rect.x1;
            let pixels = layer.rgba.pixels[span.clone()].iter().zip(&layer.disparity[span]);
            for (h, (p, &d)) in out.iter_mut().zip(pixels) {
                *h = if is_covered(p) { d } else { far };
            }
        });
        heights
    }

    /// Every layer's mip levels above level 0 over `window` ([`upper_levels`]), layer after
    /// layer: what [`Self::window_pyramids`] sends besides the layers' own rows.
    pub fn window_upper_levels(&self, stack: &LayerStack, window: &Window) -> Vec<Vec<[f32; 4]>> {
        stack.layers.iter().map(|layer| upper_levels(&layer.rgba.pixels, self.width, window.rect, &window.levels)).collect()
    }

    /// Every layer's pyramid over `window`, in order (`layers * pyramid_len` texels), as runs
    /// to copy: level 0 is the window's rows of the layer, the levels above are `upper` (from
    /// [`Self::window_upper_levels`]).
    pub fn window_pyramids<'a>(
        &'a self,
        stack: &'a LayerStack,
        window: &'a Window,
        upper: &'a [Vec<[f32; 4]>],
    ) -> impl Iterator<Item = &'a [[f32; 4]]> + 'a {
        stack.layers.iter().zip(upper).flat_map(move |(layer, upper)| {
            crop_rows(&layer.rgba.pixels, self.width, window.rect).chain(std::iter::once(upper.as_slice()))
        })
    }

    /// Whether layer `l` has coverage within reach of `pixel`'s rays (the culling mask).
    pub fn occupied(&self, l: usize, pixel: usize) -> bool {
        bit(&self.occupancy[l * self.occupancy_words..], pixel)
    }

    /// Pixels from `x` within which a ray of `x` can read layer texels with disparity in
    /// [lo, hi]: the largest CoC, plus the widest cone's trilinear footprint, plus a bilinear tap.
    fn reach(&self, lo: f32, hi: f32) -> usize {
        let rel = self.relative_reach(lo, hi);
        let level = self.level_for(self.cone * rel).ceil();
        (self.k * rel + 2.0f32.powf(level + 1.0) + 1.0).ceil() as usize
    }

    /// The largest |relative disparity| in [lo, hi].
    fn relative_reach(&self, lo: f32, hi: f32) -> f32 {
        (lo - self.focus).abs().max((hi - self.focus).abs())
    }

    /// For rays whose |relative disparity| is at most `rel`: the highest mip level they read
    /// (the trilinear read's upper level, one above the cone's; the ceiling and the extra pixel
    /// below absorb the ulps a computed disparity may stray past its bounds) and the pixels
    /// from the ray's pixel within which they read: the CoC, plus a level-L bilinear tap's
    /// texels (within 1.5 * 2^L + 0.5 of its position), plus the height lookup's rounding.
    fn read_extent(&self, rel: f32) -> (usize, usize) {
        let top = (self.level_for(self.cone * rel).ceil() as usize + 1).min(self.level_count - 1);
        let margin = (self.k * rel + 1.0 + 1.5 * (1u64 << top) as f32 + 0.5).ceil() as usize + 1;
        (top, margin)
    }

    /// Mip level of a cone `diameter` pixels wide (level 0 below one pixel).
    pub fn level_for(&self, diameter: f32) -> f32 {
        diameter.max(1.0).log2().min(self.level_count as f32 - 1.0)
    }

    /// The layer's height at the ray's position for disparity `t` (nearest texel, edge clamped).
    pub fn height(&self, l: usize, p: [f32; 2], u: [f32; 2], t: f32) -> f32 {
        let rel = t - self.focus;
        let x = nearest(p[0] + u[0] * rel, self.width);
        let y = nearest(p[1] + u[1] * rel, self.height);
        let rect = self.window.rect;
        self.heights[l * rect.area() + (y - rect.y0) * rect.width() + (x - rect.x0)]
    }

    /// Trilinear read of layer `l`'s pyramid at level-0 position `pos` for a cone `diameter`.
    pub fn sample_cone(&self, l: usize, pos: [f32; 2], diameter: f32) -> [f32; 4] {
        let level = self.level_for(diameter);
        let l0 = level.floor();
        let frac = level - l0;
        let l0 = l0 as usize;
        let l1 = (l0 + 1).min(self.level_count - 1);
        let a = self.bilinear(l, l0, pos);
        let b = self.bilinear(l, l1, pos);
        [0, 1, 2, 3].map(|c| a[c] + (b[c] - a[c]) * frac)
    }

    fn bilinear(&self, l: usize, level: usize, pos: [f32; 2]) -> [f32; 4] {
        let [offset, w, _, _] = self.window.levels[level];
        let (frame_w, frame_h) = (level_size(self.width, level), level_size(self.height, level));
        let (x_origin, y_origin) = (self.window.rect.x0 >> level, self.window.rect.y0 >> level);
        let scale = 1.0 / (1u32 << level) as f32;
        let cx = (pos[0] + 0.5) * scale - 0.5;
        let cy = (pos[1] + 0.5) * scale - 0.5;
        let (x0, y0) = (cx.floor(), cy.floor());
        let (fx, fy) = (cx - x0, cy - y0);
        let base = l * self.window.pyramid_len + offset as usize;
        let texel = |x: f32, y: f32| {
            let xi = x.clamp(0.0, frame_w as f32 - 1.0) as usize;
            let yi = y.clamp(0.0, frame_h as f32 - 1.0) as usize;
            self.pyramid[base + (yi - y_origin) * w as usize + (xi - x_origin)]
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

/// Texels across mip level `level` of a side of `size` pixels: each level half the previous,
/// rounded up (`ceil(size / 2^level)`), as the shader computes it.
fn level_size(size: usize, level: usize) -> usize {
    ((size - 1) >> level) + 1
}

/// Mip levels of a `width x height` image down to 1x1.
fn mip_level_count(width: usize, height: usize) -> usize {
    (0..).find(|&level| level_size(width, level) == 1 && level_size(height, level) == 1).unwrap_or(0) + 1
}

/// The first `count` mip levels of a `width x height` image: `[offset, width, height, 0]`.
/// Levels past 1x1 stay 1x1 (a window at the frame's corner may be 1x1 below its top level).
fn level_sizes(width: usize, height: usize, count: usize) -> Vec<[u32; 4]> {
    let mut offset = 0;
    (0..count)
        .map(|level| {
            let (w, h) = (level_size(width, level), level_size(height, level));
            let entry = [offset as u32, w as u32, h as u32, 0];
            offset += w * h;
            entry
        })
        .collect()
}

/// Mip chain of a `width x height` image down to 1x1: `[offset, width, height, 0]`.
#[cfg(test)]
fn mip_levels(width: usize, height: usize) -> Vec<[u32; 4]> {
    level_sizes(width, height, mip_level_count(width, height))
}

/// Box-filtered pyramid of a whole image.
#[cfg(test)]
fn build_pyramid(base: &[[f32; 4]], levels: &[[u32; 4]]) -> Vec<[f32; 4]> {
    let (width, height) = (levels[0][1] as usize, levels[0][2] as usize);
    window_pyramid(base, width, Rect { x0: 0, y0: 0, x1: width, y1: height }, levels)
}

/// The whole pyramid of `rect` ([`upper_levels`] after level 0), texel after texel.
#[cfg(test)]
fn window_pyramid(base: &[[f32; 4]], base_width: usize, rect: Rect, levels: &[[u32; 4]]) -> Vec<[f32; 4]> {
    let mut pyramid: Vec<[f32; 4]> = crop_rows(base, base_width, rect).flatten().copied().collect();
    pyramid.extend(upper_levels(base, base_width, rect, levels));
    pyramid
}

/// Levels 1 and up of the box-filtered pyramid of `rect` of a row-major image `base_width`
/// wide (level 0 is `rect` of the image itself), one after another: each texel the mean of its
/// up to four existing children, so alpha at level L is the coverage of its 2^L x 2^L
/// footprint. Each level's rows are computed on every core from the level below. A third of
/// level 0's texels at most; level 0 itself goes to the device as rows of the image (a
/// pyramid built texel by texel into write-combined staging memory, one layer after another,
/// was most of a 1024^2 multiview render's host time on an H200).
fn upper_levels(base: &[[f32; 4]], base_width: usize, rect: Rect, levels: &[[u32; 4]]) -> Vec<[f32; 4]> {
    let upper_len = levels.last().map_or(0, |l| (l[0] + l[1] * l[2]) as usize) - rect.area();
    let mut upper = vec![[0.0f32; 4]; upper_len];
    // The level being filled and the one below it, split off `upper` one after another.
    let mut below: &mut [[f32; 4]] = &mut [];
    let mut rest = upper.as_mut_slice();
    for (k, pair) in levels.windows(2).enumerate() {
        let ([_, pw, ph, _], [_, w, h, _]) = (pair[0], pair[1]);
        let (pw, ph, w, h) = (pw as usize, ph as usize, w as usize, h as usize);
        let (level, after) = std::mem::take(&mut rest).split_at_mut(w * h);
        if k == 0 {
            downsample(|x, y| base[(rect.y0 + y) * base_width + rect.x0 + x], pw, ph, w, level);
        } else {
            let previous: &[[f32; 4]] = below;
            downsample(|x, y| previous[y * pw + x], pw, ph, w, level);
        }
        (below, rest) = (level, after);
    }
    upper
}

/// Fills `out`, the level (`w` texels a row) above a `pw x ph` one whose texel (x, y) is
/// `previous(x, y)`, row by row on every core: each texel the mean of its existing children.
fn downsample(previous: impl Fn(usize, usize) -> [f32; 4] + Sync, pw: usize, ph: usize, w: usize, out: &mut [[f32; 4]]) {
    out.par_chunks_mut(w.max(1)).enumerate().for_each(|(y, row)| {
        for (x, texel) in row.iter_mut().enumerate() {
            let (mut sum, mut n) = ([0.0f32; 4], 0.0f32);
            for (cx, cy) in [(2 * x, 2 * y), (2 * x + 1, 2 * y), (2 * x, 2 * y + 1), (2 * x + 1, 2 * y + 1)] {
                if cx < pw && cy < ph {
                    let t = previous(cx, cy);
                    (0..4).for_each(|c| sum[c] += t[c]);
                    n += 1.0;
                }
            }
            *texel = sum.map(|s| s / n);
        }
    });
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

    /// The pyramid, its levels computed row by row on every core, is the one built texel by
    /// texel from the whole previous level (written out here), bit for bit, in the same order.
    #[test]
    fn pyramid_equals_the_levels_built_texel_by_texel() {
        for (w, h) in [(11usize, 6usize), (64, 37), (1, 9)] {
            let base = texels(w, h);
            let levels = mip_levels(w, h);
            let mut serial = base.clone();
            let mut previous = base.clone();
            for pair in levels.windows(2) {
                let ([_, pw, ph, _], [offset, nw, nh, _]) = (pair[0], pair[1]);
                let (pw, ph) = (pw as usize, ph as usize);
                assert_eq!(serial.len(), offset as usize, "level offsets");
                let mut next = Vec::new();
                for y in 0..nh as usize {
                    for x in 0..nw as usize {
                        let children: Vec<[f32; 4]> = [(2 * x, 2 * y), (2 * x + 1, 2 * y), (2 * x, 2 * y + 1), (2 * x + 1, 2 * y + 1)]
                            .into_iter()
                            .filter(|&(cx, cy)| cx < pw && cy < ph)
                            .map(|(cx, cy)| previous[cy * pw + cx])
                            .collect();
                        let sum = children.iter().fold([0.0f32; 4], |s, t| [s[0] + t[0], s[1] + t[1], s[2] + t[2], s[3] + t[3]]);
                        next.push(sum.map(|v| v / children.len() as f32));
                    }
                }
                serial.extend_from_slice(&next);
                previous = next;
            }
            let pyramid = build_pyramid(&base, &levels);
            assert_eq!(pyramid.len(), levels.last().map(|l| (l[0] + l[1] * l[2]) as usize).unwrap());
            assert_eq!(bits_of(&pyramid), bits_of(&serial), "{w}x{h}");
        }
    }

    /// A window whose origin is a multiple of 2^top and that ends on such a multiple or at the
    /// frame's edge holds, level by level up to `top`, the whole frame's texels over it: what
    /// keeps a tile's trace bit-identical to the whole frame's. Frame 23 x 13 (odd sides, so
    /// partial texels at the edges), tops 0 to 4 (4: the window's corner is 1x1 below it).
    #[test]
    fn an_aligned_window_pyramid_equals_the_frames_over_it() {
        let (w, h) = (23usize, 13usize);
        let base = texels(w, h);
        let frame_levels = mip_levels(w, h);
        let frame = build_pyramid(&base, &frame_levels);
        for top in 0..=4usize {
            let align = 1 << top;
            for (x0, y0, x1, y1) in [(0, 0, w, h), (align, 0, 2 * align, h), (align, align, w, h), (0, 0, align, align)] {
                let (x1, y1) = (x1.min(w), y1.min(h));
                if x0 >= x1 || y0 >= y1 {
                    continue;
                }
                let rect = Rect { x0, y0, x1, y1 };
                let window = Window::new(rect, top + 1);
                let pyramid = window_pyramid(&base, w, rect, &window.levels);
                assert_eq!(pyramid.len(), window.pyramid_len);
                for (level, &[offset, ww, wh, _]) in window.levels.iter().enumerate() {
                    let [frame_offset, fw, _, _] = frame_levels[level];
                    for y in 0..wh as usize {
                        for x in 0..ww as usize {
                            let ours = pyramid[offset as usize + y * ww as usize + x];
                            let (fx, fy) = (x + (x0 >> level), y + (y0 >> level));
                            let theirs = frame[frame_offset as usize + fy * fw as usize + fx];
                            assert_eq!(bits_of(&[ours]), bits_of(&[theirs]), "top {top} {rect:?} level {level} ({x}, {y})");
                        }
                    }
                }
            }
        }
    }

    /// Every tile's window starts on a multiple of 2^top, ends on one or at the frame's edge,
    /// holds its core grown by the margin, and stays within the halo the tiler is told of.
    #[test]
    fn windows_are_aligned_and_cover_the_reach() {
        use crate::camera::{Aperture, CocModel};
        use crate::image::Image;
        use crate::stack::Layer;
        let (w, h) = (97usize, 61usize);
        let layer = Layer { name: "l".into(), rgba: Image::from_fn(w, h, |_, _| [1.0; 4]), disparity: vec![0.9; w * h] };
        let stack = LayerStack::new(w, h, vec![layer]).unwrap();
        let lens = Lens { coc: CocModel::new(14.0, 0.5).unwrap(), aperture: Aperture::Disk };
        let params = MultiviewParams { samples: 16, cone_scale: 2.0, ..MultiviewParams::default() };
        let pr = Prepared::new(&stack, &lens, &params).unwrap();
        assert!(pr.top_level >= 3 && pr.margin > 1 << pr.top_level, "top {} margin {}", pr.top_level, pr.margin);
        let align = 1 << pr.top_level;
        for tile in [7, 20, 33] {
            for y0 in (0..h).step_by(tile) {
                for x0 in (0..w).step_by(tile) {
                    let core = Rect { x0, y0, x1: (x0 + tile).min(w), y1: (y0 + tile).min(h) };
                    let window = pr.window(core);
                    let (r, reach) = (window.rect, core.grown(pr.margin, w, h));
                    assert!(r.x0 % align == 0 && r.y0 % align == 0, "{core:?}: {r:?}");
                    assert!(r.x1 % align == 0 || r.x1 == w, "{core:?}: {r:?}");
                    assert!(r.y1 % align == 0 || r.y1 == h, "{core:?}: {r:?}");
                    assert!(r.x0 <= reach.x0 && r.y0 <= reach.y0 && r.x1 >= reach.x1 && r.y1 >= reach.y1, "{core:?}: {r:?}");
                    let halo = core.grown(pr.window_halo(), w, h);
                    assert!(r.x0 >= halo.x0 && r.y0 >= halo.y0 && r.x1 <= halo.x1 && r.y1 <= halo.y1, "{core:?}: {r:?}");
                    assert!(window.pyramid_len <= pr.largest_window(tile).pyramid_len);
                }
            }
        }
    }

    /// Distinct, non-dyadic texel values, so a misplaced child changes the mean.
    fn texels(w: usize, h: usize) -> Vec<[f32; 4]> {
        (0..w * h).map(|i| [i as f32 * 0.37, (i * 7 % 5) as f32, 0.25, (i % 3) as f32 / 3.0]).collect()
    }

    fn bits_of(texels: &[[f32; 4]]) -> Vec<u32> {
        texels.iter().flatten().map(|v| v.to_bits()).collect()
    }
}
