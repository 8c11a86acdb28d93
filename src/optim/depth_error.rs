//! How far fitted disparity is from the truth, over the pixels where a layer is what the
//! all-in-focus image shows: its visible coverage `alpha_l * prod_{k<l} (1 - alpha_k)` exceeds
//! 0.5. Disparity under transparent or hidden pixels barely reaches the defocused image, so
//! it is left out (as a depth map of the photograph would leave it out).
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

/// Compares two stacks with the same layers (front to back); coverage comes from `truth`.
pub fn depth_error(fitted: &LayerStack, truth: &LayerStack) -> Result<DepthError> {
    if fitted.layers.len() != truth.layers.len() || (fitted.width, fitted.height) != (truth.width, truth.height) {
        return Err(Error::param("depth error needs two stacks with the same layers and size"));
    }
    let mut transmittance = vec![1.0f32; truth.width * truth.height];
    let mut pairs: Vec<(f64, f64)> = Vec::new();
    for (f, t) in fitted.layers.iter().zip(&truth.layers) {
        for (i, tr) in transmittance.iter_mut().enumerate() {
            let alpha = t.rgba.pixels[i][3];
            if alpha * *tr > 0.5 {
                pairs.push((f.disparity[i] as f64, t.disparity[i] as f64));
            }
            *tr *= 1.0 - alpha.clamp(0.0, 1.0);
        }
    }
    if pairs.is_empty() {
        return Err(Error::param("depth error: no layer pixel is more than half visible"));
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
