//! Writing a file back with some of its channels replaced (`fit-depth`): every other channel,
//! its sample type, the parts and their names, data and display windows, compression and
//! header attributes stay as they were; a replaced channel keeps its name and sample type.
//! A multi-part file that only splits one layout's passes into parts (Blender 5's default
//! multilayer EXR) is read as one part and written back as that one part, which Blender reads
//! the same way.
use std::io::Write as _;
use std::path::Path;

use exr::prelude::{f16, FlatSamples, WritableImage};

use super::exr_header_order::sort_header_attributes;
use super::exr_read::{data_in_display, part_window, read_headers, read_pixels, window_of};
use crate::atomic_file::write_atomically;
use crate::{Error, Result};

/// New samples for one channel of the input.
#[derive(Clone, Debug, PartialEq)]
pub struct ChannelReplacement {
    /// Index of the part holding the channel.
    pub part: usize,
    /// The channel's name as stored in that part.
    pub channel: String,
    /// One entry per display-window pixel (row-major); `None` keeps the stored sample. Samples
    /// outside the display window are kept too.
    pub values: Vec<Option<f32>>,
}

/// Header attributes to set on every part of the output.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HeaderEdits {
    /// The standard `focus` attribute (distance of the plane in focus, scene units).
    pub focus: Option<f32>,
}

/// Copies `input` to `output` with `replacements` applied and `edits` stamped into the header.
pub fn replace_channels(
    input: &Path,
    output: &Path,
    replacements: &[ChannelReplacement],
    edits: HeaderEdits,
    max_pixels: u64,
) -> Result<()> {
    read_headers(input, max_pixels)?;
    let mut image = read_pixels(input)?;
    let display = window_of(&image.attributes.display_window);
    for replacement in replacements {
        if replacement.values.len() != display.width * display.height {
            return Err(Error::data(format!(
                "replacement for channel '{}' has {} samples, the display window {}",
                replacement.channel,
                replacement.values.len(),
                display.width * display.height
            )));
        }
        let part = image.layer_data.get_mut(replacement.part).ok_or_else(|| {
            Error::input(input, format!("has no part {} (for channel '{}')", replacement.part, replacement.channel))
        })?;
        let data = part_window(part);
        let channel = part
            .channel_data
            .list
            .iter_mut()
            .find(|c| c.name.to_string() == replacement.channel)
            .ok_or_else(|| Error::input(input, format!("has no channel '{}'", replacement.channel)))?;
        let values = &replacement.values;
        let pixels = data_in_display(data, display).filter_map(|(sample, pixel)| Some((sample, values[pixel]?)));
        match &mut channel.sample_data {
            FlatSamples::F16(samples) => pixels.for_each(|(i, v)| samples[i] = f16::from_f32(v)),
            FlatSamples::F32(samples) => pixels.for_each(|(i, v)| samples[i] = v),
            FlatSamples::U32(_) => {
                return Err(Error::input(
                    input,
                    format!("channel '{}' stores unsigned integers; it cannot hold depth", replacement.channel),
                ))
            }
        }
    }
    for part in image.layer_data.iter_mut() {
        if let Some(focus) = edits.focus {
            part.attributes.focus = Some(focus);
        }
    }
    // Written in memory first so the header's attributes can be put in a fixed order (the
    // input's attributes would otherwise come out in a different order on every run).
    let mut bytes = Vec::new();
    image
        .write()
        .to_buffered(std::io::Cursor::new(&mut bytes))
        .map_err(|e| Error::input(output, format!("cannot write EXR: {e}")))?;
    sort_header_attributes(&mut bytes)?;
    write_atomically(output, |file| {
        file.write_all(&bytes).map_err(Error::io(output))
    })
}
