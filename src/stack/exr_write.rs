//! Writing images and stacks as EXR: single part, ZIP scanline compression (what Blender
//! and OIIO write by default; the blocks coded by `exr_zip.rs`), channel names in the
//! convention the input used.
//! Files appear atomically: written to a temporary file beside the target, then renamed.
use std::path::Path;

use exr::meta::attribute::{AttributeValue, Text};
use exr::prelude::{
    f16, AnyChannel, AnyChannels, Compression, Encoding, FlatSamples, ImageAttributes, IntegerBounds,
    LayerAttributes, LineOrder,
};
use exr::block::chunk::{Chunk, CompressedBlock, CompressedScanLineBlock};
use exr::block::writer::ChunksWriter;
use exr::block::BlockIndex;
use exr::image::write::layers::{LayersWriter, WritableLayers};
use exr::meta::BlockDescription;
use rayon::prelude::*;

use super::exr_zip::zip_block;
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
    /// `None`: plain `R,G,B,A`. `Some(name)`: a layer `name` named per `layer_naming`
    /// (by default `name.Combined.R...`, as Blender's Image node reads it).
    pub output_layer: Option<String>,
    /// How `output_layer` is named (the input's convention, see [`StackNaming::for_convention`]).
    pub layer_naming: StackNaming,
    /// Origin of the display window (the input's, so the output lines up with it).
    pub display_origin: (i32, i32),
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
    /// One part per layer, named after it, holding `R,G,B,A,Z`.
    MultiPart,
}

impl StackNaming {
    /// The naming to write results in for an input read in `convention`: the same one, so
    /// the tool that made the input finds the result where it looks; Blender's form for
    /// inputs with no layer names of their own (plain `R,G,B,A,Z`).
    pub fn for_convention(convention: super::naming::Convention) -> Self {
        use super::naming::Convention;
        match convention {
            Convention::BlenderMultilayer | Convention::BlenderFileOutput | Convention::Unprefixed => {
                StackNaming::BlenderMultilayer
            }
            Convention::LayerDotChannel => StackNaming::LayerDotChannel,
            Convention::MultiPart => StackNaming::MultiPart,
        }
    }

    /// Part name and channel-name prefixes (colour, depth) of layer `name`.
    fn layer_names(self, name: &str) -> (Option<String>, String, String) {
        match self {
            StackNaming::BlenderMultilayer => (None, format!("{name}.Combined."), format!("{name}.Depth.")),
            StackNaming::LayerDotChannel => (None, format!("{name}."), format!("{name}.")),
            StackNaming::MultiPart => (Some(name.to_string()), String::new(), String::new()),
        }
    }
}

/// The channels of one part of a file to write (`name` is required when there are several).
struct PartChannels {
    name: Option<String>,
    channels: Vec<AnyChannel<FlatSamples>>,
}

fn samples(values: Vec<f32>, sample_type: SampleType) -> Result<FlatSamples> {
    match sample_type {
        SampleType::Float => Ok(FlatSamples::F32(values)),
        SampleType::Half => Ok(FlatSamples::F16(values.par_iter().map(|&v| f16::from_f32(v)).collect())),
        SampleType::Uint => Err(Error::unsupported(
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
            // On every core: the crate compresses on every core, and this was a serial step
            // before it (an 8K float output: 7.08 -> 6.76 s here, the pair ratio 0.92).
            let values = image.pixels.par_iter().map(|p| p[c]).collect();
            Ok(AnyChannel::new(
                format!("{prefix}{name}").as_str(),
                samples(values, sample_type)?,
            ))
        })
        .collect()
}

fn extra_channel(extra: &ExtraChannel, pixels: usize) -> Result<AnyChannel<FlatSamples>> {
    if extra.values.len() != pixels {
        return Err(Error::data(format!(
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

/// Writes one image (plain RGBA or a named layer, plus pass-through channels, which share
/// the colour's part).
pub fn write_image(path: &Path, image: &Image, options: &WriteOptions) -> Result<()> {
    let (part, prefix, _) = match &options.output_layer {
        // EXR names are Latin-1: the exr crate panics on anything else.
        Some(name) if Text::new_or_none(name).is_none() => {
            return Err(Error::invalid("output layer name", format!(
                "output layer name '{name}' has characters an EXR name cannot hold; use Latin-1 (e.g. ASCII)"
            )));
        }
        Some(name) => options.layer_naming.layer_names(name),
        None => (None, String::new(), String::new()),
    };
    let mut channels = rgba_channels(image, &prefix, options.sample_type)?;
    for extra in &options.extra_channels {
        if channels.iter().any(|c| c.name.to_string() == extra.name) {
            return Err(Error::data(format!(
                "pass-through channel '{}' collides with an output channel",
                extra.name
            )));
        }
        channels.push(extra_channel(extra, image.width * image.height)?);
    }
    let frame = Frame { width: image.width, height: image.height, origin: options.display_origin };
    write_parts(path, frame, vec![PartChannels { name: part, channels }], options.camera.as_ref())
}

/// Writes a layer stack, one named layer per stack layer, depth in `depth_kind`; where a
/// layer is empty (alpha 0) depth is the far value (Z = 1e10, as Blender writes it).
pub fn write_stack(path: &Path, stack: &LayerStack, options: &StackWriteOptions) -> Result<()> {
    let mut parts: Vec<PartChannels> = Vec::new();
    for layer in &stack.layers {
        let (part, colour, depth) = options.naming.layer_names(&layer.name);
        let mut channels = rgba_channels(&layer.rgba, &colour, SampleType::Float)?;
        let stored = layer
            .rgba
            .pixels
            .par_iter()
            .zip(&layer.disparity)
            .map(|(p, &d)| {
                options
                    .depth_kind
                    .from_disparity(if p[3] > 0.0 { d } else { 0.0 })
            })
            .collect();
        channels.push(AnyChannel::new(format!("{depth}Z").as_str(), FlatSamples::F32(stored)));
        match parts.last_mut() {
            Some(last) if part.is_none() => last.channels.extend(channels),
            _ => parts.push(PartChannels { name: part, channels }),
        }
    }
    let frame = Frame { width: stack.width, height: stack.height, origin: (0, 0) };
    write_parts(path, frame, parts, options.camera.as_ref())
}

/// Writes float channels by name (single part, ZIP scanlines) on a display window at
/// `origin`, e.g. gradients named after the channels of an input file.
pub fn write_named_channels(
    path: &Path,
    (width, height): (usize, usize),
    origin: (i32, i32),
    channels: Vec<(String, Vec<f32>)>,
) -> Result<()> {
    let channels = channels
        .into_iter()
        .map(|(name, values)| {
            if values.len() != width * height {
                return Err(Error::data(format!("channel '{name}' has {} samples, the image {}", values.len(), width * height)));
            }
            Ok(AnyChannel::new(name.as_str(), FlatSamples::F32(values)))
        })
        .collect::<Result<Vec<_>>>()?;
    write_parts(path, Frame { width, height, origin }, vec![PartChannels { name: None, channels }], None)
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

/// The display window of a written file; every part's data window is the whole of it.
#[derive(Clone, Copy)]
struct Frame {
    width: usize,
    height: usize,
    origin: (i32, i32),
}

fn write_parts(path: &Path, frame: Frame, parts: Vec<PartChannels>, camera: Option<&PhysicalCamera>) -> Result<()> {
    if frame.width == 0 || frame.height == 0 {
        return Err(Error::data("cannot write an empty image"));
    }
    let mut seen = std::collections::HashSet::new();
    let qualified = |part: &PartChannels, c: &AnyChannel<FlatSamples>| match &part.name {
        Some(p) => format!("part '{p}' channel '{}'", c.name),
        None => format!("channel '{}'", c.name),
    };
    if let Some(dup) =
        parts.iter().flat_map(|p| p.channels.iter().map(move |c| qualified(p, c))).find(|n| !seen.insert(n.clone()))
    {
        return Err(Error::data(format!("{dup} would be written twice (duplicate layer names?)")));
    }
    let encoding = Encoding {
        compression: Compression::ZIP16,
        blocks: exr::prelude::Blocks::ScanLines,
        line_order: LineOrder::Increasing,
    };
    let (own, mut shared) = camera_attributes(camera);
    let origin = exr::prelude::Vec2(frame.origin.0, frame.origin.1);
    let layers: Vec<_> = parts
        .into_iter()
        .map(|part| {
            let mut attributes = own.clone();
            attributes.layer_name = part.name.as_deref().map(Text::from);
            attributes.layer_position = origin;
            exr::prelude::Layer::new((frame.width, frame.height), attributes, encoding, AnyChannels::sort(part.channels.into()))
        })
        .collect();
    shared.display_window = IntegerBounds::new(origin, (frame.width, frame.height));
    let image = exr::prelude::Image::from_layers(shared, layers);
    write_atomically(path, |file| {
        write_zip_scanlines(&image, file).map_err(|e| Error::input(path, format!("cannot write EXR: {e}")))
    })
}

/// Whether [`write_zip_scanlines`] writes parts of this compression, stored as scan lines or not.
pub(super) fn zip_scanlines(compression: Compression, scan_lines: bool) -> bool {
    matches!(compression, Compression::ZIP16 | Compression::ZIP1) && scan_lines
}

/// Writes `image` (every part ZIP scan lines, 16 or 1 a block: [`zip_scanlines`]) as the exr
/// crate's own writer would, but codes the blocks with [`zip_block`] (libdeflate at OpenEXR's
/// level, about three times as fast as the crate's deflate for the same size: `exr_zip.rs`): on
/// every core, a group of blocks at a time so that only a group is held at once, and written in
/// file order.
pub(super) fn write_zip_scanlines<L>(image: &exr::prelude::Image<L>, file: impl std::io::Write + std::io::Seek) -> exr::error::UnitResult
where
    L: for<'a> WritableLayers<'a>,
{
    const _: () = assert!(
        cfg!(target_endian = "little"),
        "zip_block codes the blocks' native bytes as the file's little-endian ones"
    );
    let headers = image.layer_data.infer_headers(&image.attributes);
    debug_assert!(headers.iter().all(|h| zip_scanlines(h.compression, h.blocks == BlockDescription::ScanLines)));
    let layers = image.layer_data.create_writer(&headers);
    exr::block::write(file, headers, true, |meta, chunk_writer| {
        let order: Vec<(usize, BlockIndex)> = exr::block::enumerate_ordered_header_block_indices(&meta.headers).collect();
        let group = 4 * rayon::current_num_threads();
        for blocks in order.chunks(group) {
            let chunks: Vec<(usize, Chunk)> = blocks
                .par_iter()
                .map(|&(index_in_header, block)| {
                    let header = &meta.headers[block.layer];
                    let raw = layers.extract_uncompressed_block(&meta.headers, block);
                    let y_coordinate = i32::try_from(block.pixel_position.y())
                        .map_err(|_| exr::error::Error::Invalid("image too tall".into()))?
                        + header.own_attributes.layer_position.y();
                    let compressed_block =
                        CompressedBlock::ScanLine(CompressedScanLineBlock { y_coordinate, compressed_pixels_le: zip_block(raw) });
                    Ok((index_in_header, Chunk { layer_index: block.layer, compressed_block }))
                })
                .collect::<exr::error::Result<_>>()?;
            for (index_in_header, chunk) in chunks {
                chunk_writer.write_chunk(index_in_header, chunk)?;
            }
        }
        Ok(())
    })
}
