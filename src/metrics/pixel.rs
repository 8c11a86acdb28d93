//! Per-sample metrics on display-encoded values in [0, 1]: RMSE, scale-invariant RMSE, PSNR
//! and ZNCC. Inputs are equal-length sample slices (all RGB samples of an image); sums are in
//! f64 so a 4K image does not lose digits.

/// Root mean squared error.
pub fn rmse(result: &[f32], truth: &[f32]) -> f64 {
    mse(result, truth).sqrt()
}

/// Mean squared error.
pub fn mse(result: &[f32], truth: &[f32]) -> f64 {
    debug_assert_eq!(result.len(), truth.len());
    if result.is_empty() {
        return 0.0;
    }
    let sum: f64 = result.iter().zip(truth).map(|(&a, &b)| (a as f64 - b as f64).powi(2)).sum();
    sum / result.len() as f64
}

/// Scale-invariant RMSE (the paper's RMSE-s, after Sun et al. 2019): the RMSE after the
/// least-squares scale `s = <a, b> / <a, a>` is applied to the result, so a method is not
/// punished for a global exposure/gamma-like gain. An all-black result keeps `s = 1`.
pub fn si_rmse(result: &[f32], truth: &[f32]) -> f64 {
    let ab: f64 = result.iter().zip(truth).map(|(&a, &b)| a as f64 * b as f64).sum();
    let aa: f64 = result.iter().map(|&a| (a as f64).powi(2)).sum();
    let s = if aa > 0.0 { ab / aa } else { 1.0 };
    if result.is_empty() {
        return 0.0;
    }
    let sum: f64 = result.iter().zip(truth).map(|(&a, &b)| (s * a as f64 - b as f64).powi(2)).sum();
    (sum / result.len() as f64).sqrt()
}

/// PSNR in dB for a peak of 1; identical images give `f64::INFINITY`.
pub fn psnr_from_mse(mse: f64) -> f64 {
    if mse > 0.0 {
        -10.0 * mse.log10()
    } else {
        f64::INFINITY
    }
}

/// Zero-normalised cross-correlation over all samples jointly, in [-1, 1].
///
/// Undefined when a side has zero variance; we return 1 when both are constant (nothing to
/// correlate, nothing differs in structure) and 0 when only one is.
pub fn zncc(result: &[f32], truth: &[f32]) -> f64 {
    let n = result.len().max(1) as f64;
    let mean_a = result.iter().map(|&a| a as f64).sum::<f64>() / n;
    let mean_b = truth.iter().map(|&b| b as f64).sum::<f64>() / n;
    let (mut ab, mut aa, mut bb) = (0.0f64, 0.0f64, 0.0f64);
    for (&a, &b) in result.iter().zip(truth) {
        let (da, db) = (a as f64 - mean_a, b as f64 - mean_b);
        ab += da * db;
        aa += da * da;
        bb += db * db;
    }
    match (aa > 0.0, bb > 0.0) {
        (true, true) => (ab / (aa * bb).sqrt()).clamp(-1.0, 1.0),
        (false, false) => 1.0,
        _ => 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(n: usize) -> Vec<f32> {
        (0..n).map(|i| ((i * 37) % 101) as f32 / 100.0).collect()
    }

    #[test]
    fn identical_samples_score_perfectly() {
        let a = ramp(300);
        assert_eq!(rmse(&a, &a), 0.0);
        assert_eq!(si_rmse(&a, &a), 0.0);
        assert_eq!(psnr_from_mse(mse(&a, &a)), f64::INFINITY);
        assert!((zncc(&a, &a) - 1.0).abs() < 1e-12, "f64 sums of <1000 terms: exact to 1e-12");
    }

    #[test]
    fn known_mse_gives_known_psnr() {
        // A uniform offset of 0.1 has MSE 0.01, i.e. exactly 20 dB for a peak of 1.
        let a = vec![0.5f32; 64];
        let b = vec![0.6f32; 64];
        let m = mse(&a, &b);
        assert!((m - 0.01).abs() < 1e-8, "f32 representation of 0.5/0.6: error ~1e-9");
        assert!((psnr_from_mse(m) - 20.0).abs() < 1e-5);
        assert!((rmse(&a, &b) - 0.1).abs() < 1e-7);
    }

    #[test]
    fn si_rmse_ignores_a_global_gain_but_rmse_does_not() {
        let truth = ramp(200);
        let noisy: Vec<f32> = truth.iter().enumerate().map(|(i, t)| t + if i % 2 == 0 { 0.02 } else { -0.01 }).collect();
        let reference = si_rmse(&noisy, &truth);
        for gain in [0.25f32, 0.7, 3.0] {
            let scaled: Vec<f32> = noisy.iter().map(|v| v * gain).collect();
            // Scaling by `gain` rescales the optimal s by 1/gain: equal up to f32 rounding.
            assert!((si_rmse(&scaled, &truth) - reference).abs() < 1e-6, "gain {gain}");
            assert!(rmse(&scaled, &truth) > reference, "plain RMSE must see the gain");
        }
        assert!(si_rmse(&noisy, &truth) <= rmse(&noisy, &truth), "s = 1 is one of the candidates");
    }

    #[test]
    fn zncc_is_affine_invariant_and_sign_sensitive() {
        let a = ramp(150);
        let affine: Vec<f32> = a.iter().map(|v| 0.3 * v + 0.2).collect();
        let inverted: Vec<f32> = a.iter().map(|v| 1.0 - v).collect();
        assert!((zncc(&affine, &a) - 1.0).abs() < 1e-6);
        assert!((zncc(&inverted, &a) + 1.0).abs() < 1e-6);
        assert_eq!(zncc(&vec![0.4; 150], &a), 0.0, "a constant result carries no structure");
    }
}
