//! The pixels of a flat EXR, scan-line or tiled, decompressed and placed into their channels
//! on every core.
//!
//! The `exr` crate's image reader decompresses blocks on a thread pool of its own but places
//! every decompressed line into its channel on the calling thread, one block after another: on
//! an 8K five-layer file that was most of the decode. Here each block is decompressed and
//! placed by the same task of the global thread pool. The channels' buffers are split, before
//! the tasks start, into bands of whole rows: a scan-line block's rows, or a row of tiles (the
//! largest resolution level's; the smaller levels of a mip-mapped file are not read). A task
//! decompresses its block on its own and then locks its band to copy the lines in: the tiles of
//! one row of tiles take turns only for the copy, and no two bands share a sample.
//!
//! The result is the image the crate's reader gives (`read().no_deep_data()
//! .largest_resolution_level().all_channels().all_layers().all_attributes()`), sample for
//! sample. Files with subsampled channels return `None`: the caller reads them with the
//! crate's reader.
use std::path::Path;
use std::sync::Mutex;

use exr::block::chunk::Chunk;
use exr::block::UncompressedBlock;
use exr::block::chunk::TileCoordinates;
use exr::image::{AnyChannel, AnyChannels, Blocks, Encoding, FlatSamples};
use exr::meta::header::Header;
use exr::meta::BlockDescription;
use exr::prelude::{f16, SampleType, Vec2};

use super::exr_read::ExrImage;
use crate::{Error, Result};

/// The rows of one channel that one band holds.
enum ChannelRows<'a> {
    F16(&'a mut [f16]),
    F32(&'a mut [f32]),
    U32(&'a mut [u32]),
}

/// A band of rows of one part: each channel's rows, and how many blocks have been placed in
/// it (a band takes [`blocks_per_band`] of them; one more means two blocks of the file cover
/// the same pixels).
struct Band<'a> {
    rows: Vec<ChannelRows<'a>>,
    placed: usize,
}

/// Reads every part of a flat EXR (none deep, no channel subsampled), scan-line or tiled, on
/// every core; `None` for any other file.
pub(super) fn read_flat_pixels(path: &Path) -> Result<Option<ExrImage>> {
    let failed = |e: exr::error::Error| Error::input(path, format!("cannot read EXR pixels: {e}"));
    let file = std::fs::File::open(path).map_err(Error::io(path))?;
    let reader = exr::block::read(std::io::BufReader::new(file), false).map_err(failed)?;
    let eligible = reader.headers().iter().all(|h| !h.deep && h.channels.list.iter().all(|c| c.sampling == Vec2(1, 1)));
    if !eligible {
        return Ok(None);
    }
    let tiled = reader.headers().iter().any(|h| matches!(h.blocks, BlockDescription::Tiles(_)));
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
    // Scan-line files: every chunk in file order, whatever the offset tables say. Tiled files:
    // the largest level's tiles, through the offset tables, as the crate's reader takes them.
    let chunks: Box<dyn Iterator<Item = exr::error::Result<Chunk>> + Send> = if tiled {
        let largest = |_: &exr::meta::MetaData, tile: TileCoordinates, _| tile.level_index == Vec2(0, 0);
        Box::new(reader.filter_chunks(false, largest).map_err(failed)?)
    } else {
        Box::new(reader.all_chunks(false).map_err(failed)?)
    };
    let failure: Mutex<Option<Error>> = Mutex::new(None);
    {
        // bands[part][k]: the rows of every channel that the part's k-th band covers.
        let bands: Vec<Vec<Mutex<Band>>> =
            buffers.iter_mut().zip(headers).map(|(channels, header)| band_rows(channels, header)).collect();
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
                let (meta, bands, fail) = (&meta, &bands, &fail);
                scope.spawn(move |_| {
                    if let Err(error) = place_block(chunk, meta, bands) {
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
            encoding: Encoding {
                compression: header.compression,
                blocks: match header.blocks {
                    BlockDescription::ScanLines => Blocks::ScanLines,
                    BlockDescription::Tiles(tiles) => Blocks::Tiles(tiles.tile_size),
                },
                line_order: header.line_order,
            },
        })
        .collect();
    let attributes = headers.first().map(|h| h.shared_attributes.clone()).ok_or_else(|| Error::input(path, "EXR file has no parts"))?;
    Ok(Some(exr::image::Image { attributes, layer_data }))
}

/// Rows per band of a part: a scan-line block's, or a tile's height.
fn rows_per_band(header: &Header) -> usize {
    match header.blocks {
        BlockDescription::ScanLines => header.compression.scan_lines_per_block(),
        BlockDescription::Tiles(tiles) => tiles.tile_size.height(),
    }
}

/// Blocks of the file in one full band: one scan-line block, or a row of tiles.
fn blocks_per_band(header: &Header) -> usize {
    match header.blocks {
        BlockDescription::ScanLines => 1,
        BlockDescription::Tiles(tiles) => header.layer_size.width().div_ceil(tiles.tile_size.width().max(1)),
    }
}

/// Each band's rows of every channel of one part, top to bottom, ready to be locked by the
/// tasks that place the band's blocks.
fn band_rows<'a>(channels: &'a mut [FlatSamples], header: &Header) -> Vec<Mutex<Band<'a>>> {
    let rows_per_band = rows_per_band(header);
    let samples_per_band = header.layer_size.width() * rows_per_band;
    let band_count = header.layer_size.height().div_ceil(rows_per_band.max(1));
    let mut per_band: Vec<Vec<ChannelRows<'a>>> = (0..band_count).map(|_| Vec::with_capacity(channels.len())).collect();
    for channel in channels.iter_mut() {
        // An empty part (no pixels) has no blocks: nothing to split.
        if samples_per_band == 0 {
            break;
        }
        match channel {
            FlatSamples::F16(v) => v.chunks_mut(samples_per_band).zip(&mut per_band).for_each(|(r, b)| b.push(ChannelRows::F16(r))),
            FlatSamples::F32(v) => v.chunks_mut(samples_per_band).zip(&mut per_band).for_each(|(r, b)| b.push(ChannelRows::F32(r))),
            FlatSamples::U32(v) => v.chunks_mut(samples_per_band).zip(&mut per_band).for_each(|(r, b)| b.push(ChannelRows::U32(r))),
        }
    }
    per_band.into_iter().map(|rows| Mutex::new(Band { rows, placed: 0 })).collect()
}

/// Decompresses one chunk, then copies its lines into the rows of its band.
fn place_block(chunk: Chunk, meta: &exr::meta::MetaData, bands: &[Vec<Mutex<Band>>]) -> std::result::Result<(), String> {
    let block = UncompressedBlock::decompress_chunk(chunk, meta, false).map_err(|e| e.to_string())?;
    let part = block.index.layer;
    let header = meta.headers.get(part).ok_or("a block names a part the file does not have")?;
    let rows_per_band = rows_per_band(header);
    let band_index = block.index.pixel_position.y() / rows_per_band.max(1);
    let first_row = band_index * rows_per_band;
    let width = header.layer_size.width();
    let slot = bands[part].get(band_index).ok_or("a block lies outside its part")?;
    let mut band = slot.lock().unwrap_or_else(|e| e.into_inner());
    band.placed += 1;
    if band.placed > blocks_per_band(header) {
        return Err("two blocks of the file cover the same pixels".into());
    }
    for line in block.lines(&header.channels) {
        let at = line.location;
        let start = (at.position.y() - first_row) * width + at.position.x();
        let range = start..start + at.sample_count;
        let result = match band.rows.get_mut(at.channel).ok_or("a line names a channel the part does not have")? {
            ChannelRows::F16(r) => line.read_samples_into_slice(r.get_mut(range).ok_or("a line lies outside its band")?),
            ChannelRows::F32(r) => line.read_samples_into_slice(r.get_mut(range).ok_or("a line lies outside its band")?),
            ChannelRows::U32(r) => line.read_samples_into_slice(r.get_mut(range).ok_or("a line lies outside its band")?),
        };
        result.map_err(|e| e.to_string())?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use exr::prelude::{Compression, Image, IntegerBounds, Layer, LayerAttributes, LineOrder, SmallVec, WritableImage};

    /// Our reading of `path` (which must be ours to read) equals the crate's reader's: image
    /// attributes, and per part its size, encoding, attributes and every channel's samples.
    fn reads_as_the_crate_reads_it(path: &Path, case: &str) {
        let ours = read_flat_pixels(path).unwrap().expect("a flat file is read here");
        let theirs = super::super::exr_read::read_with_the_crate(path).expect("the crate reads its own file");
        assert_eq!(ours.attributes, theirs.attributes, "{case}");
        assert_eq!(ours.layer_data.len(), theirs.layer_data.len(), "{case}");
        for (a, b) in ours.layer_data.iter().zip(&theirs.layer_data) {
            assert_eq!((a.size, a.encoding, &a.attributes), (b.size, b.encoding, &b.attributes), "{case}");
            assert_eq!(a.channel_data, b.channel_data, "{case}");
        }
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
            let parts = [
                part("front", (37, 53), (0, 0), compression, order, k as u32),
                part("back", (37, 53), (-3, 5), compression, order, 100 + k as u32),
            ];
            for count in [1, 2] {
                let path = dir.join(format!("c{k}-{count}.exr"));
                let layers: Vec<_> = parts[..count].to_vec();
                let image = Image::from_layers(exr::prelude::ImageAttributes::new(IntegerBounds::from_dimensions((40, 60))), layers);
                image.write().to_file(&path).unwrap();
                reads_as_the_crate_reads_it(&path, &format!("{compression:?}, {count} part(s)"));
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Tiled files as the crate's own reader gives them: tiles smaller than the part (the last
    /// row and column of tiles partial), taller than wide, larger than the part, each
    /// compression, one and two parts, a data window off the origin.
    #[test]
    fn tiled_files_read_as_the_crate_reads_them() {
        let dir = std::env::temp_dir().join(format!("lensblur-exr-decode-tiled-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let compressions = [Compression::Uncompressed, Compression::RLE, Compression::ZIP16, Compression::PIZ];
        for (k, compression) in compressions.into_iter().enumerate() {
            for (t, tile) in [(8usize, 8usize), (16, 4), (5, 11), (64, 64)].into_iter().enumerate() {
                let tiled = |mut layer: Layer<AnyChannels<FlatSamples>>| {
                    layer.encoding.blocks = Blocks::Tiles(Vec2(tile.0, tile.1));
                    layer
                };
                let parts = [
                    tiled(part("front", (37, 53), (0, 0), compression, LineOrder::Increasing, k as u32)),
                    tiled(part("back", (37, 53), (-3, 5), compression, LineOrder::Increasing, 100 + t as u32)),
                ];
                for count in [1, 2] {
                    let path = dir.join(format!("c{k}-t{t}-{count}.exr"));
                    let image = Image::from_layers(exr::prelude::ImageAttributes::new(IntegerBounds::from_dimensions((40, 60))), parts[..count].to_vec());
                    image.write().to_file(&path).unwrap();
                    reads_as_the_crate_reads_it(&path, &format!("{compression:?}, tiles {tile:?}, {count} part(s)"));
                }
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
