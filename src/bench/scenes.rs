//! Where the benchmark's scenes come from: the built-in scenes, ray-traced to ground truth.
//! The one place the benchmark calls the ray tracer.
use indicatif::ProgressBar;

use crate::raytrace::{builtin_scenes, render_ground_truth, GroundTruth, TraceOptions};
use crate::{Error, Result};

/// `--quick`: half the native resolution (CoC radii halve too) and 4x4 rays per pixel,
/// enough to rank methods in a minute; the full run uses the ray tracer's defaults.
fn trace_options(quick: bool, progress: Option<ProgressBar>) -> TraceOptions {
    let defaults = TraceOptions::default();
    if quick {
        TraceOptions { samples_per_axis: 4, scale: 0.5, progress, ..defaults }
    } else {
        TraceOptions { progress, ..defaults }
    }
}

/// Ray-traces the built-in scenes named in `names` (all of them for none), in the built-in
/// order; unknown names are an error that lists the valid ones.
pub fn ground_truths(names: &[String], quick: bool, progress: Option<ProgressBar>) -> Result<Vec<GroundTruth>> {
    let scenes = builtin_scenes();
    if let Some(unknown) = names.iter().find(|n| !scenes.iter().any(|s| &s.name == *n)) {
        let known: Vec<&str> = scenes.iter().map(|s| s.name.as_str()).collect();
        return Err(Error::param(format!("no built-in scene '{unknown}'; available: {}", known.join(", "))));
    }
    let options = trace_options(quick, progress);
    scenes
        .iter()
        .filter(|s| names.is_empty() || names.contains(&s.name))
        .map(|scene| {
            // The tracer sets the bar's length per image; restart it for each scene.
            if let Some(bar) = &options.progress {
                bar.reset();
                bar.set_message(scene.name.clone());
            }
            render_ground_truth(scene, &options)
        })
        .collect()
}
