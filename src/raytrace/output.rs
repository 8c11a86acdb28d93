//! Files written by `lensblur raytrace`: EXR images (linear, premultiplied, f32), a
//! Blender-style multilayer EXR of the true layers, the camera as JSON and sRGB previews.
//! All EXR writing of this module is here, so the stack module's writer can replace it.
use std::path::{Path, PathBuf};

use exr::prelude::{AnyChannel, AnyChannels, Encoding, FlatSamples, Image as ExrImage, LayerAttributes, SmallVec, WritableImage};

use super::{GroundTruth, EMPTY_DEPTH};
use crate::camera::CocModel;
use crate::image::Image;
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
pub fn write_ground_truth(truth: &GroundTruth, dir: &Path) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).map_err(|source| Error::Io { path: dir.to_path_buf(), source })?;
    let (w, h) = (truth.pinhole.width, truth.pinhole.height);
    let mut written = Vec::new();
    let mut pinhole = rgba_channels("", &truth.pinhole);
    pinhole.push(AnyChannel::new("Z", FlatSamples::F32(truth.pinhole_depth.clone())));
    written.push(write_exr(dir.join("pinhole.exr"), w, h, pinhole)?);
    written.push(write_exr(dir.join("defocused.exr"), w, h, rgba_channels("", &truth.defocused))?);
    let mut layers = Vec::new();
    for layer in &truth.layers.layers {
        layers.extend(rgba_channels(&format!("{}.Combined.", layer.name), &layer.rgba));
        let z = layer.rgba.pixels.iter().zip(&layer.disparity).map(|(p, &d)| if p[3] > 0.0 && d > 0.0 { 1.0 / d } else { EMPTY_DEPTH });
        layers.push(AnyChannel::new(format!("{}.Depth.Z", layer.name).as_str(), FlatSamples::F32(z.collect())));
    }
    written.push(write_exr(dir.join("layers.exr"), w, h, layers)?);
    written.push(write_camera(truth, &dir.join("camera.json"))?);
    written.push(write_png(&truth.pinhole, &dir.join("pinhole.png"))?);
    written.push(write_png(&truth.defocused, &dir.join("defocused.png"))?);
    Ok(written)
}

fn rgba_channels(prefix: &str, image: &Image) -> Vec<AnyChannel<FlatSamples>> {
    ["R", "G", "B", "A"]
        .iter()
        .enumerate()
        .map(|(c, name)| {
            let samples = image.pixels.iter().map(|p| p[c]).collect();
            AnyChannel::new(format!("{prefix}{name}").as_str(), FlatSamples::F32(samples))
        })
        .collect()
}

fn write_exr(path: PathBuf, width: usize, height: usize, channels: Vec<AnyChannel<FlatSamples>>) -> Result<PathBuf> {
    let channels = AnyChannels::sort(channels.into_iter().collect::<SmallVec<_>>());
    let image = ExrImage::from_layer(exr::image::Layer::new((width, height), LayerAttributes::default(), Encoding::SMALL_LOSSLESS, channels));
    image.write().to_file(&path).map_err(|e| Error::input(&path, format!("cannot write EXR: {e}")))?;
    Ok(path)
}

fn write_camera(truth: &GroundTruth, path: &Path) -> Result<PathBuf> {
    let record = CameraRecord {
        scene: &truth.name,
        width: truth.pinhole.width,
        height: truth.pinhole.height,
        camera: truth.camera,
        coc: truth.coc,
        depth_convention: "planar Z in metres; 1e10 where empty",
        layers: truth.layers.layers.iter().map(|l| l.name.as_str()).collect(),
    };
    let json = serde_json::to_string_pretty(&record).map_err(|e| Error::input(path, e.to_string()))?;
    std::fs::write(path, json).map_err(|source| Error::Io { path: path.to_path_buf(), source })?;
    Ok(path.to_path_buf())
}

/// sRGB 8-bit preview of a premultiplied image over black, clipped to [0, 1].
fn write_png(image: &Image, path: &Path) -> Result<PathBuf> {
    let encode = |c: f32| {
        let c = c.clamp(0.0, 1.0);
        let s = if c <= 0.003_130_8 { 12.92 * c } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 };
        (s * 255.0 + 0.5) as u8
    };
    let bytes: Vec<u8> = image.pixels.iter().flat_map(|p| [encode(p[0]), encode(p[1]), encode(p[2])]).collect();
    let buffer = image::RgbImage::from_raw(image.width as u32, image.height as u32, bytes)
        .ok_or_else(|| Error::input(path, "image buffer has the wrong size"))?;
    buffer.save(path).map_err(|e| Error::input(path, format!("cannot write PNG: {e}")))?;
    Ok(path.to_path_buf())
}
