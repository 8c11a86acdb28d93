//! The depth-from-defocus experiment (the paper's Tables 2-3, on our ray-traced scenes where
//! the true depth is known): for each built-in scene, keep the true layers' colour and alpha,
//! flatten their disparity to one value (the alpha-weighted mean), fit it back with a given
//! renderer against the ray-traced defocused image, and score depth and re-render before and
//! after. Any [`Differentiable`] renderer plugs in, so renderers compare on equal terms.
use std::time::Instant;

use super::depth_error::{coc_error, depth_error, visible_mean_disparity, DepthError};
use super::fit::{fit_depth, FitOptions};
use crate::camera::Aperture;
use crate::metrics::compare;
use crate::raytrace::{builtin_scene, builtin_scenes, render_ground_truth, GroundTruth, TraceOptions};
use crate::render::grad::Differentiable;
use crate::render::Lens;
use crate::stack::LayerStack;
use crate::Result;

#[derive(Clone, Debug, PartialEq)]
pub struct ExperimentOptions {
    /// Multiplies the scenes' native 256x192 (0.625 gives 160x120; CoC radii scale too).
    pub scale: f32,
    /// Ray-tracer samples per pixel axis for the ground truth.
    pub samples_per_axis: usize,
    pub fit: FitOptions,
}

impl Default for ExperimentOptions {
    /// 160x120 with 8x8 rays per pixel: ground truth clean enough that the fit is not
    /// chasing sampling noise, small enough that a scene fits in about a minute.
    fn default() -> Self {
        Self { scale: 0.625, samples_per_axis: 8, fit: FitOptions::default() }
    }
}

/// One scene's outcome.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SceneResult {
    pub scene: String,
    pub width: usize,
    pub height: usize,
    pub layers: usize,
    /// Disparity error of the flat start and of the fit (visible pixels, see `depth_error`).
    pub depth_before: DepthError,
    pub depth_after: DepthError,
    /// Mean error of the CoC radius in pixels (visible pixels), start and fit: what defocus
    /// observes, blind to which side of the focus plane a layer is on.
    pub coc_px_before: f64,
    pub coc_px_after: f64,
    /// Per layer (front to back), mean disparity over its visible pixels: truth, start, fit.
    pub layer_disparity: Vec<[f64; 3]>,
    /// The focus disparity (where the CoC is 0; depth on either side blurs alike).
    pub focus_disparity: f64,
    /// PSNR (dB, display-encoded) of the renderer's output against the ray-traced image.
    pub psnr_before: f64,
    pub psnr_after: f64,
    pub loss_before: f64,
    pub loss_after: f64,
    /// Wall time of the fit alone (not the ray tracing).
    pub seconds: f64,
}

/// Ray-traces the named built-in scenes (all for none) for the experiment.
pub fn experiment_truths(names: &[String], options: &ExperimentOptions) -> Result<Vec<GroundTruth>> {
    let scenes = if names.is_empty() { builtin_scenes() } else { names.iter().map(|n| builtin_scene(n)).collect::<Result<_>>()? };
    let trace = TraceOptions { samples_per_axis: options.samples_per_axis, scale: options.scale, max_rounds: 1, ..TraceOptions::default() };
    scenes.iter().map(|s| render_ground_truth(s, &trace)).collect()
}

/// The start of the fit: the true layers with every disparity set to the alpha-weighted mean.
pub fn flat_start(stack: &LayerStack) -> LayerStack {
    let (mut sum, mut weight) = (0.0f64, 0.0f64);
    for layer in &stack.layers {
        for (p, &d) in layer.rgba.pixels.iter().zip(&layer.disparity) {
            (sum, weight) = (sum + (p[3] * d) as f64, weight + p[3] as f64);
        }
    }
    let mean = if weight > 0.0 { (sum / weight) as f32 } else { 0.0 };
    let mut flat = stack.clone();
    flat.layers.iter_mut().for_each(|l| l.disparity.fill(mean));
    flat
}

/// Fits one scene's flattened depth back with `renderer`; `progress(iteration, loss)`.
pub fn fit_scene(renderer: &dyn Differentiable, truth: &GroundTruth, fit: &FitOptions, progress: impl FnMut(usize, f64)) -> Result<SceneResult> {
    let lens = Lens { coc: truth.coc, aperture: Aperture::Disk };
    let start = flat_start(&truth.layers);
    let start_render = renderer.forward(&start, &lens)?;
    let timer = Instant::now();
    let result = fit_depth(renderer, &start, &lens, &truth.defocused, fit, progress)?;
    let seconds = timer.elapsed().as_secs_f64();
    let loss_after = result.history.iter().copied().fold(f64::INFINITY, f64::min);
    let means = [&truth.layers, &start, &result.stack].map(|s| visible_mean_disparity(s, &truth.layers));
    let layer_disparity = (0..means[0].len()).map(|l| means.each_ref().map(|m| m[l])).collect();
    Ok(SceneResult {
        scene: truth.name.clone(),
        width: truth.layers.width,
        height: truth.layers.height,
        layers: truth.layers.layers.len(),
        depth_before: depth_error(&start, &truth.layers)?,
        depth_after: depth_error(&result.stack, &truth.layers)?,
        coc_px_before: coc_error(&start, &lens.coc, &truth.layers, &truth.coc)?,
        coc_px_after: coc_error(&result.stack, &result.lens.coc, &truth.layers, &truth.coc)?,
        layer_disparity,
        focus_disparity: result.lens.coc.focus_disparity as f64,
        psnr_before: compare(&start_render, &truth.defocused)?.psnr,
        psnr_after: compare(&result.render, &truth.defocused)?.psnr,
        loss_before: result.history.first().copied().unwrap_or(f64::NAN),
        loss_after,
        seconds,
    })
}

/// Runs [`fit_scene`] on every truth; `progress(scene, iteration, loss)`.
pub fn run_experiment(renderer: &dyn Differentiable, truths: &[GroundTruth], fit: &FitOptions, mut progress: impl FnMut(&str, usize, f64)) -> Result<Vec<SceneResult>> {
    truths.iter().map(|t| fit_scene(renderer, t, fit, |i, loss| progress(&t.name, i, loss))).collect()
}

/// A plain-text table of the results, one scene per row.
pub fn format_results(results: &[SceneResult]) -> String {
    let mut out = format!(
        "{:<15} {:>7} {:>2} | {:>15} {:>15} {:>11} | {:>13} | {:>6} | per-layer disparity truth/start/fit (focus)\n",
        "scene", "size", "L", "|dd| before>after", "si before>after", "CoC px", "PSNR before>after", "time s"
    );
    for r in results {
        out += &format!(
            "{:<15} {:>7} {:>2} | {:>7.4}>{:<7.4} {:>7.4}>{:<7.4} {:>5.2}>{:<5.2} | {:>6.2}>{:<6.2} | {:>6.1} | {} ({:.3})\n",
            r.scene,
            format!("{}x{}", r.width, r.height),
            r.layers,
            r.depth_before.mean_abs,
            r.depth_after.mean_abs,
            r.depth_before.scale_invariant,
            r.depth_after.scale_invariant,
            r.coc_px_before,
            r.coc_px_after,
            r.psnr_before,
            r.psnr_after,
            r.seconds,
            r.layer_disparity.iter().map(|[t, s, f]| format!("{t:.3}/{s:.3}/{f:.3}")).collect::<Vec<_>>().join(" "),
            r.focus_disparity
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::gausspsf::GaussPsf;

    #[test]
    fn gausspsf_fit_improves_blur_and_rerender_on_a_ray_traced_scene() {
        // portrait-night at 64x48 (CoC up to ~3 px), 4x4 rays: a few seconds in the dev profile.
        let options = ExperimentOptions { scale: 0.25, samples_per_axis: 4, fit: FitOptions { iterations: 40, ..FitOptions::default() } };
        let truths = experiment_truths(&["portrait-night".to_string()], &options).unwrap();
        let results = run_experiment(&GaussPsf::default(), &truths, &options.fit, |_, _, _| {}).unwrap();
        let r = &results[0];
        eprintln!("{}", format_results(&results));
        assert_eq!((r.width, r.height, r.layers), (64, 48, 2));
        assert!(r.loss_after < r.loss_before, "loss {} -> {}", r.loss_before, r.loss_after);
        assert!(r.psnr_after > r.psnr_before, "PSNR {} -> {}", r.psnr_before, r.psnr_after);
        // What defocus observes must improve; disparity itself need not (GaussPSF cannot tell
        // front from behind focus, and carves HDR bokeh discs out of per-pixel depth).
        assert!(r.coc_px_after < r.coc_px_before, "CoC error {} -> {}", r.coc_px_before, r.coc_px_after);
    }

    #[test]
    fn flat_start_keeps_colour_and_sets_one_disparity() {
        let truths = experiment_truths(&["small-coc".to_string()], &ExperimentOptions { scale: 0.125, samples_per_axis: 1, ..ExperimentOptions::default() }).unwrap();
        let (truth, flat) = (&truths[0].layers, flat_start(&truths[0].layers));
        let first = flat.layers[0].disparity[0];
        let (lo, hi) = truth.disparity_range();
        assert!(lo < first && first < hi, "{first} outside {lo}..{hi}");
        for (t, f) in truth.layers.iter().zip(&flat.layers) {
            assert_eq!(t.rgba, f.rgba);
            assert!(f.disparity.iter().all(|&d| d == first));
        }
    }

    #[test]
    fn unknown_scene_is_an_error() {
        assert!(experiment_truths(&["no-such-scene".to_string()], &ExperimentOptions::default()).is_err());
    }
}
