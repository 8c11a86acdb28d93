//! Depth for the light a bright source spills into its neighbours (issue 46).
//!
//! A renderer anti-aliases colour but not depth. Its pixel filter (Cycles' Blackman-Harris is
//! 1.5 px wide) spreads a small bright source, a street light or a highlight, into the pixels
//! around it, while their one depth sample still hits whatever lies behind. Blurred with that
//! behind's CoC, the spilled light forms a rim wider than the source's own disc: on the night
//! city scenes of the dev split the discs came out 3.4-3.9 px in radius for a 3.3 px truth,
//! which a sharp-edged disc over a dark sky makes the largest error of the frame.
//!
//! Where the CoC jumps by a cut's worth (`discontinuity_px`) the matting splits mixed pixels
//! between two layers. Below that jump there is one layer with per-pixel CoC, and this pass
//! gives such a pixel the depth of the light it mostly holds: a pixel takes the disparity of
//! its brightest nearer 8-neighbour when
//! - that neighbour is brighter than the pixel, and nearer by more than
//!   5% in disparity (so a surface's own slope is never a source);
//! - the two CoCs differ by less than `discontinuity_px` (a larger jump is the matting's);
//! - more than half of the pixel's luminance is not its own surface's: the pixel exceeds
//!   twice the median luminance of the pixels of its own depth around it (5x5 window).
//!
//! Two passes reach the second ring of a source larger than a pixel. Pixels that hold mostly
//! their own surface keep their depth, so on frames without bright small sources nothing moves.
use rayon::prelude::*;

use crate::camera::CocModel;
use crate::image::Image;

/// A neighbour is a nearer source only if its disparity exceeds the pixel's by this factor.
const NEARER_RATIO: f32 = 1.05;
/// Half the side of the window whose same-depth pixels give the pixel's own luminance.
const WINDOW_RADIUS: usize = 2;
/// Passes; each reaches one pixel further from the source.
const PASSES: usize = 2;

fn luminance(c: [f32; 4]) -> f32 {
    (c[0] + c[1] + c[2]) / 3.0
}

/// The disparity of every pixel after spilled light took its source's (see the module docs).
pub fn assign_spill_depth(image: &Image, disparity: &[f32], coc: &CocModel, discontinuity_px: f32) -> Vec<f32> {
    let (w, h) = (image.width, image.height);
    let lum: Vec<f32> = image.pixels.iter().map(|&c| luminance(c)).collect();
    let coc_of = |d: f32| coc.signed_radius(d);
    let mut current = disparity.to_vec();
    for _ in 0..PASSES {
        let before = current.clone();
        current.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            for (x, d) in row.iter_mut().enumerate() {
                if let Some(source) = spill_source(&lum, &before, &coc_of, (w, h), x, y, discontinuity_px) {
                    *d = source;
                }
            }
        });
    }
    current
}

/// The disparity of the source whose light `(x, y)` mostly holds, if any.
fn spill_source(lum: &[f32], disparity: &[f32], coc_of: &impl Fn(f32) -> f32, (w, h): (usize, usize), x: usize, y: usize, discontinuity_px: f32) -> Option<f32> {
    let p = y * w + x;
    let (l_p, d_p) = (lum[p], disparity[p]);
    let c_p = coc_of(d_p);
    let mut best: Option<(f32, f32)> = None;
    for ny in y.saturating_sub(1)..=(y + 1).min(h - 1) {
        for nx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
            let q = ny * w + nx;
            let (l_q, d_q) = (lum[q], disparity[q]);
            let nearer = d_q > d_p * NEARER_RATIO && d_q > d_p;
            if q == p || !nearer || l_q <= l_p || (coc_of(d_q) - c_p).abs() >= discontinuity_px {
                continue;
            }
            if best.map_or(true, |(l, _)| l_q > l) {
                best = Some((l_q, d_q));
            }
        }
    }
    let (_, source) = best?;
    (l_p > 2.0 * own_luminance(lum, disparity, (w, h), x, y)).then_some(source)
}

/// Median luminance of the pixels around `(x, y)` whose disparity is the pixel's own (within
/// [`NEARER_RATIO`]): what the pixel would show without a neighbour's light.
fn own_luminance(lum: &[f32], disparity: &[f32], (w, h): (usize, usize), x: usize, y: usize) -> f32 {
    let d_p = disparity[y * w + x];
    let mut same = Vec::with_capacity((2 * WINDOW_RADIUS + 1).pow(2));
    for ny in y.saturating_sub(WINDOW_RADIUS)..=(y + WINDOW_RADIUS).min(h - 1) {
        for nx in x.saturating_sub(WINDOW_RADIUS)..=(x + WINDOW_RADIUS).min(w - 1) {
            let q = ny * w + nx;
            if (disparity[q] - d_p).abs() <= (NEARER_RATIO - 1.0) * d_p {
                same.push(lum[q]);
            }
        }
    }
    // The pixel itself is always in: the list is never empty.
    upper_median(&mut same)
}

/// The upper median of `values` (the middle one of an odd count, the higher middle of an even
/// count), reordering them. `values` must not be empty.
pub(crate) fn upper_median(values: &mut [f32]) -> f32 {
    let mid = values.len() / 2;
    *values.select_nth_unstable_by(mid, f32::total_cmp).1
}
