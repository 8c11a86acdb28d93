//! Procedural noise for the synthetic "photographs": hashed value noise and its fractal sum.
//! Pure functions of position and seed, so every render of a scene sees the same texture.

fn hash(ix: i32, iy: i32, seed: u32) -> f32 {
    let mut h = (ix as u32).wrapping_mul(0x8DA6_B343) ^ (iy as u32).wrapping_mul(0xD816_3841) ^ seed.wrapping_mul(0xCB1A_B31F);
    h ^= h >> 13;
    h = h.wrapping_mul(0x5BD1_E995);
    h ^= h >> 15;
    (h & 0x00FF_FFFF) as f32 / 0x0100_0000 as f32
}

fn smooth(t: f32) -> f32 {
    t * t * (3.0 - 2.0 * t)
}

/// Value noise in [0, 1) with a smooth (C1) interpolant; lattice spacing 1.
pub fn value_noise(x: f32, y: f32, seed: u32) -> f32 {
    let (fx, fy) = (x.floor(), y.floor());
    let (ix, iy) = (fx as i32, fy as i32);
    let (tx, ty) = (smooth(x - fx), smooth(y - fy));
    let top = hash(ix, iy, seed) + (hash(ix + 1, iy, seed) - hash(ix, iy, seed)) * tx;
    let bottom = hash(ix, iy + 1, seed) + (hash(ix + 1, iy + 1, seed) - hash(ix, iy + 1, seed)) * tx;
    top + (bottom - top) * ty
}

/// Fractal Brownian motion: `octaves` of value noise, each twice the frequency and half the
/// amplitude of the previous; normalised to [0, 1).
pub fn fbm(x: f32, y: f32, octaves: u32, seed: u32) -> f32 {
    let (mut sum, mut amplitude, mut norm, mut frequency) = (0.0, 1.0, 0.0, 1.0);
    for octave in 0..octaves {
        sum += amplitude * value_noise(x * frequency, y * frequency, seed.wrapping_add(octave * 1013));
        norm += amplitude;
        amplitude *= 0.5;
        frequency *= 2.03;
    }
    sum / norm
}

/// A deterministic pseudo-random number in [0, 1) for scene construction (positions of
/// highlights, branch angles): `index`-th draw of stream `seed`.
pub fn scatter(seed: u32, index: u32) -> f32 {
    hash(index as i32, (index >> 16) as i32 ^ 0x55, seed.wrapping_add(0x2545_F491))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_is_continuous_across_lattice_lines() {
        // C1 interpolation: values just either side of a lattice line differ by ~slope * 2e-4.
        for i in 0..50 {
            let y = i as f32 * 0.173;
            let (a, b) = (value_noise(2.9999, y, 3), value_noise(3.0001, y, 3));
            assert!((a - b).abs() < 1e-3, "jump {a} -> {b}");
        }
    }

    #[test]
    fn fbm_stays_in_unit_range() {
        for i in 0..1000 {
            let v = fbm(i as f32 * 0.37 - 100.0, i as f32 * 0.11, 5, 9);
            assert!((0.0..1.0).contains(&v));
        }
    }
}
