//! Gradients in the shape of a layer stack: dL/d(premultiplied RGBA) and dL/d(disparity) per
//! pixel of every layer, plus the CoC model's two scalars; and the chain rule from a disparity
//! gradient to one w.r.t. the depth channel as stored in a file. Every backward pass returns
//! these (`render::grad` re-exports them); readers of files and arrays map them back onto
//! their channels, which is why they live with the stack and not with the renderers.
use super::fill::push_pull_adjoint;
use super::{DepthKind, Layer};
use crate::{Error, Result};

/// dL/d(input) of one layer.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LayerGradients {
    /// dL/d(premultiplied R, G, B, A) per pixel.
    pub rgba: Vec<[f32; 4]>,
    /// dL/d(disparity) per pixel.
    pub disparity: Vec<f32>,
}

/// dL/d(everything a render depends on), for one loss.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StackGradients {
    /// Same order as the stack's layers (front to back).
    pub layers: Vec<LayerGradients>,
    /// dL/dK (pixels of CoC per unit disparity).
    pub k_px: f64,
    /// dL/d(focus disparity).
    pub focus_disparity: f64,
}

/// dL/d(stored depth) of one layer read from a file with depth convention `kind`, from
/// dL/d(disparity) `grad`. `weights` are the reader's per-pixel depth weights: where it did
/// not read the stored depth (weight 0: no coverage) the layer's disparity was filled from the
/// covered pixels, so the gradient that reached it flows back through the fill onto them; then
/// dL/d(stored) = dL/d(disparity) * d(disparity)/d(stored) on the covered pixels, 0 elsewhere.
pub fn stored_depth_gradient(kind: DepthKind, layer: &Layer, weights: &[f32], grad: &[f32]) -> Result<Vec<f32>> {
    let (w, h) = (layer.rgba.width, layer.rgba.height);
    if weights.len() != w * h || grad.len() != w * h {
        return Err(Error::Unsupported(format!(
            "layer '{}': {} depth weights and {} gradients for {w}x{h} pixels",
            layer.name,
            weights.len(),
            grad.len()
        )));
    }
    let through_fill = push_pull_adjoint(w, h, weights, grad);
    let chain = |((&g, &d), &weight): ((&f32, &f32), &f32)| {
        if weight > 0.0 {
            g * kind.disparity_derivative(kind.from_disparity(d))
        } else {
            0.0
        }
    };
    Ok(through_fill.iter().zip(&layer.disparity).zip(weights).map(chain).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::Image;

    /// Planar Z: d(disparity)/dZ = -1/Z^2 on covered pixels; uncovered pixels pass their
    /// gradient through the fill's adjoint onto covered ones, so the total is kept there.
    #[test]
    fn stored_depth_gradient_applies_the_convention_and_routes_uncovered_pixels_through_the_fill() {
        let (w, h) = (4, 1);
        let z = [2.0f32, 4.0, 5.0, 8.0];
        let layer = Layer { name: "l".into(), rgba: Image::new(w, h), disparity: z.iter().map(|z| 1.0 / z).collect() };
        let all = stored_depth_gradient(DepthKind::Z, &layer, &[1.0; 4], &[1.0; 4]).unwrap();
        for (g, z) in all.iter().zip(z) {
            assert!((g + 1.0 / (z * z)).abs() < 1e-6, "{g} at Z {z}");
        }
        let weights = [1.0, 1.0, 0.0, 1.0];
        let grad = [0.0, 0.0, 1.0, 0.0];
        let routed = stored_depth_gradient(DepthKind::Disparity, &layer, &weights, &grad).unwrap();
        assert_eq!(routed[2], 0.0, "the uncovered pixel keeps none");
        let total: f32 = routed.iter().sum();
        assert!((total - 1.0).abs() < 1e-5, "the fill's adjoint keeps the gradient's sum: {total}");
        assert!(stored_depth_gradient(DepthKind::Z, &layer, &[1.0; 3], &[1.0; 4]).is_err());
    }
}
