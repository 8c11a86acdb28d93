//! Where the benchmark's scenes come from: the built-in scenes, ray-traced to ground truth
//! (or loaded from the on-disk cache, [`super::gt_cache`]). The one place the benchmark calls
//! the ray tracer.
use std::path::Path;

use indicatif::ProgressBar;

use super::gt_cache;
use lensblur::raytrace::{builtin_scenes, render_ground_truth, single_image_scenes, GroundTruth, RowProgress, Scene, TraceOptions};
use lensblur::{Error, Result};

/// The sampling of the benchmark's ground truth. Rounds of 8 x 8 stratified rays until the
/// display-space standard error of a pixel is below the tolerance: the truth's own noise
/// must stay well under the differences between methods. Measured as the PSNR between two
/// seeds: `--quick` 43 to 49 dB on scenes without HDR lights, 31 to 38 dB with them (small
/// bright discs far out of focus stay the noisiest; the methods score 20 to 25 dB there);
/// the full settings at half scale 47 to 52 and 34 to 40 dB (it was 15 to 32 dB with the
/// former 4 x 4 rays of `--quick`). `--quick`: half the native resolution (CoC radii halve
/// too), a looser tolerance and fewer rounds.
pub fn trace_options(quick: bool, progress: Option<RowProgress>) -> TraceOptions {
    let defaults = TraceOptions::default();
    if quick {
        TraceOptions { scale: 0.5, max_rounds: 24, tolerance: 0.003, progress, ..defaults }
    } else {
        TraceOptions { progress, ..defaults }
    }
}

/// Ray-traces the built-in scenes named in `names` (all of them for none), in the built-in
/// order; unknown names are an error that lists the valid ones. With `cache`, truths are
/// loaded from and stored in that folder.
pub fn ground_truths(names: &[String], quick: bool, progress: Option<ProgressBar>, cache: Option<&Path>) -> Result<Vec<GroundTruth>> {
    truths_of(builtin_scenes(), names, quick, progress, cache)
}

/// [`ground_truths`] of the single-image scenes (`raytrace::single_image_scenes`).
pub fn single_image_truths(names: &[String], quick: bool, progress: Option<ProgressBar>, cache: Option<&Path>) -> Result<Vec<GroundTruth>> {
    truths_of(single_image_scenes(), names, quick, progress, cache)
}

fn truths_of(scenes: Vec<Scene>, names: &[String], quick: bool, progress: Option<ProgressBar>, cache: Option<&Path>) -> Result<Vec<GroundTruth>> {
    if let Some(unknown) = names.iter().find(|n| !scenes.iter().any(|s| &s.name == *n)) {
        let known: Vec<&str> = scenes.iter().map(|s| s.name.as_str()).collect();
        return Err(Error::invalid("scene name", format!("no built-in scene '{unknown}'; available: {}", known.join(", "))));
    }
    let rows = progress.clone().map(|bar| {
        RowProgress::new(move |done, total| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        })
    });
    let options = trace_options(quick, rows);
    scenes
        .iter()
        .filter(|s| names.is_empty() || names.contains(&s.name))
        .map(|scene| {
            let key = gt_cache::cache_key(scene, &options);
            if let Some(truth) = cache.and_then(|dir| gt_cache::load(dir, &key)) {
                return Ok(truth);
            }
            // The tracer sets the bar's length per image; restart it for each scene.
            if let Some(bar) = &progress {
                bar.reset();
                bar.set_message(scene.name.clone());
            }
            let truth = render_ground_truth(scene, &options)?;
            if let Some(dir) = cache {
                gt_cache::store(dir, &key, &truth)?;
            }
            Ok(truth)
        })
        .collect()
}
