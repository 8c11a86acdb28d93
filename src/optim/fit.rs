//! Direct depth-from-defocus optimisation (the paper's "direct optimization over an
//! all-in-focus image and a bokeh image pair", Sec. 5.3): the layers' colour and alpha are
//! known; their disparity maps (and optionally the focus disparity) are fitted so that the
//! renderer's output matches a defocused target under Eq. 13.
//!
//! Parameterisation: `d = s * softplus(theta)` per pixel, so disparity stays positive (0 is
//! infinitely far) without clamping, and `focus = s * phi`; `s` is the stack's mean
//! disparity at the start, so Adam's step (in `theta` units) is relative to the scene's
//! depth scale whatever units the disparity is in. The iterate with the lowest loss is
//! returned (Adam does not decrease the loss monotonically).
use super::adam::Adam;
use super::loss::{depth_loss, gradient_image, LossWeights};
use crate::image::Image;
use crate::render::grad::Differentiable;
use crate::render::Lens;
use crate::stack::naming::glob_match;
use crate::stack::LayerStack;
use crate::{Error, Result};

#[derive(Clone, Debug, PartialEq)]
pub struct FitOptions {
    pub iterations: usize,
    /// Adam's step in `theta` units (relative to the disparity scale, see module docs).
    pub learning_rate: f64,
    /// Also fit the focus disparity (K is always kept).
    pub fit_focus: bool,
    /// Names or globs of layers whose disparity is held fixed (known depth, which is what
    /// makes the focus identifiable); each must match a layer.
    pub fixed_layers: Vec<String>,
    pub weights: LossWeights,
}

impl Default for FitOptions {
    /// 0.1 lets a layer's disparity grow or shrink by e^2 within ~20 steps and settle within
    /// 200 on the built-in scenes (0.05 was too slow to reach far layers, 0.2 no better).
    fn default() -> Self {
        Self {
            iterations: 200,
            learning_rate: 0.1,
            fit_focus: false,
            fixed_layers: Vec::new(),
            weights: LossWeights::default(),
        }
    }
}

#[derive(Clone, Debug)]
pub struct FitResult {
    /// The input stack with the fitted disparity.
    pub stack: LayerStack,
    /// The input lens with the fitted focus (unchanged unless `fit_focus`).
    pub lens: Lens,
    /// The render of the fitted stack.
    pub render: Image,
    /// Loss of every evaluated iterate, the start first (`iterations + 1` entries).
    pub history: Vec<f64>,
}

fn softplus(x: f64) -> f64 {
    x.max(0.0) + (-x.abs()).exp().ln_1p()
}

fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

/// `softplus^-1(v)` for `v > 0`, stable for small and large `v`.
fn inverse_softplus(v: f64) -> f64 {
    let v = v.max(1e-9);
    v + (-(-v).exp_m1()).ln()
}

/// The disparity scale `s`: mean disparity, else the focus disparity, else 1.
fn disparity_scale(stack: &LayerStack, lens: &Lens) -> f64 {
    let count = stack.layers.iter().map(|l| l.disparity.len()).sum::<usize>().max(1);
    let mean = stack.layers.iter().flat_map(|l| l.disparity.iter()).map(|&d| d.abs() as f64).sum::<f64>() / count as f64;
    [mean, (lens.coc.focus_disparity as f64).abs(), 1.0].into_iter().find(|&s| s > 1e-9).unwrap_or(1.0)
}

/// The parameter vector: the `theta` of every free layer, then `phi` if the focus is fitted.
struct Params {
    scale: f64,
    values: Vec<f64>,
    /// Per layer: its disparity is optimised (else it keeps the input's).
    free: Vec<bool>,
    fit_focus: bool,
}

impl Params {
    fn new(stack: &LayerStack, lens: &Lens, free: Vec<bool>, fit_focus: bool) -> Self {
        let scale = disparity_scale(stack, lens);
        let free_layers = stack.layers.iter().zip(&free).filter(|(_, &free)| free);
        let mut values: Vec<f64> =
            free_layers.flat_map(|(l, _)| l.disparity.iter()).map(|&d| inverse_softplus(d as f64 / scale)).collect();
        if fit_focus {
            values.push(lens.coc.focus_disparity as f64 / scale);
        }
        Self { scale, values, free, fit_focus }
    }

    /// Writes the parameters into a copy of the stack and lens.
    fn apply(&self, stack: &mut LayerStack, lens: &mut Lens) {
        let mut theta = self.values.iter();
        for (layer, _) in stack.layers.iter_mut().zip(&self.free).filter(|(_, &free)| free) {
            for (d, t) in layer.disparity.iter_mut().zip(&mut theta) {
                *d = (self.scale * softplus(*t)) as f32;
            }
        }
        if let (true, Some(phi)) = (self.fit_focus, theta.next()) {
            lens.coc.focus_disparity = (self.scale * phi) as f32;
        }
    }
}

/// Per layer, whether its disparity is fitted: not when a `fixed` pattern matches its name.
fn free_layers(stack: &LayerStack, fixed: &[String]) -> Result<Vec<bool>> {
    for pattern in fixed {
        if !stack.layers.iter().any(|l| glob_match(pattern, &l.name)) {
            let names: Vec<&str> = stack.layers.iter().map(|l| l.name.as_str()).collect();
            return Err(Error::invalid("fixed layers", format!(
                "no layer matches the fixed-layer pattern '{pattern}'; layers: {}",
                names.join(", ")
            )));
        }
    }
    Ok(stack.layers.iter().map(|l| !fixed.iter().any(|p| glob_match(p, &l.name))).collect())
}

/// Fits the disparity of `stack` (and the focus of `lens` if asked) so that `renderer`'s
/// output matches `target`; `progress(iteration, loss)` is called after every evaluation.
pub fn fit_depth(
    renderer: &dyn Differentiable,
    stack: &LayerStack,
    lens: &Lens,
    target: &Image,
    options: &FitOptions,
    mut progress: impl FnMut(usize, f64),
) -> Result<FitResult> {
    if (target.width, target.height) != (stack.width, stack.height) {
        return Err(Error::data(format!("target is {}x{} but the stack is {}x{}", target.width, target.height, stack.width, stack.height)));
    }
    if !(options.learning_rate.is_finite() && options.learning_rate > 0.0) {
        return Err(Error::invalid("learning rate", format!("learning rate must be positive, got {}", options.learning_rate)));
    }
    let free = free_layers(stack, &options.fixed_layers)?;
    if !options.fit_focus && !free.contains(&true) {
        return Err(Error::invalid("fit", "every layer's depth is fixed and the focus is not fitted: nothing to fit"));
    }
    let mut params = Params::new(stack, lens, free, options.fit_focus);
    let mut adam = Adam::new(params.values.len(), options.learning_rate);
    let (mut current, mut current_lens) = (stack.clone(), lens.clone());
    let mut history = Vec::with_capacity(options.iterations + 1);
    let mut best: Option<(f64, LayerStack, Lens, Image)> = None;
    for iteration in 0..=options.iterations {
        params.apply(&mut current, &mut current_lens);
        let render = renderer.forward(&current, &current_lens)?;
        let loss = depth_loss(&render, target, &current, &options.weights, params.scale)?;
        history.push(loss.value);
        progress(iteration, loss.value);
        if best.as_ref().map_or(true, |b| loss.value < b.0) {
            best = Some((loss.value, current.clone(), current_lens.clone(), render));
        }
        if iteration == options.iterations {
            break;
        }
        let grads = renderer.backward(&current, &current_lens, &gradient_image(&loss.grad_image, stack.width, stack.height))?;
        let g = parameter_gradient(&params, &grads, &loss.grad_disparity)?;
        adam.step(&mut params.values, &g)?;
    }
    let (_, stack, lens, render) = best.ok_or_else(|| Error::internal("no iterate was evaluated"))?;
    Ok(FitResult { stack, lens, render, history })
}

/// Chain rule from dL/d(disparity) (render + smoothness) and dL/d(focus) to the parameters.
fn parameter_gradient(params: &Params, grads: &crate::render::grad::StackGradients, smooth: &[Vec<f64>]) -> Result<Vec<f64>> {
    let mut out = Vec::with_capacity(params.values.len());
    let mut theta = params.values.iter();
    if grads.layers.len() != smooth.len() {
        return Err(Error::internal(format!("renderer returned gradients for {} of {} layers", grads.layers.len(), smooth.len())));
    }
    let free_layers = grads.layers.iter().zip(smooth).zip(&params.free).filter(|(_, &free)| free);
    for ((render, smooth), _) in free_layers {
        if render.disparity.len() != smooth.len() {
            return Err(Error::internal("renderer returned a disparity gradient of the wrong size"));
        }
        for ((&g, &s), &t) in render.disparity.iter().zip(smooth).zip(&mut theta) {
            out.push((g as f64 + s) * params.scale * sigmoid(t));
        }
    }
    if params.fit_focus {
        out.push(grads.focus_disparity * params.scale);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Aperture, CocModel};
    use crate::optim::depth_error::depth_error;
    use crate::optim::loss::tests::noise;
    use crate::render::gausspsf::GaussPsf;
    use crate::stack::Layer;

    /// A textured opaque back layer on a gentle disparity ramp and a textured disc in front.
    fn two_layer_truth(width: usize, height: usize) -> LayerStack {
        let mut rand = noise(21);
        let back = Layer {
            name: "back".into(),
            rgba: Image::from_fn(width, height, |_, _| [rand(), rand(), rand(), 1.0]),
            disparity: (0..width * height).map(|i| 0.2 + 0.1 * (i % width) as f32 / width as f32).collect(),
        };
        let inside = |x: usize, y: usize| (x as f32 - width as f32 / 2.0).hypot(y as f32 - height as f32 / 2.0) < height as f32 / 3.0;
        let front = Layer {
            name: "front".into(),
            rgba: Image::from_fn(width, height, |x, y| if inside(x, y) { [rand(), rand(), rand(), 1.0] } else { [0.0; 4] }),
            disparity: vec![0.8; width * height],
        };
        LayerStack { width, height, layers: vec![front, back] }
    }

    fn flattened(stack: &LayerStack) -> LayerStack {
        let (mut sum, mut weight) = (0.0, 0.0);
        for layer in &stack.layers {
            for (p, d) in layer.rgba.pixels.iter().zip(&layer.disparity) {
                (sum, weight) = (sum + p[3] * d, weight + p[3]);
            }
        }
        let mut flat = stack.clone();
        flat.layers.iter_mut().for_each(|l| l.disparity.iter_mut().for_each(|d| *d = sum / weight));
        flat
    }

    #[test]
    fn fitting_from_flat_depth_recovers_a_two_layer_scene() {
        // Both layers lie in front of the focus (CoC 0.6..1.2 and 4.2 px), so there is no
        // front/behind-focus ambiguity; the target is GaussPSF's own render of the truth.
        let truth = two_layer_truth(40, 30);
        let lens = Lens { coc: CocModel { k_px: 6.0, focus_disparity: 0.1 }, aperture: Aperture::Disk };
        let renderer = GaussPsf::default();
        let target = renderer.forward(&truth, &lens).unwrap();
        let start = flattened(&truth);
        let options = FitOptions { iterations: 120, ..FitOptions::default() };
        let fit = fit_depth(&renderer, &start, &lens, &target, &options, |_, _| {}).unwrap();
        let (before, after) = (depth_error(&start, &truth).unwrap(), depth_error(&fit.stack, &truth).unwrap());
        // The loss must halve and the disparity error fall 5x (measured 0.195 -> 0.028, 6.9x).
        assert!(fit.history.iter().cloned().fold(f64::INFINITY, f64::min) < 0.5 * fit.history[0], "{:?}", fit.history);
        assert!(after.mean_abs * 5.0 < before.mean_abs, "disparity error {} -> {}", before.mean_abs, after.mean_abs);
        eprintln!("disparity error {:.4} -> {:.4}, loss {:.5} -> {:.5}", before.mean_abs, after.mean_abs, fit.history[0], fit.history.last().unwrap());
    }

    #[test]
    fn parameter_gradient_matches_finite_differences() {
        // The whole chain: softplus and scale, renderer backward, loss, smoothness, focus.
        let mut truth = two_layer_truth(12, 10);
        truth.layers[1].disparity.iter_mut().enumerate().for_each(|(i, d)| *d += 0.05 * ((i * 7) % 5) as f32);
        let lens = Lens { coc: CocModel { k_px: 6.0, focus_disparity: 0.1 }, aperture: Aperture::Disk };
        let renderer = GaussPsf::default();
        let target = renderer.forward(&flattened(&truth), &lens).unwrap();
        let weights = LossWeights { ssim_windows: vec![3, 5], smoothness: 0.1, ..LossWeights::default() };
        let params = Params::new(&truth, &lens, vec![true; 2], true);
        let loss_at = |values: &[f64]| {
            let p = Params { values: values.to_vec(), ..Params::new(&truth, &lens, vec![true; 2], true) };
            let (mut s, mut l) = (truth.clone(), lens.clone());
            p.apply(&mut s, &mut l);
            let render = renderer.forward(&s, &l).unwrap();
            (depth_loss(&render, &target, &s, &weights, params.scale).unwrap(), s, l, render)
        };
        let (loss, s, l, _) = loss_at(&params.values);
        let grads = renderer.backward(&s, &l, &gradient_image(&loss.grad_image, 12, 10)).unwrap();
        let analytic = parameter_gradient(&params, &grads, &loss.grad_disparity).unwrap();
        let scale = analytic.iter().fold(0.0f64, |m, g| m.max(g.abs()));
        // Every 7th pixel parameter of both layers, and the focus (the last one).
        for i in (0..params.values.len()).step_by(7).chain([params.values.len() - 1]) {
            let h = 1e-3;
            let (mut up, mut down) = (params.values.clone(), params.values.clone());
            up[i] += h;
            down[i] -= h;
            let fd = (loss_at(&up).0.value - loss_at(&down).0.value) / (2.0 * h);
            // Disparity and the render round to f32 inside the loop and L1/smoothness have
            // kinks near some pixels: measured worst 2e-4 of the largest entry, checked at 1e-3.
            assert!((fd - analytic[i]).abs() <= 1e-3 * scale, "parameter {i}: analytic {} vs fd {fd}", analytic[i]);
        }
    }

    #[test]
    fn a_fixed_layer_pins_the_focus_which_moves_toward_the_truth() {
        // The back layer's depth is known (fixed); the focus starts 0.1 disparity too far
        // forward and the front layer 0.2 too far back. The back layer's sharpness in the
        // target identifies the focus: the fit must remove at least 3/4 of the focus error
        // (measured 0.100 -> 0.0004 on GaussPSF's own target; the bound is loose on purpose).
        let truth = two_layer_truth(40, 30);
        let lens = Lens { coc: CocModel { k_px: 10.0, focus_disparity: 0.25 }, aperture: Aperture::Disk };
        let renderer = GaussPsf::default();
        let target = renderer.forward(&truth, &lens).unwrap();
        let mut start = truth.clone();
        start.layers[0].disparity.iter_mut().for_each(|d| *d -= 0.2);
        let wrong = Lens { coc: CocModel { focus_disparity: 0.35, ..lens.coc }, ..lens.clone() };
        let options = FitOptions { iterations: 80, fit_focus: true, fixed_layers: vec!["ba*".into()], ..FitOptions::default() };
        let fit = fit_depth(&renderer, &start, &wrong, &target, &options, |_, _| {}).unwrap();
        assert_eq!(fit.stack.layers[1].disparity, start.layers[1].disparity, "the fixed layer keeps its depth");
        let (before, after) = (0.1f32, (fit.lens.coc.focus_disparity - 0.25).abs());
        eprintln!("focus error {before:.4} -> {after:.4}, loss {:.5} -> {:.5}", fit.history[0], fit.history.iter().cloned().fold(f64::INFINITY, f64::min));
        assert!(after < 0.25 * before, "focus error {before} -> {after}");

        let unknown = FitOptions { fixed_layers: vec!["nope".into()], ..options };
        let message = fit_depth(&renderer, &start, &wrong, &target, &unknown, |_, _| {}).unwrap_err().to_string();
        assert!(message.contains("'nope'") && message.contains("front, back"), "{message}");
    }

    #[test]
    fn softplus_parameters_round_trip() {
        for v in [1e-6, 0.01, 0.5, 3.0, 40.0] {
            assert!((softplus(inverse_softplus(v)) / v - 1.0).abs() < 1e-9, "{v}");
        }
    }

    #[test]
    fn mismatched_target_is_an_error() {
        let truth = two_layer_truth(8, 6);
        let lens = Lens { coc: CocModel { k_px: 6.0, focus_disparity: 0.1 }, aperture: Aperture::Disk };
        let r = fit_depth(&GaussPsf::default(), &truth, &lens, &Image::new(6, 8), &FitOptions::default(), |_, _| {});
        assert!(r.is_err());
    }
}
