//! The pixels of a scan-line EXR, decompressed and placed into their channels on every core.
//!
//! The `exr` crate's image reader decompresses blocks on a thread pool of its own but places
//! every decompressed line into its channel on the calling thread, one block after another: on
//! an 8K five-layer file that was most of the decode. Here each block is decompressed and
//! placed by the same task of the global thread pool. A scan-line block covers whole rows of
//! its part, so every block owns its rows of each channel's buffer; the buffers are split into
//! those rows before the tasks start, and no two tasks share a sample.
//!
//! The result is the image the crate's reader gives (`read().no_deep_data()
//! .largest_resolution_level().all_channels().all_layers().all_attributes()`), sample for
//! sample. Files with tiles or subsampled channels return `None`: the caller reads them with
//! the crate's reader.
use std::path::Path;
use std::sync::Mutex;

use exr::block::chunk::Chunk;
use exr::block::UncompressedBlock;
use exr::image::{AnyChannel, AnyChannels, Blocks, Encoding, FlatSamples};
use exr::meta::header::Header;
use exr::meta::BlockDescription;
use exr::prelude::{f16, SampleType, Vec2};

use super::exr_read::ExrImage;
use crate::{Error, Result};

/// The rows of one channel that one block holds.
enum ChannelRows<'a> {
    F16(&'a mut [f16]),
    F32(&'a mut [f32]),
    U32(&'a mut [u32]),
}

/// Reads every part of a scan-line EXR (none deep, no channel subsampled) on every core; `None`
/// for any other file.
pub(super) fn read_scanline_pixels(path: &Path) -> Result<Option<ExrImage>> {
    let failed = |e: exr::error::Error| Error::input(path, format!("cannot read EXR pixels: {e}"));
    let file = std::fs::File::open(path).map_err(Error::io(path))?;
    let reader = exr::block::read(std::io::BufReader::new(file), false).map_err(failed)?;
    let eligible = reader.headers().iter().all(|h| {
        !h.deep
            && matches!(h.blocks, BlockDescription::ScanLines)
            && h.channels.list.iter().all(|c| c.sampling == Vec2(1, 1))
    });
    if !eligible {
        return Ok(None);
    }
    // One copy of the headers, kept for the tasks: the chunk reader takes the file's.
    let meta = reader.meta_data().clone();
    let headers = &meta.headers;
    let mut buffers: Vec<Vec<FlatSamples>> = headers
        .iter()
        .map(|h| {
            let n = h.layer_size.area();
            h.channels
                .list
                .iter()
                .map(|c| match c.sample_type {
                    SampleType::F16 => FlatSamples::F16(vec![f16::ZERO; n]),
                    SampleType::F32 => FlatSamples::F32(vec![0.0; n]),
                    SampleType::U32 => FlatSamples::U32(vec![0; n]),
                })
                .collect()
        })
        .collect();
    let chunks = reader.all_chunks(false).map_err(failed)?;
    let failure: Mutex<Option<Error>> = Mutex::new(None);
    {
        // blocks[part][k]: the rows of every channel that the part's k-th block covers.
        let blocks: Vec<Vec<Mutex<Option<Vec<ChannelRows>>>>> =
            buffers.iter_mut().zip(headers).map(|(channels, header)| block_rows(channels, header)).collect();
        let fail = |error: Error| {
            let mut first = failure.lock().unwrap_or_else(|e| e.into_inner());
            first.get_or_insert(error);
        };
        rayon::scope(|scope| {
            for chunk in chunks {
                let chunk: Chunk = match chunk {
                    Ok(chunk) => chunk,
                    Err(e) => return fail(failed(e)),
                };
                let (meta, blocks, fail) = (&meta, &blocks, &fail);
                scope.spawn(move |_| {
                    if let Err(error) = place_block(chunk, meta, blocks) {
                        fail(Error::input(path, format!("cannot read EXR pixels: {error}")));
                    }
                });
            }
        });
    }
    if let Some(error) = failure.into_inner().unwrap_or_else(|e| e.into_inner()) {
        return Err(error);
    }
    let layer_data = headers
        .iter()
        .zip(buffers)
        .map(|(header, samples)| exr::image::Layer {
            channel_data: AnyChannels {
                list: header
                    .channels
                    .list
                    .iter()
                    .zip(samples)
                    .map(|(c, sample_data)| AnyChannel {
                        name: c.name.clone(),
                        sample_data,
                        quantize_linearly: c.quantize_linearly,
                        sampling: c.sampling,
                    })
                    .collect(),
            },
            attributes: header.own_attributes.clone(),
            size: header.layer_size,
            encoding: Encoding { compression: header.compression, blocks: Blocks::ScanLines, line_order: header.line_order },
        })
        .collect();
    let attributes = headers.first().map(|h| h.shared_attributes.clone()).ok_or_else(|| Error::input(path, "EXR file has no parts"))?;
    Ok(Some(exr::image::Image { attributes, layer_data }))
}

/// Each block's rows of every channel of one part, in block order, ready to be taken by the
/// task that places the block.
fn block_rows<'a>(channels: &'a mut [FlatSamples], header: &Header) -> Vec<Mutex<Option<Vec<ChannelRows<'a>>>>> {
    let rows_per_block = header.compression.scan_lines_per_block();
    let samples_per_block = header.layer_size.width() * rows_per_block;
    let block_count = header.layer_size.height().div_ceil(rows_per_block);
    let mut per_block: Vec<Vec<ChannelRows<'a>>> = (0..block_count).map(|_| Vec::with_capacity(channels.len())).collect();
    for channel in channels.iter_mut() {
        // An empty part (no pixels) has no blocks: nothing to split.
        if samples_per_block == 0 {
            break;
        }
        match channel {
            FlatSamples::F16(v) => v.chunks_mut(samples_per_block).zip(&mut per_block).for_each(|(r, b)| b.push(ChannelRows::F16(r))),
            FlatSamples::F32(v) => v.chunks_mut(samples_per_block).zip(&mut per_block).for_each(|(r, b)| b.push(ChannelRows::F32(r))),
            FlatSamples::U32(v) => v.chunks_mut(samples_per_block).zip(&mut per_block).for_each(|(r, b)| b.push(ChannelRows::U32(r))),
        }
    }
    per_block.into_iter().map(|rows| Mutex::new(Some(rows))).collect()
}

/// Decompresses one chunk and copies its lines into the rows its block owns.
fn place_block(
    chunk: Chunk,
    meta: &exr::meta::MetaData,
    blocks: &[Vec<Mutex<Option<Vec<ChannelRows>>>>],
) -> std::result::Result<(), String> {
    let block = UncompressedBlock::decompress_chunk(chunk, meta, false).map_err(|e| e.to_string())?;
    let part = block.index.layer;
    let header = meta.headers.get(part).ok_or("a block names a part the file does not have")?;
    let rows_per_block = header.compression.scan_lines_per_block();
    let first_row = block.index.pixel_position.y();
    let width = header.layer_size.width();
    let slot = blocks[part].get(first_row / rows_per_block).ok_or("a block lies outside its part")?;
    let taken = slot.lock().unwrap_or_else(|e| e.into_inner()).take();
    let mut rows = taken.ok_or("two blocks of the file cover the same rows")?;
    for line in block.lines(&header.channels) {
        let at = line.location;
        let start = (at.position.y() - first_row) * width + at.position.x();
        let range = start..start + at.sample_count;
        let result = match rows.get_mut(at.channel).ok_or("a line names a channel the part does not have")? {
            ChannelRows::F16(r) => line.read_samples_into_slice(r.get_mut(range).ok_or("a line lies outside its block")?),
            ChannelRows::F32(r) => line.read_samples_into_slice(r.get_mut(range).ok_or("a line lies outside its block")?),
            ChannelRows::U32(r) => line.read_samples_into_slice(r.get_mut(range).ok_or("a line lies outside its block")?),
        };
        result.map_err(|e| e.to_string())?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use exr::prelude::{Compression, Image, IntegerBounds, Layer, LayerAttributes, LineOrder, SmallVec, WritableImage};

    fn crate_reader(path: &Path) -> ExrImage {
        super::super::exr_read::read_with_the_crate(path).expect("the crate reads its own file")
    }

    fn channel(name: &str, samples: FlatSamples) -> AnyChannel<FlatSamples> {
        AnyChannel::new(name, samples)
    }

    /// A part of `width` x `height` at `origin` with one channel of each sample type, values that
    /// tell every sample apart.
    fn part(name: &str, (width, height): (usize, usize), origin: (i32, i32), compression: Compression, line_order: LineOrder, seed: u32) -> Layer<AnyChannels<FlatSamples>> {
        let n = width * height;
        let value = |i: usize, k: u32| (i as u32).wrapping_mul(2_654_435_761).wrapping_add(seed * 7 + k) % 100_000;
        let channels = AnyChannels::sort(SmallVec::from_vec(vec![
            channel("R", FlatSamples::F32((0..n).map(|i| value(i, 0) as f32 * 0.37 - 9.0).collect())),
            channel("Z", FlatSamples::F32((0..n).map(|i| 1.0 + value(i, 1) as f32).collect())),
            channel("A", FlatSamples::F16((0..n).map(|i| f16::from_f32(value(i, 2) as f32 / 100_000.0)).collect())),
            channel("id", FlatSamples::U32((0..n).map(|i| value(i, 3)).collect())),
        ]));
        let mut attributes = LayerAttributes::named(name);
        attributes.layer_position = Vec2(origin.0, origin.1);
        Layer::new((width, height), attributes, Encoding { compression, blocks: Blocks::ScanLines, line_order }, channels)
    }

    /// Every part, channel and sample as the crate's own reader gives them: single- and
    /// multi-part, each compression the crate writes (1, 16 and 32 rows per block), a height
    /// that ends in a partial block, a data window off the origin, both line orders.
    #[test]
    fn scanline_files_read_as_the_crate_reads_them() {
        let dir = std::env::temp_dir().join(format!("lensblur-exr-decode-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let compressions = [Compression::Uncompressed, Compression::RLE, Compression::ZIP1, Compression::ZIP16, Compression::PIZ, Compression::PXR24];
        for (k, compression) in compressions.into_iter().enumerate() {
            let order = if k % 2 == 0 { LineOrder::Increasing } else { LineOrder::Decreasing };
            let parts = vec![
                part("front", (37, 53), (0, 0), compression, order, k as u32),
                part("back", (37, 53), (-3, 5), compression, order, 100 + k as u32),
            ];
            for count in [1, 2] {
                let path = dir.join(format!("c{k}-{count}.exr"));
                let layers: Vec<_> = parts[..count].to_vec();
                let image = Image::from_layers(exr::prelude::ImageAttributes::new(IntegerBounds::from_dimensions((40, 60))), layers);
                image.write().to_file(&path).unwrap();
                let ours = read_scanline_pixels(&path).unwrap().expect("a scan-line file");
                let theirs = crate_reader(&path);
                assert_eq!(ours.attributes, theirs.attributes, "{compression:?}, {count} part(s)");
                assert_eq!(ours.layer_data.len(), theirs.layer_data.len());
                for (a, b) in ours.layer_data.iter().zip(&theirs.layer_data) {
                    assert_eq!((a.size, a.encoding, &a.attributes), (b.size, b.encoding, &b.attributes), "{compression:?}");
                    assert_eq!(a.channel_data, b.channel_data, "{compression:?}, {count} part(s)");
                }
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A tiled file is left to the crate's reader.
    #[test]
    fn tiled_files_are_not_read_here() {
        let path = std::env::temp_dir().join(format!("lensblur-exr-decode-tiled-{}.exr", std::process::id()));
        let mut layer = part("tiles", (20, 20), (0, 0), Compression::ZIP16, LineOrder::Increasing, 1);
        layer.encoding.blocks = Blocks::Tiles(Vec2(8, 8));
        Image::from_layer(layer).write().to_file(&path).unwrap();
        assert!(read_scanline_pixels(&path).unwrap().is_none());
        std::fs::remove_file(&path).unwrap();
    }
}
