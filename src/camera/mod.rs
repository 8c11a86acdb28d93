//! The camera model, pure math shared by every CPU and GPU path (DESIGN.md, "Camera model").
//!
//! One formula everywhere: a point of disparity `d` (inverse depth) is blurred into a circle
//! of confusion of signed radius `K * (d - d_f)` pixels, positive when nearer than focus.
//! Everything that turns a lens into pixels goes through [`CocModel`].
mod aperture;
mod aperture_rows;
mod focus_field;
mod kernel_runs;
mod vignetted;
pub(crate) mod hints;
mod scene_unit;

pub use aperture::{bilinear_kernel_sample, cats_eye_gauge, ring_weight, Aperture, ApertureGpu, KernelImage, CATS_EYE_SHAPE, KERNEL_FADE_PX, VIGNETTED_SHAPE};
pub use aperture_rows::{aperture_row_table, closed_form_gauge, APERTURE_ROW_SEGMENTS, EMPTY_APERTURE_ROW};
pub use focus_field::FocusField;
pub use hints::CameraHints;
pub use scene_unit::{SceneUnit, SCENE_UNIT_ATTRIBUTE};
pub use kernel_runs::{kernel_run_table, KERNEL_RUN_FULL, KERNEL_RUN_ZERO};
pub use vignetted::{clipped_centroid, vignettes_in_one_pass, ClippedShape, Eye};

use crate::{Error, Result};

/// Depths at or beyond this many scene units are "infinitely far" (Blender writes 1e10).
pub const FAR_DEPTH_SENTINEL: f32 = 1.0e9;

/// A physical thin-lens camera as Blender/Cycles models it: an aperture disk of radius
/// `f / 2N` at the pinhole, field of view from `f` and the sensor width.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PhysicalCamera {
    pub focal_length_mm: f32,
    pub sensor_width_mm: f32,
    pub fstop: f32,
    /// Distance of the plane in focus, in scene units (metres unless a [`SceneUnit`] says
    /// otherwise: [`CocModel::from_physical_in`]).
    pub focus_distance: f32,
}

impl PhysicalCamera {
    pub fn validate(&self) -> Result<()> {
        let checks = [
            ("focal length", self.focal_length_mm),
            ("sensor width", self.sensor_width_mm),
            ("f-stop", self.fstop),
            ("focus distance", self.focus_distance),
        ];
        for (name, value) in checks {
            if !(value.is_finite() && value > 0.0) {
                return Err(Error::invalid("camera", format!(
                    "{name} must be a positive number, got {value}"
                )));
            }
        }
        Ok(())
    }

    /// Aperture radius in scene units (metres): `f / 2N`.
    pub fn aperture_radius(&self) -> f32 {
        self.focal_length_mm * 1.0e-3 / (2.0 * self.fstop)
    }

    /// Focal length expressed in pixels of an image `image_width_px` wide.
    pub fn focal_length_px(&self, image_width_px: usize) -> f32 {
        self.focal_length_mm / self.sensor_width_mm * image_width_px as f32
    }
}

/// Largest CoC radius the renderers accept, in pixels. A larger blur spreads a pixel far past
/// any frame (a 16K frame is 15360 px wide), and its search windows and kernels ((2r + 1)^2
/// taps per pixel) would overflow 32-bit window arithmetic and exhaust memory long before a
/// render could finish; such a radius comes from a unit mistake, not from a real lens.
pub const MAX_COC_RADIUS_PX: f32 = 4096.0;

/// Circle-of-confusion model: `r(d) = K |d - d_f|` pixels.
///
/// With a physical camera `d = 1/z` (z in metres) and
/// `K = (f / 2N) * (f / sensor_width) * image_width_px`; with normalised input `d` is the
/// file's disparity in [0, 1] (1 = near) and `K` is given directly in pixels per unit.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CocModel {
    /// Pixels of CoC radius per unit of disparity.
    pub k_px: f32,
    /// Disparity of the plane in focus.
    pub focus_disparity: f32,
}

impl CocModel {
    pub fn new(k_px: f32, focus_disparity: f32) -> Result<Self> {
        if !(k_px.is_finite() && k_px >= 0.0) {
            return Err(Error::invalid("coc model", format!(
                "blur K must be a non-negative number, got {k_px}"
            )));
        }
        if !focus_disparity.is_finite() {
            return Err(Error::invalid("coc model", format!(
                "focus disparity must be finite, got {focus_disparity}"
            )));
        }
        Ok(Self {
            k_px,
            focus_disparity,
        })
    }

    pub fn from_physical(camera: &PhysicalCamera, image_width_px: usize) -> Result<Self> {
        Self::from_physical_in(camera, image_width_px, &SceneUnit::default())
    }

    /// [`Self::from_physical`] for depths and focus distance in `unit`: the aperture radius
    /// (metres) is expressed in that unit, so disparity stays `1 / depth` as the file stores it.
    pub fn from_physical_in(camera: &PhysicalCamera, image_width_px: usize, unit: &SceneUnit) -> Result<Self> {
        camera.validate()?;
        let aperture = f64::from(camera.aperture_radius()) / unit.metres;
        let k = aperture as f32 * camera.focal_length_px(image_width_px);
        Self::new(k, 1.0 / camera.focus_distance)
    }

    /// Signed relative disparity `d - d_f` (positive = nearer than focus).
    #[inline]
    pub fn relative_disparity(&self, disparity: f32) -> f32 {
        disparity - self.focus_disparity
    }

    /// Signed CoC radius in pixels (positive = nearer than focus).
    #[inline]
    pub fn signed_radius(&self, disparity: f32) -> f32 {
        self.k_px * (disparity - self.focus_disparity)
    }

    /// CoC radius in pixels.
    #[inline]
    pub fn radius(&self, disparity: f32) -> f32 {
        self.signed_radius(disparity).abs()
    }

    /// Refuses a disparity range `[lo, hi]` whose largest CoC is not finite or exceeds
    /// [`MAX_COC_RADIUS_PX`] (computed in f64, so an f32 overflow is caught too).
    pub fn check_renderable(&self, lo: f32, hi: f32) -> Result<()> {
        let radius = |d: f32| (f64::from(self.k_px) * (f64::from(d) - f64::from(self.focus_disparity))).abs();
        let (d, r) = if radius(lo).total_cmp(&radius(hi)).is_ge() { (lo, radius(lo)) } else { (hi, radius(hi)) };
        if r.is_finite() && r <= f64::from(MAX_COC_RADIUS_PX) {
            return Ok(());
        }
        // Plain notation for everyday values, exponents for the absurd ones that land here.
        let show = |v: f32| if v == 0.0 || (1e-3..1e6).contains(&v.abs()) { format!("{v}") } else { format!("{v:e}") };
        Err(Error::data(format!(
            "a circle of confusion of {r:.3e} px (disparity {}, K = {} px per unit, focus disparity {}) is larger than \
             the {MAX_COC_RADIUS_PX} px the renderers handle; check the depth's scene units and the camera \
             (focus distance, K), or limit it (BlurRemap's maximum; --max-blur on the command line)",
            show(d),
            show(self.k_px),
            show(self.focus_disparity)
        )))
    }

    /// Largest CoC radius over a disparity range.
    pub fn max_radius(&self, min_disparity: f32, max_disparity: f32) -> f32 {
        self.radius(min_disparity).max(self.radius(max_disparity))
    }
}

/// Disparity (inverse depth) of a planar depth `z`; the far sentinel and infinity map to 0.
#[inline]
pub fn disparity_from_z(z: f32) -> f32 {
    if z >= FAR_DEPTH_SENTINEL || z.is_infinite() {
        0.0
    } else {
        1.0 / z
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn physical_k_matches_design_formula() {
        // 50 mm f/2 on a 36 mm sensor, 1000 px wide: K = (0.05/4) * (50/36) * 1000.
        let cam = PhysicalCamera {
            focal_length_mm: 50.0,
            sensor_width_mm: 36.0,
            fstop: 2.0,
            focus_distance: 2.0,
        };
        let coc = CocModel::from_physical(&cam, 1000).unwrap();
        let expected = 0.0125 * (50.0 / 36.0) * 1000.0;
        assert!((coc.k_px - expected).abs() < 1e-3 * expected);
        assert_eq!(coc.radius(0.5), 0.0, "the focus plane has no blur");
        // A point at 1 m: |1 - 0.5| * K.
        assert!((coc.radius(1.0) - 0.5 * expected).abs() < 1e-3 * expected);
        assert!(
            coc.signed_radius(1.0) > 0.0,
            "nearer than focus is positive"
        );
    }

    #[test]
    fn far_sentinels_have_zero_disparity() {
        assert_eq!(disparity_from_z(1.0e10), 0.0);
        assert_eq!(disparity_from_z(f32::INFINITY), 0.0);
        assert_eq!(disparity_from_z(4.0), 0.25);
    }

    #[test]
    fn invalid_cameras_are_refused() {
        let cam = PhysicalCamera {
            focal_length_mm: 50.0,
            sensor_width_mm: 36.0,
            fstop: 0.0,
            focus_distance: 2.0,
        };
        assert!(CocModel::from_physical(&cam, 100).is_err());
        assert!(CocModel::new(f32::NAN, 0.0).is_err());
    }

    #[test]
    fn only_a_finite_coc_up_to_the_limit_is_renderable() {
        // K = 1024 px per unit: disparity 4 above focus is exactly the 4096 px limit.
        let coc = CocModel::new(1024.0, 0.0).unwrap();
        assert!(coc.check_renderable(-4.0, 4.0).is_ok());
        assert!(coc.check_renderable(0.0, 4.01).is_err());
        assert!(coc.check_renderable(-4.01, 0.0).is_err(), "the near side counts too");
        assert!(coc.check_renderable(0.0, f32::INFINITY).is_err());
        // 3e38 * 3e38 overflows f32; the check computes in f64 and still refuses it.
        let huge = CocModel::new(3e38, 0.0).unwrap();
        let message = huge.check_renderable(0.0, 3e38).unwrap_err().to_string();
        assert!(message.contains("9.000e76 px") && message.contains("--max-blur"), "{message}");
    }
}
