//! Depth and sample cleaning that every source shares (EXR layers and flat EXR, PNG/JPEG with a
//! depth image, arrays): which stored depth samples are trusted, their conversion to
//! disparity with invalid values refused by name, the fill of depth under transparent pixels,
//! and the refusal (or replacement) of NaN/Inf colour. Readers call these; none cleans depth
//! its own way.
use std::path::Path;

use rayon::prelude::*;

use super::fill::push_pull;
use super::{DepthKind, SAMPLES_PER_TASK};
use crate::{Error, Result};

/// Disparity per pixel, the stored depth range over covered pixels, and the fill weight of
/// every stored sample (see [`known_depth_weight`]).
pub(crate) type DepthResult = (Vec<f32>, Option<(f32, f32)>, Vec<f32>);

/// How much the depth fill trusts a stored depth sample, given the pixel's alpha and the
/// sample converted to disparity: 0 where the sample is not read (no coverage, or a partly
/// covered pixel whose depth says "nothing here"), else the alpha.
pub fn known_depth_weight(alpha: f32, disparity: f32) -> f32 {
    // Cycles writes 1e10 when a partly covered pixel's depth sample missed the surface.
    if alpha <= 0.0 || (disparity == 0.0 && alpha < 1.0) {
        0.0
    } else {
        alpha.min(1.0)
    }
}

/// Converts stored depth to disparity where the layer has coverage, then fills the
/// (undefined) depth of transparent pixels from nearby covered ones, weighted by alpha.
pub(crate) fn depth_to_disparity(
    path: &Path,
    (layer, channel): (&str, &str),
    size: (usize, usize),
    depth: &[f32],
    alpha: &[f32],
    kind: DepthKind,
) -> Result<DepthResult> {
    // In runs on every core (a layer of an 8K frame holds 33 M samples); each run's range and
    // count of invalid samples are combined in order afterwards.
    let mut disparity = vec![[0.0f32; 1]; depth.len()];
    let mut weights = vec![0.0f32; depth.len()];
    let runs: Vec<(Option<(f32, f32)>, usize)> = disparity
        .par_chunks_mut(SAMPLES_PER_TASK)
        .zip(weights.par_chunks_mut(SAMPLES_PER_TASK))
        .enumerate()
        .map(|(run, (disparity, weights))| {
            let (mut range, mut invalid) = (None::<(f32, f32)>, 0usize);
            let start = run * SAMPLES_PER_TASK;
            for (k, (disparity, weight_out)) in disparity.iter_mut().zip(weights.iter_mut()).enumerate() {
                let z = depth[start + k];
                let d = kind.to_disparity(z);
                let weight = known_depth_weight(alpha[start + k], d);
                if weight <= 0.0 {
                    continue; // taken from the neighbours
                }
                // Planar Z is a distance in front of the camera: zero or negative is no valid
                // depth (a negated camera-space z from a -z-forward convention lands here, as it
                // should).
                if z.is_nan() || !d.is_finite() || (kind == DepthKind::Z && z <= 0.0) || d < 0.0 {
                    invalid += 1;
                    continue;
                }
                range = Some(range.map_or((z, z), |(lo, hi)| (lo.min(z), hi.max(z))));
                *disparity = [d];
                *weight_out = weight;
            }
            (range, invalid)
        })
        .collect();
    let invalid: usize = runs.iter().map(|r| r.1).sum();
    let range = runs.iter().filter_map(|r| r.0).reduce(|(lo, hi), (a, b)| (lo.min(a), hi.max(b)));
    if invalid > 0 {
        return Err(Error::input(
            path,
            format!(
                "layer '{layer}' channel '{channel}' has {invalid} covered pixel(s) with invalid depth \
                 (NaN, negative, or zero for --depth-kind {}); far is 1e10 or inf for z, 0 for \
                 disparity/inverse-z; check the depth kind (ReadOptions::depth_kind; --depth-kind on the command line) or fix the depth pass",
                kind.name()
            ),
        ));
    }
    // An empty layer has no depth anywhere: it stays at disparity 0 (far) and is invisible.
    push_pull(size.0, size.1, &mut disparity, &weights);
    Ok((disparity.into_iter().map(|d| d[0]).collect(), range, weights))
}

/// Refuses NaN/Inf samples in colour or alpha (they would poison every blurred neighbour),
/// or with `replace` sets them to 0 and returns a warning saying how many.
pub(crate) fn check_finite(path: &Path, layer: &str, channel: &str, values: &mut [f32], replace: bool) -> Result<Option<String>> {
    let bad: usize = values.par_chunks(SAMPLES_PER_TASK).map(|run| run.iter().filter(|v| !v.is_finite()).count()).sum();
    if bad == 0 {
        return Ok(None);
    }
    if !replace {
        return Err(Error::input(
            path,
            format!(
                "layer '{layer}' channel '{channel}' has {bad} NaN/Inf sample(s); fix the render \
                 (often a shader or denoiser fault) or set them to 0 (ReadOptions::replace_nonfinite; --replace-nonfinite on the command line)"
            ),
        ));
    }
    values.par_chunks_mut(SAMPLES_PER_TASK).for_each(|run| run.iter_mut().filter(|v| !v.is_finite()).for_each(|v| *v = 0.0));
    Ok(Some(format!("{}: layer '{layer}' channel '{channel}': replaced {bad} NaN/Inf sample(s) by 0", path.display())))
}

/// The disparity of a depth image's value `v` in [0, 1] (PNG/JPEG input): by `kind`, with a
/// planar Z of 0 meaning "no data", which an 8/16-bit image cannot say otherwise: far.
pub fn image_depth_to_disparity(kind: DepthKind, v: f32) -> f32 {
    match kind {
        DepthKind::Z if v <= 0.0 => 0.0,
        kind => kind.to_disparity(v),
    }
}
