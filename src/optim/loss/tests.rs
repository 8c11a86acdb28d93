use super::*;
use crate::stack::Layer;

/// Deterministic pseudo-random numbers in [0, 1).
pub(crate) fn noise(seed: u64) -> impl FnMut() -> f32 {
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    }
}

fn random_image(width: usize, height: usize, seed: u64) -> Image {
    let mut rand = noise(seed);
    Image::from_fn(width, height, |_, _| [rand(), rand(), rand(), 0.5 + 0.5 * rand()])
}

/// Checks `grad` against central differences of `f` along every RGB entry of `image`;
/// the step actually taken (after f32 rounding) is the divisor.
fn check_image_gradient(image: &Image, grad: &Gradient, tolerance: f64, f: impl Fn(&Image) -> f64) {
    let h = 1e-3;
    let scale = grad.iter().flat_map(|g| g.iter()).fold(0.0f64, |m, g| m.max(g.abs()));
    for (i, g) in grad.iter().enumerate() {
        for (c, &g) in g.iter().enumerate().take(3) {
            let (mut up, mut down) = (image.clone(), image.clone());
            up.pixels[i][c] += h;
            down.pixels[i][c] -= h;
            let step = (up.pixels[i][c] - down.pixels[i][c]) as f64;
            let fd = (f(&up) - f(&down)) / step;
            assert!((fd - g).abs() <= tolerance * scale, "pixel {i} channel {c}: analytic {g} vs fd {fd}");
        }
    }
}

#[test]
fn l1_gradient_matches_finite_differences() {
    let a = random_image(8, 6, 1);
    let mut rand = noise(2);
    // Every target differs from the render by at least 0.05, so no entry is within h of a kink.
    let b = Image::from_fn(8, 6, |x, y| a.get(x, y).map(|v| v + if rand() < 0.5 { -0.05 } else { 0.05 } * (1.0 + rand())));
    let (_, grad) = l1(&a, &b).unwrap();
    // L1 is linear between kinks: exact up to rounding.
    check_image_gradient(&a, &grad, 1e-6, |x| l1(x, &b).unwrap().0);
}

#[test]
fn ssim_gradient_matches_finite_differences() {
    let (a, b) = (random_image(12, 10, 3), random_image(12, 10, 4));
    let (_, grad) = ssim_box(&a, &b, 5).unwrap();
    // Smooth in the inputs: central differences (h = 1e-3) leave ~1e-6 of the largest entry.
    check_image_gradient(&a, &grad, 1e-4, |x| ssim_box(x, &b, 5).unwrap().0);
}

#[test]
fn hierarchical_ssim_gradient_matches_finite_differences() {
    let (a, b) = (random_image(12, 10, 5), random_image(12, 10, 6));
    let windows = [3, 5, 9];
    let (_, grad) = hierarchical_ssim(&a, &b, &windows).unwrap();
    check_image_gradient(&a, &grad, 1e-4, |x| hierarchical_ssim(x, &b, &windows).unwrap().0);
}

#[test]
fn ssim_of_identical_images_is_one_and_stationary() {
    let a = random_image(16, 12, 7);
    let (value, grad) = ssim_box(&a, &a, 7).unwrap();
    assert!((value - 1.0).abs() < 1e-12, "SSIM {value}");
    // A maximum: the gradient vanishes up to f64 rounding of the moments.
    assert!(grad.iter().flatten().all(|g| g.abs() < 1e-9), "gradient not zero at the maximum");
}

#[test]
fn ssim_window_larger_than_the_image_is_an_error() {
    let a = random_image(6, 6, 8);
    assert!(ssim_box(&a, &a, 7).is_err());
    assert!(ssim_box(&a, &a, 4).is_err());
}

#[test]
fn smoothness_gradient_matches_finite_differences() {
    let guide = random_image(9, 8, 9);
    let mut rand = noise(10);
    let disparity: Vec<f32> = (0..72).map(|_| rand()).collect();
    let (_, grad) = edge_aware_smoothness(&disparity, &guide, 3, 2.0).unwrap();
    let scale = grad.iter().fold(0.0f64, |m, g| m.max(g.abs()));
    for i in 0..disparity.len() {
        let (mut up, mut down) = (disparity.clone(), disparity.clone());
        up[i] += 1e-4;
        down[i] -= 1e-4;
        let step = (up[i] - down[i]) as f64;
        let fd = (edge_aware_smoothness(&up, &guide, 3, 2.0).unwrap().0 - edge_aware_smoothness(&down, &guide, 3, 2.0).unwrap().0) / step;
        // Piecewise linear, random values are far (> h) from every kink: exact up to rounding.
        assert!((fd - grad[i]).abs() <= 1e-6 * scale, "pixel {i}: analytic {} vs fd {fd}", grad[i]);
    }
}

#[test]
fn depth_steps_cost_less_across_image_edges() {
    // A disparity step of 1 between columns 3 and 4, once where the guide is flat and once
    // where it has a full-contrast edge at the same place.
    let disparity: Vec<f32> = (0..64).map(|i| if i % 8 < 4 { 0.0 } else { 1.0 }).collect();
    let flat = Image::filled(8, 8, [0.5, 0.5, 0.5, 1.0]);
    let edge = Image::from_fn(8, 8, |x, _| if x < 4 { [0.0; 4] } else { [1.0; 4] });
    let (on_flat, _) = edge_aware_smoothness(&disparity, &flat, 1, 1.0).unwrap();
    let (on_edge, _) = edge_aware_smoothness(&disparity, &edge, 1, 1.0).unwrap();
    // 8 step pairs over 64 pixels; the edge weighs them by exp(-1).
    assert!((on_flat - 8.0 / 64.0).abs() < 1e-12, "{on_flat}");
    assert!((on_edge - on_flat * (-1.0f64).exp()).abs() < 1e-12, "{on_edge}");
    let (constant, grad) = edge_aware_smoothness(&[0.3; 64], &flat, 3, 1.0).unwrap();
    assert!(constant == 0.0 && grad.iter().all(|&g| g == 0.0));
}

#[test]
fn depth_loss_image_gradient_matches_finite_differences() {
    let (a, b) = (random_image(12, 12, 11), random_image(12, 12, 12));
    let layer = Layer { name: "l".into(), rgba: random_image(12, 12, 13), disparity: vec![0.5; 144] };
    let stack = LayerStack::new(12, 12, vec![layer]).unwrap();
    let weights = LossWeights { ssim_windows: vec![3, 7, 31], ..LossWeights::default() };
    let loss = depth_loss(&a, &b, &stack, &weights, 0.5).unwrap();
    let expected = weights.l1 * loss.terms[0] + weights.smoothness * loss.terms[1] + weights.hssim * loss.terms[2];
    assert!((loss.value - expected).abs() < 1e-12);
    // The 31 window does not fit a 12x12 image and is left out rather than failing.
    check_image_gradient(&a, &loss.grad_image, 1e-4, |x| depth_loss(x, &b, &stack, &weights, 0.5).unwrap().value);
}
