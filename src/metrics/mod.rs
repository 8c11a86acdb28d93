//! Image quality metrics (the Dr.Bokeh paper's Table 1): RMSE, scale-invariant RMSE, PSNR,
//! SSIM and ZNCC, all computed on display-encoded values (see [`display_encode`]).
mod encode;
mod pixel;
mod ssim;

pub use encode::{display_encode, srgb_oetf, DisplayImage};
pub use pixel::{mse, psnr_from_mse, rmse, si_rmse, zncc};
pub use ssim::{ssim, WINDOW as SSIM_WINDOW};

use crate::image::Image;
use crate::{Error, Result};

/// One result image scored against its ground truth.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Metrics {
    pub rmse: f64,
    /// Scale-invariant RMSE (the paper's "RMSE-s").
    pub si_rmse: f64,
    /// dB for a peak of 1; infinite for identical images (serialised as `null` in JSON).
    pub psnr: f64,
    /// Mean over the RGB channels.
    pub ssim: f64,
    pub zncc: f64,
}

/// Which way each metric improves, so reports can pick the best and the worst value.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Better {
    Lower,
    Higher,
}

impl Metrics {
    /// Metric names as printed in tables, in field order.
    pub const NAMES: [&'static str; 5] = ["RMSE", "RMSE-s", "PSNR", "SSIM", "ZNCC"];
    pub const BETTER: [Better; 5] = [Better::Lower, Better::Lower, Better::Higher, Better::Higher, Better::Higher];

    pub fn values(&self) -> [f64; 5] {
        [self.rmse, self.si_rmse, self.psnr, self.ssim, self.zncc]
    }

    pub fn from_values(v: [f64; 5]) -> Self {
        Self { rmse: v[0], si_rmse: v[1], psnr: v[2], ssim: v[3], zncc: v[4] }
    }
}

/// Scores `result` against `truth` (both linear premultiplied RGBA of the same size).
pub fn compare(result: &Image, truth: &Image) -> Result<Metrics> {
    if (result.width, result.height) != (truth.width, truth.height) {
        return Err(Error::data(format!(
            "cannot compare a {}x{} result with a {}x{} ground truth",
            result.width, result.height, truth.width, truth.height
        )));
    }
    let (a, b) = (display_encode(result), display_encode(truth));
    let m = mse(a.samples(), b.samples());
    Ok(Metrics {
        rmse: m.sqrt(),
        si_rmse: si_rmse(a.samples(), b.samples()),
        psnr: psnr_from_mse(m),
        ssim: ssim(&a, &b)?,
        zncc: zncc(a.samples(), b.samples()),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_image_compared_with_itself_is_perfect() {
        let img = Image::from_fn(24, 16, |x, y| [x as f32 / 24.0, y as f32 / 16.0, 0.3, 1.0]);
        let m = compare(&img, &img).unwrap();
        assert_eq!((m.rmse, m.si_rmse, m.psnr), (0.0, 0.0, f64::INFINITY));
        // SSIM and ZNCC: ratios of equal f64 sums, exact to rounding.
        assert!((m.ssim - 1.0).abs() < 1e-9 && (m.zncc - 1.0).abs() < 1e-9);
    }

    #[test]
    fn size_mismatch_is_an_error() {
        assert!(compare(&Image::new(12, 12), &Image::new(12, 13)).is_err());
    }
}
