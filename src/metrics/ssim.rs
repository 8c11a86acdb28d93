//! SSIM (Wang et al. 2004) as in the authors' reference `ssim.m`: 11x11 Gaussian window with
//! sigma 1.5, K1 = 0.01, K2 = 0.03, dynamic range L = 1, statistics over *valid* windows only
//! (no padding). Colour images: SSIM of each RGB channel, then the mean of the three.
use super::DisplayImage;
use crate::{Error, Result};

pub const WINDOW: usize = 11;
const SIGMA: f64 = 1.5;
const C1: f64 = 0.01 * 0.01;
const C2: f64 = 0.03 * 0.03;

/// Mean SSIM over RGB channels; images must be at least `WINDOW` pixels on each side.
pub fn ssim(result: &DisplayImage, truth: &DisplayImage) -> Result<f64> {
    if result.width < WINDOW || result.height < WINDOW {
        return Err(Error::data(format!(
            "SSIM needs images of at least {WINDOW}x{WINDOW} pixels, got {}x{}",
            result.width, result.height
        )));
    }
    let total: f64 = (0..3).map(|c| ssim_plane(&result.channel(c), &truth.channel(c), result.width, result.height)).sum();
    Ok(total / 3.0)
}

fn gaussian_taps() -> [f64; WINDOW] {
    let half = (WINDOW / 2) as f64;
    let mut taps = [0.0; WINDOW];
    for (i, t) in taps.iter_mut().enumerate() {
        let x = i as f64 - half;
        *t = (-x * x / (2.0 * SIGMA * SIGMA)).exp();
    }
    let sum: f64 = taps.iter().sum();
    taps.map(|t| t / sum)
}

/// Separable Gaussian filter keeping only positions whose window lies inside the image.
fn filter_valid(plane: &[f64], width: usize, height: usize, taps: &[f64; WINDOW]) -> Vec<f64> {
    let (ow, oh) = (width + 1 - WINDOW, height + 1 - WINDOW);
    let mut rows = vec![0.0; ow * height];
    for y in 0..height {
        for x in 0..ow {
            rows[y * ow + x] = (0..WINDOW).map(|k| taps[k] * plane[y * width + x + k]).sum();
        }
    }
    let mut out = vec![0.0; ow * oh];
    for y in 0..oh {
        for x in 0..ow {
            out[y * ow + x] = (0..WINDOW).map(|k| taps[k] * rows[(y + k) * ow + x]).sum();
        }
    }
    out
}

fn ssim_plane(a: &[f32], b: &[f32], width: usize, height: usize) -> f64 {
    let taps = gaussian_taps();
    let a: Vec<f64> = a.iter().map(|&v| v as f64).collect();
    let b: Vec<f64> = b.iter().map(|&v| v as f64).collect();
    let product = |f: &dyn Fn(f64, f64) -> f64| -> Vec<f64> { a.iter().zip(&b).map(|(&x, &y)| f(x, y)).collect() };
    let mu_a = filter_valid(&a, width, height, &taps);
    let mu_b = filter_valid(&b, width, height, &taps);
    let aa = filter_valid(&product(&|x, _| x * x), width, height, &taps);
    let bb = filter_valid(&product(&|_, y| y * y), width, height, &taps);
    let ab = filter_valid(&product(&|x, y| x * y), width, height, &taps);
    let mut sum = 0.0;
    for i in 0..mu_a.len() {
        let (ma, mb) = (mu_a[i], mu_b[i]);
        let (va, vb, cov) = (aa[i] - ma * ma, bb[i] - mb * mb, ab[i] - ma * mb);
        sum += ((2.0 * ma * mb + C1) * (2.0 * cov + C2)) / ((ma * ma + mb * mb + C1) * (va + vb + C2));
    }
    sum / mu_a.len() as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(width: usize, height: usize, f: impl Fn(usize, usize) -> f32) -> DisplayImage {
        let rgb = (0..width * height).map(|i| [f(i % width, i / width); 3]).collect();
        DisplayImage { width, height, rgb }
    }

    fn texture(x: usize, y: usize) -> f32 {
        ((x * 7 + y * 13) % 17) as f32 / 16.0
    }

    #[test]
    fn identical_images_have_ssim_one() {
        let a = image(32, 24, texture);
        // Each window's ratio is exactly 1 up to f64 rounding of the variance terms.
        assert!((ssim(&a, &a).unwrap() - 1.0).abs() < 1e-9);
    }

    #[test]
    fn constant_images_match_the_luminance_term_closed_form() {
        // Zero variance: SSIM reduces to (2 m1 m2 + C1) / (m1^2 + m2^2 + C1).
        let (m1, m2) = (0.3f64, 0.5f64);
        let a = image(16, 16, |_, _| m1 as f32);
        let b = image(16, 16, |_, _| m2 as f32);
        let expected = (2.0 * m1 * m2 + C1) / (m1 * m1 + m2 * m2 + C1);
        // f32 storage of 0.3 and 0.5: relative error ~1e-8.
        assert!((ssim(&a, &b).unwrap() - expected).abs() < 1e-6);
    }

    #[test]
    fn structural_damage_lowers_ssim_symmetrically() {
        let a = image(40, 40, texture);
        let b = image(40, 40, |x, y| texture(x, y) * 0.5 + if (x + y) % 2 == 0 { 0.1 } else { 0.0 });
        let s = ssim(&a, &b).unwrap();
        assert!(s < 0.9, "{s}");
        assert!((s - ssim(&b, &a).unwrap()).abs() < 1e-12, "SSIM is symmetric");
    }

    #[test]
    fn images_smaller_than_the_window_are_refused() {
        let a = image(10, 30, texture);
        assert!(ssim(&a, &a).is_err());
    }
}
