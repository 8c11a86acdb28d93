//! The differentiable-renderer interface shared by the backward passes and the optimiser.
//!
//! Gradients are in the stack's own units: premultiplied RGBA and disparity per pixel of every
//! layer, plus the two scalars of the CoC model. Converting a disparity gradient into one w.r.t.
//! the depth channel as stored in a file is [`stored_depth_gradient`]'s job, to the physical camera
//! [`CameraGradients`]'s.
use crate::camera::{CocModel, PhysicalCamera};
use crate::image::Image;
use crate::render::tiler::{RenderOptions, RenderStats};
use crate::render::Lens;
use crate::stack::LayerStack;
// The gradient types are the stack's shape and live with it (the stack module never imports
// a renderer); re-exported here, where every backward pass names them.
pub use crate::stack::gradients::{stored_depth_gradient, LayerGradients, StackGradients};
use crate::Result;

/// A renderer with a backward pass: `backward` returns the vector-Jacobian product of the
/// render at (`stack`, `lens`) with `grad_output` = dL/d(output premultiplied RGBA).
/// `Send + Sync` as [`super::Renderer`]: bindings run it off the calling thread's lock (Python
/// releases its GIL during a backward pass).
pub trait Differentiable: Send + Sync {
    fn forward(&self, stack: &LayerStack, lens: &Lens) -> Result<Image>;
    fn backward(&self, stack: &LayerStack, lens: &Lens, grad_output: &Image) -> Result<StackGradients>;

    /// [`Self::backward`] cut into frame tiles as `options` says (tile side, memory cap,
    /// progress), with what it measured; a renderer that does not tile runs the whole frame.
    fn backward_with(
        &self,
        stack: &LayerStack,
        lens: &Lens,
        grad_output: &Image,
        options: &RenderOptions,
    ) -> Result<(StackGradients, RenderStats)> {
        let _ = options;
        Ok((self.backward(stack, lens, grad_output)?, RenderStats::default()))
    }
}

/// Which gradient a method's backward pass computes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Slope {
    /// The exact gradient of the forward (`lensblur grad`'s default).
    #[default]
    Exact,
    /// The forward's soft steps keep a small slope everywhere, so an optimisation started far
    /// from the answer still sees which way to go (`fit-depth`).
    Leaky,
}

/// dL/d(camera parameter): the CoC model's two, and with a physical camera its own three.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct CameraGradients {
    pub k_px: f64,
    pub focus_disparity: f64,
    pub focus_distance: Option<f64>,
    pub fstop: Option<f64>,
    pub focal_length_mm: Option<f64>,
}

impl CameraGradients {
    /// Chain rule from `grads` (w.r.t. K and the focus disparity of `coc`) to the physical
    /// camera behind it: K = (f / 2N) (f / sensor) width and d_f = 1 / D, so dK/dN = -K/N,
    /// dK/df = 2K/f, dd_f/dD = -1/D^2.
    pub fn new(grads: &StackGradients, coc: &CocModel, physical: Option<&PhysicalCamera>) -> Self {
        let k = coc.k_px as f64;
        Self {
            k_px: grads.k_px,
            focus_disparity: grads.focus_disparity,
            focus_distance: physical.map(|c| -grads.focus_disparity / (c.focus_distance as f64).powi(2)),
            fstop: physical.map(|c| grads.k_px * -k / c.fstop as f64),
            focal_length_mm: physical.map(|c| grads.k_px * 2.0 * k / c.focal_length_mm as f64),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A loss linear in K and d_f (L = a K + b d_f) has dL/dK = a, dL/dd_f = b; the chain
    /// rule's physical gradients must match central differences of L through the camera.
    #[test]
    fn camera_gradients_match_finite_differences_through_the_physical_camera() {
        let (a, b) = (0.37, -2.5);
        let grads = StackGradients { layers: Vec::new(), k_px: a, focus_disparity: b };
        let camera = PhysicalCamera { focal_length_mm: 50.0, sensor_width_mm: 36.0, fstop: 2.8, focus_distance: 3.0 };
        let loss = |c: &PhysicalCamera| {
            let coc = CocModel::from_physical(c, 640).unwrap();
            a * coc.k_px as f64 + b * coc.focus_disparity as f64
        };
        let coc = CocModel::from_physical(&camera, 640).unwrap();
        let got = CameraGradients::new(&grads, &coc, Some(&camera));
        let central = |step: &dyn Fn(f32) -> PhysicalCamera, h: f32| (loss(&step(h)) - loss(&step(-h))) / (2.0 * h as f64);
        let fd_fstop = central(&|h| PhysicalCamera { fstop: camera.fstop + h, ..camera }, 1e-2);
        let fd_focal = central(&|h| PhysicalCamera { focal_length_mm: camera.focal_length_mm + h, ..camera }, 1e-1);
        let fd_focus = central(&|h| PhysicalCamera { focus_distance: camera.focus_distance + h, ..camera }, 1e-2);
        for (name, analytic, numeric) in [
            ("fstop", got.fstop.unwrap(), fd_fstop),
            ("focal length", got.focal_length_mm.unwrap(), fd_focal),
            ("focus distance", got.focus_distance.unwrap(), fd_focus),
        ] {
            // f32 camera maths: 1e-3 relative.
            assert!((analytic - numeric).abs() <= 1e-3 * numeric.abs().max(1e-6), "{name}: {analytic} vs {numeric}");
        }
        assert_eq!(CameraGradients::new(&grads, &coc, None).fstop, None);
    }

}
