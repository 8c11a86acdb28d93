//! Display encoding: every metric compares what a viewer sees, not linear radiance, so that
//! errors in shadows and highlights weigh as they do on screen (and as in the paper's Table 1,
//! whose images are 8-bit sRGB).
use crate::image::Image;

/// An image as displayed: RGB in [0, 1], sRGB-encoded, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct DisplayImage {
    pub width: usize,
    pub height: usize,
    pub rgb: Vec<[f32; 3]>,
}

impl DisplayImage {
    /// All samples, channel-interleaved (`r0 g0 b0 r1 ...`).
    pub fn samples(&self) -> &[f32] {
        bytemuck::cast_slice(&self.rgb)
    }

    /// One channel as a plane.
    pub fn channel(&self, c: usize) -> Vec<f32> {
        self.rgb.iter().map(|p| p[c]).collect()
    }
}

/// The sRGB opto-electronic transfer function (IEC 61966-2-1), linear -> encoded.
#[inline]
pub fn srgb_oetf(linear: f32) -> f32 {
    if linear <= 0.003_130_8 {
        12.92 * linear
    } else {
        1.055 * linear.powf(1.0 / 2.4) - 0.055
    }
}

/// Linear premultiplied RGBA -> over black -> sRGB -> clipped to [0, 1].
///
/// Premultiplied RGB *is* the colour composited over black, so alpha drops out; clipping comes
/// because a display cannot show values outside [0, 1] (and HDR highlights would otherwise
/// dominate every squared-error metric). The OETF is monotone with OETF(1) = 1, so clipping
/// the linear value first is the same and keeps white exactly 1.
pub fn display_encode(image: &Image) -> DisplayImage {
    let rgb = image
        .pixels
        .iter()
        .map(|p| [0, 1, 2].map(|c| if p[c] >= 1.0 { 1.0 } else { srgb_oetf(p[c].max(0.0)) }))
        .collect();
    DisplayImage { width: image.width, height: image.height, rgb }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn oetf_matches_reference_points() {
        // Standard values: 0 -> 0, 1 -> 1, 0.18 (mid grey) -> 0.4614 (to 4 digits).
        assert_eq!(srgb_oetf(0.0), 0.0);
        assert!((srgb_oetf(1.0) - 1.0).abs() < 1e-6);
        assert!((srgb_oetf(0.18) - 0.4614).abs() < 1e-4);
        // The two branches meet at the breakpoint (continuity to 1e-4, the standard's rounding).
        assert!((srgb_oetf(0.003_130_8) - srgb_oetf(0.003_130_9)).abs() < 1e-4);
    }

    #[test]
    fn alpha_composites_over_black_and_highlights_clip() {
        let img = Image::from_fn(2, 1, |x, _| if x == 0 { [0.5, 0.0, 0.0, 0.5] } else { [4.0, -1.0, 1.0, 1.0] });
        let d = display_encode(&img);
        assert!((d.rgb[0][0] - srgb_oetf(0.5)).abs() < 1e-6, "premultiplied colour is used as is");
        assert_eq!(d.rgb[1], [1.0, 0.0, 1.0], "out-of-range values clip to the display range");
    }
}
