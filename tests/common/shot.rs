//! A small focus pull for the sequence tests: a subject 2 m away crossing in front of a
//! checkered wall at 4 m, 64x48, the focus moving from the subject to the wall.
use std::path::{Path, PathBuf};

use lensblur::camera::PhysicalCamera;
use lensblur::image::Image;
use lensblur::stack::{write_stack, Layer, LayerStack, StackWriteOptions};

pub const WIDTH: usize = 64;
pub const HEIGHT: usize = 48;

/// Frame `index` (0-based) of the pull: a tiny sensor so that 64 px get visible blur
/// (K = 0.025 m * 50/3 * 64 = 27 px at f/1); focus 2 m (the subject) to 4 m (the wall).
pub fn camera(index: usize) -> PhysicalCamera {
    PhysicalCamera { focal_length_mm: 50.0, sensor_width_mm: 3.0, fstop: 1.0, focus_distance: 2.0 + 0.4 * index as f32 }
}

/// The layers of a frame; the subject's left edge is at `subject_x`.
pub fn stack(subject_x: usize) -> LayerStack {
    let (w, h) = (WIDTH, HEIGHT);
    let subject = Image::from_fn(w, h, |x, y| {
        if (subject_x..subject_x + 14).contains(&x) && (12..36).contains(&y) {
            [0.9, 0.2 + 0.01 * y as f32, 0.1, 1.0]
        } else {
            [0.0; 4]
        }
    });
    let wall = Image::from_fn(w, h, |x, y| {
        let c = if (x / 4 + y / 4) % 2 == 0 { 0.8 } else { 0.1 };
        // A few highlights, where sampled methods' noise shows most.
        let highlight = if (x * 13 + y * 7) % 61 == 0 { 8.0 } else { 0.0 };
        [c + highlight, c, 1.0 - c, 1.0]
    });
    let layers = vec![
        Layer { name: "subject".into(), rgba: subject, disparity: vec![0.5; w * h] },
        Layer { name: "wall".into(), rgba: wall, disparity: vec![0.25; w * h] },
    ];
    LayerStack::new(w, h, layers).unwrap()
}

/// Writes `shot.NNNN.exr` for each of `frames` into `dir`, the subject still, the camera of
/// each frame (its index in `frames`) stamped in its header when `header_camera`; returns
/// the pattern `dir/shot.####.exr`.
pub fn write_focus_pull(dir: &Path, frames: &[i64], header_camera: bool) -> PathBuf {
    for (index, frame) in frames.iter().enumerate() {
        let options = StackWriteOptions { camera: header_camera.then(|| camera(index)), ..StackWriteOptions::default() };
        write_stack(&dir.join(format!("shot.{frame:04}.exr")), &stack(20), &options).unwrap();
    }
    dir.join("shot.####.exr")
}

/// A camera file (`--camera-file`) giving frame `frames[i]` the camera of index i.
pub fn write_camera_file(path: &Path, frames: &[i64]) {
    let cameras: Vec<(i64, PhysicalCamera)> = frames.iter().enumerate().map(|(index, &frame)| (frame, camera(index))).collect();
    lensblur::sequence::CameraFile::write(path, &cameras).unwrap();
}
