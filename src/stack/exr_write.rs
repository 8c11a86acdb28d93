//! Writing images and stacks as EXR: single part, ZIP scanline compression (what Blender
//! and OIIO write by default), channel names in the convention the input used.
//! Files appear atomically: written to a temporary file beside the target, then renamed.
use std::path::Path;

use exr::meta::attribute::{AttributeValue, Text};
use exr::prelude::{
    f16, AnyChannel, AnyChannels, Compression, Encoding, FlatSamples, ImageAttributes, IntegerBounds,
    LayerAttributes, LineOrder, WritableImage,
};

use super::info::{ExtraChannel, SampleType};
use super::{DepthKind, LayerStack};
use crate::camera::hints::{FOCAL_LENGTH_ATTRIBUTE, SENSOR_WIDTH_ATTRIBUTE};
use crate::atomic_file::write_atomically;
use crate::camera::PhysicalCamera;
use crate::image::Image;
use crate::{Error, Result};

/// How [`write_image`] names and stores its channels.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WriteOptions {
    /// `None`: plain `R,G,B,A`. `Some(name)`: `name.Combined.R...` as Blender's Image node reads.
    pub output_layer: Option<String>,
    /// Half or float for the colour channels (`Uint` is refused).
    pub sample_type: SampleType,
    /// Channels copied through unchanged (never blurred), each display-window sized.
    pub extra_channels: Vec<ExtraChannel>,
    /// Camera parameters stamped into the header (see [`crate::camera::CameraHints`]).
    pub camera: Option<PhysicalCamera>,
}

/// How [`write_stack`] names and stores a stack.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StackWriteOptions {
    pub naming: StackNaming,
    pub depth_kind: DepthKind,
    /// Camera parameters stamped into the header, so the file renders without camera flags.
    pub camera: Option<PhysicalCamera>,
}

/// Channel naming of a written stack.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum StackNaming {
    /// `<Layer>.Combined.{R,G,B,A}` + `<Layer>.Depth.Z`.
    #[default]
    BlenderMultilayer,
    /// `<Layer>.{R,G,B,A,Z}` (OpenEXR / OIIO / Nuke).
    LayerDotChannel,
}

impl StackNaming {
    /// The naming to write results in for an input read in `convention` (multi-part and
    /// unprefixed inputs are written single-part as `layer.R...`).
    pub fn for_convention(convention: super::naming::Convention) -> Self {
        use super::naming::Convention;
        match convention {
            Convention::BlenderMultilayer | Convention::BlenderFileOutput => {
                StackNaming::BlenderMultilayer
            }
            Convention::LayerDotChannel | Convention::Unprefixed | Convention::MultiPart => {
                StackNaming::LayerDotChannel
            }
        }
    }
}

fn samples(values: Vec<f32>, sample_type: SampleType) -> Result<FlatSamples> {
    match sample_type {
        SampleType::Float => Ok(FlatSamples::F32(values)),
        SampleType::Half => Ok(FlatSamples::F16(
            values.into_iter().map(f16::from_f32).collect(),
        )),
        SampleType::Uint => Err(Error::param(
            "colour cannot be written as unsigned integers; use half or float",
        )),
    }
}

fn rgba_channels(
    image: &Image,
    prefix: &str,
    sample_type: SampleType,
) -> Result<Vec<AnyChannel<FlatSamples>>> {
    (0..4)
        .zip(["R", "G", "B", "A"])
        .map(|(c, name)| {
            let values = image.pixels.iter().map(|p| p[c]).collect();
            Ok(AnyChannel::new(
                format!("{prefix}{name}").as_str(),
                samples(values, sample_type)?,
            ))
        })
        .collect()
}

fn extra_channel(extra: &ExtraChannel, pixels: usize) -> Result<AnyChannel<FlatSamples>> {
    if extra.values.len() != pixels {
        return Err(Error::param(format!(
            "pass-through channel '{}' has {} samples, the image {pixels}",
            extra.name,
            extra.values.len()
        )));
    }
    let data = match extra.sample_type {
        SampleType::Uint => FlatSamples::U32(extra.values.iter().map(|&v| v as u32).collect()),
        other => samples(extra.values.clone(), other)?,
    };
    Ok(AnyChannel::new(extra.name.as_str(), data))
}

/// Writes one image (plain or Blender-named RGBA plus pass-through channels).
pub fn write_image(path: &Path, image: &Image, options: &WriteOptions) -> Result<()> {
    let prefix = options
        .output_layer
        .as_ref()
        .map(|n| format!("{n}.Combined."))
        .unwrap_or_default();
    let mut channels = rgba_channels(image, &prefix, options.sample_type)?;
    for extra in &options.extra_channels {
        if channels.iter().any(|c| c.name.to_string() == extra.name) {
            return Err(Error::param(format!(
                "pass-through channel '{}' collides with an output channel",
                extra.name
            )));
        }
        channels.push(extra_channel(extra, image.width * image.height)?);
    }
    write_channels(
        path,
        image.width,
        image.height,
        channels,
        options.camera.as_ref(),
    )
}

/// Writes a layer stack, one named layer per stack layer, depth in `depth_kind`; where a
/// layer is empty (alpha 0) depth is the far value (Z = 1e10, as Blender writes it).
pub fn write_stack(path: &Path, stack: &LayerStack, options: &StackWriteOptions) -> Result<()> {
    let mut channels = Vec::new();
    for layer in &stack.layers {
        let (colour, depth) = match options.naming {
            StackNaming::BlenderMultilayer => (
                format!("{}.Combined.", layer.name),
                format!("{}.Depth.Z", layer.name),
            ),
            StackNaming::LayerDotChannel => {
                (format!("{}.", layer.name), format!("{}.Z", layer.name))
            }
        };
        channels.extend(rgba_channels(&layer.rgba, &colour, SampleType::Float)?);
        let stored = layer
            .rgba
            .pixels
            .iter()
            .zip(&layer.disparity)
            .map(|(p, &d)| {
                options
                    .depth_kind
                    .from_disparity(if p[3] > 0.0 { d } else { 0.0 })
            })
            .collect();
        channels.push(AnyChannel::new(depth.as_str(), FlatSamples::F32(stored)));
    }
    write_channels(
        path,
        stack.width,
        stack.height,
        channels,
        options.camera.as_ref(),
    )
}

/// Writes float channels by name (single part, ZIP scanlines), e.g. gradients named after the
/// channels of an input file.
pub fn write_named_channels(path: &Path, width: usize, height: usize, channels: Vec<(String, Vec<f32>)>) -> Result<()> {
    let channels = channels
        .into_iter()
        .map(|(name, values)| {
            if values.len() != width * height {
                return Err(Error::param(format!("channel '{name}' has {} samples, the image {}", values.len(), width * height)));
            }
            Ok(AnyChannel::new(name.as_str(), FlatSamples::F32(values)))
        })
        .collect::<Result<Vec<_>>>()?;
    write_channels(path, width, height, channels, None)
}

/// Header attributes holding a camera, named as [`crate::camera::CameraHints`] reads them:
/// the part's own attributes and the file's shared ones.
///
/// The exr crate keeps custom attributes in a `HashMap`, whose iteration order (and so the
/// header's byte order) changes from process to process. Each map gets at most one entry,
/// so the same image always gives the same bytes.
fn camera_attributes(camera: Option<&PhysicalCamera>) -> (LayerAttributes, ImageAttributes) {
    let mut own = LayerAttributes::default();
    let mut shared = ImageAttributes::new(IntegerBounds::from_dimensions((0, 0)));
    if let Some(camera) = camera {
        own.focus = Some(camera.focus_distance);
        own.aperture = Some(camera.fstop);
        own.other.insert(Text::from(FOCAL_LENGTH_ATTRIBUTE), AttributeValue::F32(camera.focal_length_mm));
        shared.other.insert(Text::from(SENSOR_WIDTH_ATTRIBUTE), AttributeValue::F32(camera.sensor_width_mm));
    }
    (own, shared)
}

fn write_channels(
    path: &Path,
    width: usize,
    height: usize,
    channels: Vec<AnyChannel<FlatSamples>>,
    camera: Option<&PhysicalCamera>,
) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(Error::param("cannot write an empty image"));
    }
    let mut seen = std::collections::HashSet::new();
    if let Some(dup) = channels
        .iter()
        .map(|c| c.name.to_string())
        .find(|n| !seen.insert(n.clone()))
    {
        return Err(Error::param(format!(
            "channel '{dup}' would be written twice (duplicate layer names?)"
        )));
    }
    let encoding = Encoding {
        compression: Compression::ZIP16,
        blocks: exr::prelude::Blocks::ScanLines,
        line_order: LineOrder::Increasing,
    };
    let (own, mut shared) = camera_attributes(camera);
    let layer = exr::prelude::Layer::new((width, height), own, encoding, AnyChannels::sort(channels.into()));
    shared.display_window = IntegerBounds::from_dimensions((width, height));
    let image = exr::prelude::Image::new(shared, layer);
    write_atomically(path, |file| {
        image
            .write()
            .to_buffered(file)
            .map_err(|e| Error::input(path, format!("cannot write EXR: {e}")))
    })
}
