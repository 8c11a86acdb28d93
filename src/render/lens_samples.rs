//! Lens samples shared by the ray-based seed renderers (`vdslr`, `multiview`).
//!
//! The host draws `patterns` independent sets of stratified, jittered samples over the lens
//! (an n x n grid of strata on the unit square, one jittered point per stratum, mapped to the
//! unit disk by the concentric map so strata stay equal-area). Each pixel picks one set with
//! an integer hash of its coordinates ([`pattern_index`], mirrored in
//! `glsl/common/sampling.glsl`). This is Lee et al.'s per-pixel offset into a precomputed
//! sequence: neighbouring pixels use different sample sets (noise instead of aliasing), and
//! the CPU reference and the shader read the *same* uploaded floats, so their sample
//! positions agree bit for bit.
//!
//! Aperture shapes: samples outside a polygon get weight 0 (kept as slots so every set has
//! the same stride); a kernel image weighs each sample by its value.
use std::f32::consts::FRAC_PI_4;

use crate::camera::Aperture;
use crate::{Error, Result};

/// Sample sets of equal stride, `[u, v, weight, 0]` per slot, `u, v` in the unit disk in
/// aperture coordinates (see [`crate::camera::Aperture::to_aperture_coords`]).
#[derive(Clone, Debug, PartialEq)]
pub struct LensSamples {
    /// Slots per set (`n * n`).
    pub slots: usize,
    pub patterns: usize,
    pub data: Vec<[f32; 4]>,
    /// Mean distance between neighbouring samples of one set, in lens radii: the diameter of
    /// the cone each ray stands for, per pixel of CoC radius (Lee et al. Sec. 4.4).
    pub spacing: f32,
}

impl LensSamples {
    /// At least `samples` slots per set (rounded up to a square), `patterns` sets.
    pub fn new(aperture: &Aperture, samples: u32, patterns: u32, seed: u32) -> Result<Self> {
        if samples == 0 || samples > 4096 {
            return Err(Error::invalid("lens samples", format!("lens samples must be in 1..=4096, got {samples}")));
        }
        if patterns == 0 || patterns > 1024 {
            return Err(Error::invalid("lens samples", format!("lens sample patterns must be in 1..=1024, got {patterns}")));
        }
        let n = (samples as f64).sqrt().ceil() as usize;
        let mut rng = SplitMix64(u64::from(seed) ^ 0x9e37_79b9_7f4a_7c15);
        let mut data = Vec::with_capacity(n * n * patterns as usize);
        for _ in 0..patterns {
            for j in 0..n {
                for i in 0..n {
                    let sx = (i as f32 + rng.unit()) / n as f32;
                    let sy = (j as f32 + rng.unit()) / n as f32;
                    let (u, v) = concentric_disk(sx, sy);
                    data.push([u, v, sample_weight(aperture, u, v), 0.0]);
                }
            }
        }
        let accepted = data.iter().filter(|s| s[2] > 0.0).count().max(1) as f32 / patterns as f32;
        let area = std::f32::consts::PI * aperture.relative_area();
        let spacing = (area / accepted).sqrt();
        Ok(Self { slots: n * n, patterns: patterns as usize, data, spacing })
    }

    /// The sample set of pixel `(x, y)`.
    pub fn set_for(&self, x: usize, y: usize) -> &[[f32; 4]] {
        let p = pattern_index(x as u32, y as u32, self.patterns as u32) as usize;
        &self.data[p * self.slots..(p + 1) * self.slots]
    }
}

fn sample_weight(aperture: &Aperture, u: f32, v: f32) -> f32 {
    match aperture {
        Aperture::Polygon { .. } | Aperture::Ellipse { .. } | Aperture::CatsEye { .. } if aperture.gauge(u, v) > 1.0 => 0.0,
        _ => aperture.weight(u, v),
    }
}

/// Shirley-Chiu concentric map of the unit square onto the unit disk (area preserving).
fn concentric_disk(sx: f32, sy: f32) -> (f32, f32) {
    let (a, b) = (2.0 * sx - 1.0, 2.0 * sy - 1.0);
    if a == 0.0 && b == 0.0 {
        return (0.0, 0.0);
    }
    let (r, phi) = if a.abs() > b.abs() { (a, FRAC_PI_4 * (b / a)) } else { (b, 2.0 * FRAC_PI_4 - FRAC_PI_4 * (a / b)) };
    (r * phi.cos(), r * phi.sin())
}

/// Integer hash (Wellons' lowbias32); same operations as `hash32` in `sampling.glsl`.
#[inline]
pub fn hash32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// Which sample set pixel `(x, y)` uses; same as `pattern_index` in `sampling.glsl`.
#[inline]
pub fn pattern_index(x: u32, y: u32, patterns: u32) -> u32 {
    hash32(hash32(x ^ 0x5bd1_e995) ^ y) % patterns
}

/// A tiny deterministic generator for the host-side jitter (no dependency, stable output).
struct SplitMix64(u64);

impl SplitMix64 {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1) with 24 bits, exactly representable in f32.
    fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn disk_samples_cover_the_disk_evenly() {
        // Stratified samples: the mean is near the centre and the mean squared radius near
        // 1/2 (the disk's value), within a few percent for 256 samples x 8 sets.
        let s = LensSamples::new(&Aperture::Disk, 256, 8, 1).unwrap();
        assert_eq!(s.slots, 256);
        let n = s.data.len() as f32;
        let (mx, my, r2) = s.data.iter().fold((0.0, 0.0, 0.0), |(a, b, c), p| (a + p[0], b + p[1], c + p[0] * p[0] + p[1] * p[1]));
        assert!((mx / n).abs() < 0.01 && (my / n).abs() < 0.01);
        assert!((r2 / n - 0.5).abs() < 0.01, "{}", r2 / n);
        assert!(s.data.iter().all(|p| p[0] * p[0] + p[1] * p[1] <= 1.0 + 1e-6 && p[2] == 1.0));
        assert!((s.spacing - (std::f32::consts::PI / 256.0).sqrt()).abs() < 1e-4);
    }

    #[test]
    fn polygon_rejects_samples_outside_its_blades() {
        let hexagon = Aperture::polygon(6, 0.0, 0.0).unwrap();
        let s = LensSamples::new(&hexagon, 400, 4, 3).unwrap();
        let kept = s.data.iter().filter(|p| p[2] > 0.0).count() as f32 / s.data.len() as f32;
        // A regular hexagon inscribed in the unit circle covers 3 sqrt(3) / (2 pi) = 0.827.
        assert!((kept - 0.827).abs() < 0.03, "{kept}");
    }

    #[test]
    fn pixels_pick_different_sets() {
        let counts = (0..64u32).flat_map(|y| (0..64u32).map(move |x| pattern_index(x, y, 16))).fold([0u32; 16], |mut c, p| {
            c[p as usize] += 1;
            c
        });
        // 4096 pixels over 16 sets: each near 256; a hash this good stays within +-25%.
        assert!(counts.iter().all(|&c| (192..=320).contains(&c)), "{counts:?}");
    }
}
