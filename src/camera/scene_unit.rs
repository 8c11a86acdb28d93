//! Scene units: what one unit of a file's depth is in metres. The physical camera works in
//! metres (its aperture `f / 2N` comes from the focal length in millimetres), so a depth in
//! centimetres read as metres gives circles of confusion 100 times too small. Focus distance
//! is given in the same unit as the file's depth; the CoC model scales the aperture into it.
use crate::{Error, Result};

/// The header attribute (string, a unit name or metres per unit) that says a file's unit.
/// No EXR standard attribute holds one; lensblur writes and reads this one, and a pipeline can
/// stamp it (`oiiotool in.exr --attrib lensblurSceneUnit cm -o out.exr`).
pub const SCENE_UNIT_ATTRIBUTE: &str = "lensblurSceneUnit";

/// One unit of depth, in metres, and the name it was given by.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SceneUnit {
    pub metres: f64,
    pub name: String,
}

impl Default for SceneUnit {
    fn default() -> Self {
        Self { metres: 1.0, name: "m".into() }
    }
}

const NAMED: [(&str, f64); 6] =
    [("m", 1.0), ("cm", 0.01), ("mm", 0.001), ("km", 1000.0), ("in", 0.0254), ("ft", 0.3048)];

impl std::str::FromStr for SceneUnit {
    type Err = Error;
    fn from_str(text: &str) -> Result<Self> {
        let text = text.trim();
        let key = text.to_ascii_lowercase();
        let alias = match key.as_str() {
            "metre" | "metres" | "meter" | "meters" => "m",
            "centimetre" | "centimetres" | "centimeter" | "centimeters" => "cm",
            "millimetre" | "millimetres" | "millimeter" | "millimeters" => "mm",
            "inch" | "inches" => "in",
            "foot" | "feet" => "ft",
            other => other,
        };
        if let Some(&(name, metres)) = NAMED.iter().find(|(n, _)| *n == alias) {
            return Ok(Self { metres, name: name.into() });
        }
        match text.parse::<f64>() {
            Ok(metres) if metres.is_finite() && metres > 0.0 => Ok(Self { metres, name: format!("{metres} m") }),
            _ => Err(Error::invalid(
                "scene unit",
                format!(
                    "unknown scene unit '{text}': give m, cm, mm, km, in, ft or metres per unit (a positive number)"
                ),
            )),
        }
    }
}

impl std::fmt::Display for SceneUnit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_numbers_parse_and_nonsense_is_refused() {
        assert_eq!("cm".parse::<SceneUnit>().unwrap().metres, 0.01);
        assert_eq!("Inches".parse::<SceneUnit>().unwrap().name, "in");
        assert_eq!("0.5".parse::<SceneUnit>().unwrap().metres, 0.5);
        let error = "furlong".parse::<SceneUnit>().unwrap_err().to_string();
        assert!(error.contains("m, cm, mm"), "{error}");
        assert!("-1".parse::<SceneUnit>().is_err());
    }
}
