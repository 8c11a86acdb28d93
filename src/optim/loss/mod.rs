//! The depth-from-defocus loss of the Dr.Bokeh paper (Eq. 13):
//! `l1 * L1(render, target) + smoothness * G(disparity) + hssim * HSSIM(render, target)`,
//! each term with its analytic gradient (w.r.t. the render, or for `G` the disparity maps).
//! Image terms use the RGB channels of linear premultiplied images; values and gradients are
//! f64 so finite differences can check them.
mod smoothness;
mod ssim;
#[cfg(test)]
pub(crate) mod tests;

pub use smoothness::edge_aware_smoothness;
pub use ssim::{hierarchical_ssim, ssim_box};

use crate::image::Image;
use crate::stack::LayerStack;
use crate::{Error, Result};

/// dL/d(image) per pixel, premultiplied RGBA (alpha entries are 0 for RGB-only terms).
pub type Gradient = Vec<[f64; 4]>;

pub(crate) fn check_sizes(rendered: &Image, target: &Image) -> Result<()> {
    if (rendered.width, rendered.height) != (target.width, target.height) {
        return Err(Error::data(format!(
            "render is {}x{} but the target is {}x{}",
            rendered.width, rendered.height, target.width, target.height
        )));
    }
    Ok(())
}

/// Mean absolute RGB difference and its (sub)gradient (0 where the two agree exactly).
pub fn l1(rendered: &Image, target: &Image) -> Result<(f64, Gradient)> {
    check_sizes(rendered, target)?;
    let scale = 1.0 / (3 * rendered.pixels.len()) as f64;
    let mut value = 0.0;
    let grad = rendered
        .pixels
        .iter()
        .zip(&target.pixels)
        .map(|(r, t)| {
            let mut g = [0.0; 4];
            for c in 0..3 {
                let diff = r[c] as f64 - t[c] as f64;
                value += scale * diff.abs();
                g[c] = if diff == 0.0 { 0.0 } else { scale * diff.signum() };
            }
            g
        })
        .collect();
    Ok((value, grad))
}

/// The coefficients and settings of Eq. 13.
#[derive(Clone, Debug, PartialEq)]
pub struct LossWeights {
    pub l1: f64,
    /// Weight of the edge-aware smoothness (of disparity in units of `disparity_unit`, see
    /// [`depth_loss`]), summed over the layers.
    pub smoothness: f64,
    pub hssim: f64,
    /// HSSIM window sizes (odd); those larger than the image are left out.
    pub ssim_windows: Vec<usize>,
    /// Pyramid levels of the smoothness term.
    pub pyramid_levels: usize,
    /// `a` in `exp(-a |dI|)`.
    pub edge_sharpness: f64,
}

impl Default for LossWeights {
    /// Windows from the default SSIM size 11 down to 5 and up to 31 cover the CoC radii of
    /// the built-in scenes at benchmark scale; the smoothness weight is small because
    /// disparity differences are not in colour units (tuned on the built-in scenes).
    fn default() -> Self {
        Self { l1: 1.0, smoothness: 0.01, hssim: 1.0, ssim_windows: vec![5, 11, 21, 31], pyramid_levels: 3, edge_sharpness: 1.0 }
    }
}

/// Eq. 13 evaluated at one render.
#[derive(Clone, Debug, PartialEq)]
pub struct DepthLoss {
    pub value: f64,
    /// Unweighted terms: L1, smoothness (summed over layers), HSSIM.
    pub terms: [f64; 3],
    /// dL/d(render).
    pub grad_image: Gradient,
    /// dL/d(disparity) per layer from the smoothness term alone (the render's share comes
    /// from the renderer's backward pass).
    pub grad_disparity: Vec<Vec<f64>>,
}

/// Eq. 13 for `rendered` (the render of `stack`) against `target`. The smoothness term sees
/// disparity divided by `disparity_unit` (the fit passes the scene's mean disparity, as
/// Monodepth's mean-normalised smoothness does), so its weight means the same in any units.
pub fn depth_loss(rendered: &Image, target: &Image, stack: &LayerStack, weights: &LossWeights, disparity_unit: f64) -> Result<DepthLoss> {
    if !(disparity_unit.is_finite() && disparity_unit > 0.0) {
        return Err(Error::invalid("disparity unit", format!("disparity unit must be positive, got {disparity_unit}")));
    }
    let (l1_value, l1_grad) = l1(rendered, target)?;
    let windows: Vec<usize> = weights.ssim_windows.iter().copied().filter(|&w| w <= rendered.width.min(rendered.height)).collect();
    let (hssim_value, hssim_grad) = if weights.hssim == 0.0 { (0.0, vec![[0.0; 4]; rendered.pixels.len()]) } else { hierarchical_ssim(rendered, target, &windows)? };
    let grad_image = l1_grad.iter().zip(&hssim_grad).map(|(a, b)| std::array::from_fn(|c| weights.l1 * a[c] + weights.hssim * b[c])).collect();
    let (mut smooth_value, mut grad_disparity) = (0.0, Vec::with_capacity(stack.layers.len()));
    for layer in &stack.layers {
        let (v, g) = edge_aware_smoothness(&layer.disparity, &layer.rgba, weights.pyramid_levels, weights.edge_sharpness)?;
        smooth_value += v / disparity_unit;
        grad_disparity.push(g.into_iter().map(|g| weights.smoothness * g / disparity_unit).collect());
    }
    let terms = [l1_value, smooth_value, hssim_value];
    let value = weights.l1 * terms[0] + weights.smoothness * terms[1] + weights.hssim * terms[2];
    Ok(DepthLoss { value, terms, grad_image, grad_disparity })
}

/// A gradient as an image, the form `Differentiable::backward` takes.
pub fn gradient_image(grad: &Gradient, width: usize, height: usize) -> Image {
    Image { width, height, pixels: grad.iter().map(|g| g.map(|v| v as f32)).collect() }
}
