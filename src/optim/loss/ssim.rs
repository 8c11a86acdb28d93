//! Differentiable SSIM with uniform (box) windows, and the paper's hierarchical SSIM
//! (Sec. 4.3): the mean of `1 - SSIM` over several window sizes, so blur larger than the
//! default 11-pixel window still gets regional feedback.
//!
//! Box windows over "valid" centres only (the whole window inside the image) keep the
//! adjoint simple: every moment is a box sum, and the adjoint of a box sum is a box sum of
//! the per-centre derivatives. Both go through summed-area tables, O(pixels) per window.
//! Computed on the RGB channels of the linear premultiplied images, in f64.
use super::{check_sizes, Gradient};
use crate::image::Image;
use crate::{Error, Result};

/// The usual SSIM stabilisers for a peak value of 1.
const C1: f64 = 0.01 * 0.01;
const C2: f64 = 0.03 * 0.03;

/// Summed-area table with a zero row and column in front: `(w + 1) x (h + 1)`.
struct Sat {
    stride: usize,
    sums: Vec<f64>,
}

impl Sat {
    fn new(width: usize, height: usize, value: impl Fn(usize) -> f64) -> Self {
        let stride = width + 1;
        let mut sums = vec![0.0; stride * (height + 1)];
        for y in 0..height {
            let mut row = 0.0;
            for x in 0..width {
                row += value(y * width + x);
                sums[(y + 1) * stride + x + 1] = sums[y * stride + x + 1] + row;
            }
        }
        Self { stride, sums }
    }

    /// Sum over the inclusive box `[x0, x1] x [y0, y1]`.
    fn sum(&self, (x0, y0): (usize, usize), (x1, y1): (usize, usize)) -> f64 {
        let s = |x: usize, y: usize| self.sums[y * self.stride + x];
        s(x1 + 1, y1 + 1) - s(x0, y1 + 1) - s(x1 + 1, y0) + s(x0, y0)
    }
}

/// Per-centre SSIM and its derivatives w.r.t. the window's raw moments of the rendered
/// image `x` (mean, mean of squares, mean of products with the target `y`).
fn ssim_and_partials(mx: f64, my: f64, exx: f64, eyy: f64, exy: f64) -> (f64, [f64; 3]) {
    let (vx, vy, cxy) = (exx - mx * mx, eyy - my * my, exy - mx * my);
    let (n1, n2) = (2.0 * mx * my + C1, 2.0 * cxy + C2);
    let (d1, d2) = (mx * mx + my * my + C1, vx + vy + C2);
    let s = n1 * n2 / (d1 * d2);
    let d_mx = s * (2.0 * my / n1 - 2.0 * my / n2 - 2.0 * mx / d1 + 2.0 * mx / d2);
    (s, [d_mx, -s / d2, 2.0 * s / n2])
}

/// Mean SSIM over valid centres and RGB channels for one window size, and its gradient
/// w.r.t. `rendered`. Errors when the window does not fit the image.
pub fn ssim_box(rendered: &Image, target: &Image, window: usize) -> Result<(f64, Gradient)> {
    check_sizes(rendered, target)?;
    let (w, h) = (rendered.width, rendered.height);
    if window % 2 == 0 || window > w || window > h {
        return Err(Error::invalid("ssim window", format!("SSIM window must be odd and fit the {w}x{h} image, got {window}")));
    }
    let half = window / 2;
    let (n, centres) = ((window * window) as f64, ((w - 2 * half) * (h - 2 * half)) as f64);
    let mut grad = vec![[0.0f64; 4]; w * h];
    let mut total = 0.0;
    #[allow(clippy::needless_range_loop)] // `c` picks the channel in closures and in `grad`
    for c in 0..3 {
        let (x, y) = (|i: usize| rendered.pixels[i][c] as f64, |i: usize| target.pixels[i][c] as f64);
        let moments = [Sat::new(w, h, x), Sat::new(w, h, y), Sat::new(w, h, |i| x(i) * x(i)), Sat::new(w, h, |i| y(i) * y(i)), Sat::new(w, h, |i| x(i) * y(i))];
        let mut partials = vec![[0.0f64; 3]; w * h];
        for py in half..h - half {
            for px in half..w - half {
                let m = moments.each_ref().map(|sat| sat.sum((px - half, py - half), (px + half, py + half)) / n);
                let (s, d) = ssim_and_partials(m[0], m[1], m[2], m[3], m[4]);
                total += s;
                partials[py * w + px] = d;
            }
        }
        let adjoint = [0, 1, 2].map(|k| Sat::new(w, h, |i| partials[i][k]));
        for qy in 0..h {
            for qx in 0..w {
                let lo = (qx.saturating_sub(half), qy.saturating_sub(half));
                let hi = ((qx + half).min(w - 1), (qy + half).min(h - 1));
                let [a, b, cc] = adjoint.each_ref().map(|sat| sat.sum(lo, hi));
                let q = qy * w + qx;
                grad[q][c] = (a + 2.0 * b * x(q) + cc * y(q)) / (n * centres * 3.0);
            }
        }
    }
    Ok((total / (centres * 3.0), grad))
}

/// Hierarchical SSIM loss: mean over `windows` of `1 - SSIM`, and its gradient.
pub fn hierarchical_ssim(rendered: &Image, target: &Image, windows: &[usize]) -> Result<(f64, Gradient)> {
    if windows.is_empty() {
        return Err(Error::invalid("ssim window", "hierarchical SSIM needs at least one window size"));
    }
    let scale = 1.0 / windows.len() as f64;
    let mut grad = vec![[0.0f64; 4]; rendered.pixels.len()];
    let mut value = 0.0;
    for &window in windows {
        let (s, g) = ssim_box(rendered, target, window)?;
        value += scale * (1.0 - s);
        for (acc, g) in grad.iter_mut().zip(g) {
            for c in 0..4 {
                acc[c] -= scale * g[c];
            }
        }
    }
    Ok((value, grad))
}
