//! Edge-aware smoothness of a disparity map (the paper's Eq. 14, after Gur & Wolf 2019 and
//! Srinivasan et al. 2018): `|dD/dx| exp(-a |dI/dx|) + |dD/dy| exp(-a |dI/dy|)`, averaged
//! over the pixels of each level of a 2x2-box pyramid and over the levels. Depth may jump
//! where the guide image has an edge, and is pulled flat elsewhere (also where the layer is
//! transparent, so hidden disparity follows its neighbours instead of drifting).
//!
//! `|dI|` is the mean absolute difference over the guide's four premultiplied channels, so
//! alpha edges count as image edges; `a` is 1 in the paper.
use crate::image::Image;
use crate::{Error, Result};

/// One pyramid level: disparity and the guide's RGBA, row-major.
struct Level {
    width: usize,
    height: usize,
    disparity: Vec<f64>,
    guide: Vec<[f64; 4]>,
}

impl Level {
    /// The next level down: 2x2 box averages (an odd last row or column is dropped).
    fn downsample(&self) -> Level {
        let (width, height) = (self.width / 2, self.height / 2);
        let mut next = Level { width, height, disparity: Vec::with_capacity(width * height), guide: Vec::with_capacity(width * height) };
        for y in 0..height {
            for x in 0..width {
                let taps = fine_taps(self.width, x, y);
                next.disparity.push(taps.iter().map(|&i| self.disparity[i]).sum::<f64>() / 4.0);
                next.guide.push(std::array::from_fn(|c| taps.iter().map(|&i| self.guide[i][c]).sum::<f64>() / 4.0));
            }
        }
        next
    }

    /// Value of the level's term and its gradient w.r.t. the level's disparity.
    fn term(&self, sharpness: f64) -> (f64, Vec<f64>) {
        let (w, h) = (self.width, self.height);
        let count = (w * h) as f64;
        let mut grad = vec![0.0; w * h];
        let mut value = 0.0;
        let mut pair = |a: usize, b: usize| {
            let edge = (0..4).map(|c| (self.guide[a][c] - self.guide[b][c]).abs()).sum::<f64>() / 4.0;
            let weight = (-sharpness * edge).exp() / count;
            let diff = self.disparity[b] - self.disparity[a];
            value += weight * diff.abs();
            let g = weight * diff.signum() * (diff != 0.0) as u8 as f64;
            grad[b] += g;
            grad[a] -= g;
        };
        for y in 0..h {
            for x in 0..w {
                if x + 1 < w {
                    pair(y * w + x, y * w + x + 1);
                }
                if y + 1 < h {
                    pair(y * w + x, (y + 1) * w + x);
                }
            }
        }
        (value, grad)
    }
}

/// Indices of the four pixels of a level `fine_width` wide under coarse pixel (x, y).
fn fine_taps(fine_width: usize, x: usize, y: usize) -> [usize; 4] {
    let i = 2 * y * fine_width + 2 * x;
    [i, i + 1, i + fine_width, i + fine_width + 1]
}

/// Eq. 14 for one disparity map guided by `guide` (same size) over `levels` pyramid levels,
/// and its gradient w.r.t. the disparity. Levels that would be smaller than 2x2 are skipped.
pub fn edge_aware_smoothness(disparity: &[f32], guide: &Image, levels: usize, sharpness: f64) -> Result<(f64, Vec<f64>)> {
    if disparity.len() != guide.pixels.len() {
        return Err(Error::data(format!("{} disparities for a {}x{} guide", disparity.len(), guide.width, guide.height)));
    }
    if levels == 0 {
        return Err(Error::invalid("smoothness levels", "smoothness needs at least one pyramid level"));
    }
    let mut pyramid = vec![Level {
        width: guide.width,
        height: guide.height,
        disparity: disparity.iter().map(|&d| d as f64).collect(),
        guide: guide.pixels.iter().map(|p| p.map(|v| v as f64)).collect(),
    }];
    while pyramid.len() < levels && pyramid[pyramid.len() - 1].width >= 4 && pyramid[pyramid.len() - 1].height >= 4 {
        let next = pyramid[pyramid.len() - 1].downsample();
        pyramid.push(next);
    }
    let scale = 1.0 / pyramid.len() as f64;
    let (mut value, mut carried) = (0.0, Vec::new());
    // Coarse to fine: each level adds its own gradient to the one pulled up from below.
    for (depth, level) in pyramid.iter().enumerate().rev() {
        let (v, mut grad) = level.term(sharpness);
        value += scale * v;
        grad.iter_mut().for_each(|g| *g *= scale);
        if depth + 1 < pyramid.len() {
            let coarse_width = pyramid[depth + 1].width;
            for (ci, g) in carried.iter().enumerate() {
                for i in fine_taps(level.width, ci % coarse_width, ci / coarse_width) {
                    grad[i] += g / 4.0;
                }
            }
        }
        carried = grad;
    }
    Ok((value, carried))
}
