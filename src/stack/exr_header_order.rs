//! Byte-identical EXR headers. The exr crate keeps custom header attributes in a `HashMap`,
//! whose iteration order (and so the order of the attributes in the written header) changes
//! from process to process. A file that carries the input's attributes (Blender writes a
//! dozen) would then differ between two runs on the same input. Sorting each header's
//! attributes by name after writing fixes the order; it moves bytes within each header only,
//! so the header sizes, the offset tables and the chunks stay exactly where they were.
use crate::{Error, Result};

/// EXR version field bit: the file has several parts (headers end with an empty header).
const MULTIPART_BIT: u32 = 0x1000;

/// Sorts the attributes of every header of the EXR file in `bytes` by name, in place.
pub fn sort_header_attributes(bytes: &mut [u8]) -> Result<()> {
    let malformed = |what: &str| Error::data(format!("cannot reorder the EXR header: {what}"));
    let version = bytes.get(4..8).ok_or_else(|| malformed("file shorter than its version field"))?;
    let multipart = u32::from_le_bytes([version[0], version[1], version[2], version[3]]) & MULTIPART_BIT != 0;
    let mut at = 8;
    loop {
        let start = at;
        let mut attributes = Vec::new(); // (name, byte range)
        while *bytes.get(at).ok_or_else(|| malformed("header runs past the end"))? != 0 {
            let begin = at;
            let name_end = find_nul(bytes, at).ok_or_else(|| malformed("attribute name not terminated"))?;
            let type_end = find_nul(bytes, name_end + 1).ok_or_else(|| malformed("attribute type not terminated"))?;
            let size_at = type_end + 1;
            let size = bytes.get(size_at..size_at + 4).ok_or_else(|| malformed("attribute size missing"))?;
            let size = i32::from_le_bytes([size[0], size[1], size[2], size[3]]);
            let size = usize::try_from(size).map_err(|_| malformed("negative attribute size"))?;
            at = size_at + 4 + size;
            if at > bytes.len() {
                return Err(malformed("attribute value runs past the end"));
            }
            attributes.push((bytes[begin..name_end].to_vec(), begin..at));
        }
        if attributes.is_empty() && start != 8 {
            break; // the empty header that ends a multi-part header list
        }
        let mut sorted = attributes.clone();
        sorted.sort_by(|a, b| a.0.cmp(&b.0));
        let reordered: Vec<u8> = sorted.iter().flat_map(|(_, range)| bytes[range.clone()].to_vec()).collect();
        bytes[start..at].copy_from_slice(&reordered);
        at += 1; // the header's terminating zero
        if !multipart {
            break;
        }
    }
    Ok(())
}

fn find_nul(bytes: &[u8], from: usize) -> Option<usize> {
    bytes.get(from..)?.iter().position(|&b| b == 0).map(|i| from + i)
}

#[cfg(test)]
mod tests {
    use std::io::Cursor;

    use exr::meta::attribute::{AttributeValue, Text};
    use exr::prelude::{
        AnyChannel, AnyChannels, Encoding, FlatSamples, ImageAttributes, IntegerBounds, LayerAttributes, ReadChannels,
        ReadLayers, WritableImage,
    };

    use super::*;

    /// Two parts, each with custom attributes inserted in the order `names`.
    fn image_bytes(names: &[&str]) -> Vec<u8> {
        let part = |layer: &str, offset: f32| {
            let mut attributes = LayerAttributes::named(layer);
            for name in names {
                attributes.other.insert(Text::from(*name), AttributeValue::F32(offset + name.len() as f32));
            }
            let samples = FlatSamples::F32((0..12).map(|i| i as f32 + offset).collect());
            let channels = AnyChannels::sort(vec![AnyChannel::new("Z", samples)].into());
            exr::prelude::Layer::new((4, 3), attributes, Encoding::SMALL_LOSSLESS, channels)
        };
        let mut shared = ImageAttributes::new(IntegerBounds::from_dimensions((4, 3)));
        for name in names {
            shared.other.insert(Text::from(format!("shared_{name}").as_str()), AttributeValue::I32(name.len() as i32));
        }
        let image = exr::prelude::Image::from_layers(shared, vec![part("fg", 0.0), part("bg", 100.0)]);
        let mut bytes = Vec::new();
        image.write().to_buffered(Cursor::new(&mut bytes)).unwrap();
        bytes
    }

    #[test]
    fn the_same_attributes_in_any_map_order_give_identical_bytes_that_read_back() {
        let names = ["cameraName", "Time", "BlenderMultiChannel", "Note", "aperture_x", "zz_last"];
        let mut reversed = names;
        reversed.reverse();
        let (mut a, mut b) = (image_bytes(&names), image_bytes(&reversed));
        let unsorted = a.clone();
        sort_header_attributes(&mut a).unwrap();
        sort_header_attributes(&mut b).unwrap();
        assert!(a == b, "sorted headers must not depend on the maps' iteration order");
        assert_eq!(a.len(), unsorted.len(), "sorting moves bytes within the headers only");

        let read = |bytes: &[u8]| {
            exr::prelude::read().no_deep_data().largest_resolution_level().all_channels().all_layers().all_attributes()
                .from_buffered(Cursor::new(bytes)).unwrap()
        };
        let (before, after) = (read(&unsorted), read(&a));
        assert_eq!(before.attributes, after.attributes);
        assert_eq!(before.layer_data.len(), 2);
        for (x, y) in before.layer_data.iter().zip(&after.layer_data) {
            assert_eq!(x.attributes, y.attributes);
            assert_eq!(x.channel_data.list[0].sample_data, y.channel_data.list[0].sample_data);
        }
    }

    #[test]
    fn a_truncated_header_is_an_error_not_a_panic() {
        let bytes = image_bytes(&["a", "b"]);
        for cut in [0, 6, 9, 20, 40] {
            let mut short = bytes[..cut].to_vec();
            assert!(sort_header_attributes(&mut short).is_err(), "cut at {cut}");
        }
    }
}
