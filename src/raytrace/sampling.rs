//! Deterministic stratified sampling: a tiny seeded generator (so results do not depend on
//! thread scheduling or a crate's version), jittered grids, and the concentric disk mapping.

/// SplitMix64: statistically good enough for jitter, trivially seedable per pixel.
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    /// A generator for one pixel; every (seed, x, y) gives an independent stream.
    pub fn for_pixel(seed: u64, x: usize, y: usize) -> Self {
        let mut rng = Rng(seed ^ 0x9E37_79B9_7F4A_7C15);
        let a = rng.next_u64() ^ (x as u64).wrapping_mul(0xD1B5_4A32_D192_ED03);
        let mut rng = Rng(a);
        let b = rng.next_u64() ^ (y as u64).wrapping_mul(0x8CB9_2BA7_2F3D_8DD7);
        Rng(b)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }

    /// Uniform integer in [0, n).
    pub fn below(&mut self, n: usize) -> usize {
        (((self.next_u64() >> 32) * n as u64) >> 32) as usize
    }
}

/// One pixel's samples: `n x n` jittered pixel-area positions, each paired with a jittered
/// lens stratum through a random permutation, so both 2D domains stay stratified while the
/// pairing is decorrelated (Cook's distributed ray tracing, "Stochastic sampling" 1986).
pub struct PixelSamples {
    /// Offsets inside the pixel, in [0, 1)^2.
    pub pixel: Vec<[f32; 2]>,
    /// Points on the unit disk.
    pub lens: Vec<[f32; 2]>,
}

impl PixelSamples {
    pub fn generate(rng: &mut Rng, n: usize) -> Self {
        let count = n * n;
        let inv = 1.0 / n as f32;
        let stratum = |i: usize, rng: &mut Rng| {
            [((i % n) as f32 + rng.next_f32()) * inv, ((i / n) as f32 + rng.next_f32()) * inv]
        };
        // Pixel positions first: the pinhole render draws the same stream, so in-focus pixels
        // of the defocused and the pinhole render see exactly the same points.
        let pixel: Vec<[f32; 2]> = (0..count).map(|i| stratum(i, rng)).collect();
        let mut order: Vec<usize> = (0..count).collect();
        for i in (1..count).rev() {
            order.swap(i, rng.below(i + 1));
        }
        let lens = order.iter().map(|&i| concentric_disk(stratum(i, rng))).collect();
        Self { pixel, lens }
    }
}

/// Shirley-Chiu concentric mapping of the unit square onto the unit disk: area preserving
/// and continuous, so square strata become disk strata of equal area.
pub fn concentric_disk([u, v]: [f32; 2]) -> [f32; 2] {
    let (a, b) = (2.0 * u - 1.0, 2.0 * v - 1.0);
    if a == 0.0 && b == 0.0 {
        return [0.0, 0.0];
    }
    let quarter = std::f32::consts::FRAC_PI_4;
    let (r, phi) = if a.abs() > b.abs() { (a, quarter * (b / a)) } else { (b, 2.0 * quarter - quarter * (a / b)) };
    [r * phi.cos(), r * phi.sin()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn concentric_disk_is_area_preserving() {
        // A uniform disk has E[r^2] = 1/2; 64x64 strata make the estimate accurate to ~1e-3.
        let n = 64;
        let mut sum = 0.0f64;
        for i in 0..n * n {
            let p = concentric_disk([((i % n) as f32 + 0.5) / n as f32, ((i / n) as f32 + 0.5) / n as f32]);
            assert!(p[0] * p[0] + p[1] * p[1] <= 1.0 + 1e-5);
            sum += (p[0] * p[0] + p[1] * p[1]) as f64;
        }
        assert!((sum / (n * n) as f64 - 0.5).abs() < 1e-3);
    }

    #[test]
    fn lens_strata_are_a_permutation_of_the_grid() {
        // Every lens stratum is used exactly once: the mean of the lens points is ~0.
        let mut rng = Rng::for_pixel(7, 3, 4);
        let s = PixelSamples::generate(&mut rng, 8);
        let mean = s.lens.iter().fold([0.0, 0.0], |m, p| [m[0] + p[0] / 64.0, m[1] + p[1] / 64.0]);
        assert!(mean[0].abs() < 0.05 && mean[1].abs() < 0.05, "{mean:?}");
    }
}
