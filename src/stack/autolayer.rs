//! Auto-layering of one flat RGB+Z image (DESIGN.md, "Layer stacks").
//!
//! 1. Layers follow the depth structure: every empty gap of more than `discontinuity_px` in
//!    the signed-CoC histogram is a cut, so surfaces blurred differently by more than a pixel
//!    never share a layer, and so is a narrower empty gap that many neighbouring pixels jump
//!    across by at least `matte_jump_px` (0.5 px) while few meet gently (a surface between the
//!    two in CoC but elsewhere in the frame, such as a ground plane, must not hide an edge)
//!    and the two are not blurred almost alike (a gap under 5% of their CoC); a
//!    surface spanning more than `coc_spacing_px` of CoC (slanted) is sliced uniformly (Lee,
//!    Eisemann, Seidel 2009, Eq. 4), each cut moved to the emptiest depth bin within half a
//!    slice. The count adapts (at most `max_layers`).
//! 2. Depth is not anti-aliased but colour is: at every cut where the CoC jumps by at least
//!    `matte_jump_px` between neighbours (`discontinuity_px` for the sampled rules), alpha and
//!    the background colour of the mixed pixels are solved ([`super::matting`]: closed-form
//!    matting with the Z pass as a soft prior, then the two colours by least squares in linear
//!    HDR). The front layer gets `c - (1 - alpha) B`,
//!    the back layer `B`, so "over" reproduces the input exactly while a blurred foreground can
//!    become transparent. [`Matting::Sampled`] keeps the earlier rules instead: alpha by
//!    projecting the colour onto the line between local foreground and background colours, an
//!    HDR pixel beside a display-range front as light from behind, a back colour that looks
//!    like the front's clamped to what the back shows nearby, and, beside a blurred structure
//!    thinner than the band, coverage from linear colour against the structure's most covered
//!    pixel (issues 22 and 35).
//! 3. Every farther layer is filled under every nearer one by push-pull from its own pixels
//!    only (so no nearer colour can leak in), weighted towards the far side of its slice as
//!    disocclusion fills prefer background, in a range-compressed colour space so that an
//!    HDR light beside the cut does not smear under it; a light cut by the edge continues
//!    under it a few pixels, mirrored at full strength. Its coverage is extended the same
//!    way from where it is seen (1 own, 0 farther), so a layer continues under a wire only
//!    where it is seen on both sides, not across the sky behind it.
use rayon::prelude::*;
use super::fill::{compress, expand, four_neighbours, is_hdr, mirror_sources, named_pixel, nearest_known, push_pull, push_pull_where, run_from, BoxSums, PixelIndex};
use super::matting::{solve_matte_of, Matte, MatteImage, MatteOptions};
use super::spill_depth::{assign_spill_depth, upper_median};
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
    /// How mixed pixels at a discontinuity are split between the two sides.
    #[serde(default)]
    pub matting: Matting,
    /// Pixels holding mostly the light a brighter, nearer neighbour spilled into them take
    /// that neighbour's depth before layering ([`super::spill_depth`]).
    #[serde(default = "yes")]
    pub spill_depth: bool,
    /// Empty CoC gaps narrower than `discontinuity_px` are cuts too where many neighbouring
    /// pixels jump across them by at least `matte_jump_px` (see [`split_into_layers`], step 1).
    #[serde(default = "yes")]
    pub narrow_gaps: bool,
    /// Smallest CoC jump between neighbours across a cut whose pixels are matted (solved
    /// matting) and that counts towards a narrow gap's cut. Below `discontinuity_px`: leaves
    /// blurred 0.65 px over a wall in focus are a cut whose anti-aliased edges must be split.
    #[serde(default = "matte_jump_default")]
    pub matte_jump_px: f32,
    /// Render the layers on a canvas extended by the largest CoC beyond the frame, guessed
    /// from the frame, and cut it back ([`super::frame_edge`]): a blur at the frame's edge is
    /// not averaged over the in-frame half of its disk alone. Only where the stack is loaded
    /// for a render job ([`crate::input::layers_for`]); [`split_into_layers`] cuts the frame.
    #[serde(default = "yes")]
    pub guess_beyond_frame: bool,
}

fn matte_jump_default() -> f32 {
    0.5
}

fn yes() -> bool {
    true
}

/// How [`split_into_layers`] finds alpha and the two colours of a mixed pixel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Matting {
    /// Closed-form matting with the depth pass as a soft prior, then the foreground and
    /// background colours by least squares ([`super::matting`], issue 46).
    #[default]
    Solved,
    /// Local colour means and samples, with the rules of issues 22 and 35 (the earlier default).
    Sampled,
}

impl AutoLayerOptions {
    /// The defaults with the three choices a user makes (`--layer-spacing`, `--max-layers`,
    /// `--no-edge-guess`; the same names in Python and `lensblur serve`): one mapping for every
    /// front end. `None`: the default.
    pub fn chosen(coc_spacing_px: Option<f32>, max_layers: Option<usize>, no_edge_guess: bool) -> Self {
        let defaults = Self::default();
        Self {
            coc_spacing_px: coc_spacing_px.unwrap_or(defaults.coc_spacing_px),
            max_layers: max_layers.unwrap_or(defaults.max_layers),
            guess_beyond_frame: !no_edge_guess,
            ..defaults
        }
    }

    /// The auto-layering before issue 46: the sampled matting, cuts at 1 px CoC jumps (the
    /// bench's `drbokeh-auto-sampled`, the "before" of its tables).
    pub fn sampled() -> Self {
        Self {
            matting: Matting::Sampled,
            discontinuity_px: 1.0,
            spill_depth: false,
            narrow_gaps: false,
            matte_jump_px: 1.0,
            guess_beyond_frame: false,
            ..Self::default()
        }
    }
}

impl Default for AutoLayerOptions {
    fn default() -> Self {
        // A jump of 0.75 px is a cut (dev split of issue 46: 33.02 dB mean at 1 px, 33.71 at
        // 0.75, 33.62 at 0.5 and below, where a foliage scene lost 1.2 dB).
        // Mattes from jumps of 0.5 px and narrow gaps (issue 46, round 3, dev split of 45
        // scenes: 32.00 dB mean with 0.75 px for both, 32.03 matting from 0.5 px alone, 32.08
        // with narrow gaps from 0.5 px as well).
        Self {
            coc_spacing_px: 4.0,
            max_layers: 16,
            band_px: 1,
            discontinuity_px: 0.75,
            matting: Matting::default(),
            spill_depth: true,
            narrow_gaps: true,
            matte_jump_px: matte_jump_default(),
            // The frame's edge (issue 46, 161 dev scenes: none down by over 0.03 dB, 42 up).
            guess_beyond_frame: true,
        }
    }
}

/// Histogram resolution of the signed CoC when looking for depth structure.
const BIN_PX: f32 = 0.25;

/// Slice boundaries in signed CoC, descending (nearest first), from the depth structure:
/// 1. every gap of at least `discontinuity_px` of CoC that no pixel occupies is a cut (at its
///    middle), so surfaces whose blur differs by more than that never share a layer, however
///    close in depth (the 4 m and 12 m planes of issue 22 differ by 3 px at 256^2);
/// 2. an occupied run wider than `coc_spacing_px` (a slanted surface) is sliced uniformly
///    (Lee et al. 2009, Eq. 4), each cut moved to the emptiest bin within half a slice;
/// 3. a narrower empty gap is a cut too where many neighbouring pixels jump across it by at
///    least `matte_jump_px` and few meet gently, unless its two sides are blurred almost
///    alike ([`narrow_gap_cuts`]);
/// 4. beyond `max_layers`, the in-surface cuts go first, then the narrowest gaps.
fn boundaries(coc: &[f32], width: usize, options: &AutoLayerOptions) -> Vec<f32> {
    let (lo, hi) = coc.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &s| (lo.min(s), hi.max(s)));
    if lo.is_nan() || hi.is_nan() || hi - lo <= 1e-6 {
        return Vec::new();
    }
    let bin = BIN_PX.max((hi - lo) / (1 << 20) as f32);
    let bins = ((hi - lo) / bin).floor() as usize + 1;
    let mut histogram = vec![0usize; bins];
    for &s in coc {
        histogram[bin_index(s, lo, bin, bins)] += 1;
    }
    let centre = |b: usize| bin_centre(b, lo, bin);
    // (cut, priority): gaps by their width, in-surface cuts below every gap.
    let mut cuts: Vec<(f32, f32)> = Vec::new();
    // Two occupied bins `d` px of CoC apart leave `d / bin - 1` empty ones between them.
    let min_gap = ((options.discontinuity_px / bin).round() - 1.0).max(1.0) as usize;
    let runs = runs_between_gaps(&histogram, min_gap);
    for (i, &(start, end)) in runs.iter().enumerate() {
        slice_run(&histogram, start, end, bin, lo, options, &mut cuts);
        if let Some(&(next, _)) = runs.get(i + 1) {
            cuts.push((0.5 * (centre(end) + centre(next - 1)), (next - end) as f32));
        }
    }
    if options.narrow_gaps {
        narrow_gap_cuts(coc, width, &histogram, min_gap, bin, lo, options, &mut cuts);
    }
    cuts.sort_by(|a, b| b.1.total_cmp(&a.1));
    cuts.truncate(options.max_layers.max(1) - 1);
    let mut out: Vec<f32> = cuts.into_iter().map(|c| c.0).collect();
    out.sort_by(|a, b| b.total_cmp(a));
    out
}

/// Cuts at empty CoC gaps narrower than `min_gap` bins that neighbouring pixels jump across:
/// a gap is a cut when at least [`NARROW_GAP_MIN_JUMPS_PER_MILLE`] per mille of the pixels (and
/// [`NARROW_GAP_MIN_JUMPS`]) have a neighbour in the run on its other side at least
/// `matte_jump_px` away, and such jumps outnumber the gentle contacts (under `matte_jump_px`)
/// between the two runs [`NARROW_GAP_JUMP_RATIO`] times: surfaces that meet gently somewhere
/// stay one layer. Why: leaves at 1.35 px CoC over a wall in focus jump by 1.35 px at every
/// leaf edge, but a ground plane ending 0.6 px from the leaves narrows their CoC gap below
/// `discontinuity_px`, and without a cut the blurred leaves could not spread over the sharp
/// wall (dev-39 of issue 46: 29.0 dB, 39.0 with the cut). A subject 0.7 px of CoC in front of
/// a night city is the same (dev-56: 30.1 -> 32.2 dB). The cost: the far end of a ground
/// plane meets the sky with jumps of 0.5-0.75 px and is cut from it (dev-6, -0.15 dB).
/// Surfaces [`blurred_alike`] are never such a cut.
#[allow(clippy::too_many_arguments)]
fn narrow_gap_cuts(coc: &[f32], width: usize, histogram: &[usize], min_gap: usize, bin: f32, lo: f32, options: &AutoLayerOptions, cuts: &mut Vec<(f32, f32)>) {
    // Occupied runs split at every empty bin; gap i lies between runs i and i + 1.
    let runs = runs_between_gaps(histogram, 1);
    if runs.len() < 2 || width == 0 {
        return;
    }
    let run_of = |s: f32| runs.partition_point(|&(start, _)| start <= bin_index(s, lo, bin, histogram.len())) - 1;
    let run_label: Vec<usize> = coc.iter().map(|&s| run_of(s)).collect();
    // (jumps, gentle contacts) between runs i and i + 1, over right and down neighbours.
    let mut contacts = vec![(0usize, 0usize); runs.len() - 1];
    let height = coc.len() / width;
    for p in 0..coc.len() {
        let (x, y) = (p % width, p / width);
        let right = (x + 1 < width).then_some(p + 1);
        let down = (y + 1 < height).then_some(p + width);
        for q in [right, down].into_iter().flatten() {
            let (a, b) = (run_label[p], run_label[q]);
            if a.abs_diff(b) != 1 {
                continue;
            }
            let gap = &mut contacts[a.min(b)];
            if (coc[p] - coc[q]).abs() >= options.matte_jump_px {
                gap.0 += 1;
            } else {
                gap.1 += 1;
            }
        }
    }
    let need = (coc.len() * NARROW_GAP_MIN_JUMPS_PER_MILLE / 1000).max(NARROW_GAP_MIN_JUMPS);
    for (pair, &(jumps, gentle)) in runs.windows(2).zip(&contacts) {
        let bins = pair[1].0 - pair[0].1;
        // The occupied bins on either side of the gap, in signed CoC.
        let (farther, nearer) = (bin_centre(pair[0].1 - 1, lo, bin), bin_centre(pair[1].0, lo, bin));
        if bins < min_gap && jumps >= need && jumps > NARROW_GAP_JUMP_RATIO * gentle && !blurred_alike(farther, nearer) {
            let middle = lo + 0.5 * (pair[0].1 + pair[1].0) as f32 * bin;
            // Below every wide gap in priority, above the in-surface slices.
            cuts.push((middle, 0.5 * bins as f32));
        }
    }
}

/// Whether two surfaces at signed CoCs `a` and `b` are blurred so alike that one layer renders
/// them closer to the lens than two. Why: a ray through the aperture that brings the farther
/// surface's light at `y` to pixel `x` crosses the nearer surface's depth at `x + (y - x) s_n /
/// s_f` (signed CoCs), right beside `y` when the two blurs are alike. So a far light just past
/// the nearer surface's edge is hidden only where the nearer surface covers it, sharply, which
/// is what one layer gives; the layers' "over" dims it by the nearer layer's blurred coverage
/// at `x` instead, as if every ray crossed at `x` (right only when the nearer is much sharper).
/// Dev split of issue 46 (the gap over the smaller CoC): 0.5 px between 13.06 and 13.56 px
/// (4%) cost dev-842 0.66 dB as a narrow gap's cut; at 7.5% and 8.7% (dev-1376, dev-36) the
/// narrow gaps' cuts gained 0.60 and 0.27 dB, and at 9.1% a wide gap's (dev-68) 0.85 dB. Wide
/// gaps keep their cut whatever the blur: 5% changed no dev scene, 10% cost dev-68.
fn blurred_alike(a: f32, b: f32) -> bool {
    a * b > 0.0 && (b - a).abs() < BLURRED_ALIKE_GAP * a.abs().min(b.abs())
}

/// The gap between two surfaces' CoCs, over the smaller, under which they are [`blurred_alike`].
const BLURRED_ALIKE_GAP: f32 = 0.05;

/// A narrow gap needs this many per mille of the frame's pixels jumping across it...
const NARROW_GAP_MIN_JUMPS_PER_MILLE: usize = 1;
/// ... and at least this many pixels in all.
const NARROW_GAP_MIN_JUMPS: usize = 8;
/// Jumps across a narrow gap must outnumber the gentle contacts between its sides this often.
const NARROW_GAP_JUMP_RATIO: usize = 2;

/// The histogram bin of signed CoC `s`, for [`boundaries`] and the runs of [`narrow_gap_cuts`]
/// alike (a pixel must fall in the run whose bins it filled).
fn bin_index(s: f32, lo: f32, bin: f32, bins: usize) -> usize {
    (((s - lo) / bin) as usize).min(bins - 1)
}

/// The signed CoC at the middle of histogram bin `b` (the inverse of [`bin_index`]).
fn bin_centre(b: usize, lo: f32, bin: f32) -> f32 {
    lo + (b as f32 + 0.5) * bin
}

/// The histogram split at every inner run of at least `min_gap` empty bins: the bin ranges
/// `[start, end)` between such gaps, in order, covering the first and last bins (a gap at
/// either end is no gap between two things).
pub(crate) fn runs_between_gaps(histogram: &[usize], min_gap: usize) -> Vec<(usize, usize)> {
    let bins = histogram.len();
    let (mut runs, mut run_start, mut b) = (Vec::new(), 0usize, 0usize);
    while b < bins {
        if histogram[b] > 0 {
            b += 1;
            continue;
        }
        let gap_start = b;
        while b < bins && histogram[b] == 0 {
            b += 1;
        }
        if b - gap_start >= min_gap && b < bins {
            runs.push((run_start, gap_start));
            run_start = b;
        }
    }
    runs.push((run_start, bins));
    runs
}

/// Uniform cuts inside one occupied run of bins `[first, end)` wider than the layer spacing,
/// each at the emptiest bin within half a slice of its target (priority 0).
fn slice_run(histogram: &[usize], first: usize, end: usize, bin: f32, lo: f32, options: &AutoLayerOptions, cuts: &mut Vec<(f32, f32)>) {
    let width = (end - first) as f32 * bin;
    // At most one slice per bin: a spacing far below the bin width would otherwise loop (and
    // push cuts) once per thousandth of a pixel, only for all but `max_layers` to be dropped.
    let slices = ((width / options.coc_spacing_px.max(1e-3)).ceil() as usize).min(end - first);
    if slices < 2 {
        return;
    }
    let per_slice = (end - first) as f32 / slices as f32;
    for i in 1..slices {
        let target = first as f32 + i as f32 * per_slice;
        let from = (target - 0.5 * per_slice).floor().max(first as f32 + 1.0) as usize;
        let to = ((target + 0.5 * per_slice).ceil() as usize).min(end - 1);
        let best = (from..=to).min_by(|&a, &b| {
            (histogram[a], (a as f32 + 0.5 - target).abs()).partial_cmp(&(histogram[b], (b as f32 + 0.5 - target).abs())).unwrap_or(std::cmp::Ordering::Equal)
        });
        if let Some(b) = best {
            // The cut sits at the bin's lower edge: the bin itself goes to the nearer slice.
            cuts.push((lo + b as f32 * bin, 0.0));
        }
    }
}

/// Layer index per pixel (0 = nearest), with empty slices removed; returns (labels, count).
fn labels(coc: &[f32], width: usize, options: &AutoLayerOptions) -> (Vec<usize>, usize) {
    let cuts = boundaries(coc, width, options);
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
    /// How much the back layer's fill trusts `back_rgba`: for a solved matte how much of the
    /// back shows here (1 - alpha; a back wholly covered is an estimate extrapolated from its
    /// neighbours), 1 for the sampled rules, where the back colour is the back's own.
    back_seen: f32,
}

/// The band pixels' splits, found by pixel: a slot per pixel into a list of the few thousand
/// splits of a frame (a split kept per pixel of the frame was 64 bytes a pixel, and its first
/// touch of fresh memory a tenth of a one-shot layering's page faults).
struct BandMap {
    slot: Vec<u32>,
    bands: Vec<Band>,
}

impl BandMap {
    const NONE: u32 = u32::MAX;

    /// No band pixel among `pixels`.
    fn empty(pixels: usize) -> Self {
        assert!(pixels < Self::NONE as usize, "frame too large for a band map");
        Self { slot: vec![Self::NONE; pixels], bands: Vec::new() }
    }

    /// The splits of `pixels` pixels, listed as (pixel, split), each pixel at most once.
    fn from_list(pixels: usize, list: Vec<(usize, Band)>) -> Self {
        let mut map = Self::empty(pixels);
        for (p, band) in list {
            map.insert(p, band);
        }
        map
    }

    fn get(&self, p: usize) -> Option<Band> {
        let slot = self.slot[p];
        (slot != Self::NONE).then(|| self.bands[slot as usize])
    }

    fn contains(&self, p: usize) -> bool {
        self.slot[p] != Self::NONE
    }

    /// Pixel `p`'s split; `p` has none yet.
    fn insert(&mut self, p: usize, band: Band) {
        debug_assert!(!self.contains(p));
        self.slot[p] = self.bands.len() as u32;
        self.bands.push(band);
    }
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

/// Mean colour (range-compressed) of non-band pixels of layer `l` around (x, y), searching
/// wider if needed, then among its band pixels.
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
    // A structure thinner than the band (a wire, a hair) has no pixel outside it: its band
    // pixels nearby are the best guess of its colour, else its mixed neighbours would keep
    // a crisp ghost of it (issue 22, failure 3).
    for (r, thin) in [(r0, false), (2 * r0, false), (4 * r0, false), (r0, true)] {
        let r = r as i64;
        let (mut sum, mut n) = ([0.0f32; 4], 0usize);
        for qy in (y as i64 - r).max(0)..=(y as i64 + r).min(h - 1) {
            for qx in (x as i64 - r).max(0)..=(x as i64 + r).min(w - 1) {
                let q = qy as usize * image.width + qx as usize;
                // A band pixel that holds HDR light is a light seen past the structure,
                // not its colour.
                if label[q] == l && (pairs[q].is_none() || (thin && !is_hdr(image.pixels[q]))) {
                    let c = compress(image.pixels[q]);
                    (0..4).for_each(|k| sum[k] += c[k]);
                    n += 1;
                }
            }
        }
        if n > 0 {
            return Some(expand(sum.map(|s| s / n as f32)));
        }
    }
    None
}

/// Splits a band pixel's colour `c` between foreground `f` and background `b`; returns
/// (front colour, back colour, squared residual of the two-colour model). Alpha comes from
/// the projection in range-compressed colour where any is HDR, so an HDR light in `c` or `b` does not decide
/// it alone. The front keeps at most what its own colour explains (`alpha f`, with margin for
/// texture); the rest of `c` is background light seen past the edge (a light behind hair)
/// and goes to the back layer, which must not stay in focus in the front one. "Over" still
/// gives `c` exactly: front + (1 - alpha) back = c.
fn split_colour(c: [f32; 4], f: [f32; 4], b: [f32; 4], hard_alpha: f32) -> ([f32; 4], [f32; 4], f32) {
    // Display-range colours mix linearly: their alpha is exact in linear colour.
    let hdr = is_hdr(c) || is_hdr(f) || is_hdr(b);
    let (cc, fc, bc) = if hdr { (compress(c), compress(f), compress(b)) } else { (c, f, b) };
    let fb = sub_scaled(fc, bc, 1.0);
    let norm = dot(fb, fb);
    // Indistinguishable colours carry no alpha information: keep the depth map's decision.
    let alpha = if norm > 1e-6 { (dot(sub_scaled(cc, bc, 1.0), fb) / norm).clamp(0.0, 1.0) } else { hard_alpha };
    let model = sub_scaled(sub_scaled(cc, bc, 1.0 - alpha), fc, alpha);
    let mut front = sub_scaled(c, b, 1.0 - alpha).map(|v| v.max(0.0));
    if alpha > FRONT_ONLY_ALPHA {
        return (front, b, dot(model, model));
    }
    let back = front_within_its_colour(c, alpha, f, &mut front);
    (front, back, dot(model, model))
}

/// Lowers a mixed pixel's front share to what the front's colour `f` explains, `alpha f`
/// with [`FRONT_MARGIN`] for texture, and returns the back colour that keeps "over" exact,
/// `(c - front) / (1 - alpha)`: light the front's own colour cannot explain is seen past
/// its edge. For `alpha` below [`FRONT_ONLY_ALPHA`] only (the back must be seen).
fn front_within_its_colour(c: [f32; 4], alpha: f32, f: [f32; 4], front: &mut [f32; 4]) -> [f32; 4] {
    for k in 0..3 {
        front[k] = front[k].min(alpha * (FRONT_MARGIN * f[k].max(0.0) + 0.05));
    }
    [0, 1, 2, 3].map(|k| ((c[k] - front[k]) / (1.0 - alpha)).max(0.0))
}

fn max3(c: [f32; 4]) -> f32 {
    c[0].max(c[1]).max(c[2])
}

/// Splits an HDR band pixel `c` next to a front surface of display-range colour `f`: its light
/// can only come from behind. Colour cannot say how much of the pixel the front covers (a
/// dim rim of a light and a bright light mostly covered look the same), so coverage comes from
/// the depth labels around it, [`geometric_alpha`]. The front gets at most `alpha f` (none of
/// the light: an in-focus front that kept it would show a bright ring around the silhouette,
/// issue 22 failure 1) and the back the rest, `(c - front) / (1 - alpha)`, so "over" still
/// gives `c`. Alpha stays in [0, LIGHT_ALPHA_MAX] and both colours are non-negative.
fn split_light(c: [f32; 4], f: [f32; 4], alpha: f32) -> ([f32; 4], [f32; 4]) {
    let alpha = alpha.clamp(0.0, LIGHT_ALPHA_MAX);
    let front = [f[0] * alpha, f[1] * alpha, f[2] * alpha, alpha].map(|v| v.max(0.0));
    let front = [0, 1, 2, 3].map(|k| if k < 3 { front[k].min(c[k].max(0.0)) } else { front[k] });
    let back = [0, 1, 2, 3].map(|k| ((c[k] - front[k]) / (1.0 - alpha)).max(0.0));
    (front, back)
}

/// Whether the light around pixel `p` comes from behind layer `front`: the brightest pixel
/// within [`SAMPLE_RADIUS`] labelled farther is brighter, by [`BEHIND_RATIO`], than the
/// brightest labelled `front` or nearer. Where a one-sample Z saw a light it mostly saw the
/// light's own layer: a light behind a blurred bar is brightest where the Z sees the light, a
/// wire lit by the sky where it sees the wire (about as often on the wall as on the wire, so
/// near ties are the front's).
fn light_from_behind(image: &Image, label: &[usize], p: usize, front: usize) -> bool {
    SidesAround::of(image, label, p, front).light_from_behind()
}

/// The pixels within [`SAMPLE_RADIUS`] of one pixel on either side of layer `front`, by their
/// brightest channel: those of `front` or nearer, and the farther ones.
struct SidesAround {
    nearer: [f32; SAMPLE_WINDOW_PIXELS],
    nearer_count: usize,
    farther: [f32; SAMPLE_WINDOW_PIXELS],
    farther_count: usize,
}

/// Pixels in the (2 [`SAMPLE_RADIUS`] + 1)^2 window.
const SAMPLE_WINDOW_PIXELS: usize = (2 * SAMPLE_RADIUS as usize + 1).pow(2);

impl SidesAround {
    fn of(image: &Image, label: &[usize], p: usize, front: usize) -> Self {
        let (w, h) = (image.width as i64, image.height as i64);
        let (x, y) = ((p % image.width) as i64, (p / image.width) as i64);
        let mut sides = Self {
            nearer: [0.0; SAMPLE_WINDOW_PIXELS],
            nearer_count: 0,
            farther: [0.0; SAMPLE_WINDOW_PIXELS],
            farther_count: 0,
        };
        for qy in (y - SAMPLE_RADIUS).max(0)..=(y + SAMPLE_RADIUS).min(h - 1) {
            for qx in (x - SAMPLE_RADIUS).max(0)..=(x + SAMPLE_RADIUS).min(w - 1) {
                let q = (qy * w + qx) as usize;
                let bright = max3(image.pixels[q]);
                if label[q] <= front {
                    sides.nearer[sides.nearer_count] = bright;
                    sides.nearer_count += 1;
                } else {
                    sides.farther[sides.farther_count] = bright;
                    sides.farther_count += 1;
                }
            }
        }
        sides
    }

    fn brightest_farther(&self) -> f32 {
        self.farther[..self.farther_count].iter().copied().fold(0.0f32, f32::max)
    }

    fn brightest_nearer(&self) -> f32 {
        self.nearer[..self.nearer_count].iter().copied().fold(0.0f32, f32::max)
    }

    /// See [`light_from_behind`].
    fn light_from_behind(&self) -> bool {
        self.brightest_farther() > BEHIND_RATIO * self.brightest_nearer()
    }
}

/// Whether pixel `p` is lit by a compact light behind layer `front`: the light can have come
/// from behind, and the brightest farther pixel within [`SAMPLE_RADIUS`] stands out from the
/// farther pixels there (over [`COMPACT_LIGHT_RATIO`] times their median): a street light, not
/// a bright sky, whose light a thin wire over it shares.
///
/// Where `p` is sharper than the back (`sharp_front`: an in-focus wire over a blurred lamp), the
/// light can have come from behind when the brightest farther pixel holds at least
/// [`LAMP_SHARE`] of `p`'s own brightness and `p` stands out from the front pixels there (over
/// [`COMPACT_LIGHT_RATIO`] times their median: the light is not the front's own), whatever the
/// brightest front pixel holds: where a wire crosses a lamp, every wire pixel over the lamp
/// holds its light, and the brightest of them kept the lamp sharp in the wire's layer (dev-60
/// of issue 46, 19.20 -> 20.35 dB; dev-24 21.72 -> 23.09; dev-30 +0.53; dev-56 -0.26, where a
/// blurred light's rim moved; 0.8 to 0.95 for the share gave the same scores). Without the
/// front's median a sunlit wire in focus, whose own light the pixel filter spills into the
/// background beside it, went to the blurred back (dev-90: 29.43 -> 26.02). Where the front
/// is the blurrier side (a blurred fence over an in-focus sky), [`light_from_behind`]'s
/// stricter test stands: the fixed Cycles scenes of blurred wires over bright skies lost up to
/// 3.9 dB without it.
fn compact_light_behind(image: &Image, label: &[usize], p: usize, front: usize, sharp_front: bool) -> bool {
    let mut sides = SidesAround::of(image, label, p, front);
    let brightest = sides.brightest_farther();
    let own = max3(image.pixels[p]);
    let from_behind = if sharp_front {
        sides.farther_count > 0
            && sides.nearer_count > 0
            && brightest >= LAMP_SHARE * own
            && own > COMPACT_LIGHT_RATIO * upper_median(&mut sides.nearer[..sides.nearer_count])
            && !elongated_light(image, p)
    } else {
        sides.light_from_behind()
    };
    // Either test found a farther pixel: the list is not empty.
    from_behind && brightest > COMPACT_LIGHT_RATIO * upper_median(&mut sides.farther[..sides.farther_count])
}

/// Whether the HDR light through pixel `p` is a line, not a lamp: a run of HDR pixels through
/// `p` along a row, a column or a diagonal spans at least [`ELONGATED_MIN_PX`] and
/// [`ELONGATED_RATIO`] times the run across it at its middle. A sunlit wire in focus
/// shines along its length, and where the one-sample Z missed the wire (its other half-pixel
/// row) that light sits on farther pixels beside the wire, which [`compact_light_behind`]'s
/// sharp-front test took for a lamp behind it: the wire's own highlight went to the blurred
/// back (dev-90 of issue 46: 30.36 -> 31.74 dB with this test). A lamp seen through a fence is
/// a blob, 2-8 px across at 256^2 (ratios 2 to 5 scored the same on the dev split).
fn elongated_light(image: &Image, p: usize) -> bool {
    let (w, h) = (image.width, image.height);
    let run = |q: usize, (dx, dy): (i64, i64)| {
        let lit = |r: usize| is_hdr(image.pixels[r]);
        (run_from(w, h, q, (-dx, -dy), ELONGATED_RUN_MAX, lit), run_from(w, h, q, (dx, dy), ELONGATED_RUN_MAX, lit))
    };
    // Each direction with its perpendicular: rows and columns, and the two diagonals. The run
    // across is taken at the middle of the run along, so that from a lamp's rim, where a run
    // towards its centre is long and the rim itself short, the run across is the lamp's width.
    [((1, 0), (0, 1)), ((0, 1), (1, 0)), ((1, 1), (1, -1)), ((1, -1), (1, 1))].into_iter().any(|(along_step, across_step)| {
        let (back, ahead) = run(p, along_step);
        let along = back + ahead + 1;
        let shift = (ahead as i64 - back as i64) / 2;
        let middle = (p as i64 + shift * (along_step.1 * w as i64 + along_step.0)) as usize;
        let (left, right) = run(middle, across_step);
        along >= ELONGATED_MIN_PX && along >= ELONGATED_RATIO * (left + right + 1)
    })
}

/// Shortest run of HDR pixels [`elongated_light`] calls a line.
const ELONGATED_MIN_PX: usize = 6;
/// How much longer than its width a line of light is, for [`elongated_light`].
const ELONGATED_RATIO: usize = 3;
/// How far [`elongated_light`] follows a run each way (a line is found long before).
const ELONGATED_RUN_MAX: usize = 16;

/// How far the brightest farther pixel must stand out for [`compact_light_behind`].
const COMPACT_LIGHT_RATIO: f32 = 2.0;

/// How much of a front pixel's brightness a farther pixel beside it must hold for
/// [`compact_light_behind`].
const LAMP_SHARE: f32 = 0.9;

/// How much brighter the farther side must be for [`light_from_behind`].
const BEHIND_RATIO: f32 = 1.1;

/// Most coverage [`split_light`] gives the front: a pixel holding light from behind is never
/// wholly the front.
const LIGHT_ALPHA_MAX: f32 = 0.95;

/// The darkest display-range colour of layer `l` within [`SAMPLE_RADIUS`] of `p`: the surface
/// colour of a front seen against lights (its mixed pixels are all brighter than it; the
/// local mean of a hair strand's layer is the skin beside it, which would ring the hair).
fn darkest_surface(image: &Image, label: &[usize], p: usize, l: usize) -> Option<[f32; 4]> {
    let (w, h) = (image.width as i64, image.height as i64);
    let (x, y) = ((p % image.width) as i64, (p / image.width) as i64);
    let mut best: Option<[f32; 4]> = None;
    for qy in (y - SAMPLE_RADIUS).max(0)..=(y + SAMPLE_RADIUS).min(h - 1) {
        for qx in (x - SAMPLE_RADIUS).max(0)..=(x + SAMPLE_RADIUS).min(w - 1) {
            let c = image.pixels[(qy * w + qx) as usize];
            if label[(qy * w + qx) as usize] == l && !is_hdr(c) && best.map_or(true, |b| max3(c) < max3(b)) {
                best = Some(c);
            }
        }
    }
    best
}

/// Coverage of pixel `p` by layers `front` and nearer, from the depth labels alone: their
/// Gaussian-weighted share (sigma 1 px) in the 5 x 5 window. For a straight edge sampled at
/// pixel centres this is close to the area the front covers; with a jittered Z pass (one
/// sample per pixel, as Cycles writes it) it stays unbiased where a single label is not.
fn geometric_alpha(label: &[usize], width: usize, p: usize, front: usize) -> f32 {
    let (w, h) = (width as i64, (label.len() / width) as i64);
    let (x, y) = ((p % width) as i64, (p / width) as i64);
    let (mut inside, mut total) = (0.0f32, 0.0f32);
    for qy in (y - 2).max(0)..=(y + 2).min(h - 1) {
        for qx in (x - 2).max(0)..=(x + 2).min(w - 1) {
            let weight = (-0.5 * ((qx - x).pow(2) + (qy - y).pow(2)) as f32).exp();
            total += weight;
            if label[(qy * w + qx) as usize] <= front {
                inside += weight;
            }
        }
    }
    inside / total.max(1e-6)
}

/// Above this alpha the back layer is not seen enough to hold the excess: the split is the
/// plain `c - (1 - alpha) b`.
const FRONT_ONLY_ALPHA: f32 = 0.95;
/// How much brighter than the local front colour a mixed pixel's front share may be.
const FRONT_MARGIN: f32 = 1.5;

/// The split of pixel `p` against another layer `other`, if both sides have local colour.
fn band_with(
    image: &Image,
    label: &[usize],
    pairs: &[Option<(usize, usize)>],
    coc: &[f32],
    p: usize,
    other: usize,
    radius: usize,
) -> Option<(Band, f32)> {
    let (x, y) = (p % image.width, p / image.width);
    let (front, back) = (label[p].min(other), label[p].max(other));
    let b = local_colour(image, label, pairs, back, x, y, radius)?;
    let c = image.pixels[p];
    if !sharp_near(label, coc, image.width, p, front) {
        if let Some(front_rgba) = thin_front_split(image, label, pairs, p, front, b) {
            return Some((Band { front, back, front_rgba, back_rgba: b, back_seen: 1.0 }, 0.0));
        }
    }
    let f = local_colour(image, label, pairs, front, x, y, radius)?;
    let hard = if label[p] == front { 1.0 } else { 0.0 };
    if is_hdr(c) && !is_hdr(f) {
        // Light past the edge of a surface that holds none: see [`split_light`].
        let f = darkest_surface(image, label, p, front).unwrap_or(f);
        let split = split_light(c, f, geometric_alpha(label, image.width, p, front));
        return Some((Band { front, back, front_rgba: split.0, back_rgba: split.1, back_seen: 1.0 }, 0.0));
    }
    let sharp_front = sharp_near(label, coc, image.width, p, front);
    // Sample-based matting: the local means and the nearby pixels of either side are
    // candidate colours; the pair that explains `c` best wins. A hair strand's own colour
    // is then its front, not the skin beside it (which would leave the strand's darkness
    // in the background, blurred into a smudge).
    // A blurred front is seen through its blur, where the robust means do better (a thin
    // blurred wire's neighbours are as mixed as it is): sample only for a sharp front.
    let means = split_colour(c, f, b, hard);
    let (mut best, mut score) = (means, means.2);
    if sharp_front {
        // A strand is all band, so band pixels serve as candidates on both sides. A mixed
        // neighbour as mixed as `c` explains it with alpha 0 or 1, i.e. the depth map's cut:
        // measured, that beats a matte of a fuzzy edge from these few samples (excluding the
        // back's band pixels: silhouette-hdr 28.53 -> 25.95 dB).
        let fronts = candidates(image, label, p, front, f);
        let backs = candidates(image, label, p, back, b);
        // The means' split stands unless a pair explains `c` clearly better.
        score *= MEAN_PREFERENCE;
        for &fc in &fronts {
            for &bc in &backs {
                let split = split_colour(c, fc, bc, hard);
                if split.2 < score {
                    (best, score) = (split, split.2);
                }
            }
        }
    }
    let (front_rgba, back_rgba, residual) = best;
    Some((Band { front, back, front_rgba, back_rgba, back_seen: 1.0 }, residual))
}

/// The front's share of pixel `p` beside a blurred structure thinner than the band (a wire, a
/// strand: no unmixed pixel of layer `front` within [`SAMPLE_RADIUS`]), by matting in linear
/// colour against the back's local colour `b`: the structure's own colour is its pixel nearby
/// farthest from `b` (its most covered sample; HDR where the wire is lit by the sky, so neither
/// left out nor range-compressed), its coverage the projection of `c` on `b`..that colour.
/// Linear light mixes linearly, so the coverage holds over an HDR back, and a pixel the
/// one-sample Z labelled back gives its share of the wire to the front (else the back keeps it,
/// in focus: the ghost fence of issue 35). None where the light around comes from behind
/// ([`light_from_behind`]: [`split_light`]'s case), the colours are too close, or none of
/// them is HDR.
fn thin_front_split(image: &Image, label: &[usize], pairs: &[Option<(usize, usize)>], p: usize, front: usize, b: [f32; 4]) -> Option<[f32; 4]> {
    let (w, h) = (image.width as i64, image.height as i64);
    let (x, y) = ((p % image.width) as i64, (p / image.width) as i64);
    let rgb = |a: [f32; 4]| [a[0], a[1], a[2], 0.0];
    let mut structure: Option<([f32; 4], f32)> = None;
    for qy in (y - SAMPLE_RADIUS).max(0)..=(y + SAMPLE_RADIUS).min(h - 1) {
        for qx in (x - SAMPLE_RADIUS).max(0)..=(x + SAMPLE_RADIUS).min(w - 1) {
            let q = (qy * w + qx) as usize;
            if label[q] != front {
                continue;
            }
            pairs[q]?; // not thin: the means and samples of band_with know its colour
            let d = rgb(sub_scaled(image.pixels[q], b, 1.0));
            let distance = dot(d, d);
            if structure.map_or(true, |(_, best)| distance > best) {
                structure = Some((image.pixels[q], distance));
            }
        }
    }
    let (f, contrast) = structure?;
    let c = image.pixels[p];
    // Display-range colours keep band_with's means and samples (measured: on issue 22's
    // thin-near, white wires over sky and grass, this split gave 40.72 dB against 42.29).
    let any_hdr = is_hdr(c) || is_hdr(f) || is_hdr(b);
    if !any_hdr || contrast < THIN_MIN_CONTRAST * (1.0 + max3(b)).powi(2) || (is_hdr(c) && light_from_behind(image, label, p, front)) {
        return None;
    }
    let alpha = (dot(rgb(sub_scaled(c, b, 1.0)), rgb(sub_scaled(f, b, 1.0))) / contrast).clamp(0.0, 1.0);
    let mut front_rgba = sub_scaled(c, b, 1.0 - alpha).map(|v| v.max(0.0));
    front_rgba[3] = alpha;
    Some(front_rgba)
}

/// Least squared colour distance (relative to the back's brightness) between a thin
/// structure and its back for [`thin_front_split`] to trust a coverage from colour.
const THIN_MIN_CONTRAST: f32 = 0.01;

/// Whether layer `l` is in focus (CoC under [`SHARP_PX`]) at its pixels next to `p`.
fn sharp_near(label: &[usize], coc: &[f32], width: usize, p: usize, l: usize) -> bool {
    let (w, h) = (width as i64, (label.len() / width) as i64);
    let (x, y) = ((p % width) as i64, (p / width) as i64);
    let mut sharp = false;
    for qy in (y - 1).max(0)..=(y + 1).min(h - 1) {
        for qx in (x - 1).max(0)..=(x + 1).min(w - 1) {
            let q = (qy * w + qx) as usize;
            if label[q] == l {
                if coc[q].abs() >= SHARP_PX {
                    return false;
                }
                sharp = true;
            }
        }
    }
    sharp
}

/// CoC radius (px) under which a front is matted per pixel by sampling.
const SHARP_PX: f32 = 2.0;

/// How much smaller a sampled pair's residual must be than the means' to replace them.
const MEAN_PREFERENCE: f32 = 0.25;


/// Radius of the candidate window of [`band_with`] (5 x 5).
const SAMPLE_RADIUS: i64 = 2;

/// The colours of layer `l` within [`SAMPLE_RADIUS`] of `p` (not `p` itself), HDR ones left
/// out (a light seen past an edge is no surface colour), and the local mean `mean`.
fn candidates(image: &Image, label: &[usize], p: usize, l: usize, mean: [f32; 4]) -> Vec<[f32; 4]> {
    let (w, h) = (image.width as i64, image.height as i64);
    let (x, y) = ((p % image.width) as i64, (p / image.width) as i64);
    let mut out = vec![mean];
    for qy in (y - SAMPLE_RADIUS).max(0)..=(y + SAMPLE_RADIUS).min(h - 1) {
        for qx in (x - SAMPLE_RADIUS).max(0)..=(x + SAMPLE_RADIUS).min(w - 1) {
            let q = (qy * w + qx) as usize;
            if q != p && label[q] == l && !is_hdr(image.pixels[q]) {
                out.push(image.pixels[q]);
            }
        }
    }
    out
}

fn bands(
    image: &Image,
    label: &[usize],
    coc: &[f32],
    pairs: &[Option<(usize, usize)>],
    options: &AutoLayerOptions,
) -> BandMap {
    let radius = options.band_px + 2;
    // Each pixel's band reads the image and labels only: pixels in parallel, same result.
    let found = (0..pairs.len())
        .into_par_iter()
        .filter_map(|p| {
            // Mixed with whichever neighbouring layer explains the colour best.
            let (near, far) = pairs[p]?;
            let a = band_with(image, label, pairs, coc, p, near, radius);
            let b = if far != near { band_with(image, label, pairs, coc, p, far, radius) } else { None };
            let band = match (a, b) {
                (Some(a), Some(b)) => Some(if b.1 < a.1 { b.0 } else { a.0 }),
                (a, b) => a.or(b).map(|(band, _)| band),
            }?;
            Some((p, keep_back_own(image, label, pairs, p, band)))
        })
        .collect();
    BandMap::from_list(pairs.len(), found)
}

/// The matting's guarantee that no colour of a nearer surface reaches a farther layer: the
/// back colour at a band pixel stays within the per-channel range of the back layer's own
/// unmixed pixels nearby (plus [`BACK_RANGE_SLACK`]); what the clamp removes stays in the
/// front, `front = c - (1 - alpha) back`, so "over" still gives `c` wherever that is
/// non-negative. (With a jittered Z pass a pixel mostly of the front is often labelled back;
/// its colour would otherwise ring the silhouette in the blurred background, issue 22.)
fn keep_back_own(image: &Image, label: &[usize], pairs: &[Option<(usize, usize)>], p: usize, band: Band) -> Band {
    let c = image.pixels[p];
    if is_hdr(c) {
        // Light past an edge: [`split_light`] already gives the front none of it.
        return band;
    }
    let (x, y) = (p % image.width, p / image.width);
    let (Some((lo, hi)), Some(f)) = (own_range(image, label, pairs, p, band.back), local_colour(image, label, pairs, band.front, x, y, 3)) else {
        return band;
    };
    let mut back = band.back_rgba;
    for k in 0..3 {
        let slack = BACK_RANGE_SLACK * (hi[k] - lo[k]).max(0.1);
        back[k] = back[k].clamp(lo[k] - slack, hi[k] + slack).max(0.0);
    }
    // Only a back colour nearer the front's own colour than anything the back shows around
    // is the front's: others are texture the window missed, and stay.
    let rgb = |a: [f32; 4]| [a[0], a[1], a[2], 0.0];
    let d = |a: [f32; 4], b: [f32; 4]| dot(rgb(sub_scaled(a, b, 1.0)), rgb(sub_scaled(a, b, 1.0)));
    if d(band.back_rgba, f) >= d(band.back_rgba, back) {
        return band;
    }
    // Coverage again, against the clamped back: the front explains what the back may not.
    let fb = rgb(sub_scaled(f, back, 1.0));
    let norm = dot(fb, fb);
    let alpha = if norm > 1e-6 { (dot(rgb(sub_scaled(c, back, 1.0)), fb) / norm).clamp(0.0, 1.0) } else { 0.0 };
    if alpha < 1e-3 {
        return band;
    }
    let mut front = [0.0, 0.0, 0.0, alpha];
    for k in 0..3 {
        front[k] = (c[k] - (1.0 - alpha) * back[k]).max(0.0);
    }
    Band { front_rgba: front, back_rgba: back, ..band }
}

/// Relative slack of [`keep_back_own`]'s range: texture a few pixels away may be a little
/// brighter or darker than the window shows.
const BACK_RANGE_SLACK: f32 = 0.1;

/// Per-channel (min, max) of layer `l`'s unmixed (non-band) pixels within 2 px of `p`, searching
/// 4 and 8 px if there are none.
fn own_range(image: &Image, label: &[usize], pairs: &[Option<(usize, usize)>], p: usize, l: usize) -> Option<([f32; 4], [f32; 4])> {
    let (w, h) = (image.width as i64, image.height as i64);
    let (x, y) = ((p % image.width) as i64, (p / image.width) as i64);
    for r in [2i64, 4, 8] {
        let (mut lo, mut hi, mut any) = ([f32::INFINITY; 4], [f32::NEG_INFINITY; 4], false);
        for qy in (y - r).max(0)..=(y + r).min(h - 1) {
            for qx in (x - r).max(0)..=(x + r).min(w - 1) {
                let q = (qy * w + qx) as usize;
                let c = image.pixels[q];
                if label[q] == l && pairs[q].is_none() {
                    (0..4).for_each(|k| (lo[k], hi[k]) = (lo[k].min(c[k]), hi[k].max(c[k])));
                    any = true;
                }
            }
        }
        if any {
            return Some((lo, hi));
        }
    }
    None
}

/// The mixed pixels by [`super::matting`]: one binary matte per cut with a depth discontinuity
/// (layers up to `f` against the farther ones), solved where the CoC jumps by at least
/// `matte_jump_px` across it; a pixel claimed by two cuts keeps the nearer cut's. The front
/// layer gets `c - (1 - alpha) B` (so "over" gives `c` exactly), the back one `B`.
fn solved_bands(image: &Image, label: &[usize], count: usize, coc: &[f32], options: &AutoLayerOptions) -> BandMap {
    let (w, h) = (image.width, image.height);
    let matte_options = MatteOptions::default();
    // Each layer's sharpest blur, for the cuts either side of it.
    let mut sharpest = vec![f32::INFINITY; count];
    for (&l, c) in label.iter().zip(coc) {
        sharpest[l] = sharpest[l].min(c.abs());
    }
    // A cut's sides, and its pixels beside a real discontinuity across it (not a slice of one
    // slanted surface); None where it has none: no matte to solve.
    let cut_edges = |f: usize| -> Option<(Vec<bool>, Vec<bool>)> {
        let front: Vec<bool> = label.iter().map(|&l| l <= f).collect();
        // Row by row: a pixel's 4-neighbours from its row and column, not from its index
        // divided by the width at every pixel of every cut.
        let mut edge = vec![false; w * h];
        edge.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            for (x, edge) in row.iter_mut().enumerate() {
                let p = y * w + x;
                let across = |q: usize| front[q] != front[p] && (coc[q] - coc[p]).abs() >= options.matte_jump_px;
                *edge = (x > 0 && across(p - 1)) || (x + 1 < w && across(p + 1)) || (y > 0 && across(p - w)) || (y + 1 < h && across(p + w));
            }
        });
        edge.contains(&true).then_some((front, edge))
    };
    let solve_cut = |f: usize, (front, edge): (Vec<bool>, Vec<bool>), shared: &MatteImage| -> Option<(Matte, Vec<bool>)> {
        // The Z prior says "front" where the sample hit the front, except for HDR light that
        // comes from behind it: a light seen between wires lights the wire pixels beside it
        // too, and as a front prior they would pull the whole light into the sharp layer.
        // The same test marks the farther pixels the light spilled onto, for the split of
        // their colour (`claim_band`); whether the front is the sharper side is the front
        // pixel's own blur, or for a farther pixel the front layer's sharpest.
        let (front_blur, back_blur) = (sharpest[f], sharpest[f + 1]);
        let lit_from_behind = |p: usize| {
            let sharp_front = if front[p] { coc[p].abs() } else { front_blur } < back_blur;
            is_hdr(image.pixels[p]) && compact_light_behind(image, label, p, f, sharp_front)
        };
        // Tested where it is read only: on front pixels for the prior, on the band's farther
        // pixels once the band is known (a bright sky is HDR everywhere).
        let mut light_behind: Vec<bool> = (0..w * h).into_par_iter().map(|p| front[p] && lit_from_behind(p)).collect();
        let prior: Vec<bool> = (0..w * h).map(|p| front[p] && !light_behind[p]).collect();
        let matte = solve_matte_of(shared, &prior, &edge, &matte_options)?;
        let lit: Vec<(usize, bool)> = matte.band.par_iter().filter(|&&p| !front[p]).map(|&p| (p, lit_from_behind(p))).collect();
        for (p, lit) in lit {
            light_behind[p] = lit;
        }
        Some((matte, light_behind))
    };
    // The mattes' shared guide, made once, and only for a frame with a cut to solve.
    let matte_image = || MatteImage::new(&image.pixels, w, h);
    let cuts = count.saturating_sub(1);
    let mut out = BandMap::empty(w * h);
    // The cuts' mattes are independent; only their claims on pixels go in order (a pixel two
    // cuts claim keeps the nearer cut's). A small frame's bands are too small to keep both
    // cores busy one cut at a time, so its cuts are solved side by side; a large frame's one
    // at a time, holding one matte (about 30 bytes a pixel) at once.
    if w * h <= CONCURRENT_CUTS_MAX_PIXELS {
        let edges: Vec<Option<(Vec<bool>, Vec<bool>)>> = (0..cuts).into_par_iter().map(cut_edges).collect();
        if edges.iter().any(Option::is_some) {
            let shared = matte_image();
            let mattes: Vec<Option<(Matte, Vec<bool>)>> = edges.into_par_iter().enumerate().map(|(f, edges)| solve_cut(f, edges?, &shared)).collect();
            for (f, matte) in mattes.into_iter().enumerate() {
                if let Some((matte, light_behind)) = matte {
                    claim_band(image, label, f, &matte, &light_behind, matte_options.radius_px, &mut out);
                }
            }
        }
    } else {
        let mut shared = None;
        for f in 0..cuts {
            let Some(edges) = cut_edges(f) else { continue };
            if let Some((matte, light_behind)) = solve_cut(f, edges, shared.get_or_insert_with(matte_image)) {
                claim_band(image, label, f, &matte, &light_behind, matte_options.radius_px, &mut out);
            }
        }
    }
    out
}

/// Largest frame whose cuts [`solved_bands`] solves concurrently.
const CONCURRENT_CUTS_MAX_PIXELS: usize = 1024 * 1024;

/// Whether pixel `p` and its four neighbours all lie on the front side of cut `f` (the frame's
/// edge counts as front): a pixel inside a solid front, not on a thin structure nor on the
/// outline itself. Its diagonal neighbours may be behind: one pixel inside a slanted or curved
/// outline is still inside (dev-212 of issue 46 +0.16 dB, dev-398 +0.10 over the eight
/// neighbours; on the dev split 25 scenes up, one down by 0.01).
fn inside_front(label: &[usize], w: usize, h: usize, p: usize, f: usize) -> bool {
    label[p] <= f && four_neighbours(p, w, h).into_iter().flatten().all(|q| label[q] <= f)
}

/// The least coverage by which a front over `background` can show colour `c`: whatever of the
/// pixel it leaves uncovered shows at least that fraction of the background, `(1 - alpha) b <=
/// c` in each channel. Beside a light the matte's alpha fell short of it by a few percent one
/// pixel inside an in-focus silhouette, and the blurred light behind, hundreds of times the
/// silhouette's colour, shone through there where the lens shows none (dev-398 of issue 46:
/// up to 3.3 one row inside a black silhouette where the truth is 0, and the plain gather, which
/// never layers, 0; with the bound 29.77 -> 30.14 dB).
fn opacity_its_colour_needs(c: [f32; 4], background: [f32; 3]) -> f32 {
    (0..3).filter(|&k| background[k] > 1e-6).map(|k| 1.0 - c[k].max(0.0) / background[k]).fold(0.0, f32::max).min(1.0)
}

/// Gives the unclaimed pixels of cut `f`'s matte their band: front and back layers, colours.
/// Where `light_behind` marks a pixel lit from behind the cut, its front keeps no more than
/// the matte's foreground colour explains ([`front_within_its_colour`]).
fn claim_band(image: &Image, label: &[usize], f: usize, matte: &Matte, light_behind: &[bool], radius_px: usize, out: &mut BandMap) {
    let (w, h) = (image.width, image.height);
    let reach = radius_px as i64 + 1;
    let claimed: Vec<(usize, Band)> = (0..matte.band.len())
        .into_par_iter()
        .filter(|&i| !out.contains(matte.band[i]))
        .filter_map(|i| {
            let p = matte.band[i];
            // The layers either side: the pixel's own, and the one across the cut whose
            // pixel is nearest (the nearer layer on a tie): a bar passing a few pixels away
            // is not what an edge hides.
            let (x, y) = ((p % w) as i64, (p / w) as i64);
            let mut other: Option<(i64, usize)> = None;
            for qy in (y - reach).max(0)..=(y + reach).min(h as i64 - 1) {
                for qx in (x - reach).max(0)..=(x + reach).min(w as i64 - 1) {
                    let l = label[qy as usize * w + qx as usize];
                    if (l <= f) != (label[p] <= f) {
                        let distance = (qx - x).pow(2) + (qy - y).pow(2);
                        if other.map_or(true, |(d, o)| distance < d || (distance == d && l < o)) {
                            other = Some((distance, l));
                        }
                    }
                }
            }
            let (_, other) = other?;
            let (front, back) = (label[p].min(other), label[p].max(other));
            let (a, c, background) = (matte.alpha[i], image.pixels[p], matte.background[i]);
            // The back's share may not exceed what the pixel shows: "over" stays exact. A
            // pixel none of the front covers is all back.
            let b = [0, 1, 2].map(|k| match a {
                a if a <= 0.0 => c[k].max(0.0),
                a if a < 1.0 => background[k].min(c[k].max(0.0) / (1.0 - a)),
                _ => background[k],
            });
            // The back's colour keeps the matte's alpha; the front's coverage may only grow.
            let a = if a > 0.0 && label[p] == front && inside_front(label, w, h, p, f) { a.max(opacity_its_colour_needs(c, background)) } else { a };
            let mut front_rgba = [0, 1, 2, 3].map(|k| if k == 3 { a } else { (c[k] - (1.0 - a) * b[k]).max(0.0) });
            let mut back_rgba = [b[0], b[1], b[2], 1.0];
            // The background estimate is the dark wall around a lamp seen past a wire, so the
            // lamp's light was all left to the front: the sharp wire layer kept a sharp lamp
            // (dev-24 of issue 46: 21.74 -> 22.79 dB, dev-30 +0.64).
            if light_behind[p] && a > 0.0 && a <= FRONT_ONLY_ALPHA {
                let [fr, fg, fb] = matte.foreground[i];
                let [br, bg, bb, _] = front_within_its_colour(c, a, [fr, fg, fb, 1.0], &mut front_rgba);
                back_rgba = [br, bg, bb, 1.0];
            }
            Some((p, Band { front, back, front_rgba, back_rgba, back_seen: 1.0 - a }))
        })
        .collect();
    for (p, band) in claimed {
        out.insert(p, band);
    }
}

/// What layer `k` holds at one pixel.
enum Cell {
    /// The layer's colour here and how much its fill trusts it (1: its own pixel).
    Own([f32; 4], f32),
    Partial([f32; 4]),
    Hidden,
    Empty,
}

fn cell(k: usize, p: usize, image: &Image, label: &[usize], bands: &BandMap) -> Cell {
    match bands.get(p) {
        Some(b) if k == b.front => Cell::Partial(b.front_rgba),
        Some(b) if k == b.back => Cell::Own(b.back_rgba, b.back_seen),
        Some(b) if k > b.back => Cell::Hidden,
        Some(_) => Cell::Empty,
        None if label[p] == k => Cell::Own(image.pixels[p], 1.0),
        None if label[p] < k => Cell::Hidden,
        None => Cell::Empty,
    }
}

/// How far (px) a light seen beside a nearer layer continues under it. Measured on `bench
/// --single-image` (lights of radius 1.5 to 4 px at 256^2): 0 -> 26.82 / 31.24 / 42.29 dB,
/// 2 -> 26.84 / 31.43, 3 -> 26.84 / 31.68, 4 -> 26.81 / 31.91, 5 -> 26.73 / 31.98, 8 -> 26.25
/// / 30.07 (silhouette-hdr / five-planes / thin-near); mirroring every pixel, not only lights,
/// at 4 px: 26.83 / 30.89 / 42.30.
const LIGHT_REACH_PX: f32 = 4.0;

/// How far (px) a light of signed CoC `light` continues under a nearer pixel of signed CoC
/// `occluder`: [`LIGHT_REACH_PX`], and never farther than the two CoCs differ. A point that far
/// behind the occluder's edge is seen from the rim of the aperture only (the parallax between
/// the two across the lens is their CoC difference); farther in, no ray reaches it, yet the
/// layers' "over" would show a continued light through the occluder's blurred edge (looked
/// for on dev-158 of issue 46, lamps behind a tower 0.5 px of CoC nearer whose discs spill
/// over its edge; that scene moved +0.01 dB, its spill has another cause). Dev split (107
/// scenes): mean +0.007 dB, 15 scenes up (dev-56 +0.19, dev-30 +0.16, dev-8 +0.15), 9 down
/// (dev-278 -0.07, dev-44 -0.06); the difference plus 1 px: +0.006; the difference up to 8 px
/// instead of 4: -0.006 (dev-15 -0.47); half the difference up to 8 px: +0.005.
fn light_reach(occluder: f32, light: f32) -> f32 {
    LIGHT_REACH_PX.min((occluder - light).abs())
}

fn build_layer(k: usize, image: &Image, disparity: &[f32], signed: &[f32], label: &[usize], bands: &BandMap) -> Layer {
    let (w, h, n) = (image.width, image.height, image.pixels.len());
    let own_disp = (0..n).filter(|&p| label[p] == k).map(|p| disparity[p]);
    let (d_far, d_near) = own_disp.fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), d| (lo.min(d), hi.max(d)));
    let guide = |d: f32| (-2.0 * (d - d_far) / (d_near - d_far).max(1e-6)).exp();
    // A layer's disparity runs in long stretches of one value (a plane): its guide is worked
    // out once per stretch, not an exponential per pixel.
    let mut last_guide: Option<(u32, f32)> = None;
    let mut guide = |d: f32| match last_guide {
        Some((bits, g)) if bits == d.to_bits() => g,
        _ => {
            let g = guide(d);
            last_guide = Some((d.to_bits(), g));
            g
        }
    };
    let mut rgba = vec![[0.0f32; 4]; n];
    let mut colour_weight = vec![0.0f32; n];
    // How much of each pixel's colour is the layer's own, before the depth guide: what the
    // hidden region's nearest colours are judged by (`NearColours`).
    let mut seen = vec![0.0f32; n];
    let mut hidden = vec![false; n];
    // Coverage where it is seen (own 1, partial alpha, farther 0), to be extended under the
    // nearer layers: a layer continues under a thin near structure only where it is seen on
    // both sides of it, not across the sky behind a wire (issue 22, failure 3).
    let mut coverage = vec![[0.0f32; 1]; n];
    let mut coverage_weight = vec![1.0f32; n];
    for p in 0..n {
        match cell(k, p, image, label, bands) {
            Cell::Own(c, trust) => {
                rgba[p] = c;
                colour_weight[p] = trust * guide(disparity[p]);
                seen[p] = trust;
                coverage[p] = [1.0];
            }
            Cell::Partial(c) => {
                rgba[p] = c;
                coverage[p] = [c[3]];
            }
            Cell::Hidden => {
                hidden[p] = true;
                coverage_weight[p] = 0.0;
            }
            Cell::Empty => {}
        }
    }
    if hidden.contains(&true) {
        fill_hidden(w, h, &mut rgba, &colour_weight, &seen, &hidden, &mut coverage, &coverage_weight, signed);
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

/// A layer's colour and coverage at the pixels a nearer layer hides (`hidden`): everything
/// here is read there only, so a layer nothing hides (the nearest) skips it all, and the
/// colour fill's finest push skips the pixels that are not hidden.
#[allow(clippy::too_many_arguments)]
fn fill_hidden(
    w: usize,
    h: usize,
    rgba: &mut [[f32; 4]],
    colour_weight: &[f32],
    seen: &[f32],
    hidden: &[bool],
    coverage: &mut [[f32; 1]],
    coverage_weight: &[f32],
    signed: &[f32],
) {
    let n = w * h;
    let mut filled: Vec<[f32; 4]> = rgba.iter().map(|&c| compress(c)).collect();
    push_pull_where(w, h, &mut filled, colour_weight, hidden);
    push_pull_where(w, h, coverage, coverage_weight, hidden);
    // A light cut by a nearer layer's edge continues under it at full strength (mirrored
    // across the edge) instead of fading into the push-pull average: its bokeh ball is then
    // round, not cut (issue 22, failure 1).
    let own_lights: Vec<bool> = (0..n).map(|p| colour_weight[p] > 0.0 && is_hdr(rgba[p])).collect();
    let lights = mirror_sources(w, h, &own_lights, hidden, |p, q| light_reach(signed[p], signed[q]));
    let near = NearColours::new(w, h, rgba, seen);
    // Every colour read here is of a pixel nothing hides (a light's own, a confident one), so
    // the hidden pixels' new colours are found from `rgba` as it is, then written.
    let hidden_list: Vec<usize> = (0..n).filter(|&p| hidden[p]).collect();
    let colours: Vec<[f32; 4]> = hidden_list
        .par_iter()
        .map(|&p| {
            let colour = match named_pixel(lights[p]) {
                Some(q) => rgba[q],
                None => match near.at(p, rgba) {
                    Some((c, t)) => {
                        let pulled = expand(filled[p]);
                        [c[0] * (1.0 - t) + pulled[0] * t, c[1] * (1.0 - t) + pulled[1] * t, c[2] * (1.0 - t) + pulled[2] * t, pulled[3]]
                    }
                    None => expand(filled[p]),
                },
            };
            let alpha = coverage[p][0].clamp(0.0, 1.0);
            colour.map(|v| v * alpha / colour[3].max(1e-6))
        })
        .collect();
    for (&p, colour) in hidden_list.iter().zip(colours) {
        rgba[p] = colour;
    }
}

/// Within this distance (px) of a layer's confident pixels, a pixel hidden behind a nearer
/// layer takes the colour those show nearest ([`NearColours`]); from here to twice as far it
/// blends into the push-pull fill. The push-pull's pyramid misses a side that ends at one of
/// its block edges: behind a tall blurred tower (dev-140 of issue 46, CoC 15 px) the fill 3 px
/// from the dark surface beside it was the bright sky 40 px above (0.125 against 0.015), and
/// the tower's blurred edge showed it as a pale streak; the plain gather, which never layers,
/// was 0.31 dB better on the scene. Measured on the dev split (77 scenes, 20 more silhouettes
/// among them), dev-140: 8 px +0.26 dB, 12 px +0.34, 16 px +0.36; a ramp from the edge itself
/// to 32 px +0.29; the mean moved by under 0.01 dB throughout.
const NEAR_FILL_REACH_PX: f32 = 12.0;

/// Half the side (px) of the square whose confident pixels, around the nearest one, give the
/// colour of [`NearColours`]: one pixel copied carries the input's noise along the hidden
/// region (dev-78, an in-focus fence over a noisy horizon, at 12 px of reach: one pixel -0.41
/// dB, a mean over 2 px -0.13, 4 px -0.04, 6 px +0.02).
const NEAR_FILL_MEAN_PX: usize = 6;

/// Fewest share of a pixel's colour that is the layer's own for it to count as confident for
/// [`NearColours`]: its own pixels, and band pixels at least half of whose colour is the
/// layer's. Not weighted by the depth guide of the push-pull, which prefers a layer's farthest
/// surface: with it, a dark surface at the near end of a layer (weight e^-2) was never
/// confident, and the hidden region beside it took the mean of a sunlit plane 9 px away, which
/// glowed through a silhouette's blurred edge (dev-956 of issue 46: 35.81 -> 36.40 dB, gather
/// 36.19).
const NEAR_FILL_CONFIDENT: f32 = 0.5;

/// The colour a layer shows nearest a hidden pixel and how much of the push-pull fill to blend
/// in (0 within [`NEAR_FILL_REACH_PX`] of the nearest confident pixel, 1 at twice that); `None`
/// farther away, or where the nearest pixel is HDR (a light continues only by mirror,
/// [`LIGHT_REACH_PX`]: extruded, it would streak). Asked of the hidden pixels only, not kept
/// for the whole frame.
struct NearColours {
    width: usize,
    /// Per pixel, its nearest confident pixel.
    nearest: Vec<PixelIndex>,
    /// The confident pixels' colours (straight, range-compressed, RGB), weighted by how much of
    /// each is the layer's own.
    sums: BoxSums<3>,
}

impl NearColours {
    fn new(w: usize, h: usize, rgba: &[[f32; 4]], seen: &[f32]) -> Self {
        let confident: Vec<bool> = seen.par_iter().map(|&c| c >= NEAR_FILL_CONFIDENT).collect();
        let sums = BoxSums::from_fn(w, h, |p| {
            if confident[p] {
                let c = rgba[p];
                let [r, g, b, _] = compress(c.map(|v| v / c[3].max(1e-6)));
                (seen[p], [r, g, b])
            } else {
                (0.0, [0.0; 3])
            }
        });
        Self { width: w, nearest: nearest_known(w, h, &confident), sums }
    }

    /// At hidden pixel `p`, given the layer's colours before the fill (`rgba`): the colour (RGB)
    /// and the share of the fill.
    fn at(&self, p: usize, rgba: &[[f32; 4]]) -> Option<([f32; 3], f32)> {
        let w = self.width;
        let q = named_pixel(self.nearest[p]).filter(|&q| !is_hdr(rgba[q]))?;
        let (dx, dy) = ((p % w) as f32 - (q % w) as f32, (p / w) as f32 - (q / w) as f32);
        let t = ((dx * dx + dy * dy).sqrt() / NEAR_FILL_REACH_PX - 1.0).clamp(0.0, 1.0);
        if t >= 1.0 {
            return None;
        }
        let [r, g, b] = self.sums.mean_around(q, NEAR_FILL_MEAN_PX)?;
        let [r, g, b, _] = expand([r, g, b, 1.0]);
        Some(([r, g, b], t))
    }
}

/// Splits one flat image with per-pixel disparity into a front-to-back layer stack whose
/// "over" composite reproduces the input (see module docs).
///
/// # Panics
/// If `disparity` does not have one value per pixel (readers guarantee it).
pub fn split_into_layers(image: &Image, disparity: &[f32], coc: &CocModel, options: &AutoLayerOptions) -> LayerStack {
    assert_eq!(disparity.len(), image.pixels.len(), "one disparity per pixel");
    let spilled;
    let disparity = if options.spill_depth {
        spilled = assign_spill_depth(image, disparity, coc, options.discontinuity_px);
        &spilled[..]
    } else {
        disparity
    };
    let signed: Vec<f32> = disparity.iter().map(|&d| coc.signed_radius(d)).collect();
    let (label, count) = labels(&signed, image.width, options);
    let bands = match options.matting {
        Matting::Sampled => {
            let pairs = band_pairs(image.width, image.height, &label, &signed, options);
            bands(image, &label, &signed, &pairs, options)
        }
        Matting::Solved => solved_bands(image, &label, count, &signed, options),
    };
    // Each layer reads the shared labels and bands only: layers in parallel, same result.
    let layers = (0..count).into_par_iter().map(|k| build_layer(k, image, disparity, &signed, &label, &bands)).collect();
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A 32x32 dark frame with HDR light (5.0) where `lit` says.
    fn lights(lit: impl Fn(usize, usize) -> bool) -> Image {
        Image::from_fn(32, 32, |x, y| if lit(x, y) { [5.0, 5.0, 5.0, 1.0] } else { [0.05, 0.05, 0.05, 1.0] })
    }

    /// dev-140 of issue 46 in small: a dark far wall with a bright sky along the top, and a tall
    /// nearer tower whose left edge falls on a block edge of the push-pull pyramid (x = 32).
    /// Behind the tower, next to the wall it hides, the far layer must continue the dark wall:
    /// the pyramid alone filled it from the sky (3.3x the wall 3 px in), and the
    /// tower's blurred edge showed a pale streak.
    #[test]
    fn a_hidden_region_continues_the_colour_beside_it_not_a_far_one() {
        let (wall, sky) = (0.015f32, 0.8f32);
        let image = Image::from_fn(64, 64, |x, y| match (x, y) {
            (32..=47, 8..) => [0.3, 0.3, 0.3, 1.0],
            (_, 0..=7) => [sky, sky, sky, 1.0],
            _ => [wall, wall, wall, 1.0],
        });
        let disparity: Vec<f32> = (0..64 * 64).map(|p| if (32..48).contains(&(p % 64)) && p / 64 >= 8 { 0.6 } else { 0.5 }).collect();
        let coc = CocModel::new(40.0, 1.0).expect("valid lens");
        let stack = split_into_layers(&image, &disparity, &coc, &AutoLayerOptions::default());
        assert_eq!(stack.layers.len(), 2, "the tower and the wall");
        let far = &stack.layers[1].rgba;
        for x in [35, 40, 43] {
            let c = far.get(x, 40);
            assert!(c[3] > 0.99, "the far layer is continued under the tower (alpha {})", c[3]);
            // 3 px in, the wall's colour (x = 31) within 10%; 11 px in, still nearer the wall's
            // than the sky's; from the right (x = 48) 5 px in.
            assert!(c[0] / c[3] < wall * if x == 35 { 1.1 } else { 2.0 }, "x = {x}: {:?}, the wall is {wall}", c);
        }
    }

    /// dev-956 of issue 46 in small: one far layer holds a sunlit plane (0.9, the layer's
    /// farthest depth) and, beside it and a little nearer, a dark wall (0.01); a silhouette
    /// below hides both. Under the silhouette, next to the wall, the far layer must continue
    /// the wall, not the plane 7 px aside: the depth guide of the fill weighs the wall e^-2,
    /// and as a test of confidence that left only the plane.
    #[test]
    fn a_hidden_region_continues_the_nearer_surface_of_its_layer_beside_it() {
        let image = Image::from_fn(64, 64, |x, y| match (x, y) {
            (_, 32..) => [0.2, 0.2, 0.2, 1.0],
            (0..=23, _) => [0.9, 0.9, 0.9, 1.0],
            _ => [0.01, 0.01, 0.01, 1.0],
        });
        let disparity: Vec<f32> = (0..64 * 64)
            .map(|p| match (p % 64, p / 64) {
                (_, 32..) => 0.7,
                (0..=23, _) => 0.5,
                _ => 0.505,
            })
            .collect();
        let coc = CocModel::new(40.0, 1.0).expect("valid lens");
        let stack = split_into_layers(&image, &disparity, &coc, &AutoLayerOptions::default());
        assert_eq!(stack.layers.len(), 2, "the silhouette, and the plane with the wall");
        let far = &stack.layers[1].rgba;
        for (x, y) in [(30, 36), (34, 38), (40, 36)] {
            let c = far.get(x, y);
            assert!(c[3] > 0.99, "({x}, {y}): the far layer is continued under the silhouette (alpha {})", c[3]);
            assert!(c[0] / c[3] < 0.05, "({x}, {y}): {:?}, the wall beside is 0.01, the plane 0.9", c);
        }
    }

    /// A light cut by a nearer layer's edge continues under it only as far as the parallax
    /// between the two (their CoC difference) lets the lens see behind the edge.
    #[test]
    fn a_light_continues_under_a_nearer_layer_only_as_far_as_the_lens_sees_behind_it() {
        // Layer 1: a dark wall with a lamp (20.0) in columns 8..16; layer 0 covers columns 16..
        let image = Image::from_fn(32, 8, |x, _| match x {
            16.. => [0.2, 0.2, 0.2, 1.0],
            8..=15 => [20.0, 20.0, 20.0, 1.0],
            _ => [0.05, 0.05, 0.05, 1.0],
        });
        let label: Vec<usize> = (0..32 * 8).map(|p| usize::from(p % 32 < 16)).collect();
        let disparity = vec![0.5; 32 * 8];
        let bands = BandMap::empty(32 * 8);
        let lamp_at = |occluder_coc: f32, x: usize| {
            let signed: Vec<f32> = label.iter().map(|&l| if l == 0 { occluder_coc } else { -5.0 }).collect();
            build_layer(1, &image, &disparity, &signed, &label, &bands).rgba.get(x, 4)[0]
        };
        // 10 px of CoC apart: the lamp goes on 4 px under the occluder (mirrored: column 14
        // for 17, 12 for 19), then the fill takes over.
        assert_eq!([lamp_at(5.0, 16), lamp_at(5.0, 17), lamp_at(5.0, 19)], [20.0; 3]);
        // 1.5 px apart: one pixel only; 0.5 px apart: none (the fill, well under the lamp).
        assert_eq!(lamp_at(-3.5, 16), 20.0);
        assert!(lamp_at(-3.5, 17) < 10.0 && lamp_at(-3.5, 19) < 10.0, "{} {}", lamp_at(-3.5, 17), lamp_at(-3.5, 19));
        assert!(lamp_at(-4.5, 16) < 10.0, "{}", lamp_at(-4.5, 16));
    }

    /// dev-398 of issue 46 in small: an in-focus black silhouette under a blurred, faintly
    /// textured far wall with a round light (up to 500) just above its outline, which runs along
    /// a row or along a diagonal (dev-212). The pixels inside the outline show no light at all,
    /// so the silhouette covers them whole. The matte alone left alpha 0.94-0.97 one row inside
    /// the level outline, on the light's flanks, and the rule over eight neighbours 0.96 one
    /// pixel inside the slanted one: 2-22 of the blurred light would shine through there. The
    /// outline pixels themselves stay the matte's.
    #[test]
    fn a_dark_pixel_inside_a_silhouette_is_covered_as_far_as_the_light_behind_requires() {
        let (light, dark) = (500.0f32, 0.002f32);
        let level = |x: usize, y: usize| y >= 24 || x > 64;
        let slanted = |x: usize, y: usize| x + y >= 58;
        for (name, front) in [("level", &level as &dyn Fn(usize, usize) -> bool), ("slanted", &slanted)] {
            let image = Image::from_fn(64, 64, |x, y| {
                let r2 = (x as f32 - 32.0).powi(2) + (y as f32 - 20.0).powi(2);
                match front(x, y) {
                    true => [0.0, 0.0, 0.0, 1.0],
                    false if r2 <= 36.0 => {
                        let v = light * (1.0 - r2 / 48.0);
                        [v, v, v, 1.0]
                    }
                    false => {
                        let v = dark * (1.0 + 0.5 * ((x * 7 + y * 3) % 5) as f32);
                        [v, v, v, 1.0]
                    }
                }
            });
            let disparity: Vec<f32> = (0..64 * 64).map(|p| if front(p % 64, p / 64) { 1.0 } else { 0.85 }).collect();
            let coc = CocModel::new(40.0, 1.0).expect("valid lens");
            let stack = split_into_layers(&image, &disparity, &coc, &AutoLayerOptions::default());
            assert_eq!(stack.layers.len(), 2, "{name}: the silhouette and the wall");
            let (front_layer, back) = (&stack.layers[0].rgba, &stack.layers[1].rgba);
            for (x, y) in (18..46).flat_map(|x| (14..34).map(move |y| (x, y))) {
                let inside = [(x, y), (x - 1, y), (x + 1, y), (x, y - 1), (x, y + 1)].iter().all(|&(x, y)| front(x, y));
                let a = front_layer.get(x, y)[3];
                // (1 - alpha) x 500 must not exceed the pixel's colour, 0.
                assert!(!inside || a >= 1.0 - 1e-6, "{name} ({x}, {y}): alpha {a}, which lets {} of the light through", (1.0 - a) * light);
                // "Over" still gives the input, on the outline and off it.
                let (f, b, c) = (front_layer.get(x, y), back.get(x, y), image.get(x, y));
                let over = f[0] + (1.0 - f[3]) * b[0];
                assert!((over - c[0]).abs() <= 1e-3 * c[0].max(1.0), "{name} ({x}, {y}): over {over}, input {}", c[0]);
            }
        }
    }

    #[test]
    fn lines_of_light_are_told_from_lamps() {
        let at = |x: usize, y: usize| y * 32 + x;
        // A sunlit wire two pixels thick along a row, and one along a diagonal: lines from any
        // of their pixels, the frame's edge included.
        let row = lights(|_, y| (15..=16).contains(&y));
        assert!([at(0, 15), at(16, 16), at(31, 15)].iter().all(|&p| elongated_light(&row, p)));
        let diagonal = lights(|x, y| x == y || x == y + 1);
        assert!([at(3, 3), at(16, 15), at(30, 30)].iter().all(|&p| elongated_light(&diagonal, p)));
        // Lamps: a 4x4 square, round ones of radius 3.5 and 8, a single pixel; from every pixel.
        let square = lights(|x, y| (14..18).contains(&x) && (14..18).contains(&y));
        let disc = lights(|x, y| (x as f32 - 15.5).powi(2) + (y as f32 - 15.5).powi(2) <= 3.5f32.powi(2));
        let big_disc = lights(|x, y| (x as f32 - 15.5).powi(2) + (y as f32 - 15.5).powi(2) <= 8.0f32.powi(2));
        let dot = lights(|x, y| x == 16 && y == 16);
        for image in [&square, &disc, &big_disc, &dot] {
            for p in (0..32 * 32).filter(|&p| is_hdr(image.pixels[p])) {
                assert!(!elongated_light(image, p), "a lamp pixel ({}, {}) taken for a line", p % 32, p / 32);
            }
        }
        // A short bar (5 x 2) is still a lamp: a line must run at least 6 px.
        let bar = lights(|x, y| (14..19).contains(&x) && (15..=16).contains(&y));
        assert!(!elongated_light(&bar, at(16, 15)));
    }
}
