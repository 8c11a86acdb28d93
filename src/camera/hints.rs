//! Camera parameters carried in file headers, so a stack written by `lensblur raytrace` (or a
//! renderer that stamps its camera) renders without camera flags. Partial: any field may be
//! missing; command-line flags win over what a header says.
use std::collections::BTreeMap;

use super::PhysicalCamera;

/// Header attribute names we write. `focus` and `aperture` (f-number) are OpenEXR standard
/// attributes; `effectiveFocalLength` is the OpenEXR 3.2 camera attribute (mm); the sensor
/// width has no standard single-float attribute, hence our own name.
pub const FOCUS_ATTRIBUTE: &str = "focus";
pub const FSTOP_ATTRIBUTE: &str = "aperture";
pub const FOCAL_LENGTH_ATTRIBUTE: &str = "effectiveFocalLength";
pub const SENSOR_WIDTH_ATTRIBUTE: &str = "lensblurSensorWidthMm";

/// Whatever physical camera parameters a header holds.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct CameraHints {
    pub focal_length_mm: Option<f32>,
    pub sensor_width_mm: Option<f32>,
    pub fstop: Option<f32>,
    pub focus_distance: Option<f32>,
}

impl CameraHints {
    /// Reads the attributes collected by the EXR reader (name -> printed value). Recognises
    /// our own names, the OpenEXR 3.2 focal lengths, and Blender's stamp `Lens` ("50.00 mm").
    pub fn from_attributes(attributes: &BTreeMap<String, String>) -> Self {
        let number = |keys: &[&str]| {
            keys.iter().find_map(|key| {
                let text = attributes.get(*key)?;
                let value: f32 = text.trim().trim_end_matches("mm").trim().parse().ok()?;
                (value.is_finite() && value > 0.0).then_some(value)
            })
        };
        Self {
            focal_length_mm: number(&[
                FOCAL_LENGTH_ATTRIBUTE,
                "nominalFocalLength",
                "focalLength",
                "Lens",
            ]),
            sensor_width_mm: number(&[SENSOR_WIDTH_ATTRIBUTE]),
            fstop: number(&[FSTOP_ATTRIBUTE, "fNumber"]),
            focus_distance: number(&[FOCUS_ATTRIBUTE]),
        }
    }

    /// Every parameter of a known camera.
    pub fn from_camera(camera: &PhysicalCamera) -> Self {
        Self {
            focal_length_mm: Some(camera.focal_length_mm),
            sensor_width_mm: Some(camera.sensor_width_mm),
            fstop: Some(camera.fstop),
            focus_distance: Some(camera.focus_distance),
        }
    }

    /// These hints, with the parameters they lack taken from `fallback` (a frame's header
    /// first, then the shot's camera file).
    pub fn or(self, fallback: Self) -> Self {
        Self {
            focal_length_mm: self.focal_length_mm.or(fallback.focal_length_mm),
            sensor_width_mm: self.sensor_width_mm.or(fallback.sensor_width_mm),
            fstop: self.fstop.or(fallback.fstop),
            focus_distance: self.focus_distance.or(fallback.focus_distance),
        }
    }

    pub fn is_empty(&self) -> bool {
        *self == Self::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_our_names_and_blender_stamp() {
        let map: BTreeMap<String, String> = [
            ("focus", "2.5"),
            ("aperture", "1.8"),
            ("Lens", "85.00 mm"),
            (SENSOR_WIDTH_ATTRIBUTE, "24"),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
        let hints = CameraHints::from_attributes(&map);
        assert_eq!(hints.focus_distance, Some(2.5));
        assert_eq!(hints.fstop, Some(1.8));
        assert_eq!(hints.focal_length_mm, Some(85.0));
        assert_eq!(hints.sensor_width_mm, Some(24.0));
    }

    #[test]
    fn ignores_unparsable_and_non_positive_values() {
        let map: BTreeMap<String, String> = [("focus", "-1"), ("aperture", "wide")]
            .into_iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        assert!(CameraHints::from_attributes(&map).is_empty());
    }
}
