//! Virtual DSLR (Yang et al. 2016): depth-guided pseudo ray tracing from ONE image and its
//! disparity map. GPU path: `glsl/vdslr_trace.comp` ([`Vdslr`]); CPU reference of the same
//! math: [`render_vdslr_cpu`].
//!
//! Per pixel `p` and lens sample `u` (unit disk, aperture coordinates) the lens ray meets a
//! surface of relative disparity `s` at image position `p + u K s` (the thin-lens geometry of
//! `crate::render::multiview`, which states the derivation). Eq. 4 of the paper in our
//! convention: pixel `q` is a hit when `q - p = u K s_q`, relaxed to half a pixel per axis.
//! The search is the paper's randomized one (Fig. 1d): start from the nearest disparity of the
//! map, jump to where the ray would be at the disparity just read, and repeat `iterations`
//! times. A ray that finds no hit is assumed occluded and tries the mirrored sample `-u`
//! (symmetric fill); if that fails too, the last pixel read other than `p` is used. Departure:
//! a failed ray that the centre does not block and whose last read lies behind the centre
//! passes beside the centre's surface and keeps that pixel without trying the mirror, which
//! lands back on a blurred foreground and kept its edges crisp (issue 22: `bench quality --quick`
//! vdslr 29.08 -> 29.71 dB mean, `bench single-image` 30.65 -> 30.89). The
//! bleeding guard replaces a farther pixel by the centre pixel whenever the centre is itself
//! a hit of the same ray (the centre's surface blocks the ray): an in-focus centre is a hit
//! of every ray, so an in-focus subject never picks up its blurred background, valid hit or
//! not (the search does not guarantee the *front-most* hit). Departure from the paper, which
//! guards every failed search: a failed ray that the centre does not block passes beside it,
//! so a thin blurred foreground over a background whose CoC is under half a pixel (where the
//! search oscillates between the two and never passes the relaxed test) turns transparent
//! instead of staying sharp; on the benchmark this is worth 3 to 8 dB on the fence, branch
//! and mesh scenes.
//!
//! Mixed edge pixels (departure, issue 22): at a depth edge an anti-aliased pixel holds both
//! surfaces' colours while its depth is one of them (a Z pass keeps one sample). Traced at that
//! one depth it is all one surface: on an in-focus outline it is kept sharp, the farther
//! surface's share included (a ray-traced light seen past hair stays a sharp, dark, blocky
//! strand instead of thin hair over a bright blur), or blurred whole; along a blurred bar it
//! keeps the bar's edge crisp; beside a thin blurred wire it keeps a faint sharp ghost of the
//! wire. Such a pixel is shaded as `a near + (1 - a) far`, the traces with the centre at the
//! nearer and at the farther surface's depth, with the coverage `a` estimated from its
//! neighbourhood's depths and colours: see `mixed_edges`. With 512 lens samples
//! ([`VdslrParams::tuned`]), `bench single-image` vdslr 24.27 / 29.93 / 34.70 dB -> 25.59 /
//! 30.44 / 36.64 (mean 29.63 -> 30.89).
//!
//! Colour blending is Eq. 5, adapted to linear HDR input: see [`Highlight`].
//! Special effects edit the disparity map as the paper does: [`FocusField`].
mod gpu;

pub use gpu::Vdslr;
// The focus field is camera math (the debug views read it too), the highlight weighting a
// method setting (`MethodSettings`); vdslr is the method that renders them.
pub use crate::camera::FocusField;
pub use crate::render::method::Highlight;

use rayon::prelude::*;

use crate::image::Image;
use crate::render::lens_samples::LensSamples;
use crate::render::method::{InputKind, MethodInput, MethodSettings, MethodSpec, Renderer, Setting};
use crate::render::tiler::RenderOptions;
use crate::render::Lens;
use crate::tile_grid::Rect;
use crate::vk::Context;
use crate::{Error, Result};

/// Virtual DSLR in the registry: reads every method setting.
pub const METHOD: MethodSpec = MethodSpec {
    name: "vdslr",
    label: "Virtual DSLR",
    summary: "Pseudo ray tracing of the flattened image + depth (Yang et al. 2016, Vulkan)",
    input: InputKind::SingleImage,
    uses_gpu: true,
    settings: &Setting::ALL,
    prepare: renderer,
    differentiable: None,
    fast_on_cpu: crate::render::method::never_fast_on_cpu,
};

fn renderer(ctx: Option<&Context>) -> Result<Box<dyn Renderer>> {
    let gpu = ctx.map(Vdslr::new).transpose()?;
    Ok(Box::new(move |input: MethodInput<'_>, lens: &Lens, options: &RenderOptions, settings: &MethodSettings| {
        let (image, disparity) = input.single_image()?;
        let params = VdslrParams::from_settings(settings);
        match &gpu {
            Some(gpu) => Ok(gpu.run_with(image, disparity, lens, &params, options)?.0),
            None => render_vdslr_cpu(image, disparity, lens, &params),
        }
    }))
}

#[derive(Clone, Debug, PartialEq)]
pub struct VdslrParams {
    /// Lens samples per pixel (rounded up to a square number of strata).
    pub samples: u32,
    /// Precomputed jittered sample sets; each pixel picks one by a hash of its coordinates.
    pub patterns: u32,
    pub seed: u32,
    /// Search steps after the initial read at the nearest disparity (the paper's T).
    pub iterations: u32,
    pub highlight: Option<Highlight>,
    pub focus: FocusField,
    /// Replace a farther invalid hit by the centre pixel (the paper does; off only for tests).
    pub bleeding_guard: bool,
    /// Shade mixed pixels at depth edges as a blend of both surfaces (`mixed_edges` in this
    /// module; off only for tests).
    pub mixed_edges: bool,
}

impl VdslrParams {
    /// What `--method vdslr` and the benchmark use. Measured on `bench quality --quick` (mean PSNR):
    /// 64 -> 256 lens samples +1.2 dB (HDR bokeh balls stop being grainy; 1024 adds 0.2 dB
    /// more), 3 -> 10 search iterations +0.9 dB (the tilted wall's continuous depth needs them).
    /// 256 -> 512 samples on `bench single-image`: +0.34 dB on silhouette-hdr (its many HDR
    /// bokeh balls: the grain along their rims), +0.18 dB mean, 1024 only 0.05 dB more; twice
    /// the time (about 1 s per 256^2 frame on lavapipe, under the peer's 2 s).
    /// Eq. 5 highlight weighting stays off: against ray-traced truth it only loses (mean over
    /// the 9 scenes: off 29.08 dB, sigma 1.0 28.46, 0.3 20.86, 0.1 17.30; gather 25.18), since
    /// linear HDR input already carries the highlights' energy that the weighting fakes.
    pub fn tuned() -> Self {
        Self { samples: 512, iterations: 10, ..Self::default() }
    }

    /// The tuned parameters with what `settings` gives: samples, iterations, highlight
    /// weighting and focus field (the default settings give [`Self::tuned`]).
    pub fn from_settings(settings: &MethodSettings) -> Self {
        let MethodSettings { samples, iterations, highlight, focus } = settings.clone();
        Self { samples, iterations, highlight, focus, ..Self::tuned() }
    }
}

impl Default for VdslrParams {
    fn default() -> Self {
        Self { samples: 64, patterns: 16, seed: 0, iterations: 3, highlight: None, focus: FocusField::Plane, bleeding_guard: true, mixed_edges: true }
    }
}

impl VdslrParams {
    fn validate(&self) -> Result<()> {
        if self.iterations > 64 {
            return Err(Error::invalid("vdslr settings", format!("vdslr iterations must be at most 64, got {}", self.iterations)));
        }
        if let Some(h) = self.highlight {
            if !(h.sigma.is_finite() && h.sigma > 0.0 && h.white.is_finite() && h.white > 0.0) {
                return Err(Error::invalid("vdslr settings", "highlight sigma and white must be positive numbers"));
            }
        }
        Ok(())
    }
}

/// Everything one pixel's tracing reads; shared by the CPU reference and the GPU host code.
struct Prepared {
    relative: Vec<f32>,
    samples: LensSamples,
    /// Largest relative disparity of the map: where every search starts.
    s_max: f32,
    /// Per pixel `[coverage, near, far, 0]` ([`mixed_edges`]); coverage 0 elsewhere. Whole
    /// frame for the CPU reference (`render_vdslr_cpu` fills it); empty for the GPU path,
    /// whose tiles each classify their own core ([`Prepared::edges_in`]): a frame's worth of
    /// vec4s is more than the flattened image itself.
    edges: Vec<[f32; 4]>,
    /// Whether mixed edge pixels are blended at all (`VdslrParams::mixed_edges`).
    mixed: bool,
}

impl Prepared {
    /// The edge records of the pixels in `rect`, row-major ([`mixed_edges`]'s classification;
    /// all zero when mixed edges are off).
    fn edges_in(&self, image: &Image, disparity: &[f32], k: f32, rect: Rect) -> Vec<[f32; 4]> {
        if !self.mixed {
            return vec![[0.0; 4]; rect.area()];
        }
        mixed_edges(image, &self.relative, disparity, k, rect)
    }
}

fn prepare(image: &Image, disparity: &[f32], lens: &Lens, params: &VdslrParams) -> Result<Prepared> {
    params.validate()?;
    let relative = params.focus.relative_disparity(disparity, image.width, image.height, &lens.coc)?;
    let samples = LensSamples::new(&lens.aperture, params.samples, params.patterns, params.seed)?;
    let s_max = relative.iter().cloned().fold(f32::NEG_INFINITY, f32::max);
    if !s_max.is_finite() {
        return Err(Error::data("disparity must be finite and the image non-empty"));
    }
    Ok(Prepared { relative, samples, s_max, edges: Vec::new(), mixed: params.mixed_edges })
}

/// Mixed pixels at depth edges: `[a, near, far, 0]` per pixel, where the 3x3 neighbourhood
/// (clamped at the frame) holds a nearest and a farthest depth whose CoCs differ by more than
/// one pixel; `near` and `far` are the neighbours holding them ([`neighbour`]'s numbering, as
/// floats), `a` the nearer surface's coverage; `[0; 4]` elsewhere. Left out: the pixels of a
/// thin blurred structure themselves (own depth near, the nearer surface blurred, fewer than
/// 18 of the 49 depths of the 7x7 neighbourhood nearer than midway), where the ray search's
/// own handling of foreground edges does better (measured: blending them too cost thin-near
/// 1.6 dB, the wires losing their blur). Their neighbours with the farther depth are blended:
/// they hold part of the wire's colour, which traced at the background's depth alone stayed a
/// faint ghost line (+1.3 dB on thin-near); on the blurred bars of five-planes the blend is
/// worth +0.25 dB.
///
/// The coverage `a` is the share of the nine depths nearer than midway between the two (each
/// is one random sample of its pixel). On a pixel whose own depth is near it is raised to the
/// colour's own estimate, the projection of its colour on the line from the far pixels' mean
/// colour to the near pixels' mean: an aliased edge, whose outline pixels hold the nearer
/// surface's colour alone, keeps them as they were (the share alone said 6/9 there and let a
/// third of the background into an in-focus subject), and on `bench single-image` this is
/// worth +0.5 dB on thin-near and +0.1 on five-planes for 0.3 on silhouette-hdr (whose hair's
/// near means are themselves mixed).
///
/// Computed for the pixels of `rect`, row-major: a GPU tile classifies its own core.
fn mixed_edges(image: &Image, relative: &[f32], disparity: &[f32], k: f32, rect: Rect) -> Vec<[f32; 4]> {
    let width = image.width;
    let pixels: Vec<usize> = (rect.y0..rect.y1).flat_map(|y| (rect.x0..rect.x1).map(move |x| y * width + x)).collect();
    pixels.into_par_iter().map(|i| mixed_edge(image, relative, disparity, k, i)).collect()
}

/// [`mixed_edges`]' record of pixel `i`.
fn mixed_edge(image: &Image, relative: &[f32], disparity: &[f32], k: f32, i: usize) -> [f32; 4] {
    let (width, height) = (image.width, image.height);
    let window = |i: usize, radius: i64| {
        let (x, y) = ((i % width) as i64, (i / width) as i64);
        (-radius..=radius).flat_map(move |dy| {
            (-radius..=radius).map(move |dx| {
                let qx = (x + dx).clamp(0, width as i64 - 1) as usize;
                let qy = (y + dy).clamp(0, height as i64 - 1) as usize;
                qy * width + qx
            })
        })
    };
    let (mut near, mut far) = (4, 4);
    // An array, not a vector: this runs for every pixel of the frame.
    let nine: [usize; 9] = std::array::from_fn(|n| neighbour(i % width, i / width, n, width, height));
    for (n, &q) in nine.iter().enumerate() {
        if disparity[q] > disparity[nine[near]] {
            near = n;
        }
        if disparity[q] < disparity[nine[far]] {
            far = n;
        }
    }
    let (qn, qf) = (nine[near], nine[far]);
    if k * (relative[qn] - relative[qf]).abs() <= 1.0 {
        return [0.0; 4];
    }
    let mid = 0.5 * (disparity[qn] + disparity[qf]);
    let in_focus = k * relative[qn].abs() < 1.0;
    if !in_focus && disparity[i] > mid && window(i, 3).filter(|&q| disparity[q] > mid).count() < 18 {
        return [0.0; 4];
    }
    let share = nine.iter().filter(|&&q| disparity[q] > mid).count() as f32 / 9.0;
    let own_near = disparity[i] > mid;
    let a = if own_near { share.max(colour_coverage(image, &nine, |q| disparity[q] > mid, i)) } else { share };
    [a, near as f32, far as f32, 0.0]
}

/// Pixel number `n` (0..9, row by row, 4 the pixel itself) of the 3x3 neighbourhood of
/// `(x, y)`, clamped at the frame; `neighbour` in `vdslr_trace.comp`.
#[inline]
fn neighbour(x: usize, y: usize, n: usize, width: usize, height: usize) -> usize {
    let qx = (x + n % 3).saturating_sub(1).min(width - 1);
    let qy = (y + n / 3).saturating_sub(1).min(height - 1);
    qy * width + qx
}

/// Where pixel `centre`'s RGB lies on the line from the mean colour of the `is_near` pixels
/// among `neighbours` (1) to the mean of the others (0), clamped to [0, 1]; 0 when the two
/// means coincide.
fn colour_coverage(image: &Image, neighbours: &[usize], is_near: impl Fn(usize) -> bool, centre: usize) -> f32 {
    let (mut near, mut far, mut counts) = ([0.0f32; 3], [0.0f32; 3], [0.0f32; 2]);
    for &q in neighbours {
        let (sum, count) = if is_near(q) { (&mut near, &mut counts[0]) } else { (&mut far, &mut counts[1]) };
        (0..3).for_each(|c| sum[c] += image.pixels[q][c]);
        *count += 1.0;
    }
    let (f, b) = (near.map(|v| v / counts[0]), far.map(|v| v / counts[1]));
    let colour = image.pixels[centre];
    let (mut along, mut length) = (0.0, 0.0);
    for c in 0..3 {
        along += (colour[c] - b[c]) * (f[c] - b[c]);
        length += (f[c] - b[c]) * (f[c] - b[c]);
    }
    if length > 1e-8 {
        (along / length).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// CPU reference of `glsl/vdslr_trace.comp`.
pub fn render_vdslr_cpu(image: &Image, disparity: &[f32], lens: &Lens, params: &VdslrParams) -> Result<Image> {
    let mut prepared = prepare(image, disparity, lens, params)?;
    let whole = Rect { x0: 0, y0: 0, x1: image.width, y1: image.height };
    prepared.edges = prepared.edges_in(image, disparity, lens.coc.k_px, whole);
    let tracer = Tracer { image, disparity, prepared: &prepared, k: lens.coc.k_px, params };
    let mut out = Image::new(image.width, image.height);
    out.pixels.par_chunks_mut(image.width.max(1)).enumerate().for_each(|(y, row)| {
        for (x, pixel) in row.iter_mut().enumerate() {
            *pixel = tracer.shade(x, y);
        }
    });
    Ok(out)
}

struct Tracer<'a> {
    image: &'a Image,
    disparity: &'a [f32],
    prepared: &'a Prepared,
    k: f32,
    params: &'a VdslrParams,
}

/// The pixel being shaded and the depth it is traced at: its own relative (`s`) and true
/// (`d`) disparity, or the farther surface's for a mixed edge pixel.
struct Centre {
    index: usize,
    s: f32,
    d: f32,
}

/// What a trace takes the centre pixel for: the relative (`s`) and true (`d`) disparity and the
/// colour (the pixel numbered `colour`) of one surface. A mixed edge pixel's colour holds both
/// surfaces: traced at the farther, in-focus surface's depth, its own colour kept the nearer
/// surface's share sharp (the faint lines left where thin blurred wires cross an in-focus
/// subject), so the farther hypothesis takes the colour of its least mixed neighbour
/// ([`Tracer::farther_colour`]; thin-near 36.6 -> 37.8 dB). The nearer hypothesis keeps the
/// centre's colour: the nearer neighbour of a hair strand is often mixed itself (taking it cost
/// silhouette-hdr's hair).
#[derive(Clone, Copy)]
struct Surface {
    s: f32,
    d: f32,
    colour: usize,
}

impl Surface {
    fn of(pixel: usize, tracer: &Tracer) -> Self {
        Self { s: tracer.prepared.relative[pixel], d: tracer.disparity[pixel], colour: pixel }
    }
}

/// Which of a pixel's sample slots a trace takes: `first`, `first + step`, ...
#[derive(Clone, Copy)]
struct Slots {
    first: usize,
    step: usize,
}

/// The pixel a search ended on, and whether it satisfied the relaxed Eq. 4.
struct Hit {
    index: usize,
    valid: bool,
}

impl Tracer<'_> {
    /// A mixed edge pixel blends the traces at the nearer and the farther surface's depth by
    /// coverage, each over half of the pixel's lens samples (even and odd slots: the strata
    /// alternate, so each half still covers the lens) so that it costs what one trace does;
    /// any other pixel is traced at its own depth with all of them.
    fn shade(&self, x: usize, y: usize) -> [f32; 4] {
        let centre = self.image.index(x, y);
        let [a, near, far, _] = self.prepared.edges[centre];
        if a > 0.0 {
            let (w, h) = (self.image.width, self.image.height);
            let [near, far] = [near, far].map(|n| neighbour(x, y, n as usize, w, h));
            let (even, odd) = (Slots { first: 0, step: 2 }, Slots { first: 1, step: 2 });
            let far_colour = self.farther_colour(x, y, near, far);
            let near = self.trace(x, y, Surface { colour: centre, ..Surface::of(near, self) }, even);
            let far = self.trace(x, y, Surface { colour: far_colour, ..Surface::of(far, self) }, odd);
            return std::array::from_fn(|c| a * near[c] + (1.0 - a) * far[c]);
        }
        self.trace(x, y, Surface::of(centre, self), Slots { first: 0, step: 1 })
    }

    /// The pixel whose colour stands for the farther surface at mixed pixel (x, y), whose 3x3
    /// neighbourhood holds the nearer surface at `near` and the farther at `far`: of the
    /// neighbours showing the farther surface (depth beyond midway), the one whose colour
    /// differs most from the nearer neighbour's (the least mixed); the centre if none does.
    fn farther_colour(&self, x: usize, y: usize, near: usize, far: usize) -> usize {
        let (w, h) = (self.image.width, self.image.height);
        let midway = 0.5 * (self.disparity[near] + self.disparity[far]);
        let near_colour = self.image.pixels[near];
        let distance = |q: usize| (0..3).map(|c| (self.image.pixels[q][c] - near_colour[c]).powi(2)).sum::<f32>();
        let centre = self.image.index(x, y);
        let candidates = (0..9).filter(|&n| n != 4).map(|n| neighbour(x, y, n, w, h));
        let farther = candidates.filter(|&q| q != centre && self.disparity[q] <= midway);
        // First of the largest distance, in neighbour order (the GPU scans the same order).
        farther.fold(None, |best: Option<(usize, f32)>, q| match best {
            Some((_, d)) if d >= distance(q) => best,
            _ => Some((q, distance(q))),
        })
        .map_or(centre, |(q, _)| q)
    }

    /// The pixel's lens samples in `slots` traced with the centre taken for `surface` (its own,
    /// or a neighbour's for a mixed pixel: a hypothesis of depth and colour).
    fn trace(&self, x: usize, y: usize, surface: Surface, slots: Slots) -> [f32; 4] {
        let centre = self.image.index(x, y);
        let (s_c, d_c) = (surface.s, surface.d);
        let at = Centre { index: centre, s: s_c, d: d_c };
        let p = [x as f32, y as f32];
        let (mut sum, mut weight) = ([0.0f32; 4], 0.0f32);
        for s in self.prepared.samples.set_for(x, y).iter().skip(slots.first).step_by(slots.step) {
            if s[2] <= 0.0 {
                continue;
            }
            let u = [s[0] * self.k, s[1] * self.k];
            let mut hit = self.search(p, u, &at);
            let centre_hit = self.hits(p, u, x, y, s_c);
            // A failed ray that the centre does not block and whose last read lies behind the
            // centre passes beside the centre's surface (a blurred foreground's edge): it keeps
            // that farther pixel rather than the mirror, which lands back on the foreground and
            // kept blurred foreground edges crisp (issue 22, failure 3).
            let beside = !centre_hit && self.disparity_at(hit.index, &at) < d_c;
            if !hit.valid && !beside {
                let mirrored = self.search(p, [-u[0], -u[1]], &at);
                if mirrored.valid {
                    hit = mirrored;
                }
            }
            // The guard: a farther pixel loses to the centre when the centre itself is a hit of
            // this ray (the ray is blocked by the centre's surface, whatever the search found).
            // The paper also applies it to every failed search; a failed ray the centre does
            // not block passes beside it (see `search`), which lets thin blurred foregrounds
            // turn transparent instead of staying sharp.
            let farther = self.disparity_at(hit.index, &at) < d_c;
            let guard = self.params.bleeding_guard && farther && centre_hit;
            let index = if guard { centre } else { hit.index };
            let colour = self.image.pixels[if index == centre { surface.colour } else { index }];
            let w = s[2] * highlight_weight(colour, self.params.highlight);
            for c in 0..4 {
                sum[c] += w * colour[c];
            }
            weight += w;
        }
        if weight > 0.0 {
            sum.map(|v| v / weight)
        } else {
            self.image.pixels[surface.colour]
        }
    }

    /// Randomized intersection search along the ray `p + u s` (u already scaled by K). A
    /// failed search reports the last pixel read other than the centre: when the centre is not
    /// a hit of the ray, the ray passes beside the centre's surface, and the search can
    /// oscillate between the centre and a farther neighbour (a thin blurred foreground over a
    /// background whose CoC is under half a pixel) without ever passing the relaxed test.
    fn search(&self, p: [f32; 2], u: [f32; 2], at: &Centre) -> Hit {
        let (w, h) = (self.image.width, self.image.height);
        let centre = at.index;
        let mut s_t = self.prepared.s_max;
        let mut other = centre;
        for _ in 0..=self.params.iterations {
            let qx = nearest_pixel(p[0] + u[0] * s_t, w);
            let qy = nearest_pixel(p[1] + u[1] * s_t, h);
            let index = qy * w + qx;
            let s_q = if index == centre { at.s } else { self.prepared.relative[index] };
            if self.hits(p, u, qx, qy, s_q) {
                return Hit { index, valid: true };
            }
            if index != centre {
                other = index;
            }
            s_t = s_q;
        }
        Hit { index: other, valid: false }
    }

    /// True disparity of pixel `index`, the centre's being the traced hypothesis.
    #[inline]
    fn disparity_at(&self, index: usize, at: &Centre) -> f32 {
        if index == at.index {
            at.d
        } else {
            self.disparity[index]
        }
    }

    /// The relaxed Eq. 4: pixel `q` of relative disparity `s_q` lies within half a pixel (per
    /// axis) of where the ray `p + u s` is at `s = s_q`.
    #[inline]
    fn hits(&self, p: [f32; 2], u: [f32; 2], qx: usize, qy: usize, s_q: f32) -> bool {
        let ex = qx as f32 - (p[0] + u[0] * s_q);
        let ey = qy as f32 - (p[1] + u[1] * s_q);
        ex.abs() <= 0.5 && ey.abs() <= 0.5
    }
}

/// Nearest pixel centre, clamped to the image (edge extension); `floor(x + 0.5)` as in GLSL.
#[inline]
fn nearest_pixel(x: f32, size: usize) -> usize {
    ((x + 0.5).floor()).clamp(0.0, size as f32 - 1.0) as usize
}

/// Eq. 5's weight of one sample colour (see [`Highlight`]); 1 when the weighting is off.
#[inline]
fn highlight_weight(colour: [f32; 4], highlight: Option<Highlight>) -> f32 {
    match highlight {
        None => 1.0,
        Some(Highlight { sigma, white }) => {
            let m = colour[0].max(colour[1]).max(colour[2]).min(white);
            (-(m - white) * (m - white) / (2.0 * sigma * sigma)).exp()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Aperture, CocModel};

    fn lens(k: f32, focus: f32) -> Lens {
        Lens { coc: CocModel::new(k, focus).unwrap(), aperture: Aperture::Disk }
    }

    /// `--method vdslr` without settings renders with the tuned parameters.
    #[test]
    fn default_settings_are_the_tuned_parameters() {
        assert_eq!(VdslrParams::from_settings(&MethodSettings::default()), VdslrParams::tuned());
    }

    #[test]
    fn mixed_edges_are_depth_edges_but_not_thin_blurred_structures() {
        // Columns 0-2 at disparity 1.0 (white, column 2 an anti-aliased 0.9 grey), 3-5 at 0.5
        // (black); K = 10: 5 px of CoC between the two.
        let (w, h) = (6, 3);
        let disparity: Vec<f32> = (0..w * h).map(|i| if i % w < 3 { 1.0 } else { 0.5 }).collect();
        let image = Image::from_fn(w, h, |x, _| [[1.0, 1.0, 0.9, 0.0, 0.0, 0.0][x]; 4]);
        let edges_for = |disparity: &[f32], image: &Image, k: f32, focus: f32| {
            let (w, h) = (image.width, image.height);
            let relative = FocusField::Plane.relative_disparity(disparity, w, h, &lens(k, focus).coc).unwrap();
            mixed_edges(image, &relative, disparity, k, Rect { x0: 0, y0: 0, x1: image.width, y1: image.height })
        };
        // The two columns along the step. Column 2 (near depth): its colour 0.9 over the near
        // mean 0.95 and the far mean 0, 0.947, above the depth share 6/9; nearest itself (4),
        // farthest the first far neighbour (2, up right). Column 3 (far depth): the share of
        // near depths, 3/9; nearest the first near neighbour (0, up left). Tolerance: f32
        // rounding of a few sums.
        let edges = edges_for(&disparity, &image, 10.0, 1.0);
        for (i, e) in edges.iter().enumerate() {
            let expected = match i % w {
                2 => [0.9 / 0.95, 4.0, 2.0, 0.0],
                3 => [3.0 / 9.0, 0.0, 4.0, 0.0],
                _ => [0.0; 4],
            };
            let close = e.iter().zip(expected).all(|(v, x)| (v - x).abs() < 1e-6);
            assert!(close, "pixel {i}: {e:?}, expected {expected:?}");
        }
        // The near side blurred (5 px) but wide (28 of the 49 depths of the 7x7): the same.
        assert_eq!(edges_for(&disparity, &image, 10.0, 0.5), edges);
        // A step under a pixel of CoC: none.
        assert!(edges_for(&disparity, &image, 1.9, 1.0).iter().all(|e| *e == [0.0; 4]));
        // A blurred line one pixel wide (7 of 49 depths): its neighbours only, not the line; the
        // same line in focus: the line too.
        let (w, h) = (9, 9);
        let line: Vec<f32> = (0..w * h).map(|i| if i % w == 4 { 1.0 } else { 0.5 }).collect();
        let grey = Image::filled(w, h, [0.5; 4]);
        let mixed = |focus: f32, columns: &[usize]| {
            let edges = edges_for(&line, &grey, 10.0, focus);
            edges.iter().enumerate().all(|(i, e)| (e[0] > 0.0) == columns.contains(&(i % w)))
        };
        assert!(mixed(0.5, &[3, 5]) && mixed(1.0, &[3, 4, 5]));
    }

    #[test]
    fn several_focal_planes_take_the_nearest_plane() {
        let rel = FocusField::Planes(vec![0.2, 0.8]).relative_disparity(&[0.1, 0.45, 0.9], 3, 1, &lens(10.0, 0.0).coc).unwrap();
        let expected = [-0.1, 0.25, 0.1];
        for (r, e) in rel.iter().zip(expected) {
            assert!((r - e).abs() < 1e-6, "{rel:?}");
        }
    }

    #[test]
    fn tilt_is_zero_at_the_centre_and_linear() {
        let rel = FocusField::Tilt { gradient: [0.1, 0.0] }.relative_disparity(&[0.5; 5], 5, 1, &lens(10.0, 0.5).coc).unwrap();
        for (i, r) in rel.iter().enumerate() {
            assert!((r + 0.1 * (i as f32 - 2.0)).abs() < 1e-6, "{rel:?}");
        }
    }

    #[test]
    fn highlight_weight_is_full_at_and_above_white() {
        let h = Some(Highlight { sigma: 0.3, white: 1.0 });
        assert_eq!(highlight_weight([20.0, 0.0, 0.0, 1.0], h), 1.0);
        assert_eq!(highlight_weight([1.0, 1.0, 1.0, 1.0], h), 1.0);
        assert!(highlight_weight([0.1, 0.1, 0.1, 1.0], h) < 0.02, "dark samples are down-weighted");
    }
}
