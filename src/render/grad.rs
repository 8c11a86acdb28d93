//! The differentiable-renderer interface shared by the backward passes and the optimiser.
//!
//! Gradients are in the stack's own units: premultiplied RGBA and disparity per pixel of every
//! layer, plus the two scalars of the CoC model. Converting a disparity gradient into one w.r.t.
//! the depth channel as stored in a file is the caller's job (`DepthKind::disparity_derivative`).
use crate::image::Image;
use crate::render::Lens;
use crate::stack::LayerStack;
use crate::Result;

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

/// A renderer with a backward pass: `backward` returns the vector-Jacobian product of the
/// render at (`stack`, `lens`) with `grad_output` = dL/d(output premultiplied RGBA).
pub trait Differentiable {
    fn forward(&self, stack: &LayerStack, lens: &Lens) -> Result<Image>;
    fn backward(&self, stack: &LayerStack, lens: &Lens, grad_output: &Image) -> Result<StackGradients>;
}
