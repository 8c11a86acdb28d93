//! How far fitted disparity is from the truth, over the pixels where a layer is what the
//! all-in-focus image shows: its visible coverage `alpha_l * prod_{k<l} (1 - alpha_k)` exceeds
//! 0.5. Disparity under transparent or hidden pixels barely reaches the defocused image, so
//! it is left out (as a depth map of the photograph would leave it out).
use crate::camera::CocModel;
use crate::stack::LayerStack;
use crate::{Error, Result};

/// Errors in disparity units, pooled over the covered pixels of every layer.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DepthError {
    /// Mean |fitted - true|.
    pub mean_abs: f64,
    /// Mean |s * fitted - true| with the least-squares scale `s`: how wrong the *shape* of
    /// the depth is, forgiving a global scale (the paper's metrics forgive gamma the same way).
    pub scale_invariant: f64,
    /// Pixels counted.
    pub pixels: usize,
}

/// Visible-coverage mask per layer of `truth` (front to back), as [`depth_error`] uses it.
fn visible(truth: &LayerStack) -> Vec<Vec<bool>> {
    let mut transmittance = vec![1.0f32; truth.width * truth.height];
    truth
        .layers
        .iter()
        .map(|t| {
            transmittance
                .iter_mut()
                .zip(&t.rgba.pixels)
                .map(|(tr, p)| {
                    let shown = p[3] * *tr > 0.5;
                    *tr *= 1.0 - p[3].clamp(0.0, 1.0);
                    shown
                })
                .collect()
        })
        .collect()
}

/// Mean disparity of `stack` over each layer's visible pixels in `truth` (NaN where none):
/// where each layer ended up, to read beside the truth's own means.
pub fn visible_mean_disparity(stack: &LayerStack, truth: &LayerStack) -> Vec<f64> {
    stack
        .layers
        .iter()
        .zip(visible(truth))
        .map(|(l, mask)| {
            let (sum, n) = l.disparity.iter().zip(&mask).filter(|(_, &m)| m).fold((0.0, 0usize), |(s, n), (&d, _)| (s + d as f64, n + 1));
            sum / n as f64
        })
        .collect()
}

/// Compares two stacks with the same layers (front to back); coverage comes from `truth`.
pub fn depth_error(fitted: &LayerStack, truth: &LayerStack) -> Result<DepthError> {
    if fitted.layers.len() != truth.layers.len() || (fitted.width, fitted.height) != (truth.width, truth.height) {
        return Err(Error::data("depth error needs two stacks with the same layers and size"));
    }
    let mut pairs: Vec<(f64, f64)> = Vec::new();
    for ((f, t), mask) in fitted.layers.iter().zip(&truth.layers).zip(visible(truth)) {
        let shown = f.disparity.iter().zip(&t.disparity).zip(mask).filter(|(_, m)| *m);
        pairs.extend(shown.map(|((&a, &b), _)| (a as f64, b as f64)));
    }
    if pairs.is_empty() {
        return Err(Error::data("depth error: no layer pixel is more than half visible"));
    }
    let (dot, norm) = pairs.iter().fold((0.0, 0.0), |(d, n), (a, b)| (d + a * b, n + a * a));
    let scale = if norm > 0.0 { dot / norm } else { 1.0 };
    let count = pairs.len() as f64;
    Ok(DepthError {
        mean_abs: pairs.iter().map(|(a, b)| (a - b).abs()).sum::<f64>() / count,
        scale_invariant: pairs.iter().map(|(a, b)| (scale * a - b).abs()).sum::<f64>() / count,
        pixels: pairs.len(),
    })
}

/// Mean `| |r_fit| - |r_true| |` in pixels over the visible pixels: the error in what defocus
/// actually observes. A layer fitted to the wrong side of the focus plane with the right
/// blur scores well here and badly in [`depth_error`].
pub fn coc_error(fitted: &LayerStack, fitted_coc: &CocModel, truth: &LayerStack, true_coc: &CocModel) -> Result<f64> {
    if fitted.layers.len() != truth.layers.len() || (fitted.width, fitted.height) != (truth.width, truth.height) {
        return Err(Error::data("CoC error needs two stacks with the same layers and size"));
    }
    let (mut sum, mut count) = (0.0f64, 0usize);
    for ((f, t), mask) in fitted.layers.iter().zip(&truth.layers).zip(visible(truth)) {
        for ((&a, &b), _) in f.disparity.iter().zip(&t.disparity).zip(mask).filter(|(_, m)| *m) {
            sum += (fitted_coc.radius(a) - true_coc.radius(b)).abs() as f64;
            count += 1;
        }
    }
    if count == 0 {
        return Err(Error::data("CoC error: no layer pixel is more than half visible"));
    }
    Ok(sum / count as f64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::Image;
    use crate::stack::Layer;

    fn stack(front: f32, back: f32) -> LayerStack {
        // The front layer covers the left half; the back layer is opaque everywhere.
        let front = Layer { name: "f".into(), rgba: Image::from_fn(4, 2, |x, _| if x < 2 { [1.0; 4] } else { [0.0; 4] }), disparity: vec![front; 8] };
        let back = Layer { name: "b".into(), rgba: Image::filled(4, 2, [1.0; 4]), disparity: vec![back; 8] };
        LayerStack { width: 4, height: 2, layers: vec![front, back] }
    }

    #[test]
    fn only_visible_pixels_count() {
        // Truth: front 1.0 over the left half, back 0.2 seen on the right half.
        let truth = stack(1.0, 0.2);
        // Moving the hidden half of the back layer costs nothing; the visible half does.
        let mut fitted = truth.clone();
        for i in [0, 1, 4, 5] {
            fitted.layers[1].disparity[i] = 5.0;
        }
        assert_eq!(depth_error(&fitted, &truth).unwrap().mean_abs, 0.0);
        let e = depth_error(&stack(1.0, 0.4), &truth).unwrap();
        assert_eq!(e.pixels, 8);
        assert!((e.mean_abs - 0.1).abs() < 1e-6, "{e:?}"); // 0.2 error on half the pixels
        assert_eq!(visible_mean_disparity(&truth, &truth), vec![1.0, 0.2f32 as f64]);
    }

    #[test]
    fn scale_invariant_error_forgives_a_global_scale() {
        let truth = stack(1.0, 0.2);
        let e = depth_error(&stack(2.0, 0.4), &truth).unwrap();
        assert!(e.mean_abs > 0.5 && e.scale_invariant < 1e-6, "{e:?}");
    }

    #[test]
    fn coc_error_cannot_tell_front_from_behind_focus() {
        // With focus at 0.6, disparity 0.2 and 1.0 blur alike: the mirror image scores 0.
        let coc = CocModel { k_px: 10.0, focus_disparity: 0.6 };
        let truth = stack(1.0, 0.2);
        assert!(coc_error(&stack(0.2, 1.0), &coc, &truth, &coc).unwrap() < 1e-5);
        assert!(depth_error(&stack(0.2, 1.0), &truth).unwrap().mean_abs > 0.7);
    }
}
