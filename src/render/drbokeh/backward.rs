//! Dr.Bokeh backward pass (paper Sec. 4): options and the per-pair derivative terms shared by
//! the gather passes (the CPU reference and its [`Differentiable`](crate::render::grad::Differentiable)
//! renderer, `DrBokehCpu`, are in `backward_cpu.rs`, which uses this module and not the reverse).
//!
//! Gradients are gathers: every input-gradient element is owned by one loop iteration (one
//! future shader invocation), which sums over the outputs its input influences. No scattered
//! adds, so the GPU version is deterministic. Passes, after the forward's four (CPU:
//! [`backward_cpu`](mod@super::backward_cpu), GPU: `glsl/drbokeh_backward_<pass>.comp`):
//! 1. `composite` (per pixel): dL/dC_l, dL/dW_l, dL/dV_l of every layer from dL/d(output).
//! 2. `own` (per layer, per pixel x, over x's forward window): the terms of x's own outputs
//!    that depend on x's inputs as the *receiver* — alpha_x and s_x in the occlusion O(y, x),
//!    r_x in V_l(x) — and `dL/dV / sum D`, the normalised adjoint of V for pass 4.
//! 3. `tile_reach` (per layer, per tile): the transpose of the tile windows — how far the
//!    receivers whose windows hold a source of the tile can be (on the host for both: the GPU
//!    backward needs it to cut its frame tiles and uploads it).
//! 4. `source` (per layer, per pixel y, over every x whose window holds y): y as a *source* —
//!    premultiplied colour and alpha in C/W, r_y and s_y in the weight, alpha_y in V(x).
//!
//! Non-smooth pieces of the forward are held constant (the gradient is that of the piece the
//! forward is on, exact wherever the forward is differentiable): tile windows and supports
//! (they only ever add or drop terms whose weight is exactly 0), the `alpha > 0` source test
//! (a transparent source contributes nothing and has no colour/alpha gradient through C/W),
//! the compat visibility box (integer half-width: no disparity gradient, as released), the
//! aperture mirror at `rel = 0`, and the kinks of `|s|`, smoothstep edges, area-table nodes,
//! bilinear kernel cells, the compat tail cut and tanh clamp (one-sided values there).
//!
//! Every dependence on K and the focus disparity goes through the pixels' `s = K (d - d_f)` and
//! `rel = d - d_f`, so with `g_s = dL/ds` and `g_rel = dL/drel` (at fixed s) per pixel:
//! `dL/dd = K g_s + g_rel`, `dL/dK = sum rel g_s`, `dL/dd_f = -sum dL/dd`.
use super::{math, LensView, Model, Params, AREA_STEP_PX};
use crate::camera::Aperture;
use crate::image::Image;
use crate::render::Lens;
use crate::stack::LayerStack;
use crate::{Error, Result};

/// What both backward passes (CPU reference and GPU) refuse: an output gradient of another
/// size than the stack, and a vignetted aperture (disk, polygon or ellipse), whose per-tile shape (forward only: the
/// backward's gauge paths take one shape per render) has no adjoint here. `grad` has no
/// `--cats-eye`, so no command reaches it.
pub(crate) fn check_inputs(stack: &LayerStack, lens: &Lens, grad_output: &Image) -> Result<()> {
    if (grad_output.width, grad_output.height) != (stack.width, stack.height) {
        return Err(Error::data(format!(
            "output gradient is {}x{}, the stack {}x{}",
            grad_output.width, grad_output.height, stack.width, stack.height
        )));
    }
    if matches!(lens.aperture, Aperture::Vignetted { .. }) {
        return Err(Error::unsupported("a vignetted aperture (one-pass --cats-eye) has no backward pass"));
    }
    Ok(())
}

/// How the backward differentiates the forward's soft steps.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BackwardOptions {
    /// Smallest slope (per pixel of CoC radius) of the scatter soft step's derivative, for
    /// every pair a window evaluates: `max(S', leaky_slope)`. Monotonic (a positive slope
    /// everywhere) and equal to the exact derivative wherever the step is steeper. 0 = the
    /// exact gradient of the forward.
    pub leaky_slope: f64,
}

impl BackwardOptions {
    /// Leak used by [`BackwardOptions::leaky`]: 1/75 of the rim ramp's peak slope 1.5.
    pub const DEFAULT_LEAKY_SLOPE: f64 = 0.02;

    pub fn exact() -> Self {
        Self { leaky_slope: 0.0 }
    }

    pub fn leaky() -> Self {
        Self { leaky_slope: Self::DEFAULT_LEAKY_SLOPE }
    }

    /// Pixels the search windows grow by: with a leak, pairs just beyond a source's support
    /// (zero forward weight) still carry the leaked slope, so a nearly in-focus layer, whose
    /// windows hold only its own pixel, gets a gradient that grows its CoC. Without this a
    /// fit from a near-focus start never moves.
    pub fn window_margin(&self) -> i32 {
        if self.leaky_slope > 0.0 {
            Self::LEAKY_WINDOW_MARGIN_PX
        } else {
            0
        }
    }

    /// Reach of the leak beyond the supports, in pixels.
    pub const LEAKY_WINDOW_MARGIN_PX: i32 = 2;

    /// The forward windows this backward differentiates.
    pub fn window(&self) -> super::Window {
        match self.window_margin() {
            0 => super::Window::Tiled,
            margin => super::Window::TiledGrown(margin),
        }
    }
}

/// One pixel of one layer as the terms read it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Px {
    pub rel: f64,
    pub s: f64,
    pub r: f64,
    pub alpha: f64,
}

impl Px {
    pub fn new(lens: &LensView, disparity: f32, alpha: f32) -> Self {
        let rel = lens.rel(disparity);
        let s = lens.k_px * rel;
        Self { rel, s, r: s.abs(), alpha: alpha as f64 }
    }

    /// d|s|/ds (0 at exact focus: the subgradient the backward picks there).
    pub fn sign(&self) -> f64 {
        if self.s > 0.0 {
            1.0
        } else if self.s < 0.0 {
            -1.0
        } else {
            0.0
        }
    }
}

/// The weight `w = S K O / A` of source y at receiver x and its partial derivatives.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct PairGrad {
    pub w: f64,
    pub s_y: f64,
    pub rel_y: f64,
    pub s_x: f64,
    pub rel_x: f64,
    pub alpha_x: f64,
}

/// `w` and its partials for the offset `x - y = (dx, dy)`; mirrors the source branch of
/// `layer_pixel` in `cpu.rs` (the forward skips sources with alpha 0: callers too).
pub(crate) fn pair_grad(params: &Params, leak: f64, dx: f64, dy: f64, src: &Px, dst: &Px, is_self: bool) -> PairGrad {
    let (g, k, dk) = params.lens.lens_d(dx, dy, src.r, src.rel);
    let (s, ds, area, d_area, occ) = match params.model {
        Model::DrBokeh => (
            math::scatter(src.r, g),
            math::leaky(math::d_scatter(src.r, g), leak),
            params.area(src.r),
            math::d_area_from_lut(&params.area_lut, AREA_STEP_PX, src.r),
            (math::occlusion(src.s, dst.s, dst.r, dst.alpha, is_self), math::d_occlusion(src.s, dst.s, dst.r, dst.alpha, is_self)),
        ),
        Model::Compat => (
            math::scatter_compat(src.r, g),
            math::leaky(math::d_scatter_compat(src.r, g), leak),
            math::area_compat(src.r),
            math::d_area_compat(src.r),
            (math::occlusion_compat(src.rel, dst.rel, dst.r, is_self), math::d_occlusion_compat(src.rel, dst.rel, dst.r, is_self)),
        ),
    };
    let (o, d_o) = occ;
    let base = s * k / area;
    let d_r_y = ((ds * k + s * dk) - s * k * d_area / area) * o / area;
    let d_receiver = base * d_o.r_x * dst.sign();
    match params.model {
        Model::DrBokeh => PairGrad {
            w: base * o,
            s_y: d_r_y * src.sign() + base * d_o.src,
            rel_y: 0.0,
            s_x: base * d_o.dst + d_receiver,
            rel_x: 0.0,
            alpha_x: base * d_o.alpha_x,
        },
        Model::Compat => PairGrad {
            w: base * o,
            s_y: d_r_y * src.sign(),
            rel_y: base * d_o.src,
            s_x: d_receiver,
            rel_x: base * d_o.dst,
            alpha_x: 0.0,
        },
    }
}

/// Default-model visibility weight `D = F(r_x, g) K` of source y at receiver x (F the
/// receiver's footprint), and dD/dr_x.
pub(crate) fn vis_weight(params: &Params, leak: f64, dx: f64, dy: f64, dst: &Px) -> (f64, f64) {
    let (g, k, dk) = params.lens.lens_d(dx, dy, dst.r, dst.rel);
    let s = math::footprint(dst.r, g);
    (s * k, math::leaky(math::d_footprint(dst.r, g), leak) * k + s * dk)
}

impl LensView {
    /// [`LensView::lens`] plus d(kernel weight)/dr: the kernel is sampled at `p / (r + 1/2)`
    /// and faded in with `kernel_blend(r)`, the ring's obstruction has radius `inner r`; the
    /// gauge does not depend on r.
    pub fn lens_d(&self, dx: f64, dy: f64, r: f64, rel: f64) -> (f64, f64, f64) {
        let (u, v) = math::to_aperture_coords(dx, dy, rel);
        let g = math::gauge(&self.aperture, u, v);
        if self.is_ring() {
            let inner = self.aperture[2];
            return (g, math::ring_weight(g, r, inner), math::d_ring_weight(g, r, inner));
        }
        if self.aperture[3] < 0.5 || self.kernel_size == 0 {
            return (g, 1.0, 0.0);
        }
        let scale = 1.0 / (r + 0.5);
        let (sample, du, dv) = math::kernel_sample_grad(&self.kernel, self.kernel_size, u * scale, v * scale);
        let d_sample = -(du * u + dv * v) * scale * scale;
        let blend = math::kernel_blend(r);
        (g, 1.0 + (sample - 1.0) * blend, d_sample * blend + (sample - 1.0) * math::d_kernel_blend(r))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Aperture, CocModel};
    use crate::image::Image;
    use crate::render::Lens;
    use crate::stack::{Layer, LayerStack};

    fn params(model: Model) -> Params {
        let layer = Layer { name: "l".into(), rgba: Image::new(4, 4), disparity: vec![0.9; 16] };
        let stack = LayerStack::new(4, 4, vec![layer]).unwrap();
        let lens = Lens { coc: CocModel::new(10.0, 0.5).unwrap(), aperture: Aperture::Disk };
        Params::new(&stack, &lens, model).unwrap()
    }

    /// The leak changes a pair's derivative only through dS/dr (the source's radius), and only
    /// where the exact step slope is below the leak: on the saturated sides of the step.
    #[test]
    fn leak_changes_only_saturated_scatter_slopes() {
        let leak = BackwardOptions::DEFAULT_LEAKY_SLOPE;
        for model in [Model::DrBokeh, Model::Compat] {
            let p = params(model);
            let (mut saturated, mut ramp) = (0, 0);
            for i in 0..400 {
                let r = 0.01 + 0.05 * i as f64 % 6.0; // s > 0: |s| has slope 1
                let (dx, dy) = ((i % 9) as f64 - 4.0, (i % 7) as f64 - 3.0);
                let src = Px { rel: 0.3, s: r, r, alpha: 0.8 };
                let dst = Px { rel: 0.01, s: 0.1 + 0.01 * (i % 5) as f64, r: 0.1 + 0.01 * (i % 5) as f64, alpha: 0.6 };
                let (e, l) = (pair_grad(&p, 0.0, dx, dy, &src, &dst, false), pair_grad(&p, leak, dx, dy, &src, &dst, false));
                assert_eq!((e.w, e.rel_y, e.s_x, e.rel_x, e.alpha_x), (l.w, l.rel_y, l.s_x, l.rel_x, l.alpha_x));
                let g = (dx * dx + dy * dy).sqrt();
                let slope = match model {
                    Model::DrBokeh => math::d_scatter(r, g),
                    Model::Compat => math::d_scatter_compat(r, g),
                };
                if slope >= leak {
                    assert_eq!(e.s_y, l.s_y, "{model:?} r={r} g={g}: leak on the ramp");
                    ramp += 1;
                } else {
                    assert_ne!(e.s_y, l.s_y, "{model:?} r={r} g={g}: no leak where saturated");
                    saturated += 1;
                }
            }
            assert!(saturated > 50 && ramp > 50, "{model:?}: {saturated} saturated, {ramp} on the ramp");
        }
    }
}
