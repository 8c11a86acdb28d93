//! Files written by `lensblur raytrace`: EXR images (linear, premultiplied, f32), a
//! Blender-style multilayer EXR of the true layers, the camera as JSON and sRGB previews.
//! The files are written with the stack module's writers (the same code as `lensblur render`).
use std::path::{Path, PathBuf};

use super::GroundTruth;
use crate::camera::CocModel;
use crate::image::Image;
use crate::stack::{
    write_image, write_png_preview, write_stack, ExtraChannel, SampleType, StackWriteOptions,
    WriteOptions,
};
use crate::{Error, Result};

/// What `camera.json` holds: enough to re-render or to interpret the depth channels.
#[derive(Debug, serde::Serialize)]
struct CameraRecord<'a> {
    scene: &'a str,
    width: usize,
    height: usize,
    camera: crate::camera::PhysicalCamera,
    coc: CocModel,
    depth_convention: &'static str,
    layers: Vec<&'a str>,
}

/// Writes every file for one ground truth into `dir` (created if missing); returns the paths.
/// EXRs carry the camera in their headers, so `lensblur render DIR/layers.exr` needs no flags.
pub fn write_ground_truth(truth: &GroundTruth, dir: &Path) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).map_err(Error::io(dir))?;
    let float = |extra_channels| WriteOptions {
        sample_type: SampleType::Float,
        extra_channels,
        camera: Some(truth.camera),
        ..WriteOptions::default()
    };
    let depth = ExtraChannel {
        name: "Z".into(),
        sample_type: SampleType::Float,
        values: truth.pinhole_depth.clone(),
    };
    let written = [
        (
            "pinhole.exr",
            Output::Image(&truth.pinhole, float(vec![depth])),
        ),
        (
            "defocused.exr",
            Output::Image(&truth.defocused, float(Vec::new())),
        ),
        ("layers.exr", Output::Stack(&truth.layers)),
        ("pinhole.png", Output::Preview(&truth.pinhole)),
        ("defocused.png", Output::Preview(&truth.defocused)),
    ];
    let mut paths = Vec::new();
    for (name, output) in written {
        let path = dir.join(name);
        match output {
            Output::Image(image, options) => write_image(&path, image, &options)?,
            Output::Stack(stack) => {
                let options = StackWriteOptions {
                    camera: Some(truth.camera),
                    ..StackWriteOptions::default()
                };
                write_stack(&path, stack, &options)?
            }
            Output::Preview(image) => write_png_preview(&path, image)?,
        }
        paths.push(path);
    }
    paths.push(write_camera(truth, &dir.join("camera.json"))?);
    Ok(paths)
}

enum Output<'a> {
    Image(&'a Image, WriteOptions),
    Stack(&'a crate::stack::LayerStack),
    Preview(&'a Image),
}

fn write_camera(truth: &GroundTruth, path: &Path) -> Result<PathBuf> {
    let record = CameraRecord {
        scene: &truth.name,
        width: truth.pinhole.width,
        height: truth.pinhole.height,
        camera: truth.camera,
        coc: truth.coc,
        depth_convention: "planar Z in metres; 1e10 where empty",
        layers: truth
            .layers
            .layers
            .iter()
            .map(|l| l.name.as_str())
            .collect(),
    };
    let json =
        serde_json::to_string_pretty(&record).map_err(|e| Error::input(path, e.to_string()))?;
    std::fs::write(path, json).map_err(Error::io(path))?;
    Ok(path.to_path_buf())
}
