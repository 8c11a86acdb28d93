//! The per-frame camera of a shot (a focus pull, a zoom), for frames whose EXR header carries
//! none: `{"frames": {"1001": {"focal_length_mm": 85, "sensor_width_mm": 36, "fstop": 1.8,
//! "focus_distance": 1.2}, ...}}`. Any field of a frame may be left out (the header or a flag
//! gives it); keys other than these are ignored, so a tool may store more per frame. The
//! Blender add-on writes this file from the scene camera's animation.
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::camera::{CameraHints, PhysicalCamera};
use crate::{Error, Result};

/// A camera file: the camera hints of every frame it lists.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraFile {
    path: PathBuf,
    frames: BTreeMap<i64, CameraHints>,
}

#[derive(serde::Deserialize)]
struct FileJson {
    frames: BTreeMap<String, FrameJson>,
}

#[derive(serde::Deserialize)]
struct FrameJson {
    focal_length_mm: Option<f64>,
    sensor_width_mm: Option<f64>,
    fstop: Option<f64>,
    focus_distance: Option<f64>,
}

impl CameraFile {
    /// Writes (atomically) the camera file of a shot whose frame `f` has camera `c`, for each
    /// `(f, c)` of `cameras`.
    pub fn write(path: &Path, cameras: &[(i64, PhysicalCamera)]) -> Result<()> {
        let frames: serde_json::Map<String, serde_json::Value> = cameras
            .iter()
            .map(|(frame, camera)| {
                // The shortest decimal that reads back as the same f32 (1.4, not 1.399999976).
                let number = |v: f32| v.to_string().parse::<f64>().unwrap_or(f64::from(v));
                let entry = serde_json::json!({
                    "focal_length_mm": number(camera.focal_length_mm),
                    "sensor_width_mm": number(camera.sensor_width_mm),
                    "fstop": number(camera.fstop),
                    "focus_distance": number(camera.focus_distance),
                });
                (frame.to_string(), entry)
            })
            .collect();
        let text = serde_json::to_string_pretty(&serde_json::json!({ "frames": frames }))
            .map_err(|e| Error::input(path, format!("encoding the camera file: {e}")))?;
        crate::atomic_file::write_atomically(path, |w| {
            std::io::Write::write_all(w, text.as_bytes()).map_err(Error::io(path))
        })
    }

    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(Error::io(path))?;
        Self::parse(path, &text)
    }

    /// Parses the text of the file at `path` (named in every message).
    pub fn parse(path: &Path, text: &str) -> Result<Self> {
        let invalid = |message: String| Error::input(path, message);
        let json: FileJson = serde_json::from_str(text).map_err(|e| {
            invalid(format!(
                "not a camera file ({e}); expected {{\"frames\": {{\"1001\": {{\"focal_length_mm\": 85, \
                 \"sensor_width_mm\": 36, \"fstop\": 1.8, \"focus_distance\": 1.2}}, ...}}}}"
            ))
        })?;
        let mut frames = BTreeMap::new();
        for (key, entry) in json.frames {
            let frame: i64 = key.trim().parse().map_err(|_| invalid(format!("frame key '{key}' is not an integer")))?;
            let value = |name: &str, value: Option<f64>| match value {
                Some(v) if !(v.is_finite() && v > 0.0 && v <= f64::from(f32::MAX)) => {
                    Err(invalid(format!("frame {key}: {name} must be a positive number, got {v}")))
                }
                v => Ok(v.map(|v| v as f32)),
            };
            let hints = CameraHints {
                focal_length_mm: value("focal_length_mm", entry.focal_length_mm)?,
                sensor_width_mm: value("sensor_width_mm", entry.sensor_width_mm)?,
                fstop: value("fstop", entry.fstop)?,
                focus_distance: value("focus_distance", entry.focus_distance)?,
            };
            if frames.insert(frame, hints).is_some() {
                return Err(invalid(format!("frame {frame} is listed twice (keys '{key}' and another)")));
            }
        }
        Ok(Self { path: path.to_path_buf(), frames })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The camera of `frame`; a frame the file does not list is an error naming it.
    pub fn hints(&self, frame: i64) -> Result<CameraHints> {
        self.check_covers(&[frame])?;
        Ok(self.frames[&frame])
    }

    /// Refuses, before any work, a frame list the file does not cover, naming every frame missing.
    pub fn check_covers(&self, frames: &[i64]) -> Result<()> {
        let missing: Vec<String> = frames.iter().filter(|f| !self.frames.contains_key(f)).map(i64::to_string).collect();
        if missing.is_empty() {
            return Ok(());
        }
        let listed = match (self.frames.keys().next(), self.frames.keys().next_back()) {
            (Some(first), Some(last)) => format!("it lists {} frame(s), {first} to {last}", self.frames.len()),
            _ => "it lists no frames".to_string(),
        };
        let shown = if missing.len() > 10 { format!("{}, ...", missing[..10].join(", ")) } else { missing.join(", ") };
        Err(Error::input(
            &self.path,
            format!(
                "no camera for frame(s) {shown} ({} missing; {listed}); add them to the camera file or \
                 render only the frames it has",
                missing.len()
            ),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SHOT: &str = r#"{"frames": {
        "1001": {"focal_length_mm": 85, "sensor_width_mm": 36, "fstop": 1.8, "focus_distance": 1.2, "shutter": 0.5},
        "1002": {"focus_distance": 1.4}
    }, "scene": "pull"}"#;

    #[test]
    fn reads_each_frames_camera_and_ignores_other_keys() {
        let file = CameraFile::parse(Path::new("shot.json"), SHOT).unwrap();
        let first = file.hints(1001).unwrap();
        assert_eq!((first.focal_length_mm, first.sensor_width_mm, first.fstop, first.focus_distance), (Some(85.0), Some(36.0), Some(1.8), Some(1.2)));
        let second = file.hints(1002).unwrap();
        assert_eq!((second.focal_length_mm, second.focus_distance), (None, Some(1.4)), "fields may be left to the header or flags");
    }

    #[test]
    fn a_written_file_reads_back_frame_for_frame() {
        let path = std::env::temp_dir().join(format!("lensblur-camera-file-{}.json", std::process::id()));
        let camera = |focus| PhysicalCamera { focal_length_mm: 85.0, sensor_width_mm: 36.0, fstop: 1.8, focus_distance: focus };
        CameraFile::write(&path, &[(1001, camera(1.2)), (1002, camera(1.5))]).unwrap();
        let file = CameraFile::read(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(file.hints(1001).unwrap(), CameraHints::from_camera(&camera(1.2)));
        assert_eq!(file.hints(1002).unwrap(), CameraHints::from_camera(&camera(1.5)));
    }

    #[test]
    fn a_missing_frame_is_an_error_naming_it_and_the_file() {
        let file = CameraFile::parse(Path::new("shot.json"), SHOT).unwrap();
        let message = file.check_covers(&[1001, 1003, 1007]).unwrap_err().to_string();
        assert!(message.starts_with("shot.json: no camera for frame(s) 1003, 1007 (2 missing; it lists 2 frame(s), 1001 to 1002)"), "{message}");
    }

    #[test]
    fn bad_values_and_shapes_are_refused_with_the_file_and_frame() {
        for (text, why) in [
            (r#"{"frames": {"1": {"fstop": -2}}}"#, "frame 1: fstop must be a positive number, got -2"),
            (r#"{"frames": {"one": {}}}"#, "frame key 'one' is not an integer"),
            (r#"{"frames": {"1": {}, "01": {}}}"#, "frame 1 is listed twice"),
            (r#"{"1001": {"fstop": 2}}"#, "not a camera file"),
            (r#"{"frames": {"1": {"fstop": "f/2"}}}"#, "not a camera file"),
        ] {
            let message = CameraFile::parse(Path::new("cam.json"), text).unwrap_err().to_string();
            assert!(message.starts_with("cam.json: ") && message.contains(why), "{text}: {message}");
        }
    }
}
