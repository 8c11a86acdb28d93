//! Writing a file back with some of its channels replaced (`fit-depth`): every other channel,
//! its sample type, the parts and their names, data and display windows, compression and
//! header attributes stay as they were; a replaced channel keeps its name and sample type.
//! A multi-part file that only splits one layout's passes into parts (Blender 5's default
//! multilayer EXR) is read as one part and written back as that one part, which Blender reads
//! the same way.
use std::io::Write as _;
use std::path::Path;

use exr::prelude::{f16, Blocks, FlatSamples, WritableImage};

use super::exr_header_order::sort_header_attributes;
use super::exr_read::{data_in_display, part_window, read_headers, read_pixels, window_of};
use super::exr_write::{write_zip_scanlines, zip_scanlines};
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
    // ZIP scan lines (what Blender writes) are coded on every core with OpenEXR's deflate, as
    // lensblur's own outputs are; every other layout through the crate's writer.
    let mut bytes = Vec::new();
    let cursor = std::io::Cursor::new(&mut bytes);
    let written = if image.layer_data.iter().all(|part| zip_scanlines(part.encoding.compression, part.encoding.blocks == Blocks::ScanLines)) {
        write_zip_scanlines(&image, cursor)
    } else {
        image.write().to_buffered(cursor)
    };
    written.map_err(|e| Error::input(output, format!("cannot write EXR: {e}")))?;
    sort_header_attributes(&mut bytes)?;
    write_atomically(output, |file| {
        file.write_all(&bytes).map_err(Error::io(output))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use exr::prelude::{AnyChannel, AnyChannels, Compression, Encoding, Image, Layer, LayerAttributes, LineOrder, SmallVec};

    /// Every compression and line order keeps its layout, the replaced channel holds the new
    /// samples (its sample type kept) and every other sample is untouched, as the crate's
    /// reader reads the result: ZIP scan lines go through lensblur's own ZIP writer, the rest
    /// through the crate's.
    #[test]
    fn replaced_files_keep_every_other_sample_and_their_layout() {
        let dir = std::env::temp_dir().join(format!("lensblur-exr-replace-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (w, h) = (29usize, 23usize);
        let cases = [
            (Compression::ZIP16, LineOrder::Increasing),
            (Compression::ZIP1, LineOrder::Decreasing),
            (Compression::PIZ, LineOrder::Increasing),
        ];
        for (k, (compression, line_order)) in cases.into_iter().enumerate() {
            let channels = AnyChannels::sort(SmallVec::from_vec(vec![
                AnyChannel::new("R", FlatSamples::F32((0..w * h).map(|i| i as f32 * 0.5).collect())),
                AnyChannel::new("Z", FlatSamples::F16((0..w * h).map(|i| f16::from_f32(1.0 + i as f32 * 0.01)).collect())),
            ]));
            let encoding = Encoding { compression, blocks: Blocks::ScanLines, line_order };
            let layer = Layer::new((w, h), LayerAttributes::named("shot"), encoding, channels);
            let input = dir.join(format!("in{k}.exr"));
            Image::from_layer(layer).write().to_file(&input).unwrap();
            let values: Vec<Option<f32>> = (0..w * h).map(|i| (i % 3 != 0).then_some(7.0 + i as f32)).collect();
            let replacement = ChannelReplacement { part: 0, channel: "Z".into(), values: values.clone() };
            let output = dir.join(format!("out{k}.exr"));
            replace_channels(&input, &output, &[replacement], HeaderEdits { focus: Some(2.5) }, u64::MAX).unwrap();
            let (before, after) = (super::super::exr_read::read_with_the_crate(&input).unwrap(), super::super::exr_read::read_with_the_crate(&output).unwrap());
            let (a, b) = (&before.layer_data[0], &after.layer_data[0]);
            assert_eq!(b.encoding, a.encoding, "{compression:?}");
            assert_eq!(b.attributes.focus, Some(2.5));
            assert_eq!(b.channel_data.list[0].sample_data, a.channel_data.list[0].sample_data, "R untouched, {compression:?}");
            let FlatSamples::F16(z) = &b.channel_data.list[1].sample_data else { panic!("Z stays half") };
            let FlatSamples::F16(z_before) = &a.channel_data.list[1].sample_data else { panic!() };
            for (i, v) in values.iter().enumerate() {
                let expected = v.map_or(z_before[i], f16::from_f32);
                assert_eq!(z[i].to_bits(), expected.to_bits(), "Z sample {i}, {compression:?}");
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
