//! A render's options as plain named values: what Python's keyword arguments and a `lensblur
//! serve` request carry. One parser for both, so a name or a check cannot differ between them:
//! a front end hands over a JSON object (Python's keywords become one), and gets a
//! [`JobSpec`] or the library's message naming the option.
use std::path::PathBuf;

use serde::Deserialize;
use serde_json::{Map, Value};

use super::{JobSpec, MethodOptions};
use crate::camera::{Aperture, CameraHints, CocModel, SceneUnit};
use crate::character::bloom::DEFAULT_BLOOM_GAIN;
use crate::character::{Bloom, BlurRemap, CatsEye, Character};
use crate::input::{CameraRequest, InputOptions};
use crate::render::Method;
use crate::stack::deep::{DeepReadOptions, PartChoice};
use crate::stack::{AutoLayerOptions, DepthKind};
use crate::{Error, Result};

/// The options of every render, in the order help texts list them: `lensblur render`'s
/// image-changing flags in snake_case (the camera's own flags are [`CameraValues`]).
pub const RENDER_OPTIONS: [&str; 21] = [
    "method", "aperture", "scene_unit", "layer_spacing", "max_layers", "no_edge_guess", "near_blur", "far_blur", "max_blur",
    "focus_at", "bloom", "chromatic", "cats_eye", "samples", "iterations", "highlight_sigma", "tilt_shift",
    "focal_planes", "overscan", "tile", "max_memory",
];

/// The further options of a render read from a file: how the file is read (`--layers`,
/// `--depth`, `--depth-kind`, the deep flags).
pub const FILE_OPTIONS: [&str; 9] =
    ["layers", "depth", "depth_kind", "max_pixels", "replace_nonfinite", "merge", "max_samples", "deep_part", "deep_flatten"];

/// `bloom`: a threshold (gain [`DEFAULT_BLOOM_GAIN`], as `--bloom THRESHOLD`), or
/// `[threshold, gain]`.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum BloomValue {
    Pair(f32, f32),
    Threshold(f32),
}

/// Every option of [`RENDER_OPTIONS`] and [`FILE_OPTIONS`]; `None`: not given (the default).
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct JobOptions {
    pub method: Option<String>,
    pub aperture: Option<String>,
    pub scene_unit: Option<String>,
    pub layer_spacing: Option<f32>,
    pub max_layers: Option<usize>,
    pub no_edge_guess: Option<bool>,
    pub near_blur: Option<f32>,
    pub far_blur: Option<f32>,
    pub max_blur: Option<f32>,
    pub focus_at: Option<[usize; 2]>,
    pub bloom: Option<BloomValue>,
    pub chromatic: Option<[f32; 3]>,
    pub cats_eye: Option<f32>,
    pub samples: Option<u32>,
    pub iterations: Option<u32>,
    pub highlight_sigma: Option<f32>,
    pub tilt_shift: Option<[f32; 2]>,
    pub focal_planes: Option<Vec<f32>>,
    pub overscan: Option<usize>,
    pub tile: Option<usize>,
    pub max_memory: Option<u64>,
    pub layers: Option<Vec<String>>,
    pub depth: Option<PathBuf>,
    pub depth_kind: Option<String>,
    pub max_pixels: Option<u64>,
    pub replace_nonfinite: Option<bool>,
    pub merge: Option<Vec<PathBuf>>,
    pub max_samples: Option<u64>,
    pub deep_part: Option<String>,
    pub deep_flatten: Option<bool>,
}

/// Which options a caller takes: a render of arrays or of a resident stack takes
/// [`RENDER_OPTIONS`]; a render read from a file also takes [`FILE_OPTIONS`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OptionSet {
    Render,
    File,
}

impl OptionSet {
    fn names(self) -> Vec<&'static str> {
        match self {
            OptionSet::Render => RENDER_OPTIONS.to_vec(),
            OptionSet::File => RENDER_OPTIONS.iter().chain(FILE_OPTIONS.iter()).copied().collect(),
        }
    }
}

impl JobOptions {
    /// The options named in `object` (a JSON object: `{"near_blur": 2, "focus_at": [40, 100]}`;
    /// `null` is not given). An unknown name or a value of the wrong type is refused naming the
    /// option (`Error::InvalidParameter` with parameter `"options"`).
    pub fn from_json(object: Map<String, Value>, accepted: OptionSet) -> Result<Self> {
        let names = accepted.names();
        if let Some(key) = object.keys().find(|key| !names.contains(&key.as_str())) {
            let hint = if FILE_OPTIONS.contains(&key.as_str()) { " (a file option: give it where the file is read)" } else { "" };
            return Err(Error::invalid("options", format!("unknown option '{key}'{hint}; the options are: {}", names.join(", "))));
        }
        // Field by field, so that a wrong type names its option.
        for (key, value) in &object {
            let single = Value::Object(Map::from_iter([(key.clone(), value.clone())]));
            if let Err(error) = serde_json::from_value::<JobOptions>(single) {
                return Err(Error::invalid("options", format!("option {key}: {error}")));
            }
        }
        serde_json::from_value(Value::Object(object)).map_err(|e| Error::invalid("options", format!("options: {e}")))
    }

    /// How a file is read.
    pub fn input(&self) -> Result<InputOptions> {
        let defaults = InputOptions::default();
        let deep = DeepReadOptions {
            max_samples: self.max_samples.unwrap_or(defaults.deep.max_samples),
            max_pixels: self.max_pixels.unwrap_or(defaults.deep.max_pixels),
            part: self.deep_part.as_deref().map(str::parse::<PartChoice>).transpose()?.unwrap_or_default(),
        };
        let auto_layer =
            AutoLayerOptions::chosen(self.layer_spacing, self.max_layers, self.no_edge_guess.unwrap_or(false));
        Ok(InputOptions {
            layers: self.layers.clone(),
            depth_kind: self.depth_kind.as_deref().map(str::parse::<DepthKind>).transpose()?,
            depth_image: self.depth.clone(),
            max_pixels: deep.max_pixels,
            replace_nonfinite: self.replace_nonfinite.unwrap_or(false),
            merge: self.merge.clone().unwrap_or_default(),
            deep,
            deep_flatten: self.deep_flatten.unwrap_or(false),
            auto_layer,
            ..defaults
        })
    }

    /// The job's spec: `camera` (None: everything from the file's header), `default_method`
    /// unless `method` is given. [`super::RenderJob::new`] checks it.
    pub fn spec(&self, camera: Option<&CameraValues>, default_method: Method) -> Result<JobSpec> {
        let scene_unit = self.scene_unit.as_deref().map(str::parse::<SceneUnit>).transpose()?;
        let aperture = Aperture::parse(self.aperture.as_deref().unwrap_or("disk"))?;
        let bloom = self.bloom.map(|bloom| match bloom {
            BloomValue::Pair(threshold, gain) => Bloom { threshold, gain },
            BloomValue::Threshold(threshold) => Bloom { threshold, gain: DEFAULT_BLOOM_GAIN },
        });
        Ok(JobSpec {
            method: self.method.as_deref().map(str::parse::<Method>).transpose()?.unwrap_or(default_method),
            camera: CameraValues::request(camera, aperture, scene_unit)?,
            input: self.input()?,
            method_options: MethodOptions {
                samples: self.samples,
                iterations: self.iterations,
                highlight_sigma: self.highlight_sigma,
                tilt_shift: self.tilt_shift,
                focal_planes: self.focal_planes.clone(),
            },
            character: Character {
                remap: BlurRemap { near: self.near_blur.unwrap_or(1.0), far: self.far_blur.unwrap_or(1.0), max_px: self.max_blur },
                focus_at: self.focus_at,
                bloom,
                chromatic: self.chromatic,
                cats_eye: self.cats_eye.map(CatsEye::new).transpose()?,
            },
            overscan: self.overscan.unwrap_or(0),
            tile: self.tile,
            max_memory: self.max_memory,
            ..JobSpec::default()
        })
    }
}

/// A camera as a caller names its values: physical (`focal_length_mm`, `fstop`,
/// `focus_distance`, optionally `sensor_width_mm`; any left out come from the file's header) or
/// normalised (`k_px`: CoC pixels per unit of disparity, `focus_disparity`).
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CameraValues {
    pub focal_length_mm: Option<f32>,
    pub fstop: Option<f32>,
    pub focus_distance: Option<f32>,
    pub sensor_width_mm: Option<f32>,
    pub k_px: Option<f32>,
    pub focus_disparity: Option<f32>,
}

impl CameraValues {
    /// The camera in a JSON object, refusing unknown names and a camera that mixes the two
    /// models or gives half of the normalised one.
    pub fn from_json(value: Value) -> Result<Self> {
        let camera: Self =
            serde_json::from_value(value).map_err(|e| Error::invalid("camera", format!("camera: {e}")))?;
        let physical = [camera.focal_length_mm, camera.fstop, camera.focus_distance, camera.sensor_width_mm];
        match (camera.k_px, camera.focus_disparity) {
            (Some(_), Some(_)) if physical.iter().any(Option::is_some) => Err(Error::invalid(
                "camera",
                "camera: give a physical camera (focal_length_mm, fstop, focus_distance, sensor_width_mm) or the normalised model (k_px, focus_disparity), not both",
            )),
            (Some(_), None) | (None, Some(_)) => {
                Err(Error::invalid("camera", "camera: the normalised model needs both k_px and focus_disparity"))
            }
            _ => Ok(camera),
        }
    }

    /// The library's camera request (None: everything from the file's header).
    pub fn request(camera: Option<&Self>, aperture: Aperture, scene_unit: Option<SceneUnit>) -> Result<CameraRequest> {
        let Some(camera) = camera else {
            return Ok(CameraRequest { aperture, scene_unit, ..CameraRequest::default() });
        };
        let normalised = match (camera.k_px, camera.focus_disparity) {
            (Some(k), Some(focus)) => Some(CocModel::new(k, focus)?),
            _ => None,
        };
        let physical = CameraHints {
            focal_length_mm: camera.focal_length_mm,
            sensor_width_mm: camera.sensor_width_mm,
            fstop: camera.fstop,
            focus_distance: camera.focus_distance,
        };
        Ok(CameraRequest { physical, normalised, aperture, scene_unit })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn object(value: Value) -> Map<String, Value> {
        match value {
            Value::Object(map) => map,
            _ => unreachable!("the tests pass objects"),
        }
    }

    #[test]
    fn options_become_the_job_the_command_line_builds() {
        let options = JobOptions::from_json(
            object(json!({"near_blur": 2, "focus_at": [40, 100], "bloom": [3, 2], "max_layers": 4, "no_edge_guess": true, "samples": null})),
            OptionSet::Render,
        )
        .unwrap();
        let spec = options.spec(None, Method::DrBokeh).unwrap();
        assert_eq!(spec.character.remap.near, 2.0);
        assert_eq!(spec.character.focus_at, Some([40, 100]));
        assert_eq!(spec.character.bloom, Some(Bloom { threshold: 3.0, gain: 2.0 }));
        assert_eq!(spec.input.auto_layer.max_layers, 4);
        assert!(!spec.input.auto_layer.guess_beyond_frame, "--no-edge-guess");
        assert_eq!(JobOptions::default().input().unwrap().auto_layer, AutoLayerOptions::default(), "nothing given: the defaults");
        assert!(JobOptions::default().input().unwrap().auto_layer.guess_beyond_frame, "the canvas by default");
        assert_eq!(spec.method_options.samples, None);
        let threshold = JobOptions { bloom: Some(BloomValue::Threshold(1.5)), ..JobOptions::default() };
        assert_eq!(threshold.spec(None, Method::DrBokeh).unwrap().character.bloom.unwrap().gain, DEFAULT_BLOOM_GAIN);
    }

    #[test]
    fn an_unknown_name_or_a_wrong_type_is_refused_naming_the_option() {
        let error = JobOptions::from_json(object(json!({"nearblur": 2})), OptionSet::Render).unwrap_err().to_string();
        assert!(error.starts_with("unknown option 'nearblur'; the options are: method, aperture"), "{error}");
        let error = JobOptions::from_json(object(json!({"deep_flatten": true})), OptionSet::Render).unwrap_err().to_string();
        assert!(error.contains("'deep_flatten' (a file option"), "{error}");
        assert!(JobOptions::from_json(object(json!({"deep_flatten": true})), OptionSet::File).is_ok());
        let error = JobOptions::from_json(object(json!({"focus_at": [1, 2, 3]})), OptionSet::Render).unwrap_err().to_string();
        assert!(error.starts_with("option focus_at: "), "{error}");
        let error = JobOptions::from_json(object(json!({"samples": "many"})), OptionSet::Render).unwrap_err().to_string();
        assert!(error.starts_with("option samples: invalid type: string \"many\""), "{error}");
    }

    #[test]
    fn a_camera_is_one_model_or_the_other() {
        let physical = CameraValues::from_json(json!({"focal_length_mm": 50, "fstop": 2, "focus_distance": 3})).unwrap();
        assert_eq!(physical.fstop, Some(2.0));
        assert!(CameraValues::from_json(json!({"k_px": 8, "focus_disparity": 0.5})).is_ok());
        for bad in [json!({"k_px": 8}), json!({"k_px": 8, "focus_disparity": 0.5, "fstop": 2}), json!({"fstopp": 2})] {
            assert!(CameraValues::from_json(bad.clone()).is_err(), "{bad}");
        }
    }
}
