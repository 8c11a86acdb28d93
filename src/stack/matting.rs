//! Matting by solving (issue 46): at a depth discontinuity of one flat RGB+Z image, alpha and
//! the foreground and background colours come from a linear system, not from thresholds.
//!
//! 1. Alpha minimises the closed-form matting energy of Levin, Lischinski and Weiss (2008),
//!    `a' L a`, plus a soft prior from the depth pass, `sum_i c_i (a_i - z_i)^2`: `z_i` is 1
//!    where the pixel's Z sample hit the nearer surface, and its confidence `c_i` is low next
//!    to the edge (one Z sample says little about a mixed pixel) and rises with the distance
//!    from it. Only pixels within `radius_px` of the edge are unknown; the rest keep their
//!    label. The system `(L + C) a = C z` is solved sparse by conjugate gradients with a
//!    Jacobi preconditioner; `L` is applied matrix-free through per-window sums (He, Sun and
//!    Tang 2010), so memory grows with the edge's length, not with the frame.
//! 2. Given alpha, the foreground F and background B at the unknown pixels minimise the
//!    compositing residual `|a F + (1 - a) B - I|^2` plus a smoothness term weighted by the
//!    alpha gradient (Germer, Uelwer, Conrad and Harmeling 2020). Their multi-level start is
//!    replaced by a push-pull fill of each side's confident pixels (the same coarse-to-fine
//!    idea), then red-black Gauss-Seidel sweeps on the unknown pixels only.
//!
//! The guide image of the Laplacian is linear colour up to the frame's 90th percentile and
//! logarithmic above (`guide_value`: HDR lights do not rule the local colour models), while F
//! and B are solved in linear HDR, never clipped to the display range: a light seen between
//! wires keeps its energy in B.
use rayon::prelude::*;

use super::fill::{compress, expand, four_neighbours, is_hdr, push_pull_where, run_from};

/// Parameters of [`solve_matte`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MatteOptions {
    /// Unknown band: pixels within this many pixels (Chebyshev) of the depth edge.
    pub radius_px: usize,
    /// Regularisation of each 3x3 window's colour covariance (Levin et al.'s epsilon; the
    /// guide is 1 at the frame's 90th percentile).
    pub epsilon: f32,
    /// Confidence of the depth prior on the edge itself, and how much it grows per pixel of
    /// distance from it (squared).
    pub edge_confidence: f32,
    pub confidence_growth: f32,
    /// Confidence of the depth prior on a front pixel of a line at most [`THIN_RUN_PX`] wide
    /// (along its row or its column; `on_thin_line`), unless the pixel is HDR: every
    /// pixel of a 1-2 px wire is on the edge, where the prior is trusted least, and a wire
    /// lit like the wall behind it gives the colours nothing to tell its coverage by, so the
    /// matte faded it (alpha 0.2 on dev-108's wires of issue 46). Where the pixel is HDR, a
    /// light behind the wire shows how much of it the wire covers, and the prior stays
    /// uncertain (with it trusted there too, dev-24 lost 1.08 dB: lamps cut by sharp wires).
    /// On the dev split (before tips were told from lines), 0.3: +0.07 dB mean, 0.5: +0.11,
    /// 1: +0.12, 2: +0.11, 3: +0.05.
    pub thin_confidence: f32,
    /// Conjugate-gradient stopping rule: relative residual and most iterations.
    pub tolerance: f32,
    pub max_iterations: usize,
    /// Red-black Gauss-Seidel sweeps of the foreground/background estimate.
    pub colour_sweeps: usize,
}

impl Default for MatteOptions {
    fn default() -> Self {
        // Tuned on the dev split of the Cycles scenes (issue 46; `lensblur bench single-image
        // --cycles`, dev-0..11 and the blurred fences dev-13, 19, 25, 31), mean dB: edge
        // confidence 0.3 / growth 0.5: 33.75; 0.05: 33.81; 0.01: 33.39; 0.1: 33.76 (band 2 px:
        // 33.78, 4 px: 33.77); 0.1 / growth 0.1: 33.67, 2: 33.92, 4: 33.97, 8: 33.96.
        Self {
            radius_px: 3,
            epsilon: 1e-5,
            edge_confidence: 0.1,
            confidence_growth: 4.0,
            thin_confidence: 1.0,
            tolerance: 1e-5,
            max_iterations: 400,
            colour_sweeps: 40,
        }
    }
}

/// One binary matte: a foreground (the pixels whose Z hit the nearer side) against the rest,
/// kept for its band only: every other pixel keeps its label. (A layering holds the mattes of
/// all its cuts at once; as whole-frame arrays they were 29 bytes a pixel each, for bands of a
/// few thousand pixels.)
pub struct Matte {
    /// The solved pixels (within the band), in ascending order.
    pub band: Vec<usize>,
    /// Per band pixel (in `band`'s order): alpha, and the foreground and background colour
    /// (linear RGB).
    pub alpha: Vec<f32>,
    pub foreground: Vec<[f32; 3]>,
    pub background: Vec<[f32; 3]>,
    /// Conjugate-gradient iterations taken and the final relative residual.
    pub iterations: usize,
    pub residual: f32,
}

impl Matte {
    /// Where pixel `p` is in [`Self::band`]; None outside the band.
    pub fn index_of(&self, p: usize) -> Option<usize> {
        self.band.binary_search(&p).ok()
    }
}

/// Linear colour mixes linearly, so the Laplacian's guide is linear up to the lights; it is
/// scaled so that the 90th percentile of the brightest channel is 1.
fn guide_scale(image: &[[f32; 4]]) -> f32 {
    let mut brightest: Vec<f32> = image.iter().step_by((image.len() / 4096).max(1)).map(|c| c[0].max(c[1]).max(c[2]).max(0.0)).collect();
    let k = (brightest.len() * 9 / 10).min(brightest.len() - 1);
    let p90 = *brightest.select_nth_unstable_by(k, f32::total_cmp).1;
    1.0 / p90.max(1e-3)
}

/// The guide is linear up to the scale's 1 and logarithmic above: lights a hundred times
/// brighter than the frame would make the windows' covariances span 1e9 and their inverses
/// lose the precision that keeps the Laplacian positive semi-definite (conjugate gradients
/// then stop at once), while a light still stands far from a surface in the guide.
fn guide_value(v: f64) -> f64 {
    if v <= 1.0 {
        v
    } else {
        1.0 + v.ln()
    }
}

/// Chebyshev distance (px) to the nearest edge pixel plus one (1 on the edge: the edge runs
/// beside it), up to `limit + 1`.
///
/// Each edge pixel lowers the distances around it: edges are a percent or two of a frame, and
/// a search around every pixel of it was the layering's hottest loop.
fn edge_distance(edge: &[bool], width: usize, height: usize, limit: usize) -> Vec<u16> {
    // Two bytes a pixel, not eight: one of a cut's arrays of the whole frame.
    let limit = u16::try_from(limit).ok().filter(|&l| l < u16::MAX).expect("a matte's band radius under 65535 px");
    let r = i64::from(limit) - 1;
    let mut best = vec![limit + 1; width * height];
    for p in (0..width * height).filter(|&p| edge[p]) {
        let (x, y) = ((p % width) as i64, (p / width) as i64);
        for qy in (y - r).max(0)..=(y + r).min(height as i64 - 1) {
            for qx in (x - r).max(0)..=(x + r).min(width as i64 - 1) {
                let q = qy as usize * width + qx as usize;
                best[q] = best[q].min((qx - x).unsigned_abs().max((qy - y).unsigned_abs()) as u16 + 1);
            }
        }
    }
    best
}

/// The 3x3 windows of the matting Laplacian that touch an unknown pixel: centre, colour mean,
/// and the inverse of the regularised covariance (symmetric: xx, xy, xz, yy, yz, zz).
struct Windows {
    centres: Vec<usize>,
    mean: Vec<[f64; 3]>,
    inverse: Vec<[f64; 6]>,
    /// Per pixel, its window's slot in the lists above (u32::MAX: no window there).
    slot: Vec<u32>,
}

fn invert_symmetric(m: [f64; 6]) -> [f64; 6] {
    let [a, b, c, d, e, f] = m;
    // Cofactors of [[a b c] [b d e] [c e f]].
    let (ca, cb, cc) = (d * f - e * e, c * e - b * f, b * e - c * d);
    let det = a * ca + b * cb + c * cc;
    let inv = 1.0 / det;
    [ca * inv, cb * inv, cc * inv, (a * f - c * c) * inv, (b * c - a * e) * inv, (a * d - b * b) * inv]
}

#[inline]
fn mat_vec(m: &[f64; 6], v: [f64; 3]) -> [f64; 3] {
    [m[0] * v[0] + m[1] * v[1] + m[2] * v[2], m[1] * v[0] + m[3] * v[1] + m[4] * v[2], m[2] * v[0] + m[4] * v[1] + m[5] * v[2]]
}

#[inline]
fn dot3(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The nine pixels of the window centred at `c` (interior centres only).
fn window_pixels(c: usize, width: usize) -> [usize; 9] {
    let mut out = [0; 9];
    let mut k = 0;
    for dy in 0..3 {
        for dx in 0..3 {
            out[k] = c + dy * width + dx - width - 1;
            k += 1;
        }
    }
    out
}

fn windows(guide: &[[f64; 3]], width: usize, height: usize, unknown: &[usize], epsilon: f64) -> Windows {
    let mut active = vec![false; width * height];
    for &p in unknown {
        let (x, y) = (p % width, p / width);
        for cy in y.saturating_sub(1)..=(y + 1).min(height - 1) {
            for cx in x.saturating_sub(1)..=(x + 1).min(width - 1) {
                if cx >= 1 && cy >= 1 && cx + 1 < width && cy + 1 < height {
                    active[cy * width + cx] = true;
                }
            }
        }
    }
    let centres: Vec<usize> = (0..width * height).filter(|&c| active[c]).collect();
    let stats: Vec<([f64; 3], [f64; 6])> = centres
        .par_iter()
        .map(|&c| {
            let pixels = window_pixels(c, width);
            let mut mean = [0.0f64; 3];
            for &q in &pixels {
                for k in 0..3 {
                    mean[k] += guide[q][k] / 9.0;
                }
            }
            let mut cov = [0.0f64; 6];
            for &q in &pixels {
                let d = [guide[q][0] - mean[0], guide[q][1] - mean[1], guide[q][2] - mean[2]];
                let terms = [d[0] * d[0], d[0] * d[1], d[0] * d[2], d[1] * d[1], d[1] * d[2], d[2] * d[2]];
                for k in 0..6 {
                    cov[k] += terms[k] / 9.0;
                }
            }
            let reg = epsilon / 9.0;
            cov[0] += reg;
            cov[3] += reg;
            cov[5] += reg;
            (mean, invert_symmetric(cov))
        })
        .collect();
    let mut slot = vec![u32::MAX; width * height];
    centres.iter().enumerate().for_each(|(i, &c)| slot[c] = i as u32);
    let (mean, inverse) = stats.into_iter().unzip();
    Windows { centres, mean, inverse, slot }
}

/// The windows containing pixel `p` (their slots).
fn windows_of(p: usize, width: usize, height: usize, windows: &Windows) -> impl Iterator<Item = usize> + '_ {
    let (x, y) = (p % width, p / width);
    let rows = y.saturating_sub(1)..=(y + 1).min(height - 1);
    rows.flat_map(move |cy| (x.saturating_sub(1)..=(x + 1).min(width - 1)).map(move |cx| cy * width + cx))
        .filter_map(move |c| (windows.slot[c] != u32::MAX).then_some(windows.slot[c] as usize))
}

/// The matting Laplacian `L` at the unknown pixels, applied matrix-free; its per-window
/// models live in one buffer that every application of the conjugate gradients reuses.
struct Laplacian<'a> {
    guide: &'a [[f64; 3]],
    width: usize,
    windows: &'a Windows,
    unknown: &'a [usize],
    /// Per window: the affine model's offset and slope fitted to the last `x` (He et al. 2010).
    models: Vec<(f64, [f64; 3])>,
    /// The windows holding each unknown pixel (`windows_of`, in its order), listed once:
    /// unknown `i`'s are `containing[starts[i]..starts[i + 1]]`.
    containing: Vec<u32>,
    starts: Vec<usize>,
}

impl<'a> Laplacian<'a> {
    fn new(guide: &'a [[f64; 3]], width: usize, height: usize, windows: &'a Windows, unknown: &'a [usize]) -> Self {
        let mut starts = Vec::with_capacity(unknown.len() + 1);
        let mut containing = Vec::with_capacity(unknown.len() * 9);
        starts.push(0);
        for &p in unknown {
            containing.extend(windows_of(p, width, height, windows).map(|k| k as u32));
            starts.push(containing.len());
        }
        Self { guide, width, windows, unknown, models: Vec::new(), containing, starts }
    }

    /// `(L x)_i` at the unknown pixels into `out`, for `x` given on the whole frame.
    fn apply(&mut self, x: &[f64], out: &mut Vec<f64>) {
        let (guide, width, windows) = (self.guide, self.width, self.windows);
        (0..windows.centres.len())
            .into_par_iter()
            .map(|k| {
                let pixels = window_pixels(windows.centres[k], width);
                // The window's sums, divided once: four divisions instead of 36, in the hottest
                // loop of the conjugate gradients.
                let (mut a, mut s) = (0.0f64, [0.0f64; 3]);
                for &q in &pixels {
                    a += x[q];
                    for c in 0..3 {
                        s[c] += guide[q][c] * x[q];
                    }
                }
                let (a, s) = (a / 9.0, [s[0] / 9.0, s[1] / 9.0, s[2] / 9.0]);
                let mu = windows.mean[k];
                let v = mat_vec(&windows.inverse[k], [s[0] - mu[0] * a, s[1] - mu[1] * a, s[2] - mu[2] * a]);
                (a - dot3(mu, v), v)
            })
            .collect_into_vec(&mut self.models);
        let (models, containing, starts) = (&self.models, &self.containing, &self.starts);
        self.unknown
            .par_iter()
            .enumerate()
            .map(|(i, &p)| {
                let mut out = 0.0f64;
                for &k in &containing[starts[i]..starts[i + 1]] {
                    let (offset, slope) = models[k as usize];
                    out += x[p] - offset - dot3(guide[p], slope);
                }
                out
            })
            .collect_into_vec(out);
    }
}

/// The diagonal of `L` at the unknown pixels (the Jacobi preconditioner).
fn laplacian_diagonal(guide: &[[f64; 3]], width: usize, height: usize, windows: &Windows, unknown: &[usize]) -> Vec<f64> {
    unknown
        .par_iter()
        .map(|&p| {
            windows_of(p, width, height, windows)
                .map(|k| {
                    let (g, mu) = (guide[p], windows.mean[k]);
                    let d = [g[0] - mu[0], g[1] - mu[1], g[2] - mu[2]];
                    1.0 - (1.0 + dot3(d, mat_vec(&windows.inverse[k], d))) / 9.0
                })
                .sum()
        })
        .collect()
}

/// Widest run of front pixels, along a row or a column, that [`MatteOptions::thin_confidence`]
/// treats as a thin structure.
pub const THIN_RUN_PX: usize = 2;

/// Whether front pixel `p` lies on a structure at most [`THIN_RUN_PX`] wide: its run of front
/// pixels along its row or its column is that short.
fn is_thin(front: &[bool], width: usize, height: usize, p: usize) -> bool {
    let run = |dx: i64, dy: i64| {
        let lit = |q: usize| front[q];
        1 + run_from(width, height, p, (-dx, -dy), THIN_RUN_PX, lit) + run_from(width, height, p, (dx, dy), THIN_RUN_PX, lit)
    };
    run(1, 0).min(run(0, 1)) <= THIN_RUN_PX
}

/// Whether pixel `p` is on a thin line, not the tip of a wider shape, given `thin`, whether a
/// pixel is a front pixel and [`is_thin`]: it is thin and so are at least two pixels of its 3x3
/// neighbourhood (along the line, either way). The top pixels of a disc are as narrow as a
/// wire, but the pixels below them are wide.
fn on_thin_line(thin: impl Fn(usize) -> bool, width: usize, height: usize, p: usize) -> bool {
    if !thin(p) {
        return false;
    }
    let (x, y) = (p % width, p / width);
    let rows = y.saturating_sub(1)..=(y + 1).min(height - 1);
    let neighbours = rows.flat_map(|qy| (x.saturating_sub(1)..=(x + 1).min(width - 1)).map(move |qx| qy * width + qx));
    neighbours.filter(|&q| q != p && thin(q)).count() >= 2
}

/// What every matte of one image shares, whatever its cut: the image and the Laplacian's
/// guide. A flat frame's layering solves one matte per cut; each computed the guide again over
/// the whole frame, for a band of a few percent of it.
pub struct MatteImage<'a> {
    pixels: &'a [[f32; 4]],
    width: usize,
    height: usize,
    /// Per pixel, the guide colour of the matting Laplacian ([`guide_value`] of the scaled colour).
    guide: Vec<[f64; 3]>,
}

impl<'a> MatteImage<'a> {
    /// `pixels`: linear RGBA, straight, alpha 1, `width` x `height`.
    pub fn new(pixels: &'a [[f32; 4]], width: usize, height: usize) -> Self {
        assert_eq!(pixels.len(), width * height);
        let scale = guide_scale(pixels);
        let guide = pixels.par_iter().map(|&c| [0, 1, 2].map(|k| guide_value(f64::from(c[k].max(0.0) * scale)))).collect();
        Self { pixels, width, height, guide }
    }
}

/// Solves one binary matte of `image` (linear RGBA, straight, alpha 1) where `front` marks the
/// pixels whose Z sample hit the nearer side, around the pixels `edge` marks (beside the other
/// side). Returns None when no pixel is on an edge.
pub fn solve_matte(image: &[[f32; 4]], width: usize, height: usize, front: &[bool], edge: &[bool], options: &MatteOptions) -> Option<Matte> {
    solve_matte_of(&MatteImage::new(image, width, height), front, edge, options)
}

/// [`solve_matte`] on an image's shared data (several mattes of one image).
pub fn solve_matte_of(shared: &MatteImage, front: &[bool], edge: &[bool], options: &MatteOptions) -> Option<Matte> {
    let (image, width, height) = (shared.pixels, shared.width, shared.height);
    let n = width * height;
    assert_eq!(front.len(), n);
    assert_eq!(edge.len(), n);
    let distance = edge_distance(edge, width, height, options.radius_px);
    let unknown_list: Vec<usize> = (0..n).filter(|&p| usize::from(distance[p]) <= options.radius_px).collect();
    if unknown_list.is_empty() {
        return None;
    }
    let mut unknown = vec![false; n];
    unknown_list.iter().for_each(|&p| unknown[p] = true);
    let guide = &shared.guide;
    let windows = windows(guide, width, height, &unknown_list, f64::from(options.epsilon));
    // The Z prior: 1 on the front, 0 behind.
    let prior = |p: usize| if front[p] { 1.0f64 } else { 0.0 };
    // Pixels next to the edge (distance 1: the edge runs between them) trust Z least, but
    // those of a thin line. Whether a pixel is thin is asked of the band's pixels and their
    // neighbours only.
    let thin = |p: usize| front[p] && is_thin(front, width, height, p);
    let confidence: Vec<f64> = unknown_list
        .par_iter()
        .map(|&p| {
            let d = f64::from(distance[p].saturating_sub(1));
            let base = f64::from(options.edge_confidence) + f64::from(options.confidence_growth) * d * d;
            if !is_hdr(image[p]) && on_thin_line(thin, width, height, p) {
                base.max(f64::from(options.thin_confidence))
            } else {
                base
            }
        })
        .collect();
    let mut laplacian = Laplacian::new(guide, width, height, &windows, &unknown_list);
    // Right-hand side: C z - L x_fixed, x_fixed = the labels outside the band, 0 inside.
    let mut fixed: Vec<f64> = (0..n).map(prior).collect();
    unknown_list.iter().for_each(|&p| fixed[p] = 0.0);
    let mut lx_fixed = Vec::new();
    laplacian.apply(&fixed, &mut lx_fixed);
    let b: Vec<f64> = (0..unknown_list.len()).map(|i| confidence[i] * prior(unknown_list[i]) - lx_fixed[i]).collect();
    let diagonal: Vec<f64> = laplacian_diagonal(guide, width, height, &windows, &unknown_list)
        .iter()
        .zip(&confidence)
        .map(|(d, c)| (d + c).max(1e-6))
        .collect();
    // Operator on the unknowns: (L + C) restricted to the band, into `out` (every buffer of
    // the iterations is allocated once: the frame-long one is x_fixed's, cleared).
    let mut scratch = fixed;
    scratch.fill(0.0);
    let mut apply = |v: &[f64], out: &mut Vec<f64>| {
        unknown_list.iter().zip(v).for_each(|(&p, &x)| scratch[p] = x);
        laplacian.apply(&scratch, out);
        out.iter_mut().zip(v).zip(&confidence).for_each(|((l, x), c)| *l += c * x);
    };
    // Preconditioned conjugate gradients from the prior.
    let mut x: Vec<f64> = unknown_list.iter().map(|&p| prior(p)).collect();
    let mut ap = Vec::with_capacity(x.len());
    apply(&x, &mut ap);
    let mut r: Vec<f64> = b.iter().zip(&ap).map(|(b, a)| b - a).collect();
    let mut z: Vec<f64> = r.iter().zip(&diagonal).map(|(r, d)| r / d).collect();
    let mut p = z.clone();
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let b_norm = norm(&b).max(1e-12);
    let dotf = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let mut rz = dotf(&r, &z);
    let mut iterations = 0;
    let mut residual = norm(&r) / b_norm;
    while iterations < options.max_iterations && residual > f64::from(options.tolerance) {
        apply(&p, &mut ap);
        let pap = dotf(&p, &ap);
        if pap <= 0.0 {
            break;
        }
        let step = rz / pap;
        x.iter_mut().zip(&p).for_each(|(x, p)| *x += step * p);
        r.iter_mut().zip(&ap).for_each(|(r, a)| *r -= step * a);
        z.iter_mut().zip(r.iter().zip(&diagonal)).for_each(|(z, (r, d))| *z = r / d);
        let rz_next = dotf(&r, &z);
        let beta = rz_next / rz.max(1e-300);
        rz = rz_next;
        p.iter_mut().zip(&z).for_each(|(p, z)| *p = z + beta * *p);
        iterations += 1;
        residual = norm(&r) / b_norm;
    }
    let mut alpha: Vec<f32> = (0..n).map(|p| prior(p) as f32).collect();
    unknown_list.iter().zip(&x).for_each(|(&p, &a)| alpha[p] = snap(a as f32));
    let (foreground, background) = estimate_colours(shared, &alpha, &unknown, &unknown_list, options.colour_sweeps);
    Some(Matte {
        alpha: unknown_list.iter().map(|&p| alpha[p]).collect(),
        foreground: unknown_list.iter().map(|&p| foreground[p]).collect(),
        background: unknown_list.iter().map(|&p| background[p]).collect(),
        band: unknown_list,
        iterations,
        residual: residual as f32,
    })
}

/// Within this of 0 or 1, alpha is 0 or 1: the smoothness of the solution leaves a few
/// percent on pixels wholly of one side, and behind an HDR light a 0.97 in-focus pixel would
/// hand the light's 3% to the front and take its colour away.
const SNAP: f32 = 0.03;

fn snap(a: f32) -> f32 {
    if a < SNAP {
        0.0
    } else if a > 1.0 - SNAP {
        1.0
    } else {
        a
    }
}

/// One side's colour where the sweeps read it (`read`, listed in `read_list`): the image's own
/// at the side's confident pixels (weight 1), elsewhere a fill from them, made in the
/// range-compressed space of the layering's fills so that a light does not smear. Outside
/// `read` nothing reads the other side's colour, which is left the image's.
fn side_colours(shared: &MatteImage, weight: &[f32], read: &[bool], read_list: &[usize]) -> Vec<[f32; 3]> {
    let mut values: Vec<[f32; 4]> = shared.pixels.iter().map(|&c| compress(c.map(|v| v.max(0.0)))).collect();
    push_pull_where(shared.width, shared.height, &mut values, weight, read);
    let mut colours: Vec<[f32; 3]> = shared.pixels.iter().map(|c| [c[0], c[1], c[2]]).collect();
    for &p in read_list.iter().filter(|&&p| weight[p] <= 0.0) {
        let [r, g, b, _] = expand(values[p]);
        colours[p] = [r, g, b];
    }
    colours
}

/// Weight of the smoothness term between two neighbours (Germer et al. 2020: regularisation
/// plus the alpha gradient, so colours are smooth where alpha is and free across its edges).
const COLOUR_REGULARISATION: f32 = 1e-3;

/// Foreground and background colours at the unknown pixels (see the module docs).
fn estimate_colours(shared: &MatteImage, alpha: &[f32], unknown: &[bool], unknown_list: &[usize], sweeps: usize) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let (image, width, height) = (shared.pixels, shared.width, shared.height);
    let known_front: Vec<f32> = (0..alpha.len()).map(|p| if !unknown[p] && alpha[p] >= 0.5 { 1.0 } else { 0.0 }).collect();
    let known_back: Vec<f32> = (0..alpha.len()).map(|p| if !unknown[p] && alpha[p] < 0.5 { 1.0 } else { 0.0 }).collect();
    // The fills are read in the band and, by the sweeps, at its pixels' 4-neighbours only.
    // Outside the band the pixel is all one side: that side's colour is the pixel's.
    let mut read = vec![false; alpha.len()];
    let mut read_list = Vec::with_capacity(unknown_list.len() * 2);
    for &p in unknown_list {
        for q in std::iter::once(p).chain(four_neighbours(p, width, height).into_iter().flatten()) {
            if !read[q] {
                read[q] = true;
                read_list.push(q);
            }
        }
    }
    let mut foreground = side_colours(shared, &known_front, &read, &read_list);
    let mut background = side_colours(shared, &known_back, &read, &read_list);
    let parity: [Vec<usize>; 2] = [0, 1].map(|k| unknown_list.iter().copied().filter(|&p| (p % width + p / width) % 2 == k).collect());
    // A pixel's 4-neighbours are all of the other parity: each half sweep reads the other
    // half's colours and writes its own, in place, in arrays of the band's pixels alone.
    let mut slot = vec![u32::MAX; alpha.len()];
    for set in &parity {
        set.iter().enumerate().for_each(|(i, &p)| slot[p] = i as u32);
    }
    let pixels: [Vec<SweepPixel>; 2] = parity.each_ref().map(|set| set.par_iter().map(|&p| SweepPixel::new(p, width, height, alpha, unknown, &slot)).collect());
    let mut colours: [Vec<([f32; 3], [f32; 3])>; 2] = parity.each_ref().map(|set| set.iter().map(|&p| (foreground[p], background[p])).collect());
    for _ in 0..sweeps {
        for (k, pixels) in pixels.iter().enumerate() {
            let (first, second) = colours.split_at_mut(1);
            let (own, other) = if k == 0 { (&mut first[0], &second[0]) } else { (&mut second[0], &first[0]) };
            own.par_iter_mut().zip(pixels).with_min_len(SWEEP_PIXELS_PER_TASK).for_each(|(out, pixel)| {
                *out = pixel.update(image, other, &foreground, &background);
            });
        }
    }
    for (set, colours) in parity.iter().zip(&colours) {
        for (&p, &(f, b)) in set.iter().zip(colours) {
            foreground[p] = f;
            background[p] = b;
        }
    }
    // The sweeps spread colour along the band as well as across it: behind an in-focus edge an
    // HDR light's B would run along the whole silhouette (a bright streak once blurred).
    // The background stays within the range of what pixels nearly all of it (alpha under
    // NEARLY_BACK_ALPHA, in the band or not: a light between two wires is all band) show
    // nearest; a mixed pixel's colour would let the front's colour in.
    let nearly_back: Vec<f32> = alpha.iter().map(|&a| if a < NEARLY_BACK_ALPHA { 1.0 } else { 0.0 }).collect();
    let clamped: Vec<[f32; 3]> = unknown_list
        .par_iter()
        .map(|&p| match known_range(image, width, height, &nearly_back, p) {
            Some((lo, hi)) => [0, 1, 2].map(|k| background[p][k].clamp(lo[k], hi[k])),
            None => background[p],
        })
        .collect();
    for (&p, b) in unknown_list.iter().zip(clamped) {
        background[p] = b;
    }
    (foreground, background)
}

/// One unknown pixel of the colour sweeps and what stays the same from sweep to sweep: its
/// 2x2 system's matrix (inverted) and its neighbours' weights.
struct SweepPixel {
    pixel: u32,
    alpha: f32,
    a00: f32,
    a01: f32,
    inv: f32,
    a11: f32,
    /// The neighbours left, right, up, down that are in the frame: weight, and where their
    /// colours are (`SWEPT` set: the other parity's slot; else the pixel, whose colours are
    /// fixed); unused taps have weight 0 and come after the used ones.
    taps: [(f32, u32); 4],
    count: u8,
}

/// Marks a tap of [`SweepPixel`] whose colours are swept (a slot of the other parity).
const SWEPT: u32 = 1 << 31;

impl SweepPixel {
    fn new(p: usize, width: usize, height: usize, alpha: &[f32], unknown: &[bool], slot: &[u32]) -> Self {
        let a = alpha[p];
        let (mut a00, a01, mut a11) = (a * a, a * (1.0 - a), (1.0 - a) * (1.0 - a));
        let (mut taps, mut count) = ([(0.0f32, 0u32); 4], 0);
        for q in four_neighbours(p, width, height).into_iter().flatten() {
            let w = COLOUR_REGULARISATION + (a - alpha[q]).abs();
            a00 += w;
            a11 += w;
            taps[count] = (w, if unknown[q] { slot[q] | SWEPT } else { q as u32 });
            count += 1;
        }
        let det = a00 * a11 - a01 * a01;
        Self { pixel: p as u32, alpha: a, a00, a01, inv: 1.0 / det, a11, taps, count: count as u8 }
    }

    /// The pixel's F and B given its neighbours' (the same operations, in the same order, as
    /// solving its system from scratch).
    ///
    /// Plain loops over the three channels, not array maps: the sweeps are the matte's hottest
    /// loop, and the maps' closures were left uninlined there (the same operations either way).
    fn update(&self, image: &[[f32; 4]], swept: &[([f32; 3], [f32; 3])], foreground: &[[f32; 3]], background: &[[f32; 3]]) -> ([f32; 3], [f32; 3]) {
        let (a, c) = (self.alpha, image[self.pixel as usize]);
        let (mut b0, mut b1) = ([0.0f32; 3], [0.0f32; 3]);
        for k in 0..3 {
            b0[k] = a * c[k];
            b1[k] = (1.0 - a) * c[k];
        }
        for &(w, source) in &self.taps[..usize::from(self.count)] {
            let (f, b) = if source & SWEPT != 0 {
                swept[(source & !SWEPT) as usize]
            } else {
                (foreground[source as usize], background[source as usize])
            };
            for k in 0..3 {
                b0[k] += w * f[k];
                b1[k] += w * b[k];
            }
        }
        let (mut f, mut b) = ([0.0f32; 3], [0.0f32; 3]);
        for k in 0..3 {
            f[k] = ((self.a11 * b0[k] - self.a01 * b1[k]) * self.inv).max(0.0);
            b[k] = ((self.a00 * b1[k] - self.a01 * b0[k]) * self.inv).max(0.0);
        }
        (f, b)
    }
}

/// Fewest pixels of a colour sweep handed to one task of the thread pool.
const SWEEP_PIXELS_PER_TASK: usize = 512;

/// Alpha under which a pixel's colour is the background's for [`estimate_colours`]' range.
const NEARLY_BACK_ALPHA: f32 = 0.1;

/// How far (px) [`estimate_colours`] looks for the colours a side shows: the nearest reach
/// where that side shows at all.
const CLAMP_REACHES_PX: [i64; 3] = [2, 4, 8];

/// Per-channel range of the pixels marked `known` around `p`, within the first of
/// [`CLAMP_REACHES_PX`] that holds any.
fn known_range(image: &[[f32; 4]], width: usize, height: usize, known: &[f32], p: usize) -> Option<([f32; 3], [f32; 3])> {
    let (x, y) = ((p % width) as i64, (p / width) as i64);
    CLAMP_REACHES_PX.iter().find_map(|&reach| {
        let (mut lo, mut hi, mut any) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3], false);
        for qy in (y - reach).max(0)..=(y + reach).min(height as i64 - 1) {
            for qx in (x - reach).max(0)..=(x + reach).min(width as i64 - 1) {
                let q = qy as usize * width + qx as usize;
                if known[q] > 0.0 {
                    (0..3).for_each(|k| (lo[k], hi[k]) = (lo[k].min(image[q][k]), hi[k].max(image[q][k])));
                    any = true;
                }
            }
        }
        any.then_some((lo, hi))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A disc of colour `f` over a smooth background, anti-aliased by 4x4 supersampling; the
    /// Z "sample" is the centre sample. Returns (image, exact coverage, front labels).
    fn disc_scene(size: usize, f: [f32; 3], background: impl Fn(usize, usize) -> [f32; 3]) -> (Vec<[f32; 4]>, Vec<f32>, Vec<bool>) {
        let (cx, cy, r) = (size as f32 * 0.5, size as f32 * 0.45, size as f32 * 0.27);
        let mut image = Vec::new();
        let mut coverage = Vec::new();
        let mut front = Vec::new();
        for y in 0..size {
            for x in 0..size {
                let mut hits = 0;
                for sy in 0..4 {
                    for sx in 0..4 {
                        let (px, py) = (x as f32 + (sx as f32 + 0.5) / 4.0, y as f32 + (sy as f32 + 0.5) / 4.0);
                        hits += ((px - cx).powi(2) + (py - cy).powi(2) < r * r) as usize;
                    }
                }
                let a = hits as f32 / 16.0;
                let b = background(x, y);
                image.push([0, 1, 2].map(|k| a * f[k] + (1.0 - a) * b[k]).into_iter().chain([1.0]).collect::<Vec<_>>().try_into().unwrap());
                coverage.push(a);
                let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
                front.push((px - cx).powi(2) + (py - cy).powi(2) < r * r);
            }
        }
        (image, coverage, front)
    }

    /// Pixels with a 4-neighbour on the other side.
    fn edges(front: &[bool], size: usize) -> Vec<bool> {
        (0..front.len())
            .map(|p| {
                four_neighbours(p, size, size)
                    .into_iter()
                    .flatten()
                    .any(|q| front[q] != front[p])
            })
            .collect()
    }

    #[test]
    fn the_laplacian_of_a_constant_is_zero_and_it_is_symmetric() {
        // L 1 = 0 (every window's affine model fits a constant exactly) and x'Ly = y'Lx:
        // the two properties conjugate gradients rely on.
        let size = 12;
        let guide: Vec<[f64; 3]> = (0..size * size).map(|p| [((p * 7) % 11) as f64 / 11.0, ((p * 3) % 5) as f64 / 5.0, 0.3]).collect();
        let all: Vec<usize> = (0..size * size).collect();
        let w = windows(&guide, size, size, &all, 1e-5);
        let mut laplacian = Laplacian::new(&guide, size, size, &w, &all);
        let mut apply = |x: &[f64]| {
            let mut out = Vec::new();
            laplacian.apply(x, &mut out);
            out
        };
        let ones = vec![1.0f64; size * size];
        let l1 = apply(&ones);
        assert!(l1.iter().all(|v| v.abs() < 1e-4), "L 1 = {:?}", l1.iter().fold(0.0f64, |m, v| m.max(v.abs())));
        let x: Vec<f64> = (0..size * size).map(|p| ((p * 13) % 17) as f64 / 17.0).collect();
        let y: Vec<f64> = (0..size * size).map(|p| ((p * 5) % 7) as f64 / 7.0).collect();
        let (lx, ly) = (apply(&x), apply(&y));
        let (xly, ylx): (f64, f64) = (x.iter().zip(&ly).map(|(a, b)| a * b).sum(), y.iter().zip(&lx).map(|(a, b)| a * b).sum());
        assert!((xly - ylx).abs() < 1e-3 * xly.abs().max(1.0), "{xly} vs {ylx}");
        // And its diagonal is what the operator gives for a unit vector.
        let diagonal = laplacian_diagonal(&guide, size, size, &w, &all);
        for p in [0, 13, 50, 143] {
            let mut e = vec![0.0f64; size * size];
            e[p] = 1.0;
            let le = apply(&e);
            assert!((le[p] - diagonal[p]).abs() < 1e-4, "pixel {p}: {} vs {}", le[p], diagonal[p]);
        }
    }

    #[test]
    fn thin_lines_are_told_from_the_tips_of_wider_shapes() {
        // A vertical wire 1 px wide (x = 4), a diagonal one (x = y + 20), a horizontal one 2 px
        // high (y = 30, 31), and a disc of radius 6 whose top and bottom rows are 1-3 px wide.
        let (w, h) = (48, 48);
        let disc = |x: usize, y: usize| (x as f32 - 30.0).powi(2) + (y as f32 - 12.0).powi(2) <= 36.0;
        let front: Vec<bool> = (0..w * h)
            .map(|p| {
                let (x, y) = (p % w, p / w);
                x == 4 || (x == y + 20 && y < 20) || ((30..=31).contains(&y) && x > 8) || disc(x, y)
            })
            .collect();
        // Along them, at the frame's edge too where the line goes on beside it (a line's last pixel
        // has one neighbour on it, and is left to the colours, as a tip).
        let thin = |p: usize| front[p] && is_thin(&front, w, h, p);
        for (x, y) in [(4, 10), (4, 1), (24, 4), (30, 30), (40, 31), (47, 30)] {
            assert!(on_thin_line(thin, w, h, y * w + x), "({x}, {y}) is on a line");
        }
        for p in (0..w * h).filter(|&p| disc(p % w, p / w)) {
            assert!(!on_thin_line(thin, w, h, p), "disc pixel ({}, {}) taken for a line", p % w, p / w);
        }
    }

    #[test]
    fn recovers_the_coverage_of_an_antialiased_edge_within_a_tenth() {
        // A red disc over a blue-green gradient: the prior is the centre sample (hard), the
        // solved alpha must be the true coverage within 0.1 on every edge pixel, where the
        // prior itself is off by up to 0.5.
        let (image, coverage, front) = disc_scene(48, [0.9, 0.15, 0.1], |x, y| [0.05, 0.2 + 0.01 * x as f32, 0.5 + 0.005 * y as f32]);
        let matte = solve_matte(&image, 48, 48, &front, &edges(&front, 48), &MatteOptions::default()).expect("an edge");
        let mut worst: f32 = 0.0;
        let mut prior_worst: f32 = 0.0;
        for p in (0..48 * 48).filter(|&p| coverage[p] > 0.0 && coverage[p] < 1.0) {
            let i = matte.index_of(p).expect("every mixed pixel is in the band");
            worst = worst.max((matte.alpha[i] - coverage[p]).abs());
            prior_worst = prior_worst.max(((front[p] as u8 as f32) - coverage[p]).abs());
        }
        assert!(prior_worst > 0.4, "the prior alone is wrong at the edge: {prior_worst}");
        assert!(worst < 0.1, "alpha off by {worst} (CG {} iterations, residual {})", matte.iterations, matte.residual);
        assert!(matte.residual < 1e-3, "converged: {}", matte.residual);
    }

    #[test]
    fn foreground_and_background_are_the_true_colours_in_hdr_without_clipping() {
        // An HDR background (a light of 20 behind the right of the disc's edge): at every
        // mixed pixel B is the true background within 10% (+0.05), so B keeps the light's
        // energy where the disc half covers it, and F the disc's colour over the dim part.
        let disc = [0.6, 0.5, 0.4];
        let back = |x: usize, y: usize| if x > 30 { [20.0, 18.0, 15.0] } else { [0.1 + 0.01 * y as f32, 0.2, 0.3] };
        let (image, coverage, front) = disc_scene(48, disc, back);
        let matte = solve_matte(&image, 48, 48, &front, &edges(&front, 48), &MatteOptions::default()).expect("an edge");
        // Where the background itself has an edge next to the disc's, no method can tell which
        // side's colour a mixed pixel hides: judged where it is uniform within 3 px.
        let uniform = |p: usize| (p % 48 > 33 || p % 48 < 28) && ((p % 48 > 33) == (p % 48 > 30));
        let mixed: Vec<usize> = (0..48 * 48).filter(|&p| coverage[p] > 0.2 && coverage[p] < 0.8 && uniform(p)).collect();
        assert!(mixed.iter().any(|&p| p % 48 > 32), "some mixed pixels over the light");
        for p in mixed {
            let truth = back(p % 48, p / 48);
            let i = matte.index_of(p).expect("every mixed pixel is in the band");
            for k in 0..3 {
                let (f, b) = (matte.foreground[i][k], matte.background[i][k]);
                // Over the light an alpha error e moves F by e * 20 / alpha, so F is judged over
                // the display-range background only (the layering uses B: front = c - (1 - a) B).
                if truth[0] <= 1.0 {
                    assert!((f - disc[k]).abs() <= 0.1 * disc[k] + 0.05, "pixel {p}: F {:?}, disc {disc:?}", matte.foreground[i]);
                }
                assert!((b - truth[k]).abs() <= 0.1 * truth[k] + 0.05, "pixel {p}: B {:?}, truth {truth:?}", matte.background[i]);
            }
        }
    }

    #[test]
    fn no_edge_no_matte() {
        let image = vec![[0.5f32, 0.5, 0.5, 1.0]; 16];
        assert!(solve_matte(&image, 4, 4, &[true; 16], &[false; 16], &MatteOptions::default()).is_none());
    }
}
