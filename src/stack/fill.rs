//! Push-pull hole filling (Gortler et al. 1996): weighted averages down an image pyramid,
//! then each finer level takes the coarse value wherever its own weight is missing. Used to
//! define depth under transparent pixels and to fill hidden background behind cut layers.
//! It is smooth, has no parameters to tune, and never invents values outside the range of
//! the known samples (every output is a convex combination of them).
//!
//! [`mirror_sources`] is the structure-keeping complement near a hole's edge: each hole pixel
//! names the known pixel mirrored across the edge (the symmetric fill of Virtual DSLR, Yang
//! et al. 2016), so what is cut by an occluder (an HDR light) continues at full strength.

use rayon::prelude::*;

/// Reversible range compression `c / (1 + max(r, g, b))` (alpha kept): averages taken in it
/// are not ruled by a few HDR lights, so a light next to a cut cannot smear over the hidden
/// background or into a matte (issue 22, failure 1).
pub(crate) fn compress(c: [f32; 4]) -> [f32; 4] {
    let s = 1.0 / (1.0 + c[0].max(c[1]).max(c[2]).max(0.0));
    [c[0] * s, c[1] * s, c[2] * s, c[3]]
}

/// Whether a colour is brighter than display white in any channel: a light, for the rules of
/// the auto-layering and the matte that treat lights apart.
pub(crate) fn is_hdr(c: [f32; 4]) -> bool {
    c[0].max(c[1]).max(c[2]) > 1.0
}

/// The 4-neighbours of pixel `p` in a `width` x `height` frame, in a fixed order (left, right,
/// up, down); `None` beyond the frame's edge.
pub(crate) fn four_neighbours(p: usize, width: usize, height: usize) -> [Option<usize>; 4] {
    let (x, y) = (p % width, p / width);
    [(x > 0).then(|| p - 1), (x + 1 < width).then(|| p + 1), (y > 0).then(|| p - width), (y + 1 < height).then(|| p + width)]
}

/// How many pixels in a row from pixel `p` on (not counting it), one way along `step`, `lit`
/// accepts, up to `max`: one side of a run through `p` (the image's edge ends it).
pub(crate) fn run_from(width: usize, height: usize, p: usize, step: (i64, i64), max: usize, lit: impl Fn(usize) -> bool) -> usize {
    let (x, y) = ((p % width) as i64, (p / width) as i64);
    (1..=max as i64)
        .take_while(|&k| {
            let (qx, qy) = (x + k * step.0, y + k * step.1);
            qx >= 0 && qy >= 0 && qx < width as i64 && qy < height as i64 && lit(qy as usize * width + qx as usize)
        })
        .count()
}

/// The inverse of [`compress`].
pub(crate) fn expand(c: [f32; 4]) -> [f32; 4] {
    let s = 1.0 / (1.0 - c[0].max(c[1]).max(c[2]).clamp(0.0, 0.999));
    [c[0] * s, c[1] * s, c[2] * s, c[3]]
}

struct Level<const N: usize> {
    width: usize,
    height: usize,
    values: Vec<[f32; N]>,
    weights: Vec<f32>,
}

/// The fine pixels that carry weight among the 2x2 block under coarse pixel (x, y) of a level
/// `width` x `height` with `weights`.
///
/// Four calls of one closure, not an array map: the map's closure was left uninlined in the
/// pull, the fills' widest loop.
#[inline]
fn pull_children(width: usize, height: usize, weights: &[f32], x: usize, y: usize) -> [Option<usize>; 4] {
    let child = |dx: usize, dy: usize| {
        let (fx, fy) = (2 * x + dx, 2 * y + dy);
        let i = fy * width + fx;
        // Weightless values are undefined (may be NaN or infinite): never read.
        (fx < width && fy < height && weights[i] > 0.0).then_some(i)
    };
    [child(0, 0), child(1, 0), child(0, 1), child(1, 1)]
}

/// The next coarser level, row by row on every core (each coarse pixel reads its own 2x2 block):
/// the pyramid of every layer with transparent pixels is built while a stack is read, and one
/// thread's passes were most of reading a large layered EXR.
fn pull<const N: usize>(fine: &Level<N>) -> Level<N> {
    pull_from(fine.width, fine.height, &fine.values, &fine.weights)
}

/// [`pull`] from a level given as its arrays (the finest level is the caller's own).
fn pull_from<const N: usize>(fine_width: usize, fine_height: usize, fine_values: &[[f32; N]], fine_weights: &[f32]) -> Level<N> {
    let (width, height) = (fine_width.div_ceil(2), fine_height.div_ceil(2));
    let mut values = vec![[0.0; N]; width * height];
    let mut weights = vec![0.0; width * height];
    values.par_chunks_mut(width).zip(weights.par_chunks_mut(width)).enumerate().for_each(|(y, (values, weights))| {
        // The block's two fine rows (the second may lie below the frame), read as slices: the
        // children in [`pull_children`]'s order, the same sums, without an index computed and
        // tested against the frame for each.
        let fine_row = |fy: usize| (fy < fine_height).then(|| (&fine_weights[fy * fine_width..][..fine_width], &fine_values[fy * fine_width..][..fine_width]));
        let rows = [fine_row(2 * y), fine_row(2 * y + 1)];
        for x in 0..width {
            let (mut sum, mut total) = ([0.0f32; N], 0.0f32);
            for (row_weights, row_values) in rows.iter().flatten() {
                for fx in (2 * x..2 * x + 2).take_while(|&fx| fx < fine_width) {
                    // Weightless values are undefined (may be NaN or infinite): never read.
                    let w = row_weights[fx];
                    if w > 0.0 {
                        total += w;
                        for (s, v) in sum.iter_mut().zip(row_values[fx]) {
                            *s += w * v;
                        }
                    }
                }
            }
            if total > 0.0 {
                values[x] = sum.map(|s| s / total);
            }
            weights[x] = total.min(1.0);
        }
    });
    Level { width, height, values, weights }
}

/// The first coarse pixel (unclamped) and the bilinear fraction towards the next for the
/// centre of fine pixel `v` (see [`coarse_taps`]).
fn coarse_corner(v: usize) -> (i64, f32) {
    ((v as i64 + 1) / 2 - 1, if v % 2 == 0 { 0.75 } else { 0.25 })
}

/// The coarse pixels that [`sample_coarse`] blends for the centre of fine pixel (x, y): up to
/// four (index, bilinear weight x level weight), only those carrying weight, and the pixel
/// used when none does.
///
/// The centre of fine pixel `x` lies at coarse coordinate `x / 2 - 1/4`: for an even `x = 2m`
/// that is `m - 1/4` (taps `m - 1` and `m`, fraction 3/4), for an odd one `m + 1/4` (taps `m`
/// and `m + 1`, fraction 1/4). Integer arithmetic gives the exact floor and fraction the float
/// form `floor((x + 0.5) * 0.5 - 0.5)` gives, without a `floor` call per pixel (it was a fifth
/// of the layering's time).
#[inline]
fn coarse_taps(width: usize, height: usize, weights: &[f32], x: usize, y: usize) -> ([(usize, f32); 4], usize, usize) {
    weighted_taps(full_coarse_taps(width, height, x, y), weights)
}

/// [`coarse_taps`] from the bilinear taps ([`full_coarse_taps`]) of the fine pixel.
#[inline]
fn weighted_taps(bilinear: [(usize, f32); 4], weights: &[f32]) -> ([(usize, f32); 4], usize, usize) {
    let (mut taps, mut count) = ([(0, 0.0); 4], 0);
    for (i, w) in bilinear {
        let w = w * weights[i];
        if w > 0.0 {
            taps[count] = (i, w);
            count += 1;
        }
    }
    // The first tap: the clamped corner pixel.
    (taps, count, bilinear[0].0)
}

/// Bilinear sample of a coarse level at the centre of fine pixel (x, y), using only
/// coarse pixels that carry weight (so empty regions do not pull values towards zero).
#[inline]
fn sample_coarse<const N: usize>(coarse: &Level<N>, bilinear: [(usize, f32); 4]) -> [f32; N] {
    let (taps, count, fallback) = weighted_taps(bilinear, &coarse.weights);
    let (mut sum, mut total) = ([0.0f32; N], 0.0f32);
    for &(i, w) in &taps[..count] {
        total += w;
        for (s, v) in sum.iter_mut().zip(coarse.values[i]) {
            *s += w * v;
        }
    }
    if total > 0.0 {
        sum.map(|s| s / total)
    } else {
        coarse.values[fallback]
    }
}

/// [`sample_coarse`] on a level every pixel of which has weight 1, as every level but the top
/// has once it is pushed: all four taps count and their bilinear weights (products of 1/4 and
/// 3/4) sum to exactly 1, so this plain sum adds the same terms in the same order and gives the
/// same bits, without the per-tap weight tests.
#[inline]
fn sample_full_coarse<const N: usize>(coarse: &Level<N>, bilinear: [(usize, f32); 4]) -> [f32; N] {
    let mut sum = [0.0f32; N];
    for (i, w) in bilinear {
        for (s, v) in sum.iter_mut().zip(coarse.values[i]) {
            *s += w * v;
        }
    }
    sum
}

/// The four bilinear taps (index, weight) of fine pixel (x, y) on the coarse level, clamped at
/// its edges: [`coarse_taps`] before the level's weights, and all of it on a level whose weights
/// are all 1.
#[inline]
fn full_coarse_taps(width: usize, height: usize, x: usize, y: usize) -> [(usize, f32); 4] {
    bilinear_taps(CoarseSpan::of(x, width, 1), CoarseSpan::of(y, height, width))
}

/// One axis of a fine pixel's bilinear taps: its two coarse neighbours along the axis (clamped
/// to the level's `size` along it, times `stride`: 1 for a column, the level's width for a row)
/// and the fraction towards the second.
#[derive(Clone, Copy)]
struct CoarseSpan(usize, usize, f32);

impl CoarseSpan {
    fn of(v: usize, size: usize, stride: usize) -> Self {
        let (v0, t) = coarse_corner(v);
        let clamp = |v: i64| v.clamp(0, size as i64 - 1) as usize * stride;
        Self(clamp(v0), clamp(v0 + 1), t)
    }
}

/// The four bilinear taps of a fine pixel from its column's and its row's [`CoarseSpan`].
#[inline]
fn bilinear_taps(CoarseSpan(xa, xb, tx): CoarseSpan, CoarseSpan(ya, yb, ty): CoarseSpan) -> [(usize, f32); 4] {
    [(ya + xa, (1.0 - tx) * (1.0 - ty)), (ya + xb, tx * (1.0 - ty)), (yb + xa, (1.0 - tx) * ty), (yb + xb, tx * ty)]
}

/// [`full_coarse_taps`] of every pixel of a fine level, its columns' spans worked out once per
/// push and its rows' once per row: the same numbers, without the corner, the clamps and the
/// fractions computed again at every pixel of the fills' largest loops.
struct CoarseTaps {
    coarse_width: usize,
    coarse_height: usize,
    /// Per fine column, its span.
    columns: Vec<CoarseSpan>,
}

impl CoarseTaps {
    fn new(fine_width: usize, coarse_width: usize, coarse_height: usize) -> Self {
        let columns = (0..fine_width).map(|x| CoarseSpan::of(x, coarse_width, 1)).collect();
        Self { coarse_width, coarse_height, columns }
    }

    /// Fine row `y`'s span.
    fn row(&self, y: usize) -> CoarseSpan {
        CoarseSpan::of(y, self.coarse_height, self.coarse_width)
    }

    #[inline]
    fn at(&self, row: CoarseSpan, x: usize) -> [(usize, f32); 4] {
        bilinear_taps(self.columns[x], row)
    }
}

/// The last push, into the caller's `values`: every pixel whose weight is 0 or below (and that
/// `wanted` names, where given) takes the coarse level's sample, as [`push`] gives it a
/// weightless pixel (`0 + 1 c`, the same bits); the others keep their own value.
fn push_into_weightless<const N: usize>(width: usize, values: &mut [[f32; N]], weights: &[f32], wanted: Option<&[bool]>, coarse: &Level<N>) {
    let full = coarse.weights.iter().all(|&w| w == 1.0);
    let taps = CoarseTaps::new(width, coarse.width, coarse.height);
    values.par_chunks_mut(width).zip(weights.par_chunks(width)).enumerate().for_each(|(y, (values, weights))| {
        let row = taps.row(y);
        for x in 0..width {
            if weights[x] <= 0.0 && wanted.map_or(true, |wanted| wanted[y * width + x]) {
                let bilinear = taps.at(row, x);
                let c = if full { sample_full_coarse(coarse, bilinear) } else { sample_coarse(coarse, bilinear) };
                for (v, c) in values[x].iter_mut().zip(c) {
                    *v = 0.0 + 1.0 * c;
                }
            }
        }
    });
}

/// Fills the fine level's missing weight from the coarse level, row by row on every core (each
/// fine pixel writes only itself).
fn push<const N: usize>(fine: &mut Level<N>, coarse: &Level<N>) {
    let width = fine.width;
    let full = coarse.weights.iter().all(|&w| w == 1.0);
    let taps = CoarseTaps::new(width, coarse.width, coarse.height);
    fine.values.par_chunks_mut(width).zip(fine.weights.par_chunks_mut(width)).enumerate().for_each(
        |(y, (values, weights))| {
            let row = taps.row(y);
            for x in 0..width {
                let w = weights[x].clamp(0.0, 1.0);
                if w < 1.0 {
                    let bilinear = taps.at(row, x);
                    let c = if full { sample_full_coarse(coarse, bilinear) } else { sample_coarse(coarse, bilinear) };
                    for (v, c) in values[x].iter_mut().zip(c) {
                        let own = if w > 0.0 { w * *v } else { 0.0 };
                        *v = own + (1.0 - w) * c;
                    }
                    weights[x] = 1.0;
                }
            }
        },
    );
}

/// Replaces `values` wherever `weights` is 0 by a smooth weighted extension of the pixels
/// with positive weight; those keep their value exactly. Returns false (and changes
/// nothing) when no pixel has weight.
pub fn push_pull<const N: usize>(width: usize, height: usize, values: &mut [[f32; N]], weights: &[f32]) -> bool {
    fill_pyramid(width, height, values, weights, None)
}

/// [`push_pull`] for a caller that reads the fill at the pixels `wanted` names only: the other
/// weightless pixels keep their value, and the finest level's push, the largest, skips them.
/// Where `wanted` is true the values are [`push_pull`]'s, bit for bit.
pub fn push_pull_where<const N: usize>(width: usize, height: usize, values: &mut [[f32; N]], weights: &[f32], wanted: &[bool]) -> bool {
    assert_eq!(wanted.len(), width * height);
    fill_pyramid(width, height, values, weights, Some(wanted))
}

fn fill_pyramid<const N: usize>(width: usize, height: usize, values: &mut [[f32; N]], weights: &[f32], wanted: Option<&[bool]>) -> bool {
    assert_eq!(values.len(), width * height);
    assert_eq!(weights.len(), width * height);
    if width == 0 || height == 0 || !weights.iter().any(|&w| w > 0.0) {
        return false;
    }
    // The finest level is the caller's arrays, not a copy of them (two arrays of the frame per
    // layer, most of reading a large layered file went to allocating and copying them): the
    // pull reads only weights above 0, as it read the clamped copy, and the last push writes
    // only the pixels the fill replaces, which is all its copy was read for.
    let mut levels = vec![pull_from(width, height, values, weights)];
    while levels.last().is_some_and(|l| l.width > 1 || l.height > 1) {
        let next = pull(levels.last().expect("pyramid has a level"));
        levels.push(next);
    }
    for k in (1..levels.len()).rev() {
        let (finer, coarser) = levels.split_at_mut(k);
        push(&mut finer[k - 1], &coarser[0]);
    }
    push_into_weightless(width, values, weights, wanted, &levels[0]);
    true
}

/// A pixel's index in a map of the whole frame, or [`NO_PIXEL`]: four bytes a pixel where an
/// `Option<usize>` takes sixteen (the auto-layering keeps two such maps per layer).
pub type PixelIndex = u32;

/// No pixel, in a map of [`PixelIndex`].
pub const NO_PIXEL: PixelIndex = PixelIndex::MAX;

/// The pixel a [`PixelIndex`] names, if any.
pub fn named_pixel(index: PixelIndex) -> Option<usize> {
    (index != NO_PIXEL).then_some(index as usize)
}

/// For every pixel, the index of (approximately) the nearest pixel with `known` set, by two
/// raster passes that propagate seeds from the 8 neighbours (sequential distance transform,
/// Danielsson 1980; off the exact nearest by under a pixel). [`NO_PIXEL`] where nothing is
/// known.
pub fn nearest_known(width: usize, height: usize, known: &[bool]) -> Vec<PixelIndex> {
    assert_eq!(known.len(), width * height);
    assert!(known.len() < NO_PIXEL as usize, "frame too large for nearest_known");
    assert!(width <= i32::MAX as usize && height <= i32::MAX as usize, "frame too large for nearest_known");
    if known.is_empty() {
        return Vec::new();
    }
    // Each pixel's seed as coordinates, with its squared distance kept beside it: the same
    // comparisons in the same order as measuring both distances at every relaxation, without
    // a division per candidate (this runs once or twice per layer of every auto-layered
    // frame). The neighbours are offered in a fixed order, each behind the frame-edge tests it
    // needs, and ties keep the first seed found, as the sequential transform defines
    // (`tests::nearest_known_plain` is that definition; the test holds this one to it, bit for
    // bit). Two things make it faster and change nothing: a pixel's seed and distance stay in
    // registers while its neighbours are offered, the one it just settled beside it along the
    // row carried over (not stored and loaded back, which put a store-to-load delay in the
    // row's chain of dependence); and a pixel at distance 0 (a known one) takes no offer, as
    // none can be nearer.
    let mut seed: Vec<Seed> = Vec::with_capacity(known.len());
    for (y, row) in known.chunks_exact(width).enumerate() {
        seed.extend(row.iter().enumerate().map(|(x, &k)| if k { (x as i32, y as i32) } else { NO_SEED }));
    }
    let mut best: Vec<i64> = known.iter().map(|&k| if k { 0 } else { i64::MAX }).collect();
    let last_x = width - 1;
    // Down the frame, each row left to right from its left neighbour and the three above, then
    // right to left from its right neighbour.
    for y in 0..height {
        let row = y * width;
        let (done, rest) = seed.split_at_mut(row);
        let here = &mut rest[..width];
        let above = (y > 0).then(|| &done[row - width..]);
        let best = &mut best[row..row + width];
        let mut left = NO_SEED;
        for x in 0..width {
            let mut nearest = (here[x], best[x]);
            if nearest.1 != 0 {
                if x > 0 {
                    offer(&mut nearest, x, y, left);
                }
                if let Some(above) = above {
                    if x > 0 {
                        offer(&mut nearest, x, y, above[x - 1]);
                    }
                    offer(&mut nearest, x, y, above[x]);
                    if x < last_x {
                        offer(&mut nearest, x, y, above[x + 1]);
                    }
                }
                (here[x], best[x]) = nearest;
            }
            left = nearest.0;
        }
        along_the_row(here, best, y, (0..last_x).rev(), 1);
    }
    // Up the frame, each row right to left from its right neighbour and the three below, then
    // left to right from its left neighbour.
    for y in (0..height).rev() {
        let row = y * width;
        let (head, below) = seed.split_at_mut(row + width);
        let here = &mut head[row..];
        let below = (y + 1 < height).then(|| &below[..width]);
        let best = &mut best[row..row + width];
        let mut right = NO_SEED;
        for x in (0..width).rev() {
            let mut nearest = (here[x], best[x]);
            if nearest.1 != 0 {
                if x < last_x {
                    offer(&mut nearest, x, y, right);
                }
                if let Some(below) = below {
                    if x < last_x {
                        offer(&mut nearest, x, y, below[x + 1]);
                    }
                    offer(&mut nearest, x, y, below[x]);
                    if x > 0 {
                        offer(&mut nearest, x, y, below[x - 1]);
                    }
                }
                (here[x], best[x]) = nearest;
            }
            right = nearest.0;
        }
        along_the_row(here, best, y, 1..width, -1);
    }
    let width = width as PixelIndex;
    seed.into_iter().map(|s| if s == NO_SEED { NO_PIXEL } else { s.1 as PixelIndex * width + s.0 as PixelIndex }).collect()
}

/// A seed of [`nearest_known`]: a known pixel's coordinates, or [`NO_SEED`].
type Seed = (i32, i32);

/// No seed yet.
const NO_SEED: Seed = (i32::MIN, i32::MIN);

/// Offers seed `s` to pixel (x, y), whose `nearest` is (its seed, the squared distance to it):
/// taken if strictly nearer.
#[inline(always)]
fn offer(nearest: &mut (Seed, i64), x: usize, y: usize, s: Seed) {
    if s != NO_SEED {
        let d = (x as i64 - i64::from(s.0)).pow(2) + (y as i64 - i64::from(s.1)).pow(2);
        if d < nearest.1 {
            *nearest = (s, d);
        }
    }
}

/// The second scan of a row in [`nearest_known`]: each pixel of `xs`, in that order, offered
/// the seed of its neighbour at `x + step` (settled just before it).
#[inline(always)]
fn along_the_row(here: &mut [Seed], best: &mut [i64], y: usize, xs: impl Iterator<Item = usize>, step: isize) {
    let mut xs = xs.peekable();
    let Some(&first) = xs.peek() else { return };
    let mut previous = here[first.wrapping_add_signed(step)];
    for x in xs {
        let mut nearest = (here[x], best[x]);
        if nearest.1 != 0 {
            offer(&mut nearest, x, y, previous);
            (here[x], best[x]) = nearest;
        }
        previous = nearest.0;
    }
}

/// Weighted sums of `values` over any axis-aligned rectangle in constant time: two integral
/// images (f64, so a large frame's sums keep their precision).
pub struct BoxSums<const N: usize> {
    width: usize,
    height: usize,
    sum: Vec<[f64; N]>,
    total: Vec<f64>,
}

impl<const N: usize> BoxSums<N> {
    /// Integral images of `weights` (negative read as 0) and of `weights * values`.
    pub fn new(width: usize, height: usize, values: &[[f32; N]], weights: &[f32]) -> Self {
        assert_eq!(values.len(), width * height);
        assert_eq!(weights.len(), width * height);
        Self::from_fn(width, height, |p| (weights[p], values[p]))
    }

    /// [`Self::new`] of the weight and value `pixel(p)` gives at each pixel `p` (read only
    /// where the weight is above 0), without arrays of them for the whole frame.
    pub fn from_fn(width: usize, height: usize, pixel: impl Fn(usize) -> (f32, [f32; N]) + Sync) -> Self {
        let stride = width + 1;
        let mut sum = vec![[0.0f64; N]; stride * (height + 1)];
        let mut total = vec![0.0f64; stride * (height + 1)];
        // Each row's running sums on every core, then the rows added down the frame (row y + 1
        // of the tables holds the sums over rows 0..=y; row 0 and column 0 stay 0).
        sum.par_chunks_mut(stride).zip(total.par_chunks_mut(stride)).skip(1).enumerate().for_each(|(y, (sum, total))| {
            let (mut row, mut row_total) = ([0.0f64; N], 0.0f64);
            for x in 0..width {
                let (weight, value) = pixel(y * width + x);
                let w = f64::from(weight.max(0.0));
                if w > 0.0 {
                    row_total += w;
                    for k in 0..N {
                        row[k] += w * f64::from(value[k]);
                    }
                }
                (sum[x + 1], total[x + 1]) = (row, row_total);
            }
        });
        for y in 1..=height {
            let (above, here) = sum.split_at_mut(y * stride);
            for (s, a) in here[..stride].iter_mut().zip(&above[(y - 1) * stride..]) {
                for k in 0..N {
                    s[k] += a[k];
                }
            }
            let (above, here) = total.split_at_mut(y * stride);
            here[..stride].iter_mut().zip(&above[(y - 1) * stride..]).for_each(|(t, a)| *t += a);
        }
        Self { width, height, sum, total }
    }

    /// The weighted mean over the (2 `radius` + 1)^2 square around pixel `p`, clipped to the
    /// frame; `None` where the square holds no weight.
    pub fn mean_around(&self, p: usize, radius: usize) -> Option<[f32; N]> {
        let (x, y, stride) = (p % self.width, p / self.width, self.width + 1);
        let (x0, x1) = (x.saturating_sub(radius), (x + radius + 1).min(self.width));
        let (y0, y1) = (y.saturating_sub(radius), (y + radius + 1).min(self.height));
        let corners = [(y1 * stride + x1, 1.0), (y0 * stride + x1, -1.0), (y1 * stride + x0, -1.0), (y0 * stride + x0, 1.0)];
        let w: f64 = corners.iter().map(|&(i, s)| s * self.total[i]).sum();
        (w > 1e-9).then(|| std::array::from_fn(|k| (corners.iter().map(|&(i, s)| s * self.sum[i][k]).sum::<f64>() / w) as f32))
    }
}

/// For each pixel `p` with `hole` set within `reach(p, q)` pixels of its nearest `known` pixel
/// `q`: the known pixel mirrored across the hole's edge (`2 q - p`), or `q` itself where the
/// mirror point is not known; [`NO_PIXEL`] elsewhere. Only `known` pixels are ever named.
pub fn mirror_sources(width: usize, height: usize, known: &[bool], hole: &[bool], reach: impl Fn(usize, usize) -> f32) -> Vec<PixelIndex> {
    assert_eq!(hole.len(), width * height);
    if !known.iter().any(|&k| k) {
        return vec![NO_PIXEL; known.len()];
    }
    let nearest = nearest_known(width, height, known);
    let source = |p: usize| -> Option<usize> {
        let q = named_pixel(nearest[p]).filter(|_| hole[p] && !known[p])?;
        let (px, py, qx, qy) = ((p % width) as i64, (p / width) as i64, (q % width) as i64, (q / width) as i64);
        let reach = reach(p, q);
        if (((px - qx).pow(2) + (py - qy).pow(2)) as f32) > reach * reach {
            return None;
        }
        let (rx, ry) = (2 * qx - px, 2 * qy - py);
        let inside = rx >= 0 && ry >= 0 && rx < width as i64 && ry < height as i64;
        Some(inside.then(|| ry as usize * width + rx as usize).filter(|&r| known[r]).unwrap_or(q))
    };
    (0..known.len()).map(|p| source(p).map_or(NO_PIXEL, |q| q as PixelIndex)).collect()
}

/// The weights of a level after [`push`] ran on it: every pixel it filled is complete.
fn pushed_weights(weights: &[f32]) -> Vec<f32> {
    weights.iter().map(|&w| if w.clamp(0.0, 1.0) < 1.0 { 1.0 } else { w }).collect()
}

/// The transpose of [`push_pull`] (one channel): given dL/d(its output), returns dL/d(its
/// input). For fixed weights push-pull is linear in the values, so this is exact; it lets a
/// gradient that reached filled pixels flow back to the known pixels they were made from.
/// Pixels with weight <= 0 get 0 (their input is never read), unless no pixel has weight
/// (then push-pull changes nothing and its transpose is the identity).
pub fn push_pull_adjoint(width: usize, height: usize, weights: &[f32], grad_output: &[f32]) -> Vec<f32> {
    assert_eq!(weights.len(), width * height);
    assert_eq!(grad_output.len(), width * height);
    if width == 0 || height == 0 || !weights.iter().any(|&w| w > 0.0) {
        return grad_output.to_vec();
    }
    let base = Level::<1> {
        width,
        height,
        values: vec![[0.0]; width * height],
        weights: weights.iter().map(|w| w.max(0.0)).collect(),
    };
    let mut levels = vec![base];
    while levels.last().is_some_and(|l| l.width > 1 || l.height > 1) {
        let next = pull(levels.last().expect("pyramid has a level"));
        levels.push(next);
    }
    let top = levels.len() - 1;
    let mut grads: Vec<Vec<f32>> = levels.iter().map(|l| vec![0.0; l.width * l.height]).collect();
    // The output: known pixels are the input itself, the others level 0 after the pushes.
    let mut result = vec![0.0f32; width * height];
    let mut pushed: Vec<f32> = vec![0.0; width * height];
    for i in 0..width * height {
        if weights[i] > 0.0 {
            result[i] = grad_output[i]
        } else {
            pushed[i] = grad_output[i]
        }
    }
    // Pushes, finest first (the forward ran them coarsest first): `pushed` is dL/d(level k-1
    // after its push); it splits into dL/d(level k-1 before) and dL/d(level k after its push).
    for k in 1..levels.len() {
        let (fine, coarse) = (&levels[k - 1], &levels[k]);
        let sampled = if k == top { coarse.weights.clone() } else { pushed_weights(&coarse.weights) };
        let mut coarse_pushed = vec![0.0f32; coarse.width * coarse.height];
        for y in 0..fine.height {
            for x in 0..fine.width {
                let i = y * fine.width + x;
                let w = fine.weights[i].clamp(0.0, 1.0);
                if w >= 1.0 {
                    grads[k - 1][i] = pushed[i];
                    continue;
                }
                grads[k - 1][i] = if w > 0.0 { w * pushed[i] } else { 0.0 };
                let (taps, count, fallback) = coarse_taps(coarse.width, coarse.height, &sampled, x, y);
                let total: f32 = taps[..count].iter().map(|t| t.1).sum();
                if total > 0.0 {
                    for &(j, t) in &taps[..count] {
                        coarse_pushed[j] += pushed[i] * (1.0 - w) * t / total;
                    }
                } else {
                    coarse_pushed[fallback] += pushed[i] * (1.0 - w);
                }
            }
        }
        pushed = coarse_pushed;
    }
    grads[top].iter_mut().zip(&pushed).for_each(|(g, p)| *g += p);
    // Pulls, coarsest first: each coarse value is a weighted mean of its known children.
    for k in (1..levels.len()).rev() {
        let (finer, coarser) = grads.split_at_mut(k);
        let (fine, coarse) = (&levels[k - 1], &levels[k]);
        for y in 0..coarse.height {
            for x in 0..coarse.width {
                let children = pull_children(fine.width, fine.height, &fine.weights, x, y);
                let total: f32 = children.iter().flatten().map(|&i| fine.weights[i]).sum();
                if total > 0.0 {
                    for &i in children.iter().flatten() {
                        finer[k - 1][i] += coarser[0][y * coarse.width + x] * fine.weights[i] / total;
                    }
                }
            }
        }
    }
    result.iter_mut().zip(&grads[0]).for_each(|(r, g)| *r += g);
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The integer corner and fraction are those of the float form `floor((v + 0.5) * 0.5 - 0.5)`
    /// that [`coarse_taps`] used before, bit for bit, on every coordinate of a 64K frame.
    #[test]
    fn coarse_corner_equals_the_float_floor_form() {
        for v in 0..65536usize {
            let c = (v as f32 + 0.5) * 0.5 - 0.5;
            let (x0, t) = coarse_corner(v);
            assert_eq!((x0, t.to_bits()), (c.floor() as i64, (c - c.floor()).to_bits()), "v = {v}");
        }
    }

    /// On a level of weight 1 everywhere the fast sample is the weighted one, bit for bit, on
    /// every fine pixel of odd and even sizes (edges clamp alike); the pushes' tap grid gives
    /// every pixel the taps of its definition.
    #[test]
    fn full_level_sample_equals_the_weighted_sample() {
        for (fine_w, fine_h) in [(1usize, 1usize), (2, 2), (3, 5), (17, 12), (40, 33)] {
            let (width, height) = (fine_w.div_ceil(2), fine_h.div_ceil(2));
            let values: Vec<[f32; 3]> = (0..width * height).map(|i| [i as f32 * 0.37 + 0.1, (i * i % 11) as f32 / 7.0, 1e3 / (i + 1) as f32]).collect();
            let coarse = Level { width, height, values, weights: vec![1.0; width * height] };
            let taps = CoarseTaps::new(fine_w, width, height);
            for y in 0..fine_h {
                for x in 0..fine_w {
                    let bilinear = full_coarse_taps(width, height, x, y);
                    assert_eq!(taps.at(taps.row(y), x), bilinear, "the tap grid's taps, ({x}, {y}) of {fine_w}x{fine_h}");
                    assert_eq!(sample_full_coarse(&coarse, bilinear), sample_coarse(&coarse, bilinear), "({x}, {y}) of {fine_w}x{fine_h}");
                }
            }
        }
    }

    #[test]
    fn known_pixels_are_kept_and_holes_stay_in_range() {
        let (w, h) = (13, 9);
        let mut values: Vec<[f32; 1]> = (0..w * h).map(|i| [(i % w) as f32]).collect();
        let weights: Vec<f32> = (0..w * h).map(|i| if (i % w) < 4 || (i % w) > 9 { 1.0 } else { 0.0 }).collect();
        let original = values.clone();
        for (i, v) in values.iter_mut().enumerate() {
            if weights[i] == 0.0 {
                v[0] = f32::NAN;
            }
        }
        assert!(push_pull(w, h, &mut values, &weights));
        for i in 0..w * h {
            if weights[i] > 0.0 {
                assert_eq!(values[i], original[i]);
            } else {
                // Convex combinations of the known x = 0..3 and 10..12 columns.
                assert!(values[i][0] >= 0.0 && values[i][0] <= 12.0, "{:?}", values[i]);
            }
        }
    }

    /// The finest level is the caller's array: what lies under a weight of 0 or below is never
    /// read (garbage there changes no bit), partial weights keep their value exactly.
    #[test]
    fn values_under_no_weight_are_never_read_and_partial_weights_are_kept() {
        let (w, h) = (11, 7);
        let weights: Vec<f32> = (0..w * h).map(|i| [1.0, 0.3, 0.0, -2.0][(i * 7 + i / w) % 4]).collect();
        let known: Vec<[f32; 2]> = (0..w * h).map(|i| [(i % w) as f32 * 0.5, (i / w) as f32 - 3.0]).collect();
        let with_garbage = |garbage: f32| {
            let mut values: Vec<[f32; 2]> =
                known.iter().zip(&weights).map(|(&v, &wt)| if wt > 0.0 { v } else { [garbage; 2] }).collect();
            assert!(push_pull(w, h, &mut values, &weights));
            values
        };
        let (a, b) = (with_garbage(f32::NAN), with_garbage(1e30));
        for i in 0..w * h {
            assert_eq!(a[i].map(f32::to_bits), b[i].map(f32::to_bits), "pixel {i}");
            if weights[i] > 0.0 {
                assert_eq!(a[i].map(f32::to_bits), known[i].map(f32::to_bits), "pixel {i} has weight {}", weights[i]);
            } else {
                assert!(a[i][0] >= 0.0 && a[i][0] <= 5.0 && a[i][1] >= -3.0 && a[i][1] <= 3.0, "pixel {i}: {:?}", a[i]);
            }
        }
    }

    #[test]
    fn constant_known_values_fill_with_that_constant() {
        let (w, h) = (8, 8);
        let mut values = vec![[0.0f32, 0.0]; w * h];
        let mut weights = vec![0.0f32; w * h];
        values[0] = [3.0, -1.0];
        weights[0] = 0.5;
        assert!(push_pull(w, h, &mut values, &weights));
        for v in &values {
            assert!((v[0] - 3.0).abs() < 1e-5 && (v[1] + 1.0).abs() < 1e-5, "{v:?}");
        }
    }

    #[test]
    fn nearest_known_is_within_a_pixel_of_the_exact_nearest() {
        let (w, h) = (37, 23);
        let known: Vec<bool> = (0..w * h).map(|i| (i * 7919) % 97 == 0).collect();
        let nearest = nearest_known(w, h, &known);
        let d = |p: usize, q: usize| (((p % w) as f32 - (q % w) as f32).powi(2) + ((p / w) as f32 - (q / w) as f32).powi(2)).sqrt();
        for p in 0..w * h {
            let exact = (0..w * h).filter(|&q| known[q]).map(|q| d(p, q)).fold(f32::INFINITY, f32::min);
            let q = named_pixel(nearest[p]).expect("some pixel is known");
            // Sequential propagation misses the exact nearest seed by under a pixel.
            assert!(known[q] && d(p, q) <= exact + 1.0, "pixel {p}: {} vs exact {exact}", d(p, q));
        }
    }

    /// The sequential transform as defined: every relaxation reads its neighbour's seed from
    /// the frame and measures both distances (the squared ones, in integers).
    fn nearest_known_plain(width: usize, height: usize, known: &[bool]) -> Vec<PixelIndex> {
        let mut seed: Vec<Option<(i64, i64)>> = (0..known.len()).map(|i| known[i].then(|| ((i % width) as i64, (i / width) as i64))).collect();
        let d2 = |x: usize, y: usize, s: (i64, i64)| (x as i64 - s.0).pow(2) + (y as i64 - s.1).pow(2);
        let mut relax = |p: usize, q: usize| {
            let (x, y) = (p % width, p / width);
            if let Some(s) = seed[q] {
                if seed[p].map_or(true, |t| d2(x, y, s) < d2(x, y, t)) {
                    seed[p] = Some(s);
                }
            }
        };
        for y in 0..height {
            for x in 0..width {
                let p = y * width + x;
                if x > 0 {
                    relax(p, p - 1);
                }
                if y > 0 {
                    if x > 0 {
                        relax(p, p - width - 1);
                    }
                    relax(p, p - width);
                    if x + 1 < width {
                        relax(p, p - width + 1);
                    }
                }
            }
            for x in (0..width.saturating_sub(1)).rev() {
                relax(y * width + x, y * width + x + 1);
            }
        }
        for y in (0..height).rev() {
            for x in (0..width).rev() {
                let p = y * width + x;
                if x + 1 < width {
                    relax(p, p + 1);
                }
                if y + 1 < height {
                    if x + 1 < width {
                        relax(p, p + width + 1);
                    }
                    relax(p, p + width);
                    if x > 0 {
                        relax(p, p + width - 1);
                    }
                }
            }
            for x in 1..width {
                relax(y * width + x, y * width + x - 1);
            }
        }
        seed.into_iter().map(|s| s.map_or(NO_PIXEL, |(x, y)| (y as usize * width + x as usize) as PixelIndex)).collect()
    }

    #[test]
    fn nearest_known_is_the_sequential_transform_bit_for_bit() {
        // Sparse and dense random masks, blobs and lines (where ties between seeds are common),
        // nothing known, everything known, one row, one column, one pixel.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut random = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let mut cases: Vec<(usize, usize, Vec<bool>)> = Vec::new();
        for &(w, h) in &[(1, 1), (1, 9), (9, 1), (2, 2), (37, 23), (64, 48), (5, 70)] {
            for density in [0u64, 1, 3, 20, 60, 97, 100] {
                cases.push((w, h, (0..w * h).map(|_| random() % 100 < density).collect()));
            }
            cases.push((w, h, (0..w * h).map(|i| ((i % w) / 4 + (i / w) / 3) % 5 == 0).collect()));
            cases.push((w, h, (0..w * h).map(|i| (i % w + 2 * (i / w)) % 11 == 0).collect()));
        }
        for (w, h, known) in cases {
            assert_eq!(nearest_known(w, h, &known), nearest_known_plain(w, h, &known), "{w}x{h}, {} known", known.iter().filter(|&&k| k).count());
        }
    }

    #[test]
    fn box_sums_give_the_weighted_mean_of_each_square() {
        // Against the sum written out, with zero, partial and negative (read as 0) weights, the
        // frame's edges inside the square, and a square that holds no weight.
        let (w, h, r) = (13, 9, 2usize);
        let weights: Vec<f32> = (0..w * h).map(|i| if i % w >= 10 { 0.0 } else { [0.0, 1.0, 0.3, -1.0, 2.0][(i * 7) % 5] }).collect();
        let values: Vec<[f32; 2]> = (0..w * h).map(|i| [((i * 37) % 11) as f32 - 4.0, (i % w) as f32 * 0.5]).collect();
        let sums = BoxSums::new(w, h, &values, &weights);
        let means: Vec<Option<[f32; 2]>> = (0..w * h).map(|p| sums.mean_around(p, r)).collect();
        for p in 0..w * h {
            let (x, y) = ((p % w) as i64, (p / w) as i64);
            let (mut sum, mut total) = ([0.0f64; 2], 0.0f64);
            for q in (0..w * h).filter(|&q| ((q % w) as i64 - x).abs() <= r as i64 && ((q / w) as i64 - y).abs() <= r as i64) {
                let wq = f64::from(weights[q].max(0.0));
                total += wq;
                (0..2).for_each(|k| sum[k] += wq * f64::from(values[q][k]));
            }
            match means[p] {
                None => assert_eq!(total, 0.0, "pixel {p} has weight around it"),
                Some(m) => (0..2).for_each(|k| assert!((f64::from(m[k]) - sum[k] / total).abs() < 1e-5, "pixel {p}: {m:?} vs {}", sum[k] / total)),
            }
        }
        assert!((0..h).all(|y| means[y * w + 12].is_none()), "columns 10-12 carry no weight: the last is 3 px from any");
    }

    #[test]
    fn mirror_sources_reflect_across_the_edge_and_name_only_known_pixels() {
        // Known columns 0..6; the hole 6..12. Within reach 4, column 6 + k mirrors column
        // 5 - k (the nearest known pixel is in column 5); beyond reach nothing is named.
        let (w, h) = (12, 5);
        let known: Vec<bool> = (0..w * h).map(|i| i % w < 6).collect();
        let hole: Vec<bool> = known.iter().map(|k| !k).collect();
        let sources = mirror_sources(w, h, &known, &hole, |_, _| 4.0);
        for (i, &s) in sources.iter().enumerate() {
            let (x, s) = (i % w, named_pixel(s));
            match x {
                0..=5 => assert_eq!(s, None, "known pixels are not filled"),
                6..=9 => assert_eq!(s.map(|q| (q % w, q / w)), Some((10 - x, i / w)), "column {x}"),
                _ => assert_eq!(s, None, "column {x} is beyond reach"),
            }
        }
    }

    #[test]
    fn push_pull_where_fills_the_wanted_pixels_as_push_pull_does_and_keeps_the_rest() {
        // Odd sizes (pyramid edges), partial and zero weights, a wanted set that takes in
        // weighted and weightless pixels: wanted pixels equal push_pull's bit for bit, the
        // others keep their input (weightless ones included).
        let (w, h) = (23, 17);
        let weights: Vec<f32> = (0..w * h).map(|i| [0.0, 1.0, 0.4, 0.0, 0.0][(i * 7) % 5]).collect();
        let input: Vec<[f32; 2]> = (0..w * h).map(|i| [(i % 13) as f32 * 0.25, -((i % 7) as f32)]).collect();
        let wanted: Vec<bool> = (0..w * h).map(|i| (i * 11) % 3 == 0).collect();
        let mut everywhere = input.clone();
        assert!(push_pull(w, h, &mut everywhere, &weights));
        let mut some = input.clone();
        assert!(push_pull_where(w, h, &mut some, &weights, &wanted));
        for p in 0..w * h {
            let expected = if wanted[p] { everywhere[p] } else { input[p] };
            assert_eq!(some[p].map(f32::to_bits), expected.map(f32::to_bits), "pixel {p} (wanted {}, weight {})", wanted[p], weights[p]);
        }
        assert!((0..w * h).any(|p| !wanted[p] && weights[p] <= 0.0 && everywhere[p] != input[p]), "some unwanted pixel would have been filled");
    }

    #[test]
    fn adjoint_is_the_transpose_of_push_pull() {
        // <push_pull(u), g> = <u, adjoint(g)> for any u and g, with holes, partial weights and
        // odd sizes (pyramid edges). f32 sums of ~100 terms of size <= 1: 1e-5 relative.
        let (w, h) = (11, 7);
        let weights: Vec<f32> = (0..w * h).map(|i| [0.0, 0.0, 1.0, 0.4, 0.0, 1.0, 0.7][(i * 5 + i / w) % 7]).collect();
        let u: Vec<f32> = (0..w * h).map(|i| ((i * 37) % 11) as f32 / 11.0 - 0.3).collect();
        let g: Vec<f32> = (0..w * h).map(|i| ((i * 53) % 13) as f32 / 13.0 - 0.5).collect();
        let mut filled: Vec<[f32; 1]> = u.iter().map(|&v| [v]).collect();
        assert!(push_pull(w, h, &mut filled, &weights));
        let adjoint = push_pull_adjoint(w, h, &weights, &g);
        let lhs: f64 = filled.iter().zip(&g).map(|(f, &g)| (f[0] * g) as f64).sum();
        let rhs: f64 = u.iter().zip(&adjoint).map(|(&u, &a)| (u * a) as f64).sum();
        assert!((lhs - rhs).abs() <= 1e-5 * lhs.abs().max(1.0), "{lhs} vs {rhs}");
        assert!(weights.iter().zip(&adjoint).all(|(&w, &a)| w > 0.0 || a == 0.0), "unread inputs get no gradient");
        // Every filled value is a convex combination: the gradient's total is kept.
        let (sum_g, sum_a) = (g.iter().sum::<f32>(), adjoint.iter().sum::<f32>());
        assert!((sum_g - sum_a).abs() < 1e-4, "{sum_g} vs {sum_a}");
    }
}
