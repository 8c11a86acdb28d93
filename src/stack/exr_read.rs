//! Reading layer stacks from EXR files in any of the conventions of [`super::naming`].
//!
//! Order of work: cheap checks first (file exists, EXR magic, header sizes against
//! `max_pixels`), then the pixels; every channel is looked up by name and placed into the
//! display window (zero / transparent outside its data window).
use std::collections::{BTreeMap, HashSet};
use std::path::Path;

use exr::prelude::{AnyChannels, AttributeValue, FlatSamples, IntegerBounds, MetaData, ReadChannels, ReadLayers};
use rayon::prelude::*;

use super::depth_clean::{check_finite, depth_to_disparity};
use super::info::{ChannelInfo, ExtraChannel, LayerInfo, PartInfo, SampleType, StackFile, StackInfo, Window};
use super::file_output_slots::group_channels;
use super::naming::{glob_match, ChannelGroup, Convention};
use super::{DepthKind, Layer, LayerStack, SAMPLES_PER_TASK};
use crate::image::Image;
use crate::{Error, Result};

pub(super) type ExrImage = exr::image::Image<exr::image::Layers<AnyChannels<FlatSamples>>>;

pub(super) type ExrPart = exr::image::Layer<AnyChannels<FlatSamples>>;

/// The default pixel budget per window: 2^28 pixels (16384 x 16384), 4 GiB as RGBA f32.
pub const DEFAULT_MAX_PIXELS: u64 = 1 << 28;

/// What to read and how to interpret depth.
#[derive(Clone, Debug, PartialEq)]
pub struct ReadOptions {
    /// Layer names or shell globs (`fg*`), any order; `None` = every complete layer.
    pub layers: Option<Vec<String>>,
    pub depth_kind: DepthKind,
    /// Refuse files whose headers declare more pixels than this (per window), before allocating.
    pub max_pixels: u64,
    /// Replace NaN/Inf colour and alpha samples by 0 (and say so in [`StackInfo::warnings`])
    /// instead of refusing the file.
    pub replace_nonfinite: bool,
}

impl Default for ReadOptions {
    fn default() -> Self {
        Self { layers: None, depth_kind: DepthKind::Z, max_pixels: DEFAULT_MAX_PIXELS, replace_nonfinite: false }
    }
}

/// A layer name paired with the channel group and part it came from.
struct Candidate {
    name: String,
    part: usize,
    group: ChannelGroup,
}

/// Reads a layer stack: layers front to back, premultiplied colour, depth as disparity.
pub fn read_stack(path: &Path, options: &ReadOptions) -> Result<StackFile> {
    let meta = read_headers(path, options.max_pixels)?;
    let mut image = read_pixels(path)?;
    let display = window_of(&image.attributes.display_window);
    let candidates = candidates(&image);
    let selected = select(path, &candidates, options.layers.as_deref())?;
    // Described before the layers take their channels' samples out of the file's image.
    let parts = part_infos(&image);
    let mut layers = Vec::new();
    let mut infos = Vec::new();
    let mut warnings = Vec::new();
    // Channels are taken out one layer after the other (layers may share a part), then the
    // layers are checked, converted and depth-filled in parallel; errors in layer order.
    let taken = selected
        .iter()
        .map(|candidate| take_layer_channels(path, &mut image.layer_data[candidate.part], candidate, display))
        .collect::<Result<Vec<_>>>()?;
    let built: Vec<Result<(Layer, LayerInfo, Vec<String>)>> = selected
        .par_iter()
        .zip(taken.into_par_iter())
        .map(|(candidate, channels)| assemble_layer(path, candidate, channels, display, options))
        .collect();
    for result in built {
        let (layer, info, layer_warnings) = result?;
        layers.push(layer);
        infos.push(info);
        warnings.extend(layer_warnings);
    }
    let single_image = holds_one_image(&candidates, &selected);
    let used: HashSet<(usize, String)> =
        selected.iter().flat_map(|c| rendered_names(c).into_iter().map(move |n| (c.part, n))).collect();
    let mut stack = LayerStack::new(display.width, display.height, layers)?;
    stack.sort_front_to_back();
    infos.sort_by_key(|info: &LayerInfo| stack.layers.iter().position(|l| l.name == info.name));
    let info = StackInfo {
        path: path.to_path_buf(),
        display_window: display,
        depth_kind: options.depth_kind,
        single_image,
        parts,
        layers: infos,
        camera: camera_attributes(&meta),
        extra_channels: extra_channels(&image, display, &used),
        warnings,
    };
    Ok(StackFile { stack, info })
}

/// Reads one colour image (no depth needed) onto the display window: plain `R,G,B[,A]`, or the
/// layer named `layer` in any naming convention. Missing alpha is 1 inside the data window.
/// For inputs such as the output gradient of `lensblur grad`.
pub fn read_rgba(path: &Path, layer: Option<&str>, max_pixels: u64) -> Result<Image> {
    read_headers(path, max_pixels)?;
    let image = read_pixels(path)?;
    let display = window_of(&image.attributes.display_window);
    let candidates = candidates(&image);
    let coloured: Vec<&Candidate> = candidates
        .iter()
        .filter(|c| {
            c.group.channels.red.is_some() && c.group.channels.green.is_some() && c.group.channels.blue.is_some()
        })
        .collect();
    let names = || coloured.iter().map(|c| format!("'{}'", c.name)).collect::<Vec<_>>().join(", ");
    let chosen = match layer {
        Some(name) => coloured.iter().find(|c| glob_match(name, &c.name)).copied(),
        None if coloured.len() == 1 => coloured.first().copied(),
        None => {
            return Err(Error::input(path, format!("several colour layers ({}); name the one to read", names())));
        }
    };
    let Some(candidate) = chosen else {
        return Err(Error::input(path, format!("no colour layer {} (found {})", layer.unwrap_or(""), names())));
    };
    let part = &image.layer_data[candidate.part];
    let data = part_window(part);
    let ch = &candidate.group.channels;
    let fetch = |name: &str| -> Result<Vec<f32>> {
        let channel =
            find_channel(part, name).ok_or_else(|| Error::input(path, format!("channel '{name}' vanished")))?;
        let mut values = place(&channel.sample_data, data, display, 0.0);
        check_finite(path, &candidate.name, name, &mut values, false)?;
        Ok(values)
    };
    let [red, green, blue] = [&ch.red, &ch.green, &ch.blue].map(|name| fetch(name.as_deref().unwrap_or_default()));
    let (red, green, blue) = (red?, green?, blue?);
    let alpha = match &ch.alpha {
        Some(name) => fetch(name)?,
        None => place(&FlatSamples::F32(vec![1.0; data.width * data.height]), data, display, 0.0),
    };
    let pixels = (0..red.len()).map(|i| [red[i], green[i], blue[i], alpha[i]]).collect();
    Ok(Image { width: display.width, height: display.height, pixels })
}

/// Header-only view of a file (parts and channels), for `lensblur info` on files that are
/// not valid stacks.
pub fn read_parts(path: &Path, max_pixels: u64) -> Result<(Vec<PartInfo>, BTreeMap<String, String>)> {
    let meta = read_headers(path, max_pixels)?;
    let parts = meta
        .headers
        .iter()
        .map(|h| PartInfo {
            name: h.own_attributes.layer_name.as_ref().map(|t| t.to_string()),
            data_window: window_of(&IntegerBounds::new(h.own_attributes.layer_position, h.layer_size)),
            compression: format!("{:?}", h.compression),
            channels: h
                .channels
                .list
                .iter()
                .map(|c| ChannelInfo { name: c.name.to_string(), sample_type: sample_type_of_desc(c.sample_type) })
                .collect(),
        })
        .collect();
    Ok((parts, camera_attributes(&meta)))
}

/// The frame size (display window) an EXR's headers declare, read without its pixels: what a
/// caller decides on before the read (`RenderJob::place_frame`). None where the file is not a
/// readable EXR: the read itself says why.
pub fn declared_size(path: &Path) -> Option<(usize, usize)> {
    let meta = read_headers(path, u64::MAX).ok()?;
    let window = meta.headers.first()?.shared_attributes.display_window;
    Some((window.size.x(), window.size.y()))
}

pub(super) fn read_headers(path: &Path, max_pixels: u64) -> Result<MetaData> {
    let mut magic = [0u8; 4];
    let mut file = std::fs::File::open(path).map_err(Error::io(path))?;
    let is_exr = std::io::Read::read_exact(&mut file, &mut magic).is_ok() && magic == [0x76, 0x2f, 0x31, 0x01];
    if !is_exr {
        return Err(Error::input(
            path,
            "not an OpenEXR file (missing EXR magic number; empty or another format?); lensblur reads \
             layered EXRs, and PNG/JPEG images with their depth image (InputOptions::depth_image; --depth DEPTH.png on the command line)",
        ));
    }
    let meta = MetaData::read_from_file(path, false).map_err(|e| {
        Error::input(path, format!("invalid EXR header ({e}); the file is damaged or truncated: write it again"))
    })?;
    let first = meta.headers.first().ok_or_else(|| Error::input(path, "EXR file has no parts"))?;
    let display = first.shared_attributes.display_window;
    for header in meta.headers.iter() {
        let other = header.shared_attributes.display_window;
        if other != display {
            return Err(Error::input(
                path,
                format!(
                    "parts have mismatched display windows ({}x{} and {}x{}); every layer of a stack must \
                     have the same size: re-export the parts at one resolution",
                    display.size.x(),
                    display.size.y(),
                    other.size.x(),
                    other.size.y()
                ),
            ));
        }
        if header.deep {
            return Err(Error::input(
                path,
                "is a deep EXR, and this reader takes flat (layered) EXRs. `lensblur render` reads \
                 deep files, splitting their samples into layers by circle of confusion (the \
                 library's `input::load`); or flatten it to layers (Nuke: DeepToImage per layer)",
            ));
        }
        for size in [display.size, header.layer_size] {
            super::check_pixel_budget(path, size.x() as u64, size.y() as u64, max_pixels)?;
        }
    }
    Ok(meta)
}

/// Every part's pixels; a file whose parts only split one layout's passes comes back as one part
/// (see [`join_split_passes`]).
pub(super) fn read_pixels(path: &Path) -> Result<ExrImage> {
    // Flat files, scan-line and tiled, decode on every core; subsampled channels through the crate.
    if let Some(image) = super::exr_decode::read_flat_pixels(path)? {
        return Ok(join_split_passes(image));
    }
    Ok(join_split_passes(read_with_the_crate(path)?))
}

/// Every part's pixels at the largest resolution, through the `exr` crate's image reader: files
/// with subsampled channels, and what [`super::exr_decode`] is held equal to.
pub(super) fn read_with_the_crate(path: &Path) -> Result<ExrImage> {
    exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_file(path)
        .map_err(|e| Error::input(path, format!("cannot read EXR pixels: {e}")))
}

/// Blender 5 writes multilayer EXRs multi-part by default, one part per pass (`ViewLayer.Combined`,
/// `ViewLayer.Depth`, ...), each channel keeping its full name (`ViewLayer.Depth.Z`), as OpenEXR
/// advises so that splitting a file into parts loses nothing. Colour and depth of one layer then
/// sit in different parts. When every part is named, every channel of a part starts with the
/// part's name, and all parts cover the same data window, the parts are one layout split up:
/// their channels are joined into one part and read like the single-part file holding them.
/// Anything else (stereo views, one layer per part with short channel names) stays as it is.
fn join_split_passes(mut image: ExrImage) -> ExrImage {
    let [first, rest @ ..] = image.layer_data.as_slice() else { return image };
    let names: Vec<String> =
        image.layer_data.iter().flat_map(|part| part.channel_data.list.iter().map(|c| c.name.to_string())).collect();
    let split = !rest.is_empty()
        && names.iter().collect::<HashSet<_>>().len() == names.len()
        && image.layer_data.iter().all(|part| {
            let Some(name) = part_name(part) else { return false };
            let prefix = format!("{name}.");
            part.size == first.size
                && part.attributes.layer_position == first.attributes.layer_position
                && part.channel_data.list.iter().all(|c| c.name.to_string().starts_with(&prefix))
        });
    if !split {
        return image;
    }
    let mut parts = std::mem::take(&mut image.layer_data).into_iter();
    let mut joined = parts.next().expect("two parts or more");
    let mut channels = std::mem::take(&mut joined.channel_data.list);
    for part in parts {
        channels.extend(part.channel_data.list);
    }
    joined.channel_data = AnyChannels::sort(channels);
    joined.attributes.layer_name = None;
    image.layer_data.push(joined);
    image
}

pub(super) fn window_of(bounds: &IntegerBounds) -> Window {
    Window { x: bounds.position.x(), y: bounds.position.y(), width: bounds.size.x(), height: bounds.size.y() }
}

pub(super) fn part_window(part: &ExrPart) -> Window {
    window_of(&IntegerBounds::new(part.attributes.layer_position, part.size))
}

fn part_name(part: &ExrPart) -> Option<String> {
    part.attributes.layer_name.as_ref().map(|t| t.to_string())
}

/// Every channel group of every part, named as the user will select it.
fn candidates(image: &ExrImage) -> Vec<Candidate> {
    let multi_part = image.layer_data.len() > 1;
    let mut out: Vec<Candidate> = Vec::new();
    for (index, part) in image.layer_data.iter().enumerate() {
        let names: Vec<String> = part.channel_data.list.iter().map(|c| c.name.to_string()).collect();
        for mut group in group_channels(&names) {
            let part_name = part_name(part).filter(|_| multi_part);
            let mut name = match (part_name, group.layer.as_str()) {
                (Some(p), "") => p,
                (Some(p), l) if l == p => p,
                (Some(p), l) => format!("{p}.{l}"),
                (None, "") => FLAT_IMAGE_LAYER.to_string(),
                (None, l) => l.to_string(),
            };
            if multi_part {
                group.convention = Convention::MultiPart;
            }
            while out.iter().any(|c| c.name == name) {
                name.push_str("#2");
            }
            out.push(Candidate { name, part: index, group });
        }
    }
    out
}

/// The name of an unprefixed single-part group (`R,G,B,A,Z`): the file's flat image.
const FLAT_IMAGE_LAYER: &str = "All";

/// Whether the selection is one flat image to auto-layer: the only complete layer of the file,
/// or its flat `All` image chosen by name. One layer picked out of a stack is just that layer.
fn holds_one_image(candidates: &[Candidate], selected: &[&Candidate]) -> bool {
    let complete = candidates.iter().filter(|c| c.group.channels.is_complete()).count();
    matches!(selected, [only] if complete == 1 || only.name == FLAT_IMAGE_LAYER)
}

fn describe(candidates: &[&Candidate]) -> String {
    candidates
        .iter()
        .map(|c| format!("'{}' [{}]", c.name, c.group.channels.all_names().join(", ")))
        .collect::<Vec<_>>()
        .join("; ")
}

fn missing_message(candidate: &Candidate) -> Option<String> {
    let ch = &candidate.group.channels;
    if let Some(ambiguity) = &candidate.group.ambiguity {
        return Some(format!("layer '{}' has no unambiguous depth channel: {ambiguity}", candidate.name));
    }
    let mut missing = Vec::new();
    if ch.red.is_none() || ch.green.is_none() || ch.blue.is_none() {
        missing.push("colour (R, G, B)");
    }
    if ch.depth.is_none() {
        missing.push("depth (Z, depth or V)");
    }
    (!missing.is_empty()).then(|| {
        format!(
            "layer '{}' has no {} channel; channels found: {}",
            candidate.name,
            missing.join(" or "),
            ch.all_names().join(", ")
        )
    })
}

fn select<'c>(path: &Path, candidates: &'c [Candidate], patterns: Option<&[String]>) -> Result<Vec<&'c Candidate>> {
    let Some(patterns) = patterns else {
        // Leaving an ambiguous layer out would render an incomplete stack without a word.
        if let Some(message) = candidates.iter().filter(|c| c.group.ambiguity.is_some()).find_map(missing_message) {
            return Err(Error::input(path, format!("{message}; or choose the layers (ReadOptions::layers; --layers on the command line)")));
        }
        let complete: Vec<&Candidate> = candidates.iter().filter(|c| c.group.channels.is_complete()).collect();
        if complete.is_empty() {
            let all: Vec<&Candidate> = candidates.iter().collect();
            return Err(Error::input(
                path,
                format!(
                    "no layer has both colour and depth channels; found {}. Render a depth pass into \
                     the file (a Z channel; Blender: View Layer > Passes > Z) or select layers (ReadOptions::layers; --layers on the command line)",
                    describe(&all)
                ),
            ));
        }
        // A flattened `All` beside real layers is the composite, not a layer of the stack.
        if complete.len() > 1 {
            return Ok(complete.into_iter().filter(|c| !c.name.eq_ignore_ascii_case(FLAT_IMAGE_LAYER)).collect());
        }
        return Ok(complete);
    };
    let mut chosen: Vec<&Candidate> = Vec::new();
    for pattern in patterns {
        let matches: Vec<&Candidate> = candidates.iter().filter(|c| glob_match(pattern, &c.name)).collect();
        if matches.is_empty() {
            let names: Vec<&str> = candidates.iter().map(|c| c.name.as_str()).collect();
            return Err(Error::input(
                path,
                format!("no layer matches '{pattern}'; available layers: {}", names.join(", ")),
            ));
        }
        for m in matches {
            if let Some(message) = missing_message(m) {
                return Err(Error::input(path, message));
            }
            if !chosen.iter().any(|c| std::ptr::eq(*c, m)) {
                chosen.push(m);
            }
        }
    }
    Ok(chosen)
}

fn rendered_names(candidate: &Candidate) -> Vec<String> {
    let ch = &candidate.group.channels;
    [&ch.red, &ch.green, &ch.blue, &ch.alpha, &ch.depth].into_iter().flatten().cloned().collect()
}

fn find_channel<'p>(part: &'p ExrPart, name: &str) -> Option<&'p exr::image::AnyChannel<FlatSamples>> {
    part.channel_data.list.iter().find(|c| c.name.to_string() == name)
}

fn sample_type_of(samples: &FlatSamples) -> SampleType {
    match samples {
        FlatSamples::F16(_) => SampleType::Half,
        FlatSamples::F32(_) => SampleType::Float,
        FlatSamples::U32(_) => SampleType::Uint,
    }
}

fn sample_type_of_desc(t: exr::prelude::SampleType) -> SampleType {
    match t {
        exr::prelude::SampleType::F16 => SampleType::Half,
        exr::prelude::SampleType::F32 => SampleType::Float,
        exr::prelude::SampleType::U32 => SampleType::Uint,
    }
}

/// Every sample of a data window that lies in the display window: (index in the data
/// window, index in the display window), both row-major.
pub(super) fn data_in_display(data: Window, display: Window) -> impl Iterator<Item = (usize, usize)> {
    (0..data.height).flat_map(move |row| {
        let y = data.y as i64 + row as i64 - display.y as i64;
        (0..data.width).filter_map(move |col| {
            let x = data.x as i64 + col as i64 - display.x as i64;
            let inside = (0..display.width as i64).contains(&x) && (0..display.height as i64).contains(&y);
            inside.then(|| (row * data.width + col, y as usize * display.width + x as usize))
        })
    })
}

/// Copies a channel's data window into a display-window-sized buffer, `outside` elsewhere.
fn place(samples: &FlatSamples, data: Window, display: Window, outside: f32) -> Vec<f32> {
    let mut out = vec![outside; display.width * display.height];
    // The data window's overlap with the display window, in display coordinates.
    let clip = |data_at: i32, data_len: usize, display_at: i32, display_len: usize| {
        let start = (data_at as i64).max(display_at as i64);
        let end = (data_at as i64 + data_len as i64).min(display_at as i64 + display_len as i64);
        (start, end.max(start))
    };
    let (x0, x1) = clip(data.x, data.width, display.x, display.width);
    let (y0, y1) = clip(data.y, data.height, display.y, display.height);
    let width = (x1 - x0) as usize;
    if width == 0 {
        return out; // no column overlaps (the row offsets below would point past the rows)
    }
    for y in y0..y1 {
        let src = (y - data.y as i64) as usize * data.width + (x0 - data.x as i64) as usize;
        let dst = (y - display.y as i64) as usize * display.width + (x0 - display.x as i64) as usize;
        let row = &mut out[dst..dst + width];
        match samples {
            FlatSamples::F32(v) => row.copy_from_slice(&v[src..src + width]),
            FlatSamples::F16(v) => row.iter_mut().zip(&v[src..src + width]).for_each(|(o, s)| *o = s.to_f32()),
            FlatSamples::U32(v) => row.iter_mut().zip(&v[src..src + width]).for_each(|(o, &s)| *o = s as f32),
        }
    }
    out
}

/// [`place`] of samples taken out of the file: float samples whose data window is the display
/// window are moved, not copied (a stack's layers then hold the only copy of their pixels).
fn place_owned(samples: FlatSamples, data: Window, display: Window, outside: f32) -> Vec<f32> {
    match samples {
        FlatSamples::F32(values) if data == display => values,
        samples => place(&samples, data, display, outside),
    }
}

/// Takes the samples of channel `name` out of `part` (leaving it empty) and places them on
/// the display window; refuses a channel that is absent or was already taken.
fn take_channel(path: &Path, part: &mut ExrPart, name: &str, display: Window, outside: f32) -> Result<Vec<f32>> {
    let data = part_window(part);
    let channel = part.channel_data.list.iter_mut().find(|c| c.name.to_string() == name);
    let vanished = || Error::input(path, format!("channel '{name}' vanished"));
    let channel = channel.ok_or_else(vanished)?;
    let samples = std::mem::replace(&mut channel.sample_data, FlatSamples::F32(Vec::new()));
    if samples.len() != data.width * data.height {
        return Err(vanished());
    }
    Ok(place_owned(samples, data, display, outside))
}

/// One layer's channels taken out of the file's image, placed on the display window.
struct LayerChannels {
    data_window: Window,
    /// Alpha channel name and samples; None: opaque inside the data window.
    alpha: Option<(String, Vec<f32>)>,
    depth_name: String,
    depth: Vec<f32>,
    colour: [(String, Vec<f32>); 3],
}

fn take_layer_channels(path: &Path, part: &mut ExrPart, candidate: &Candidate, display: Window) -> Result<LayerChannels> {
    let data_window = part_window(part);
    if part.channel_data.list.iter().any(|c| c.sampling != exr::prelude::Vec2(1, 1)) {
        return Err(Error::input(
            path,
            format!("layer '{}' uses subsampled channels, which are not supported", candidate.name),
        ));
    }
    let ch = &candidate.group.channels;
    let missing = || Error::input(path, missing_message(candidate).unwrap_or_default());
    let [Some(red), Some(green), Some(blue), Some(depth_name)] = [&ch.red, &ch.green, &ch.blue, &ch.depth] else {
        return Err(missing());
    };
    let alpha = match &ch.alpha {
        Some(name) => Some((name.clone(), take_channel(path, part, name, display, 0.0)?)),
        None => None,
    };
    let depth = take_channel(path, part, depth_name, display, f32::INFINITY)?;
    let mut take = |name: &String| take_channel(path, part, name, display, 0.0).map(|values| (name.clone(), values));
    let colour = [take(red)?, take(green)?, take(blue)?];
    Ok(LayerChannels { data_window, alpha, depth_name: depth_name.clone(), depth, colour })
}

/// Checks, converts and depth-fills one layer; its warnings (replaced samples) come back
/// colour first, as the channels are listed.
fn assemble_layer(
    path: &Path,
    candidate: &Candidate,
    channels: LayerChannels,
    display: Window,
    options: &ReadOptions,
) -> Result<(Layer, LayerInfo, Vec<String>)> {
    let LayerChannels { data_window: data, alpha, depth_name, depth, colour } = channels;
    let mut replaced = Vec::new();
    // No alpha channel: opaque inside the data window, transparent outside.
    let alpha = match alpha {
        Some((name, mut alpha)) => {
            replaced.push(check_finite(path, &candidate.name, &name, &mut alpha, options.replace_nonfinite)?);
            alpha
        }
        None => place(&FlatSamples::F32(vec![1.0; data.width * data.height]), data, display, 0.0),
    };
    let (disparity, stored_depth_range, depth_weights) = depth_to_disparity(
        path,
        (&candidate.name, &depth_name),
        (display.width, display.height),
        &depth,
        &alpha,
        options.depth_kind,
    )?;
    drop(depth);
    let mut colour = colour;
    for (c, (name, values)) in colour.iter_mut().enumerate() {
        replaced.insert(c, check_finite(path, &candidate.name, name, values, options.replace_nonfinite)?);
    }
    // Interleaved in one pass, in runs on every core (four strided passes over a frame of
    // RGBA were a third of reading a large layered file).
    let [(_, red), (_, green), (_, blue)] = &colour;
    let mut pixels = vec![[0.0f32; 4]; alpha.len()];
    pixels.par_chunks_mut(SAMPLES_PER_TASK).enumerate().for_each(|(run, pixels)| {
        let start = run * SAMPLES_PER_TASK;
        for (k, p) in pixels.iter_mut().enumerate() {
            let i = start + k;
            *p = [red[i], green[i], blue[i], alpha[i]];
        }
    });
    drop((alpha, colour));
    let rgba = Image { width: display.width, height: display.height, pixels };
    let layer = Layer { name: candidate.name.clone(), rgba, disparity };
    let disparity_range =
        layer.disparity.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &d| (lo.min(d), hi.max(d)));
    let info = LayerInfo {
        name: candidate.name.clone(),
        convention: candidate.group.convention,
        part: candidate.part,
        channels: candidate.group.channels.clone(),
        data_window: data,
        stored_depth_range,
        disparity_range,
        depth_weights,
    };
    Ok((layer, info, replaced.into_iter().flatten().collect()))
}

fn part_infos(image: &ExrImage) -> Vec<PartInfo> {
    image
        .layer_data
        .iter()
        .map(|part| PartInfo {
            name: part_name(part),
            data_window: part_window(part),
            compression: format!("{:?}", part.encoding.compression),
            channels: part
                .channel_data
                .list
                .iter()
                .map(|c| ChannelInfo { name: c.name.to_string(), sample_type: sample_type_of(&c.sample_data) })
                .collect(),
        })
        .collect()
}

fn extra_channels(image: &ExrImage, display: Window, used: &HashSet<(usize, String)>) -> Vec<ExtraChannel> {
    let multi_part = image.layer_data.len() > 1;
    let mut out = Vec::new();
    for (index, part) in image.layer_data.iter().enumerate() {
        for channel in part.channel_data.list.iter() {
            let name = channel.name.to_string();
            if used.contains(&(index, name.clone())) || channel.sampling != exr::prelude::Vec2(1, 1) {
                continue;
            }
            let name = match part_name(part).filter(|_| multi_part) {
                Some(p) if !name.starts_with(&format!("{p}.")) => format!("{p}.{name}"),
                _ => name,
            };
            let values = place(&channel.sample_data, part_window(part), display, 0.0);
            out.push(ExtraChannel { name, sample_type: sample_type_of(&channel.sample_data), values });
        }
    }
    out
}

fn attribute_text(value: &AttributeValue) -> String {
    match value {
        AttributeValue::Text(t) => t.to_string(),
        AttributeValue::F32(v) => v.to_string(),
        AttributeValue::F64(v) => v.to_string(),
        AttributeValue::I32(v) => v.to_string(),
        other => format!("{other:?}"),
    }
}

/// Camera-related header attributes: the standard ones and stamped metadata (Blender writes
/// e.g. `Lens`, `Camera` when stamping is on), keyed by attribute name.
fn camera_attributes(meta: &MetaData) -> BTreeMap<String, String> {
    const KEYS: [&str; 10] = ["lens", "focal", "fstop", "f-stop", "aperture", "sensor", "focus", "camera", "fov", "unit"];
    let mut out = BTreeMap::new();
    for header in meta.headers.iter() {
        let own = &header.own_attributes;
        let standard = [
            ("focus", own.focus),
            ("aperture", own.aperture),
            ("horizontalFieldOfView", own.horizontal_field_of_view),
            ("verticalFieldOfView", own.vertical_field_of_view),
            ("nearClipPlane", own.near_clip_plane),
            ("farClipPlane", own.far_clip_plane),
        ];
        for (key, value) in standard {
            if let Some(value) = value {
                out.insert(key.to_string(), value.to_string());
            }
        }
        if let Some(m) = &own.world_to_camera {
            out.insert("worldToCamera".to_string(), format!("{m:?}"));
        }
        for (key, value) in own.other.iter().chain(header.shared_attributes.other.iter()) {
            let key = key.to_string();
            if KEYS.iter().any(|k| key.to_ascii_lowercase().contains(k)) {
                out.insert(key, attribute_text(value));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use exr::prelude::f16;

    /// Per-pixel definition of placing: display pixel (x, y) takes data sample (x - dx, y - dy)
    /// where that lies inside the data window, `outside` elsewhere.
    fn placed_by_definition(values: &[f32], data: Window, display: Window, outside: f32) -> Vec<f32> {
        let mut out = Vec::new();
        for y in display.y..display.y + display.height as i32 {
            for x in display.x..display.x + display.width as i32 {
                let (col, row) = (x - data.x, y - data.y);
                let inside = (0..data.width as i32).contains(&col) && (0..data.height as i32).contains(&row);
                out.push(if inside { values[row as usize * data.width + col as usize] } else { outside });
            }
        }
        out
    }

    /// A part named `name` of `size` at `position` holding zeroed channels `channels`.
    fn part(name: Option<&str>, channels: &[&str], size: (usize, usize), position: (i32, i32)) -> ExrPart {
        use exr::prelude::{AnyChannel, Encoding, LayerAttributes, Vec2};
        let list = channels.iter().map(|c| AnyChannel::new(*c, FlatSamples::F32(vec![0.0; size.0 * size.1]))).collect();
        let mut attributes = LayerAttributes::default();
        attributes.layer_name = name.map(Into::into);
        attributes.layer_position = Vec2(position.0, position.1);
        exr::image::Layer::new(size, attributes, Encoding::FAST_LOSSLESS, AnyChannels::sort(list))
    }

    fn joined(parts: Vec<ExrPart>) -> Vec<(Option<String>, Vec<String>)> {
        use exr::prelude::{ImageAttributes, IntegerBounds};
        let image = ExrImage::from_layers(ImageAttributes::new(IntegerBounds::from_dimensions((4, 3))), parts);
        join_split_passes(image)
            .layer_data
            .iter()
            .map(|p| (part_name(p), p.channel_data.list.iter().map(|c| c.name.to_string()).collect()))
            .collect()
    }

    #[test]
    fn parts_that_split_one_layouts_passes_are_joined_and_other_multi_part_files_are_not() {
        let colour = |layer: &str| {
            let pass = format!("{layer}.Combined");
            let names: Vec<String> = ["A", "B", "G", "R"].iter().map(|c| format!("{pass}.{c}")).collect();
            (pass, names)
        };
        let (front, front_channels) = colour("Front");
        let front_refs: Vec<&str> = front_channels.iter().map(String::as_str).collect();
        let depth = || part(Some("Front.Depth"), &["Front.Depth.Z"], (4, 3), (0, 0));
        // Blender 5: one part per pass, full channel names -> one part, sorted by name.
        let got = joined(vec![part(Some(&front), &front_refs, (4, 3), (0, 0)), depth()]);
        let mut want = front_channels.clone();
        want.push("Front.Depth.Z".into());
        assert_eq!(got, vec![(None, want)]);
        // Stereo views and one-layer-per-part files use short names: left alone.
        let got = joined(vec![part(Some("left"), &["R", "Z"], (4, 3), (0, 0)), part(Some("right"), &["R", "Z"], (4, 3), (0, 0))]);
        assert_eq!(got.len(), 2);
        // Parts over different data windows cannot be one part.
        let got = joined(vec![part(Some(&front), &front_refs, (4, 3), (0, 0)), part(Some("Front.Depth"), &["Front.Depth.Z"], (4, 3), (1, 0))]);
        assert_eq!(got.len(), 2);
        let got = joined(vec![part(Some(&front), &front_refs, (4, 3), (0, 0)), part(Some("Front.Depth"), &["Front.Depth.Z"], (3, 3), (0, 0))]);
        assert_eq!(got.len(), 2);
        // An unnamed part, and a channel outside its part's name: left alone.
        assert_eq!(joined(vec![part(None, &["Front.Depth.Z"], (4, 3), (0, 0)), depth()]).len(), 2);
        assert_eq!(joined(vec![part(Some(&front), &["Back.Combined.R"], (4, 3), (0, 0)), depth()]).len(), 2);
        // Nested part names whose channels would collide: left alone.
        let got = joined(vec![part(Some("A"), &["A.B.R"], (4, 3), (0, 0)), part(Some("A.B"), &["A.B.R"], (4, 3), (0, 0))]);
        assert_eq!(got.len(), 2);
        // A single part is what it is.
        assert_eq!(joined(vec![depth()]), vec![(Some("Front.Depth".into()), vec!["Front.Depth.Z".into()])]);
    }

    #[test]
    fn placing_clips_data_windows_that_overhang_or_miss_the_display_window() {
        let display = Window { x: -2, y: 1, width: 7, height: 5 };
        let values: Vec<f32> = (0..40).map(|i| i as f32 * 0.5).collect();
        // Inside, overhanging each side, covering it whole, and entirely outside.
        for (x, y, width, height) in [(0, 2, 4, 3), (-4, -1, 6, 4), (3, 4, 6, 4), (-3, 0, 8, 3), (9, 1, 4, 6)] {
            let data = Window { x, y, width, height };
            let values = &values[..width * height];
            let want = placed_by_definition(values, data, display, -1.0);
            assert_eq!(place(&FlatSamples::F32(values.to_vec()), data, display, -1.0), want, "{data:?}");
            let halves = FlatSamples::F16(values.iter().map(|&v| f16::from_f32(v)).collect());
            assert_eq!(place(&halves, data, display, -1.0), want, "{data:?} as half (exact: multiples of 0.5)");
        }
        let same: Vec<f32> = values[..35].to_vec();
        assert_eq!(place_owned(FlatSamples::F32(same.clone()), display, display, -1.0), same, "moved as is");
    }
}
