//! Search windows, computed on the host before anything is uploaded: they bound both the
//! gather loops of `drbokeh_layer.comp` and the halo each frame tile must upload.
//!
//! Each 16x16 output tile loops over a square window of half-width `h_T` pixels around each
//! of its pixels. A source y of radius r reaches x only if `|x - y| < support(r)` (every
//! aperture gauge is at least the Euclidean length), and V at x gathers over
//! `|x - y| < r_x + 1/2`. So `h_T = ceil(reach_T) - 1` with
//! `reach_T = max(gather_T, max { support_U : tile U's support reaches tile T })` covers both.
use rayon::prelude::*;

use super::{math, Model, Params, TILE};
use crate::stack::{Layer, LayerStack};
use crate::tile_grid::Rect;

/// Per tile `[scatter support, gather radius]` (mirrors the `tile_bounds` vec2 buffer):
/// support = max over pixels with alpha > 0 (transparent sources scatter nothing),
/// gather = max over all pixels of `r + 1/2` (V is evaluated everywhere).
pub fn tile_bounds_cpu(params: &Params, layer: &Layer) -> Vec<[f64; 2]> {
    (0..params.tiles_x * params.tiles_y)
        .into_par_iter()
        .map(|t| scan_tile(params, layer, t % params.tiles_x, t / params.tiles_x).0)
        .collect()
}

/// One pass over a layer's pixels of the search tile (tx, ty): its `[scatter support, gather
/// radius]` ([`tile_bounds_cpu`]) and its [`AbsSRange`], which read the same pixels.
///
/// The pass keeps only each set's extremes ([`PixelSet`]), and the bounds follow from them:
/// the radius `k (d - d_f)` and the shaders' `s` are monotone in the disparity under rounding,
/// so their largest magnitudes sit at the smallest or largest disparity. Evaluating the f64
/// radius, the support and the f32 `s` at every pixel made this scan the largest host cost of
/// preparing a frame; the tests keep that per-pixel evaluation (`scan_tile_per_pixel`) and hold
/// this one equal to it, bit for bit.
fn scan_tile(params: &Params, layer: &Layer, tx: usize, ty: usize) -> ([f64; 2], AbsSRange) {
    let [all, sources] = scan_sets(layer, params.width, params.height, tx, ty, params.push(0).focus_disparity);
    tile_bounds(params, all, sources)
}

/// The [`PixelSet`]s `[every pixel, the sources]` of a layer's search tile (tx, ty), their
/// `nearest` measured from `focus_disparity`.
fn scan_sets(layer: &Layer, width: usize, height: usize, tx: usize, ty: usize, focus_disparity: f32) -> [PixelSet; 2] {
    let (mut all, mut sources) = (PixelSet::EMPTY, PixelSet::EMPTY);
    let columns = tx * TILE..((tx + 1) * TILE).min(width);
    for py in ty * TILE..((ty + 1) * TILE).min(height) {
        let row = py * width + columns.start..py * width + columns.end;
        for (&disparity, rgba) in layer.disparity[row.clone()].iter().zip(&layer.rgba.pixels[row]) {
            all.add(disparity, focus_disparity);
            // Transparent pixels scatter nothing: only the others are sources.
            if rgba[3] > 0.0 {
                sources.add(disparity, focus_disparity);
            }
        }
    }
    [all, sources]
}

/// A search tile's `[scatter support, gather radius]` and [`AbsSRange`] from the extremes of its
/// pixels and of its sources, their `nearest` measured from the lens's focus.
fn tile_bounds(params: &Params, all: PixelSet, sources: PixelSet) -> ([f64; 2], AbsSRange) {
    let push = params.push(0);
    // The bounds, in f64 as the CPU reference computes radii.
    let gather = all.max_radius(params).map_or(0.0, |r| r + 0.5);
    let support = sources.max_radius(params).map_or(0.0, |r| match params.model {
        Model::DrBokeh => math::support(r),
        Model::Compat => math::support_compat(r),
    });
    // The |s| ranges, in f32 as the shaders compute them.
    let (all_s, source_s) = (all.abs_s(push.k_px, push.focus_disparity), sources.abs_s(push.k_px, push.focus_disparity));
    let range = AbsSRange {
        source_min: source_s.map_or(f32::INFINITY, |s| s.min),
        source_max: source_s.map_or(f32::NEG_INFINITY, |s| s.max),
        all_max: all_s.map_or(f32::NEG_INFINITY, |s| s.max),
        all_min: all_s.map_or(f32::INFINITY, |s| s.min),
        source_near: source_s.is_some_and(|s| s.near),
        source_far: source_s.is_some_and(|s| s.far),
        all_near: all_s.is_some_and(|s| s.near),
        all_far: all_s.is_some_and(|s| s.far),
        source_disparity: sources.disparities(),
        all_disparity: all.disparities(),
    };
    ([support, gather], range)
}

/// The pass over a stack's pixels that a render's search bounds need, kept for renders of the
/// same stack through other lenses: the extremes of each layer's search tiles (their pixels'
/// and their sources' smallest and largest disparities, and which is nearest to focus). Only
/// the nearest depends on the lens (its focus); a render focused elsewhere works it out from the
/// extremes, exactly, wherever focus lies outside a tile's disparities, and reads again only
/// the tiles that straddle it. On a resident stack this takes the pass over every pixel (the
/// largest host cost of preparing a render: at 1024^2 five layers it reads 100 MB) out of all
/// but the first render.
///
/// The scan is of the stack it was made from: the caller keeps the two together, unchanged.
pub struct StackScan {
    width: usize,
    height: usize,
    tiles_x: usize,
    /// `[every pixel, the sources]` per layer and search tile, layer-major.
    sets: Vec<[PixelSet; 2]>,
    /// The focus disparity the sets' `nearest` were measured from.
    focus_disparity: f32,
}

impl StackScan {
    /// One pass over every pixel of `stack`, on every core, `nearest` measured from
    /// `focus_disparity` (the lens of the first render).
    pub fn new(stack: &LayerStack, focus_disparity: f32) -> Self {
        let (tiles_x, tiles_y) = (stack.width.div_ceil(TILE), stack.height.div_ceil(TILE));
        let per_layer = tiles_x * tiles_y;
        let sets = (0..stack.layers.len() * per_layer)
            .into_par_iter()
            .map(|i| {
                let (layer, t) = (&stack.layers[i / per_layer], i % per_layer);
                scan_sets(layer, stack.width, stack.height, t % tiles_x, t / tiles_x, focus_disparity)
            })
            .collect();
        Self { width: stack.width, height: stack.height, tiles_x, sets, focus_disparity }
    }

    /// Whether `stack` has the size and the layer count of the stack the scan was made from
    /// (what a render can check of the caller's promise that it is that stack, unchanged).
    pub fn fits(&self, stack: &LayerStack) -> bool {
        let tiles = stack.width.div_ceil(TILE) * stack.height.div_ceil(TILE);
        (self.width, self.height, self.sets.len()) == (stack.width, stack.height, stack.layers.len() * tiles)
    }

    /// Smallest and largest disparity of the stack, NaN left out (as
    /// [`LayerStack::disparity_range`], without another pass over the pixels).
    pub fn disparity_range(&self) -> (f32, f32) {
        self.sets.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), [all, _]| (lo.min(all.lowest), hi.max(all.highest)))
    }

    /// The scan's tiles bounded for `params`: [`scan_tile`] of each, with the pixels read again
    /// only where the lens's focus differs from the scan's and straddles the tile.
    fn bounds(&self, params: &Params, stack: &LayerStack) -> Vec<([f64; 2], AbsSRange)> {
        assert!(self.fits(stack), "a stack scan renders the stack it was made from");
        let focus = params.push(0).focus_disparity;
        let per_layer = params.tiles_x * params.tiles_y;
        self.sets
            .par_iter()
            .enumerate()
            .map(|(i, &[all, sources])| {
                let refocused = if focus.to_bits() == self.focus_disparity.to_bits() {
                    Some([all, sources])
                } else {
                    all.refocused(focus).zip(sources.refocused(focus)).map(|(all, sources)| [all, sources])
                };
                let [all, sources] = refocused.unwrap_or_else(|| {
                    let t = i % per_layer;
                    scan_sets(&stack.layers[i / per_layer], self.width, self.height, t % self.tiles_x, t / self.tiles_x, focus)
                });
                tile_bounds(params, all, sources)
            })
            .collect()
    }
}

/// What [`scan_tile`] keeps of a set of pixels' disparities: enough to bound any monotone
/// function of them, and to tell whether they are one value.
#[derive(Clone, Copy, Debug)]
struct PixelSet {
    /// Smallest and largest disparity (NaN left out).
    lowest: f32,
    highest: f32,
    /// Smallest and largest f32 bit pattern (NaN included, as [`Disparities`] counts them).
    lowest_bits: u32,
    highest_bits: u32,
    /// Smallest `|d - d_f|` in f32 (the shaders' subtraction): the source nearest to focus.
    nearest: f32,
    /// Whether any disparity is NaN / finite; whether the set has any pixel.
    any_nan: bool,
    any_finite: bool,
    any: bool,
}

/// [`PixelSet::abs_s`]: the f32 `|s|` bounds of a set, and which sides of focus it lies on.
#[derive(Clone, Copy, Debug)]
struct SRange {
    /// Smallest and largest `|s|`, a non-finite `s` counting as 0 and infinity.
    min: f32,
    max: f32,
    /// Whether some `s > 0` / some `s` is not (NaN included).
    near: bool,
    far: bool,
}

impl PixelSet {
    const EMPTY: Self = Self {
        lowest: f32::INFINITY,
        highest: f32::NEG_INFINITY,
        lowest_bits: u32::MAX,
        highest_bits: 0,
        nearest: f32::INFINITY,
        any_nan: false,
        any_finite: false,
        any: false,
    };

    #[inline]
    fn add(&mut self, disparity: f32, focus_disparity: f32) {
        // f32::min and max leave NaN out.
        self.lowest = self.lowest.min(disparity);
        self.highest = self.highest.max(disparity);
        let bits = disparity.to_bits();
        self.lowest_bits = self.lowest_bits.min(bits);
        self.highest_bits = self.highest_bits.max(bits);
        self.nearest = self.nearest.min((disparity - focus_disparity).abs());
        self.any_nan |= disparity.is_nan();
        self.any_finite |= disparity.is_finite();
        self.any = true;
    }

    /// The set with its `nearest` measured from `focus_disparity` instead, where the extremes
    /// give it exactly: `d - d_f` rounds monotonically in d, so where focus lies at or below
    /// every (non-NaN) disparity the smallest `|d - d_f|` is the lowest's, at or above every
    /// one the highest's. `None` where focus lies strictly between them (or is NaN): only the
    /// pixels tell.
    fn refocused(self, focus_disparity: f32) -> Option<Self> {
        let nearest = if self.lowest > self.highest {
            // No disparity that is a number: `add` measured nothing.
            f32::INFINITY
        } else if focus_disparity <= self.lowest {
            (self.lowest - focus_disparity).abs()
        } else if focus_disparity >= self.highest {
            (self.highest - focus_disparity).abs()
        } else {
            return None;
        };
        (!focus_disparity.is_nan()).then_some(Self { nearest, ..self })
    }

    /// Largest f64 CoC radius `|k (d - d_f)|` over the pixels whose radius is a number; `None`
    /// where none is. The radius is monotone in d, so it is largest at an extreme (a zero k
    /// makes every finite disparity's radius 0 and an infinite one's NaN).
    fn max_radius(&self, params: &Params) -> Option<f64> {
        if params.lens.k_px == 0.0 {
            return self.any_finite.then_some(0.0);
        }
        (self.lowest <= self.highest)
            .then(|| params.lens.signed_radius(self.lowest).abs().max(params.lens.signed_radius(self.highest).abs()))
    }

    /// The f32 `s = k (d - d_f)` of the shaders over the set; `None` for an empty set. `s` is
    /// monotone in d under rounding, so its extremes are the extreme disparities'; the
    /// smallest `|s|` is `|k|` times the smallest `|d - d_f|` (rounding is symmetric in sign
    /// and monotone).
    fn abs_s(&self, k: f32, focus_disparity: f32) -> Option<SRange> {
        if !self.any {
            return None;
        }
        let s = |d: f32| k * (d - focus_disparity);
        let is_near = |s: f32| s > 0.0;
        let (at_lowest, at_highest) = if self.lowest <= self.highest {
            (s(self.lowest), s(self.highest))
        } else {
            (f32::NAN, f32::NAN)
        };
        let finite = !self.any_nan && at_lowest.is_finite() && at_highest.is_finite();
        Some(SRange {
            min: if finite { k.abs() * self.nearest } else { 0.0 },
            max: if finite { at_lowest.abs().max(at_highest.abs()) } else { f32::INFINITY },
            near: is_near(at_lowest) || is_near(at_highest),
            // NaN is not near.
            far: self.any_nan || !is_near(at_lowest) || !is_near(at_highest),
        })
    }

    fn disparities(&self) -> Disparities {
        match (self.any, self.lowest_bits == self.highest_bits) {
            (false, _) => Disparities::None,
            (true, true) => Disparities::One(self.lowest_bits),
            (true, false) => Disparities::Several,
        }
    }
}

/// Along one axis of `side` px, the search tiles holding a pixel within `margin` px of tile
/// `tile`'s pixels.
fn tiles_within(tile: usize, side: usize, margin: usize) -> std::ops::RangeInclusive<usize> {
    let first = (tile * TILE).saturating_sub(margin) / TILE;
    let last = (((tile + 1) * TILE).min(side) - 1 + margin).min(side - 1) / TILE;
    first..=last
}

/// Per layer and search tile, the smallest f32 `|s|` (as the shaders compute it) of a pixel
/// within `reach + 1` px of the tile, `reach` being the tile's (`tile_reach_cpu`): every
/// receiver the backward's pass 4 visits from a source of the tile
/// (`glsl/drbokeh_backward_source_disk.comp`'s `receiver_radius`).
pub fn receiver_radii(params: &Params, ranges: &SourceRanges, reach: &[i32]) -> Vec<f32> {
    let per_layer = params.tiles_x * params.tiles_y;
    (0..reach.len())
        .map(|i| {
            let (l, t) = (i / per_layer.max(1), i % per_layer.max(1));
            let (tx, ty) = (t % params.tiles_x, t / params.tiles_x);
            let margin = reach[i].max(0) as usize + 1;
            let mut smallest = f32::INFINITY;
            for uy in tiles_within(ty, params.height, margin) {
                for ux in tiles_within(tx, params.width, margin) {
                    smallest = smallest.min(ranges.0[l * per_layer + uy * params.tiles_x + ux].all_min);
                }
            }
            smallest
        })
        .collect()
}

/// Window of a tile that no source reaches: the gather loops `-h..=h` run zero times, and a
/// layer-by-layer pass leaves the tile alone (`DRBOKEH_EMPTY_WINDOW`, `glsl/common/drbokeh_layer_out.glsl`).
pub const EMPTY_WINDOW: i32 = -1;

/// Pixel gap along one axis between two tiles `k` tiles apart: `16k - 15`, or 0 for the same.
#[inline]
fn tile_gap(k: i64) -> f64 {
    if k == 0 {
        0.0
    } else {
        (k.abs() * TILE as i64 - (TILE as i64 - 1)) as f64
    }
}

/// Window half-width per tile (mirrors the `tile_window` int buffer); `EMPTY_WINDOW` where
/// the default model's layer contributes exactly nothing (no source with alpha > 0 reaches the
/// tile, so W = 0 and the existence gate zeroes V): those tiles skip their gathers. `bounds`
/// may hold several layers, layer-major: each layer's tiles see only its own.
pub fn tile_window_cpu(params: &Params, bounds: &[[f64; 2]]) -> Vec<i32> {
    let (tiles_x, tiles_y) = (params.tiles_x, params.tiles_y);
    let per_layer = (tiles_x * tiles_y).max(1);
    // Per layer: tiles farther apart than `range` are not reached by the layer's largest
    // support (gaps grow with the distance), so no tile looks farther, and the gap to a tile
    // `i - range` tiles away. The loop below visits (2 range + 1)^2 tiles per tile (an 8K
    // frame's 130K tiles per layer): it only looks things up.
    let reach_tables: Vec<(usize, Vec<f64>)> = bounds
        .chunks(per_layer)
        .map(|layer| {
            let largest = layer.iter().map(|b| b[0]).fold(0.0, f64::max);
            let mut range = 0;
            while range < tiles_x.max(tiles_y) && tile_gap(range as i64 + 1) < largest {
                range += 1;
            }
            (range, (0..=2 * range).map(|i| tile_gap(i as i64 - range as i64)).collect())
        })
        .collect();
    // Every layer's tiles in one pass on every core: a pass per layer waited for the pool
    // five times (1 ms of a 1024^2 five-layer frame's preparation on a 16-core host).
    let mut windows = vec![0i32; bounds.len()];
    windows.par_iter_mut().enumerate().for_each(|(i, window)| {
        let (l, t) = (i / per_layer, i % per_layer);
        let (range, ref centred_gaps) = reach_tables[l];
        let supports = &bounds[l * per_layer..(l + 1) * per_layer];
        let (tx, ty) = (t % tiles_x, t / tiles_x);
        let mut reach = supports[t][1];
        let mut reached = false;
        let (x0, x1) = (tx.saturating_sub(range), (tx + range).min(tiles_x - 1));
        let gaps_x = &centred_gaps[x0 + range - tx..=x1 + range - tx];
        for uy in ty.saturating_sub(range)..=(ty + range).min(tiles_y - 1) {
            let gap_y = centred_gaps[uy + range - ty];
            for (bound, &gap_x) in supports[uy * tiles_x + x0..=uy * tiles_x + x1].iter().zip(gaps_x) {
                let support = bound[0];
                if gap_x.max(gap_y) < support {
                    reach = reach.max(support);
                    reached = true;
                }
            }
        }
        *window = if !reached && params.model == Model::DrBokeh { EMPTY_WINDOW } else { (reach.ceil() as i32 - 1).max(0) };
    });
    windows
}

/// Window half-widths of every layer, layer-major (`[layer * tiles + tile]`): the
/// `tile_window` buffer of `drbokeh_layer.comp`, and the frame tiles' halos; with the
/// [`SourceRanges`] of the span paths, from one pass over the pixels, on every core.
pub fn windows_and_ranges(params: &Params, stack: &LayerStack) -> (Vec<i32>, SourceRanges) {
    scanned_windows_and_ranges(params, stack, &StackScan::new(stack, params.push(0).focus_disparity))
}

/// [`windows_and_ranges`] from a [`StackScan`] of `stack`, which reads the pixels again only
/// where the lens is focused elsewhere than the scan's and in the middle of a tile's disparities.
pub fn scanned_windows_and_ranges(params: &Params, stack: &LayerStack, scan: &StackScan) -> (Vec<i32>, SourceRanges) {
    let scans = scan.bounds(params, stack);
    let windows = tile_window_cpu(params, &scans.iter().map(|scan| scan.0).collect::<Vec<_>>());
    (windows, SourceRanges(scans.into_iter().map(|scan| scan.1).collect()))
}

/// Windows grown by `margin` pixels, empty tiles left empty (their layer contributes exactly
/// nothing there, whatever the pairs).
pub fn grow_windows(mut windows: Vec<i32>, margin: i32) -> Vec<i32> {
    for w in windows.iter_mut().filter(|w| **w != EMPTY_WINDOW) {
        *w += margin;
    }
    windows
}

/// Bounds of the span paths' taps per layer and search tile of the frame tile `core` (the
/// `tile_radii` vec4 buffer of `drbokeh_layer_{disk,gauge}.comp`, indexed like `windows`):
/// - interior: a lower bound of the f32 `|s|` and of the coverage radius the shader computes
///   for every source with alpha > 0 in the tile's window (square, so a superset of the
///   disk), `f32::MAX` where there is none; 0 disables the interior. Only a smaller bound is safe (it shrinks the
///   cheap interior), so the margin is generous.
/// - outer: an upper bound of every such source's support `coverage_radius(|s|) + 1/2` and of
///   the tile's own pixels' `|s| + 1/2` (V's reach): taps at least this far add exact zeros,
///   so the shader trims its rows to it. Only a larger bound is safe; `f32::MAX` disables the trim.
/// - orientation: 1 when every such source and every pixel of the tile is nearer than focus
///   (f32 `s > 0`), -1 when every one is not, 0 when both occur. The gauge path then bounds
///   its rows by the aperture alone (1) or its mirror alone (-1), not by both.
/// - one disparity: 1 when every pixel of the tile and every such source hold the same
///   disparity (bit for bit, so the shader's s is the same number at each), else 0. Then any
///   source that adds something sees the aperture through the centre's own CoC, and the kernel
///   path samples the kernel image once a tap for both.
///
/// Tiles outside the core hold `[0, f32::MAX, 0, 0]`: no shortcut.
pub fn span_radii(params: &Params, ranges: &SourceRanges, windows: &[i32], core: Rect) -> Vec<[f32; 4]> {
    let per_layer = params.tiles_x * params.tiles_y;
    let mut radii = vec![NO_SPAN_RADII; windows.len()];
    // On every core, a row of tiles a task, every layer's in one pass: a 1024^2 five-layer
    // frame looks at about 50 neighbours for each of 20K tiles, 1.5 ms of one core that a GPU
    // waited for while the tile recorded.
    let (columns, rows) = search_tile_ranges(core);
    radii.par_chunks_mut(params.tiles_x).enumerate().for_each(|(layer_row, row_radii)| {
        let (l, ty) = (layer_row / params.tiles_y, layer_row % params.tiles_y);
        if !rows.contains(&ty) {
            return;
        }
        let layer = l * per_layer..(l + 1) * per_layer;
        let (tile_ranges, layer_windows) = (&ranges.0[layer.clone()], &windows[layer]);
        for (tx, radii) in row_radii.iter_mut().enumerate().take(columns.end).skip(columns.start) {
            let window = layer_windows[ty * params.tiles_x + tx];
            if window >= 0 {
                *radii = tile_span_radii(params, tile_ranges, tx, ty, window as usize);
            }
        }
    });
    radii
}

/// [`span_radii`] of the search tile (tx, ty) of a layer whose sources it gathers within
/// `window` px: the tile's own pixels' ranges and those of every source tile in reach.
fn tile_span_radii(params: &Params, tile_ranges: &[AbsSRange], tx: usize, ty: usize, window: usize) -> [f32; 4] {
    let mut range = tile_ranges[ty * params.tiles_x + tx];
    let own_reach = range.all_max;
    let (mut near, mut far) = (range.all_near, range.all_far);
    let mut one_disparity = range.all_disparity;
    for uy in tiles_within(ty, params.height, window) {
        for ux in tiles_within(tx, params.width, window) {
            let other = tile_ranges[uy * params.tiles_x + ux];
            range.source_min = range.source_min.min(other.source_min);
            range.source_max = range.source_max.max(other.source_max);
            near |= other.source_near;
            far |= other.source_far;
            one_disparity = match other.source_disparity {
                Disparities::None => one_disparity,
                theirs if theirs == one_disparity => one_disparity,
                _ => Disparities::Several,
            };
        }
    }
    // Every source covers at least the smaller of its own radius and its coverage
    // radius (below it over the dips), both increasing in |s|.
    let m = range.source_min;
    let interior = if m.is_finite() {
        let covered = m.min(math::coverage_radius(f64::from(m)) as f32);
        (covered - (1e-3 + 1e-5 * covered)).max(0.0)
    } else {
        f32::MAX
    };
    // A source reaches as far as its coverage radius, V as far as the centre's own
    // radius.
    let source_reach = if range.source_max.is_finite() {
        math::coverage_radius(f64::from(range.source_max)) as f32
    } else {
        range.source_max
    };
    let reach = source_reach.max(own_reach) + 0.5;
    let outer = if reach.is_finite() { reach + (1e-3 + 1e-5 * reach) } else { f32::MAX };
    let orientation = match (near, far) {
        (true, false) => 1.0,
        (false, true) => -1.0,
        _ => 0.0,
    };
    let one_disparity = if matches!(one_disparity, Disparities::One(_)) { 1.0 } else { 0.0 };
    [interior, outer, orientation, one_disparity]
}

/// [`span_radii`] of a tile without shortcuts: no interior, no trim, both orientations.
pub const NO_SPAN_RADII: [f32; 4] = [0.0, f32::MAX, 0.0, 0.0];

/// The `AbsSRange` of every search tile of every layer (layer-major, as the windows), for
/// [`span_radii`]: found once per frame with the windows ([`windows_and_ranges`]), where each
/// frame tile evaluating the search tiles its windows reach evaluated those of its halo again,
/// one tile after another (the largest host cost of recording a frame's tiles).
pub struct SourceRanges(Vec<AbsSRange>);

/// f32 `|s|` ranges of one tile, evaluated as `glsl/drbokeh_layer_sources.comp` does.
#[derive(Clone, Copy, Debug, PartialEq)]
struct AbsSRange {
    /// Smallest over the sources with alpha > 0 (0 if one is not finite, infinity if none).
    source_min: f32,
    /// Largest over the sources with alpha > 0 (infinity if one is not finite, -infinity if none).
    source_max: f32,
    /// Largest over every pixel (V gathers at each; infinity if one is not finite).
    all_max: f32,
    /// Smallest over every pixel (0 if one is not finite, infinity if the tile has none).
    all_min: f32,
    /// Whether a source with alpha > 0 is nearer than focus (f32 `s > 0`) / is not.
    source_near: bool,
    source_far: bool,
    /// The same over every pixel (the centres: V's gauge takes their orientation).
    all_near: bool,
    all_far: bool,
    /// The disparities of the sources with alpha > 0 and of every pixel.
    source_disparity: Disparities,
    all_disparity: Disparities,
}

/// The distinct disparities (f32 bits) of a set of pixels: none, one, or several.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Disparities {
    None,
    One(u32),
    Several,
}

impl Disparities {
    /// The per-pixel scan of the tests adds the pixels one at a time.
    #[cfg(test)]
    fn with(self, disparity: f32) -> Self {
        match self {
            Disparities::None => Disparities::One(disparity.to_bits()),
            Disparities::One(bits) if bits == disparity.to_bits() => self,
            _ => Disparities::Several,
        }
    }
}

/// The 16x16 search tiles a frame core overlaps (cores start on multiples of 16).
pub(crate) fn search_tiles(params: &Params, core: Rect) -> impl Iterator<Item = usize> + '_ {
    let (columns, rows) = search_tile_ranges(core);
    rows.flat_map(move |ty| columns.clone().map(move |tx| ty * params.tiles_x + tx))
}

/// [`search_tiles`] as the ranges of their columns and rows.
fn search_tile_ranges(core: Rect) -> (std::ops::Range<usize>, std::ops::Range<usize>) {
    (core.x0 / TILE..core.x1.div_ceil(TILE), core.y0 / TILE..core.y1.div_ceil(TILE))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Aperture, CocModel};
    use crate::image::Image;
    use crate::render::Lens;

    /// The per-pixel evaluation [`scan_tile`] replaces: every pixel's f64 radius and support and
    /// f32 `s`, as the CPU reference and the shaders compute them.
    fn scan_tile_per_pixel(
        params: &Params,
        layer: &Layer,
        tx: usize,
        ty: usize,
    ) -> ([f64; 2], AbsSRange) {
        let push = params.push(0);
        let (mut support, mut gather) = (0.0f64, 0.0f64);
        let mut range = AbsSRange {
            source_min: f32::INFINITY,
            source_max: f32::NEG_INFINITY,
            all_max: f32::NEG_INFINITY,
            all_min: f32::INFINITY,
            source_near: false,
            source_far: false,
            all_near: false,
            all_far: false,
            source_disparity: Disparities::None,
            all_disparity: Disparities::None,
        };
        let columns = tx * TILE..((tx + 1) * TILE).min(params.width);
        for py in ty * TILE..((ty + 1) * TILE).min(params.height) {
            let row = py * params.width + columns.start..py * params.width + columns.end;
            for (&disparity, rgba) in layer.disparity[row.clone()].iter().zip(&layer.rgba.pixels[row]) {
                let opaque = rgba[3] > 0.0;
                let r = params.lens.signed_radius(disparity).abs();
                gather = gather.max(r + 0.5);
                if opaque {
                    let s = match params.model {
                        Model::DrBokeh => math::support(r),
                        Model::Compat => math::support_compat(r),
                    };
                    support = support.max(s);
                }
                let signed = push.k_px * (disparity - push.focus_disparity);
                let s = signed.abs();
                let finite = s.is_finite();
                let near = signed > 0.0;
                range.all_max = range.all_max.max(if finite { s } else { f32::INFINITY });
                range.all_min = range.all_min.min(if finite { s } else { 0.0 });
                range.all_near |= near;
                range.all_far |= !near;
                range.all_disparity = range.all_disparity.with(disparity);
                if opaque {
                    range.source_disparity = range.source_disparity.with(disparity);
                    range.source_min = range.source_min.min(if finite { s } else { 0.0 });
                    range.source_max = range.source_max.max(if finite { s } else { f32::INFINITY });
                    range.source_near |= near;
                    range.source_far |= !near;
                }
            }
        }
        ([support, gather], range)
    }

    /// A deterministic scramble in [0, 1).
    fn hash(i: usize) -> f32 {
        let mut x = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0xD1B5_4A32_D192_ED03;
        x ^= x >> 29;
        x = x.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        x ^= x >> 32;
        (x >> 40) as f32 / (1u64 << 24) as f32
    }

    /// A layer with tiles of every kind the bounds must survive: one disparity, +0 and -0
    /// together, values on both sides of `focus` and exactly at it, NaN, transparent and
    /// negative alpha, and a partial last tile.
    fn layer_of_every_kind(focus: f32) -> Layer {
        let (w, h): (usize, usize) = (16 * 7 + 5, 16 * 2 + 9);
        let disparity_of = |i: usize, tile: usize| -> f32 {
            let u = hash(i * 3 + 1);
            match tile % 7 {
                0 => 0.25,
                1 => if u < 0.5 { 0.0 } else { -0.0 },
                2 => focus + (u - 0.5) * 1e-3,
                3 => if u < 0.1 { f32::NAN } else { u },
                4 => if u < 0.5 { focus } else { focus + 0.3 },
                5 => focus - 0.5 * u,
                _ => u * 2.0 - 0.5,
            }
        };
        let tile_of = |x: usize, y: usize| (y / TILE) * w.div_ceil(TILE) + x / TILE;
        Layer {
            name: "scanned".into(),
            rgba: Image::from_fn(w, h, |x, y| {
                let u = hash((y * w + x) * 3 + 2);
                let alpha = if tile_of(x, y) % 3 == 0 { 0.0 } else if u < 0.3 { 0.0 } else if u < 0.35 { -0.5 } else { u };
                [u, u, u, alpha]
            }),
            disparity: (0..w * h).map(|i| disparity_of(i, tile_of(i % w, i / w))).collect(),
        }
    }

    /// Params refuses NaN in the range it reads: it gets a stack of `layer` without them.
    fn without_nan(layer: &Layer) -> LayerStack {
        let clean = Layer { disparity: layer.disparity.iter().map(|d| if d.is_nan() { 0.5 } else { *d }).collect(), ..layer.clone() };
        LayerStack::new(layer.rgba.width, layer.rgba.height, vec![clean]).unwrap()
    }

    /// Under both models, a zero and a non-zero blur, on [`layer_of_every_kind`].
    #[test]
    fn the_extremes_scan_equals_the_per_pixel_scan_bit_for_bit() {
        let focus = 0.4f32;
        let layer = layer_of_every_kind(focus);
        let stack = without_nan(&layer);
        let mut compared = 0;
        for k in [0.0f32, 7.5, 40.0] {
            for model in [Model::DrBokeh, Model::Compat] {
                let lens = Lens { coc: CocModel::new(k, focus).unwrap(), aperture: Aperture::Disk };
                let params = Params::new(&stack, &lens, model).unwrap();
                for ty in 0..params.tiles_y {
                    for tx in 0..params.tiles_x {
                        let (fast, slow) = (scan_tile(&params, &layer, tx, ty), scan_tile_per_pixel(&params, &layer, tx, ty));
                        assert_eq!(fast.0.map(f64::to_bits), slow.0.map(f64::to_bits), "bounds of tile ({tx}, {ty}), k {k}, {model:?}");
                        let bits = |r: &AbsSRange| [r.source_min, r.source_max, r.all_max, r.all_min].map(f32::to_bits);
                        assert_eq!(bits(&fast.1), bits(&slow.1), "|s| of tile ({tx}, {ty}), k {k}, {model:?}");
                        assert_eq!(fast.1, slow.1, "ranges of tile ({tx}, {ty}), k {k}, {model:?}");
                        compared += 1;
                    }
                }
            }
        }
        assert_eq!(compared, 6 * 8 * 3);
    }

    /// A scan kept from a render focused elsewhere gives every tile's bounds that a fresh
    /// scan gives, bit for bit: focus below, above, inside and at the edges of the tiles'
    /// disparities (those tiles read again), on both models; and the disparity range of the
    /// stack without another pass.
    #[test]
    fn a_kept_scan_refocused_equals_a_fresh_scan_bit_for_bit() {
        let layer = layer_of_every_kind(0.4);
        let nan_free = without_nan(&layer);
        let scan = StackScan::new(&nan_free, 0.4);
        assert_eq!(
            scan.disparity_range().0.to_bits() | 0x8000_0000,
            nan_free.disparity_range().0.to_bits() | 0x8000_0000,
            "smallest disparity (either zero)"
        );
        assert_eq!(scan.disparity_range().1, nan_free.disparity_range().1, "largest disparity");
        let with_nan = LayerStack { layers: vec![layer], ..nan_free.clone() };
        let scan = StackScan::new(&with_nan, 0.4);
        let mut compared = 0;
        for focus in [0.4f32, -0.7, 0.0, -0.0, 0.25, 0.4 + 1e-4, 0.7, 0.9, 1.6] {
            for model in [Model::DrBokeh, Model::Compat] {
                let lens = Lens { coc: CocModel::new(12.0, focus).unwrap(), aperture: Aperture::Disk };
                let params = Params::new(&nan_free, &lens, model).unwrap();
                let kept = scan.bounds(&params, &with_nan);
                let fresh = StackScan::new(&with_nan, focus).bounds(&params, &with_nan);
                for (t, (kept, fresh)) in kept.iter().zip(&fresh).enumerate() {
                    assert_eq!(kept.0.map(f64::to_bits), fresh.0.map(f64::to_bits), "bounds of tile {t}, focus {focus}, {model:?}");
                    let bits = |r: &AbsSRange| [r.source_min, r.source_max, r.all_max, r.all_min].map(f32::to_bits);
                    assert_eq!(bits(&kept.1), bits(&fresh.1), "|s| of tile {t}, focus {focus}, {model:?}");
                    assert_eq!(kept.1, fresh.1, "ranges of tile {t}, focus {focus}, {model:?}");
                    let (tx, ty) = (t % params.tiles_x, t / params.tiles_x);
                    let slow = scan_tile(&params, &with_nan.layers[0], tx, ty);
                    assert_eq!(fresh.1, slow.1, "fresh scan of tile {t} against scan_tile");
                    compared += 1;
                }
            }
        }
        assert_eq!(compared, 9 * 2 * 8 * 3);
    }

    /// The windows as first written: every tile looks at every tile within the stack's largest
    /// support, through `tile_gap` each time.
    fn tile_window_per_pair(params: &Params, bounds: &[[f64; 2]]) -> Vec<i32> {
        let (tiles_x, tiles_y) = (params.tiles_x as i64, params.tiles_y as i64);
        let range = (params.max_support / TILE as f64).ceil() as i64 + 1;
        (0..bounds.len())
            .map(|t| {
                let (tx, ty) = (t as i64 % tiles_x, t as i64 / tiles_x);
                let mut reach = bounds[t][1];
                let mut reached = false;
                for uy in (ty - range).max(0)..=(ty + range).min(tiles_y - 1) {
                    for ux in (tx - range).max(0)..=(tx + range).min(tiles_x - 1) {
                        let support = bounds[(uy * tiles_x + ux) as usize][0];
                        if tile_gap(ux - tx).max(tile_gap(uy - ty)) < support {
                            reach = reach.max(support);
                            reached = true;
                        }
                    }
                }
                if !reached && params.model == Model::DrBokeh { EMPTY_WINDOW } else { (reach.ceil() as i32 - 1).max(0) }
            })
            .collect()
    }

    /// The windows equal the per-pair evaluation on tiles of scattered supports: none (0),
    /// exactly a gap (a support of 17 does not reach the tile beside, 17.5 does), small and the
    /// stack's largest; a frame wider than high and one with a partial last tile; both models.
    #[test]
    fn the_windows_equal_the_per_pair_evaluation() {
        for (w, h, k) in [(16 * 23 + 3, 16 * 9, 40.0f32), (16 * 5, 16 * 31 + 9, 120.0), (40, 24, 3.0)] {
            let stack = LayerStack::new(w, h, vec![Layer { name: "l".into(), rgba: Image::new(w, h), disparity: vec![0.0; w * h] }]).unwrap();
            let focus = 0.5;
            for model in [Model::DrBokeh, Model::Compat] {
                let lens = Lens { coc: CocModel::new(k, focus).unwrap(), aperture: Aperture::Disk };
                let params = Params::new(&stack, &lens, model).unwrap();
                let largest = params.max_support;
                let bounds: Vec<[f64; 2]> = (0..params.tiles_x * params.tiles_y)
                    .map(|t| {
                        let u = hash(t * 5 + 3) as f64;
                        let support = match t % 6 {
                            0 | 1 => 0.0,
                            2 => 17.0,
                            3 => 17.5,
                            4 => largest,
                            _ => u * largest,
                        };
                        [support, 0.5 + u * 3.0]
                    })
                    .collect();
                let windows = tile_window_per_pair(&params, &bounds);
                assert_eq!(tile_window_cpu(&params, &bounds), windows, "{w}x{h}, k {k}, {model:?}");
                // Layers side by side, each with its own reach: a layer of small supports
                // between two of this one sees only its own tiles.
                let small: Vec<[f64; 2]> = bounds.iter().map(|&[support, gather]| [support.min(2.0), gather]).collect();
                let three: Vec<[f64; 2]> = [&bounds, &small, &bounds].into_iter().flatten().copied().collect();
                let expected: Vec<i32> = [windows.clone(), tile_window_per_pair(&params, &small), windows].concat();
                assert_eq!(tile_window_cpu(&params, &three), expected, "{w}x{h}, k {k}, {model:?}, three layers");
            }
        }
    }

    /// Pass 4's interior rests on `receiver_radii`: no pixel within a tile's reach + 1 px has
    /// a smaller f32 |s| (as the shaders compute it) than its tile's entry.
    #[test]
    fn receiver_radii_bound_every_receiver_within_reach() {
        let focus = 0.4f32;
        let stack = without_nan(&layer_of_every_kind(focus));
        let layer = &stack.layers[0];
        let lens = Lens { coc: CocModel::new(7.5, focus).unwrap(), aperture: Aperture::Disk };
        let params = Params::new(&stack, &lens, Model::DrBokeh).unwrap();
        let (windows, ranges) = windows_and_ranges(&params, &stack);
        let reach = crate::render::drbokeh::backward_cpu::tile_reach_cpu(&params, &windows);
        let radii = receiver_radii(&params, &ranges, &reach);
        let push = params.push(0);
        let (mut checked, mut reached) = (0, 0);
        for (t, (&smallest, &tile_reach)) in radii.iter().zip(&reach).enumerate() {
            let (tx, ty) = (t % params.tiles_x, t / params.tiles_x);
            let margin = tile_reach.max(0) as usize + 1;
            let (x0, y0) = ((tx * TILE).saturating_sub(margin), (ty * TILE).saturating_sub(margin));
            let x1 = ((tx + 1) * TILE - 1 + margin).min(params.width - 1);
            let y1 = ((ty + 1) * TILE - 1 + margin).min(params.height - 1);
            let mut least = f32::INFINITY;
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let s = push.k_px * (layer.disparity[y * params.width + x] - push.focus_disparity);
                    least = least.min(if s.is_finite() { s.abs() } else { 0.0 });
                    checked += 1;
                }
            }
            assert!(smallest <= least, "tile {t}: {smallest} above a receiver's {least}");
            reached += usize::from(smallest == least);
        }
        assert!(checked > 0 && reached > 0, "{checked} receivers, {reached} tiles' bounds attained");
    }
}
