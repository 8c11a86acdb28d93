//! Distributed ray tracing through a thin lens (Cook et al. 1984), box-filtered over the
//! pixel, with stratified pixel x lens samples.
//!
//! Thin lens, exactly as DESIGN.md: pixel point `p` (pixels, principal point at the image
//! centre) has the pinhole ray `t = (p - c) / f_px`, which meets the focus plane at
//! `P = z_f (t, 1)`. A lens sample `a` on the disk of radius `R = f / 2N` (metres, plane
//! z = 0) gives the ray from `a` through `P`. It meets depth `z` at `a (1 - z/z_f) + z (t, 1)`,
//! which the pinhole camera images at `p + f_px a (1/z - 1/z_f)`. So the pixel sees depth z
//! through a disk of radius `f_px R |1/z - 1/z_f|` pixels around `p`, i.e. a point at depth z
//! spreads into a CoC of radius `K |1/z - 1/z_f|` with
//! `K = R f_px = (f / 2N) (f / sensor_width) W`, the camera model's K.
use std::sync::Arc;

use super::sampling::{PixelSamples, Rng};
use super::scene::{Scene, Surface, MAX_SURFACES};
use super::texture::Rgba;
use crate::{Error, Result};

/// How to sample the ground truth.
#[derive(Clone, Debug)]
pub struct TraceOptions {
    /// `n`: a round gives each pixel `n x n` stratified pixel-area samples, each paired with
    /// one of `n x n` lens strata.
    pub samples_per_axis: usize,
    /// Multiplies the scene's native resolution (CoC in pixels scales with it).
    pub scale: f32,
    /// Seed of the per-pixel sample streams; equal seeds give bit-identical renders.
    pub seed: u64,
    /// Rounds every pixel takes (at least 2 to estimate the error); the pinhole pass and the
    /// true layers use their pixel positions. Capped by `max_rounds`.
    pub min_rounds: usize,
    /// Most rounds a pixel may take: rounds beyond `min_rounds` (fresh strata) are spent only
    /// where the estimate is still noisy (see `render::defocus_pixel`). 1 = one round.
    pub max_rounds: usize,
    /// Target standard error of a defocused pixel in display units (sRGB-encoded, clipped
    /// to [0, 1], the scale the metrics use); 0.002 is half an 8-bit step.
    pub tolerance: f32,
    /// Told as image rows finish.
    pub progress: Option<RowProgress>,
}

/// Called with (rows finished, rows in all) from the tracer's worker threads: a progress bar,
/// a log line, a farm's task status; the library draws nothing itself.
#[derive(Clone)]
pub struct RowProgress(pub Arc<dyn Fn(usize, usize) + Send + Sync>);

impl RowProgress {
    pub fn new(report: impl Fn(usize, usize) + Send + Sync + 'static) -> Self {
        Self(Arc::new(report))
    }
}

impl std::fmt::Debug for RowProgress {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("RowProgress")
    }
}

impl Default for TraceOptions {
    /// 4 rounds of 8 x 8 = 256 rays per pixel, up to 64 rounds (4096 rays) where noisy.
    fn default() -> Self {
        Self { samples_per_axis: 8, scale: 1.0, seed: 0, min_rounds: 4, max_rounds: 64, tolerance: 0.002, progress: None }
    }
}

impl TraceOptions {
    pub fn validate(&self) -> Result<()> {
        if !(1..=64).contains(&self.samples_per_axis) {
            return Err(Error::invalid("trace options", format!("samples per axis must be 1 to 64, got {}", self.samples_per_axis)));
        }
        if !(1..=1024).contains(&self.max_rounds) || !(1..=1024).contains(&self.min_rounds) {
            return Err(Error::invalid("trace options", format!("rounds must be 1 to 1024, got {} to {}", self.min_rounds, self.max_rounds)));
        }
        if !(self.tolerance.is_finite() && self.tolerance >= 0.0) {
            return Err(Error::invalid("trace options", format!("tolerance must be a non-negative number, got {}", self.tolerance)));
        }
        if !(self.scale.is_finite() && self.scale > 0.0 && self.scale <= 16.0) {
            return Err(Error::invalid("trace options", format!("scale must be in (0, 16], got {}", self.scale)));
        }
        Ok(())
    }

    /// Rounds every pixel takes: `min_rounds`, capped by `max_rounds`.
    pub fn first_rounds(&self) -> usize {
        self.min_rounds.min(self.max_rounds)
    }
}

/// The camera in the units the tracer needs.
#[derive(Clone, Copy, Debug)]
pub(super) struct View {
    pub width: usize,
    pub height: usize,
    pub f_px: f32,
    pub focus: f32,
    /// Aperture radius `f / 2N` in metres; 0 makes a pinhole.
    pub aperture: f32,
}

impl View {
    pub fn new(scene: &Scene, width: usize, height: usize) -> Self {
        let camera = &scene.camera;
        let (f_px, focus, aperture) = (camera.focal_length_px(width), camera.focus_distance, camera.aperture_radius());
        Self { width, height, f_px, focus, aperture }
    }

    /// Pinhole ray slope `(x/z, y/z)` through image point `(x, y)` in pixels.
    #[inline]
    pub fn slope(&self, x: f32, y: f32) -> [f32; 2] {
        [(x - self.width as f32 * 0.5) / self.f_px, (y - self.height as f32 * 0.5) / self.f_px]
    }

    /// The thin-lens ray through image point `(x, y)` and unit-disk lens point `lens`:
    /// origin on the lens, direction towards the in-focus point `P` (module docs).
    #[inline]
    pub fn lens_ray(&self, x: f32, y: f32, lens: [f32; 2]) -> ([f32; 2], [f32; 3]) {
        let t = self.slope(x, y);
        let a = [self.aperture * lens[0], self.aperture * lens[1]];
        (a, [self.focus * t[0] - a[0], self.focus * t[1] - a[1], self.focus])
    }
}

/// One ray's intersections, nearest first: `(depth, surface index, u, v)`.
pub(super) struct Hits {
    items: [(f32, usize, f32, f32); MAX_SURFACES],
    len: usize,
}

impl Hits {
    #[inline]
    pub fn find(surfaces: &[Surface], origin: [f32; 2], dir: [f32; 3]) -> Self {
        let mut hits = Hits { items: [(0.0, 0, 0.0, 0.0); MAX_SURFACES], len: 0 };
        for (i, s) in surfaces.iter().enumerate() {
            if let Some((z, u, v)) = s.hit(origin, dir) {
                // Insertion keeps the list sorted by depth; there are only a handful.
                let mut j = hits.len;
                while j > 0 && hits.items[j - 1].0 > z {
                    hits.items[j] = hits.items[j - 1];
                    j -= 1;
                }
                hits.items[j] = (z, i, u, v);
                hits.len += 1;
            }
        }
        hits
    }

    pub fn iter(&self) -> impl Iterator<Item = &(f32, usize, f32, f32)> {
        self.items[..self.len].iter()
    }
}

/// Premultiplied "over": `acc += (1 - acc.a) * c`.
#[inline]
pub(super) fn over(acc: &mut Rgba, c: Rgba) {
    let t = 1.0 - acc[3];
    for (a, c) in acc.iter_mut().zip(c) {
        *a += t * c;
    }
}

/// Radiance along one ray: surfaces composited front to back through their cut-outs.
#[inline]
pub(super) fn trace(surfaces: &[Surface], origin: [f32; 2], dir: [f32; 3]) -> Rgba {
    let mut acc = [0.0; 4];
    for &(_, i, u, v) in Hits::find(surfaces, origin, dir).iter() {
        over(&mut acc, surfaces[i].texture.sample(u, v));
        if acc[3] >= 1.0 {
            break;
        }
    }
    acc
}

/// Per-pixel stream of samples for one round; round 0 is shared by the pinhole and the lens
/// passes, later rounds draw fresh strata.
pub(super) fn pixel_samples(options: &TraceOptions, x: usize, y: usize, round: usize) -> PixelSamples {
    let seed = options.seed.wrapping_add((round as u64).wrapping_mul(0xA076_1D64_78BD_642F));
    PixelSamples::generate(&mut Rng::for_pixel(seed, x, y), options.samples_per_axis)
}
