//! The Dr.Bokeh forward render on the CPU for the common case (default model, disk aperture):
//! the same terms as the f64 reference (`cpu.rs`), summed as the disk shader sums them, in row
//! spans. Where a frame is small, this is what a one-shot render runs instead of opening a
//! device: on lavapipe, opening the device and compiling four pipelines costs more CPU than
//! this whole render (`RenderJob::place_frame`).
//!
//! Why it is exact, not an approximation: along window row `oy`, a source `y` at Euclidean
//! distance `g <= coverage_radius(r_y) - 1/2` scatters `S = 1` (the smoothstep's argument is
//! at least 1), and a centre `x` with `g <= r_x - 1/2` sees it with footprint `D = 1`. Each
//! row's columns where every such term is 1 (from the smallest coverage radius of the window's
//! sources, or the centre's own radius) add `P / A`, `alpha` and `1` and come from row prefix
//! sums; only the rim columns outside them evaluate their terms. A centre that can occlude
//! (`alpha_x in_focus(r_x) > 0`) evaluates every tap. Taps at `g >= h + 1` (the tile's window
//! `h`) add exact zeros, as in the shader. The sums differ from the reference's in order only
//! (f64 rounding, ~1e-15 relative), which `tests::native_equals_the_reference` checks.
use rayon::prelude::*;

use super::bounds::{scanned_windows_and_ranges, windows_and_ranges, StackScan, EMPTY_WINDOW};
use super::cpu::composite_step;
use super::{math, AperturePath, LensView, Model, Params, TILE};
use crate::image::{self, Image};
use crate::render::Lens;
use crate::stack::{Layer, LayerStack};
use crate::Result;

/// Room kept below the levels where a smoothstep reaches 1, so that rounding in `g` (a square
/// root) can never put a tap whose term is below 1 inside a summed span.
const INTERIOR_MARGIN: f64 = 1e-9;

/// Whether [`render_native`] renders `lens` under `model`: the default model with a plain disk
/// (no polygon, ring, kernel image or vignetting, which the reference and the GPU render).
pub fn supports(lens: &Lens, model: Model) -> bool {
    model == Model::DrBokeh && LensView::new(&lens.coc, &lens.aperture).path(model) == AperturePath::Disk
}

/// Renders `stack` through `lens` under the default model (see [`supports`]): premultiplied
/// linear RGBA, HDR unclamped, alpha = coverage; equal to `render_cpu` up to f64 rounding.
/// `scan`: a [`StackScan`] of `stack` kept from an earlier render (a resident session's),
/// which bounds the search windows without reading every pixel again (the same windows, bit
/// for bit); None scans the stack here.
pub fn render_native(stack: &LayerStack, lens: &Lens, scan: Option<&StackScan>) -> Result<Image> {
    debug_assert!(supports(lens, Model::DrBokeh));
    let params = Params::new(stack, lens, Model::DrBokeh)?;
    let (width, height) = (params.width, params.height);
    let windows = match scan {
        Some(scan) => scanned_windows_and_ranges(&params, stack, scan).0,
        None => windows_and_ranges(&params, stack).0,
    };
    // The running composite, front to back: premultiplied RGBA and the transmittance.
    let mut composite = vec![[0.0f64; 4]; width * height];
    let mut transmittance = vec![1.0f64; width * height];
    let mut sources = Sources::new(&params);
    for (layer, window) in stack.layers.iter().zip(windows.chunks(params.tiles_x * params.tiles_y)) {
        sources.load(layer);
        let sources = &sources;
        let scatter_rows = scatter_rows(&params, sources, window);
        composite.par_chunks_mut(width).zip(transmittance.par_chunks_mut(width)).enumerate().for_each(|(y, (out, t))| {
            // The footprint's rows follow the centre's radius: a layer's neighbours share it.
            let mut footprint: Option<(i64, f64, DiskRows)> = None;
            for x in 0..width {
                // Hidden completely by the layers in front: this layer would add exactly 0.
                if t[x] == 0.0 {
                    continue;
                }
                let tile = (y / TILE) * params.tiles_x + x / TILE;
                let h = window[tile] as i64;
                if window[tile] == EMPTY_WINDOW {
                    continue;
                }
                let r_x = sources.s[y * width + x].abs();
                if !matches!(&footprint, Some((fh, fr, _)) if *fh == h && *fr == r_x) {
                    footprint = Some((h, r_x, DiskRows::new(h, r_x, width)));
                }
                let rows = Rows { scatter: &scatter_rows[tile], footprint: &footprint.as_ref().expect("set above").2 };
                let (cw, visibility) = sources.gather(x, y, h, rows);
                composite_step(Model::DrBokeh, cw, visibility, &mut out[x], &mut t[x]);
            }
        });
    }
    let mut out = Image { width, height, pixels: image::filled_vec([0.0f32; 4], width * height) };
    out.pixels.par_iter_mut().zip(&composite).for_each(|(o, c)| *o = c.map(|v| v as f32));
    Ok(out)
}

/// One window row's half-widths: `|ox| <= outer` may add something (beyond, every term is
/// exactly 0); `|ox| <= inner` adds with a term of exactly 1 (`inner <= outer`, -1 = none).
/// `weights`: where the row's term is one function of the offset, its value at `ox` is
/// `weights[ox + outer]` of the row's table.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Span {
    outer: i64,
    inner: i64,
    weights: usize,
}

/// The rows `oy = -h..=h` of a gather's term `smoothstep(0, 1, radius + 1/2 - g)` within the
/// window's disk: exactly 1 up to `radius - 1/2`, 0 from `radius + 1/2` (taps at that distance
/// itself are kept: they add zeros), for radii in `[least, most]`. Where every radius is one,
/// the term is one function of the offset: tabulated, with the taps' own arithmetic.
struct DiskRows {
    spans: Vec<Span>,
    weights: Vec<f64>,
    /// Tabulated rows (where every radius is one) as flat offsets, for centres whose window
    /// lies inside the image; None where the rows are not tabulated.
    stencil: Option<Stencil>,
}

/// Tabulated [`DiskRows`] as offsets from a centre in a `width`-pixel frame: every row's rim
/// taps in one list and its summed span in another, so that a centre whose window lies inside
/// the image adds them without the per-row clipping and set-up that cost more than the few
/// taps of a rim.
struct Stencil {
    /// (pixel offset `oy width + ox`, weight) of every rim tap.
    taps: Vec<(isize, f64)>,
    /// Per summed span, the offsets of the row prefix entries left of it and at its right end.
    spans: Vec<(isize, isize)>,
    /// The sum of the weights and the spans' column counts: a footprint's `sum of D` for every
    /// centre inside the image.
    weight_sum: f64,
}

impl Stencil {
    fn new(spans: &[Span], weights: &[f64], h: i64, width: usize) -> Self {
        let mut stencil = Self { taps: Vec::new(), spans: Vec::new(), weight_sum: 0.0 };
        for (span, oy) in spans.iter().zip(-h..=h) {
            let mut tap = |ox: i64| stencil.taps.push(((oy * width as i64 + ox) as isize, weights[span.weights + (ox + span.outer) as usize]));
            if span.outer < 0 {
                continue;
            } else if span.inner < 0 {
                (-span.outer..=span.outer).for_each(&mut tap);
            } else {
                (-span.outer..-span.inner).for_each(&mut tap);
                (span.inner + 1..=span.outer).for_each(&mut tap);
                let line = oy * (width as i64 + 1);
                stencil.spans.push(((line - span.inner) as isize, (line + span.inner + 1) as isize));
                stencil.weight_sum += (2 * span.inner + 1) as f64;
            }
        }
        stencil.weight_sum += stencil.taps.iter().map(|&(_, weight)| weight).sum::<f64>();
        stencil
    }
}

/// `sum of term(item)` over `items`, in four running sums: with one, each add waits for the one
/// before, and a rim's taps and a window's spans are most of a small blur's work.
#[inline]
fn running_sum<T>(items: &[T], term: impl Fn(&T) -> f64) -> f64 {
    let mut sums = [0.0f64; 4];
    let mut quads = items.chunks_exact(4);
    for quad in &mut quads {
        for (sum, item) in sums.iter_mut().zip(quad) {
            *sum += term(item);
        }
    }
    for (sum, item) in sums.iter_mut().zip(quads.remainder()) {
        *sum += term(item);
    }
    (sums[0] + sums[1]) + (sums[2] + sums[3])
}

/// [`running_sum`] of RGBA terms, in two running sums of four channels.
#[inline]
fn running_sum4<T>(items: &[T], term: impl Fn(&T) -> [f64; 4]) -> [f64; 4] {
    let mut sums = [[0.0f64; 4]; 2];
    let mut pairs = items.chunks_exact(2);
    for pair in &mut pairs {
        for (sum, item) in sums.iter_mut().zip(pair) {
            let t = term(item);
            for c in 0..4 {
                sum[c] += t[c];
            }
        }
    }
    for item in pairs.remainder() {
        let t = term(item);
        for c in 0..4 {
            sums[0][c] += t[c];
        }
    }
    [0, 1, 2, 3].map(|c| sums[0][c] + sums[1][c])
}

impl DiskRows {
    /// The rows of one radius (a footprint, or the sources of a layer of one depth).
    fn new(h: i64, radius: f64, width: usize) -> Self {
        Self::spanning(h, radius, radius, width)
    }

    fn spanning(h: i64, least: f64, most: f64, width: usize) -> Self {
        let tabulated = least == most;
        let mut weights = Vec::new();
        let spans = (-h..=h)
            .map(|oy| {
                let outer = half_width_within(most + 0.5, oy, row_half_width(h, oy));
                let span = Span { outer, inner: half_width_within(least - 0.5 - INTERIOR_MARGIN, oy, outer), weights: weights.len() };
                if tabulated {
                    weights.extend((-outer..=outer).map(|ox| math::smoothstep(0.0, 1.0, most + 0.5 - ((ox * ox + oy * oy) as f64).sqrt())));
                }
                span
            })
            .collect::<Vec<Span>>();
        let stencil = tabulated.then(|| Stencil::new(&spans, &weights, h, width));
        Self { spans, weights, stencil }
    }

    /// Whether the rows' term is tabulated (one radius): `weights` holds it.
    fn tabulated(&self) -> bool {
        self.stencil.is_some()
    }

    /// The term at offset (ox, oy) of `span` (row oy) for a radius of `radius`.
    #[inline]
    fn term(&self, span: &Span, ox: i64, g: impl FnOnce() -> f64, radius: f64) -> f64 {
        if self.tabulated() {
            self.weights[span.weights + (ox + span.outer) as usize]
        } else {
            math::smoothstep(0.0, 1.0, radius + 0.5 - g())
        }
    }
}

/// The rows of a centre's gather: the scatter's (a tile's, from its sources' coverage radii)
/// and the footprint's (the centre's own radius).
struct Rows<'r> {
    scatter: &'r DiskRows,
    footprint: &'r DiskRows,
}

/// A layer's sources, one array per term (`drbokeh_layer_sources.comp`'s, in f64), and their
/// row prefix sums.
struct Sources<'a> {
    params: &'a Params,
    /// `P / A(r)`, premultiplied RGBA; exactly 0 where alpha <= 0 (such sources add nothing to
    /// C and W, as the reference's `alpha_y > 0` test).
    pa: Vec<[f64; 4]>,
    alpha: Vec<f64>,
    /// Signed CoC radius.
    s: Vec<f64>,
    /// `coverage_radius(|s|)`: the scatter is `smoothstep(0, 1, cov + 1/2 - g)`.
    cov: Vec<f64>,
    /// Per row, `width + 1` running sums of `pa` and of `alpha`: entry `i` is the sum over
    /// columns `0..i`.
    prefix_pa: Vec<[f64; 4]>,
    prefix_alpha: Vec<f64>,
}

impl<'a> Sources<'a> {
    /// The arrays of `params`' frame, allocated (and zeroed) once per render, then filled layer
    /// by layer ([`Self::load`]).
    fn new(params: &'a Params) -> Self {
        let n = params.width * params.height;
        let lines = (params.width + 1) * params.height;
        Self {
            params,
            pa: vec![[0.0; 4]; n],
            alpha: vec![0.0; n],
            s: vec![0.0; n],
            cov: vec![0.0; n],
            prefix_pa: vec![[0.0; 4]; lines],
            prefix_alpha: vec![0.0; lines],
        }
    }

    /// Fills every array with `layer`'s values (each line's prefix entry 0 stays 0).
    fn load(&mut self, layer: &Layer) {
        let (params, width) = (self.params, self.params.width);
        let lens = &params.lens;
        let Self { pa, alpha, s, cov, prefix_pa, prefix_alpha, .. } = self;
        let rows = pa.par_chunks_mut(width).zip(alpha.par_chunks_mut(width)).zip(s.par_chunks_mut(width)).zip(cov.par_chunks_mut(width));
        let sums = prefix_pa.par_chunks_mut(width + 1).zip(prefix_alpha.par_chunks_mut(width + 1));
        rows.zip(sums).enumerate().for_each(|(y, ((((pa, alpha), s), cov), (prefix_pa, prefix_alpha)))| {
            // A layer's disparity is often one value over long runs: its radius, area and
            // coverage radius are worked out once per run.
            let mut last: Option<(u32, f64, f64, f64)> = None;
            let (mut sum, mut alpha_sum) = ([0.0f64; 4], 0.0f64);
            for x in 0..width {
                let i = y * width + x;
                let p = layer.rgba.pixels[i];
                let d = layer.disparity[i];
                let (radius, area, coverage) = match last {
                    Some((bits, radius, area, coverage)) if bits == d.to_bits() => (radius, area, coverage),
                    _ => {
                        let radius = lens.signed_radius(d);
                        let terms = (radius, params.area(radius.abs()), math::coverage_radius(radius.abs()));
                        last = Some((d.to_bits(), terms.0, terms.1, terms.2));
                        terms
                    }
                };
                alpha[x] = p[3] as f64;
                pa[x] = if alpha[x] > 0.0 { p.map(|v| v as f64 / area) } else { [0.0; 4] };
                (s[x], cov[x]) = (radius, coverage);
                for c in 0..4 {
                    sum[c] += pa[x][c];
                }
                alpha_sum += alpha[x];
                (prefix_pa[x + 1], prefix_alpha[x + 1]) = (sum, alpha_sum);
            }
        });
    }

    /// `[C.rgb, W]` and `V` of centre (x, y) over its tile's window `h`.
    fn gather<'s>(&'s self, x: usize, y: usize, h: i64, rows: Rows) -> ([f64; 4], f64) {
        let (width, height) = (self.params.width, self.params.height as i64);
        let (s_x, alpha_x) = (self.s[y * width + x], self.alpha[y * width + x]);
        let r_x = s_x.abs();
        let occluder = alpha_x * (1.0 - math::smoothstep(0.5, 1.5, r_x));
        let mut cw = [0.0f64; 4];
        let mut vis = [0.0f64; 2]; // sum of alpha D, sum of D
        let (xi, yi) = (x as i64, y as i64);
        // A window inside the image: tabulated rows add through their stencil (the same terms).
        let inside = yi >= h && yi + h < height && xi >= h && xi + h < width as i64;
        let scatter_stencil = rows.scatter.stencil.as_ref().filter(|_| inside && occluder == 0.0);
        let footprint_stencil = rows.footprint.stencil.as_ref().filter(|_| inside);
        let (pixel, line) = (y * width + x, y * (width + 1) + x);
        // Rim taps, then the summed spans' prefix differences.
        let tap = |&(offset, _): &(isize, f64)| pixel.wrapping_add_signed(offset);
        let span = |&(left, right): &(isize, isize)| (line.wrapping_add_signed(left), line.wrapping_add_signed(right));
        if let Some(Stencil { taps, spans, .. }) = scatter_stencil {
            let rim = running_sum4(taps, |t| self.pa[tap(t)].map(|v| v * t.1));
            let summed = running_sum4(spans, |s| {
                let (left, right) = span(s);
                [0, 1, 2, 3].map(|c| self.prefix_pa[right][c] - self.prefix_pa[left][c])
            });
            cw = [0, 1, 2, 3].map(|c| rim[c] + summed[c]);
        }
        if let Some(Stencil { taps, spans, weight_sum }) = footprint_stencil {
            let rim = running_sum(taps, |t| self.alpha[tap(t)] * t.1);
            let summed = running_sum(spans, |s| {
                let (left, right) = span(s);
                self.prefix_alpha[right] - self.prefix_alpha[left]
            });
            vis = [rim + summed, *weight_sum];
        }
        if scatter_stencil.is_some() && footprint_stencil.is_some() {
            let visibility = if vis[1] > 0.0 { vis[0] / vis[1] } else { 0.0 };
            return (cw, visibility);
        }
        for oy in (-h).max(-yi)..=h.min(height - 1 - yi) {
            let row = (yi + oy) as usize;
            let line = |values: &'s [f64]| &values[row * width..][..width];
            let (pa, alpha, cov) = (&self.pa[row * width..][..width], line(&self.alpha), line(&self.cov));
            let (prefix_pa, prefix_alpha) = (&self.prefix_pa[row * (width + 1)..][..width + 1], &self.prefix_alpha[row * (width + 1)..][..width + 1]);
            // C and W over the row's columns `lo..=hi`, `a..=b` of them summed.
            let span = rows.scatter.spans[(oy + h) as usize];
            let ((lo, hi), (a, b)) = (columns(xi, span.outer, width), columns(xi, span.inner, width));
            // (Added above through the stencil.)
            let scatter_left = scatter_stencil.is_none();
            if scatter_left && occluder > 0.0 {
                let s = line(&self.s);
                for column in lo..=hi {
                    let ox = column as i64 - xi;
                    let mut weight = rows.scatter.term(&span, ox, || distance(ox, oy), cov[column]);
                    if ox != 0 || oy != 0 {
                        weight *= 1.0 - occluder * (1.0 - math::smoothstep(-0.5, 0.0, s[column] - s_x));
                    }
                    add(&mut cw, &pa[column], weight);
                }
            } else if scatter_left && a > b {
                rows.scatter.add_scatter(&mut cw, &span, (x, oy), lo..hi + 1, pa, cov);
            } else if scatter_left {
                rows.scatter.add_scatter(&mut cw, &span, (x, oy), lo..a, pa, cov);
                rows.scatter.add_scatter(&mut cw, &span, (x, oy), b + 1..hi + 1, pa, cov);
                for c in 0..4 {
                    cw[c] += prefix_pa[b + 1][c] - prefix_pa[a][c];
                }
            }
            // V, the same way.
            let span = rows.footprint.spans[(oy + h) as usize];
            let ((lo, hi), (a, b)) = (columns(xi, span.outer, width), columns(xi, span.inner, width));
            let footprint_left = footprint_stencil.is_none();
            if footprint_left && a > b {
                rows.footprint.add_footprint(&mut vis, &span, (x, oy), lo..hi + 1, alpha, r_x);
            } else if footprint_left {
                rows.footprint.add_footprint(&mut vis, &span, (x, oy), lo..a, alpha, r_x);
                rows.footprint.add_footprint(&mut vis, &span, (x, oy), b + 1..hi + 1, alpha, r_x);
                vis[0] += prefix_alpha[b + 1] - prefix_alpha[a];
                vis[1] += (b - a + 1) as f64;
            }
        }
        let visibility = if vis[1] > 0.0 { vis[0] / vis[1] } else { 0.0 };
        (cw, visibility)
    }
}

/// The Euclidean distance of offset (ox, oy), as every tap computes it.
#[inline]
fn distance(ox: i64, oy: i64) -> f64 {
    ((ox * ox + oy * oy) as f64).sqrt()
}

impl DiskRows {
    /// Adds the scatter of the sources in `columns` of row `oy` (whose span is `span`) at
    /// centre column `x` to `cw`: `pa` times the term of each source's coverage radius.
    #[inline]
    fn add_scatter(&self, cw: &mut [f64; 4], span: &Span, (x, oy): (usize, i64), columns: std::ops::Range<usize>, pa: &[[f64; 4]], cov: &[f64]) {
        if columns.is_empty() {
            return;
        }
        if self.tabulated() {
            let weights = &self.weights[span.weights + columns.start + span.outer as usize - x..][..columns.len()];
            for (p, &weight) in pa[columns].iter().zip(weights) {
                add(cw, p, weight);
            }
        } else {
            for column in columns {
                let ox = column as i64 - x as i64;
                add(cw, &pa[column], math::smoothstep(0.0, 1.0, cov[column] + 0.5 - distance(ox, oy)));
            }
        }
    }

    /// Adds the footprint of radius `r_x` over `columns` of row `oy` at centre column `x` to
    /// `vis`: `[sum of alpha D, sum of D]`.
    #[inline]
    fn add_footprint(&self, vis: &mut [f64; 2], span: &Span, (x, oy): (usize, i64), columns: std::ops::Range<usize>, alpha: &[f64], r_x: f64) {
        if columns.is_empty() {
            return;
        }
        let first = span.weights + columns.start + span.outer as usize - x;
        for (k, column) in columns.enumerate() {
            let d = if self.tabulated() { self.weights[first + k] } else { math::smoothstep(0.0, 1.0, r_x + 0.5 - distance(column as i64 - x as i64, oy)) };
            vis[0] += alpha[column] * d;
            vis[1] += d;
        }
    }
}

/// The image's columns within `half` of column `x` (`half` = -1: none, as `lo > hi`).
#[inline]
fn columns(x: i64, half: i64, width: usize) -> (usize, usize) {
    if half < 0 {
        return (1, 0);
    }
    ((x - half).max(0) as usize, (x + half).min(width as i64 - 1) as usize)
}

fn add(cw: &mut [f64; 4], pa: &[f64; 4], weight: f64) {
    for c in 0..4 {
        cw[c] += pa[c] * weight;
    }
}

/// Largest `|ox|` with `ox^2 + oy^2 < (h + 1)^2`: the row of the window's disk at `oy` (taps
/// beyond add exact zeros, `row_half_width` in `glsl/drbokeh_layer.glsl`).
fn row_half_width(h: i64, oy: i64) -> i64 {
    let room = (h + 1) * (h + 1) - oy * oy;
    let mut half = (room as f64).sqrt() as i64;
    while half * half >= room {
        half -= 1;
    }
    while (half + 1) * (half + 1) < room {
        half += 1;
    }
    half
}

/// Largest `m` in `0..=cap` with `sqrt(m^2 + oy^2) <= level` (computed as the taps compute
/// it), or -1 where none is; `level` may be infinite.
fn half_width_within(level: f64, oy: i64, cap: i64) -> i64 {
    let within = |m: i64| ((m * m + oy * oy) as f64).sqrt() <= level;
    if within(cap) {
        return cap;
    }
    let mut m = ((level * level - (oy * oy) as f64).max(0.0).sqrt() as i64).min(cap);
    while m >= 0 && !within(m) {
        m -= 1;
    }
    while m < cap && within(m + 1) {
        m += 1;
    }
    m
}

/// Per search tile, the scatter's rows ([`DiskRows`]) over the smallest and largest coverage
/// radius of the sources with alpha > 0 within its window (the others' `P / A` is 0): the
/// scatter `smoothstep(0, 1, cov + 1/2 - g)` is 1 up to `cov - 1/2` and 0 from `cov + 1/2`.
fn scatter_rows(params: &Params, sources: &Sources, window: &[i32]) -> Vec<DiskRows> {
    let (tiles_x, tiles_y) = (params.tiles_x, params.tiles_y);
    let extremes: Vec<(f64, f64)> = (0..tiles_x * tiles_y)
        .into_par_iter()
        .map(|t| {
            let (tx, ty) = (t % tiles_x, t / tiles_x);
            let (mut least, mut most) = (f64::INFINITY, f64::NEG_INFINITY);
            for y in ty * TILE..((ty + 1) * TILE).min(params.height) {
                let columns = y * params.width + tx * TILE..y * params.width + ((tx + 1) * TILE).min(params.width);
                for (&alpha, &cov) in sources.alpha[columns.clone()].iter().zip(&sources.cov[columns]) {
                    if alpha > 0.0 {
                        least = least.min(cov);
                        most = most.max(cov);
                    }
                }
            }
            (least, most)
        })
        .collect();
    (0..tiles_x * tiles_y)
        .into_par_iter()
        .map(|t| {
            if window[t] == EMPTY_WINDOW {
                return DiskRows { spans: Vec::new(), weights: Vec::new(), stencil: None };
            }
            let h = window[t] as i64;
            let (tx, ty) = (t % tiles_x, t / tiles_x);
            let reach = (h as usize).div_ceil(TILE);
            let (mut least, mut most) = (f64::INFINITY, f64::NEG_INFINITY);
            for ny in ty.saturating_sub(reach)..=(ty + reach).min(tiles_y - 1) {
                for nx in tx.saturating_sub(reach)..=(tx + reach).min(tiles_x - 1) {
                    let (l, m) = extremes[ny * tiles_x + nx];
                    least = least.min(l);
                    most = most.max(m);
                }
            }
            DiskRows::spanning(h, least, most, params.width)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Aperture, CocModel};
    use crate::render::drbokeh::render_cpu;

    /// A deterministic hash of (i, salt) in [0, 1).
    fn noise(i: usize, salt: u64) -> f32 {
        let mut z = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ salt.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z ^= z >> 31;
        z = z.wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 29;
        (z >> 40) as f32 / (1u64 << 24) as f32
    }

    /// Three layers over a 53x37 frame (not whole tiles): a sparse front layer of partial
    /// alphas and a depth ramp, an opaque middle layer at the focus disparity (centres that
    /// occlude) with holes, and a noisy backdrop whose depth varies per pixel.
    fn stack() -> LayerStack {
        let (w, h) = (53, 37);
        let front = Layer {
            name: "front".into(),
            rgba: Image::from_fn(w, h, |x, y| {
                let a = if (x as i64 - 12).abs() < 6 && (y as i64 - 20).abs() < 8 { 1.0 } else if (x + 2 * y) % 9 == 0 { 0.35 } else { 0.0 };
                [2.5 * a, 0.4 * a, 0.1 * a, a]
            }),
            disparity: (0..w * h).map(|i| 0.8 + 0.1 * (i % w) as f32 / w as f32).collect(),
        };
        let middle = Layer {
            name: "middle".into(),
            rgba: Image::from_fn(w, h, |x, y| if (x / 5 + y / 7) % 3 == 0 { [0.0; 4] } else { [0.2, 0.9, 0.3, 1.0] }),
            disparity: (0..w * h).map(|i| 0.5 + 0.01 * noise(i, 1)).collect(),
        };
        let back = Layer {
            name: "back".into(),
            rgba: Image::from_fn(w, h, |x, y| {
                let i = y * w + x;
                [4.0 * noise(i, 2), noise(i, 3), noise(i, 4), 1.0]
            }),
            disparity: (0..w * h).map(|i| 0.1 + 0.15 * noise(i, 5)).collect(),
        };
        LayerStack::new(w, h, vec![front, middle, back]).unwrap()
    }

    #[test]
    fn native_equals_the_reference() {
        let stack = stack();
        // CoC scales from sub-pixel (the coverage radius's lift and dips) to ~20 px, focus on
        // the middle layer (its centres occlude), in front of everything and behind it.
        for (k_px, focus) in [(3.0, 0.5), (12.0, 0.5), (40.0, 0.5), (25.0, 0.95), (20.0, 0.0)] {
            let lens = Lens { coc: CocModel::new(k_px, focus).unwrap(), aperture: Aperture::Disk };
            assert!(supports(&lens, Model::DrBokeh));
            let ours = render_native(&stack, &lens, None).unwrap();
            let reference = render_cpu(&stack, &lens, Model::DrBokeh).unwrap();
            let mut worst = 0.0f32;
            for (a, b) in ours.pixels.iter().zip(&reference.pixels) {
                for c in 0..4 {
                    worst = worst.max((a[c] - b[c]).abs() / b[c].abs().max(1.0));
                }
            }
            // Another summation order in f64, then rounded to f32: an ulp or two of f32.
            assert!(worst <= 2.5e-7, "k_px {k_px}, focus {focus}: worst relative difference {worst}");
            assert!(reference.pixels.iter().any(|p| p[3] > 0.5), "the frame renders something");
        }
    }

    #[test]
    fn a_kept_scan_renders_the_same_bits() {
        let stack = stack();
        let scan = StackScan::new(&stack, 0.5);
        // Focus where the scan was made, outside every layer, and inside the middle and the
        // front layers' disparities (their tiles are read again).
        for (k_px, focus) in [(12.0, 0.5), (25.0, 0.95), (20.0, 0.0), (12.0, 0.505), (8.0, 0.85)] {
            let lens = Lens { coc: CocModel::new(k_px, focus).unwrap(), aperture: Aperture::Disk };
            let kept = render_native(&stack, &lens, Some(&scan)).unwrap();
            let fresh = render_native(&stack, &lens, None).unwrap();
            assert!(kept.pixels == fresh.pixels, "k_px {k_px}, focus {focus}: a kept scan changed the image");
        }
    }

    #[test]
    fn disk_rows_hold_exactly_the_columns_within_their_levels() {
        for (h, least, most) in [(0, 0.5, 0.5), (3, 0.9, 1.0), (7, 4.2, 4.7), (7, 5.5, 8.5), (12, 10.49, 10.5), (6, f64::INFINITY, f64::INFINITY), (9, 0.0, 0.0), (11, 10.0, 10.0)] {
            let rows = DiskRows::spanning(h, least, most, 64);
            assert_eq!(rows.tabulated(), least == most);
            for (span, oy) in rows.spans.iter().zip(-h..=h) {
                for ox in -h - 1..=h + 1 {
                    let (g, in_disk) = (((ox * ox + oy * oy) as f64).sqrt(), ox * ox + oy * oy < (h + 1) * (h + 1));
                    let outer = in_disk && g <= most + 0.5;
                    assert_eq!(ox.abs() <= span.outer, outer, "h {h}, oy {oy}, ox {ox}: {span:?}");
                    assert_eq!(ox.abs() <= span.inner, outer && g <= least - 0.5 - INTERIOR_MARGIN, "h {h}, oy {oy}, ox {ox}: {span:?}");
                    if outer {
                        // Beyond the outer span the term is 0, inside the inner one exactly 1.
                        for radius in [least, most] {
                            let term = rows.term(span, ox, || g, radius);
                            assert!((0.0..=1.0).contains(&term));
                            if ox.abs() <= span.inner {
                                assert_eq!(term, 1.0, "h {h}, oy {oy}, ox {ox}");
                            }
                        }
                        if rows.tabulated() {
                            assert_eq!(rows.term(span, ox, || g, most), math::smoothstep(0.0, 1.0, most + 0.5 - g));
                        }
                    } else if g.is_finite() && most.is_finite() {
                        assert_eq!(math::smoothstep(0.0, 1.0, most + 0.5 - g) * f64::from(in_disk), 0.0);
                    }
                }
            }
        }
    }

    #[test]
    fn window_rows_end_before_the_disk_of_radius_h_plus_one() {
        for h in 0..20 {
            for oy in -h..=h {
                let half = row_half_width(h, oy);
                assert!(half * half + oy * oy < (h + 1) * (h + 1));
                assert!((half + 1) * (half + 1) + oy * oy >= (h + 1) * (h + 1));
            }
        }
    }

    #[test]
    fn other_apertures_and_the_compat_model_are_left_to_the_reference() {
        let coc = CocModel::new(10.0, 0.5).unwrap();
        assert!(!supports(&Lens { coc, aperture: Aperture::polygon(6, 0.0, 0.0).unwrap() }, Model::DrBokeh));
        assert!(!supports(&Lens { coc, aperture: Aperture::Disk }, Model::Compat));
    }
}
