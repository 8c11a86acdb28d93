//! A writer of deep OpenEXR files (uncompressed or ZIPS), scanline or tiled, single- or multi-part, in
//! plain Rust (no C library): the deep files of the ray tracer's true layers (tests and the
//! benchmark) and fuzz seeds. Channels A, B, G, R (half or float), Z and, when asked, ZBack
//! (float), as OpenEXR stores them: sorted by name.
use std::io::Write as _;
use std::path::Path;

use super::DeepImage;
use crate::stack::exr_zip::zip_block;
use crate::{Error, Result};

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DeepWriteOptions {
    /// Colour and alpha as half floats (depth is always float).
    pub half_colour: bool,
    /// Write ZBack beside Z.
    pub z_back: bool,
    /// Deep tiles of this side (else deep scanlines, one line per chunk).
    pub tile: Option<usize>,
    /// ZIPS compression (zlib, per chunk) instead of none.
    pub zip: bool,
}

/// Writes `parts` (name and image; all on their own display windows at their origins) to
/// `path`. One part is a single-part file; its name is written only if given.
pub fn write_deep(path: &Path, parts: &[(Option<&str>, &DeepImage)], options: &DeepWriteOptions) -> Result<()> {
    if parts.is_empty() {
        return Err(Error::data("no part to write"));
    }
    let multipart = parts.len() > 1;
    let mut names = vec!["A", "B", "G", "R", "Z"];
    if options.z_back {
        names.push("ZBack");
    }
    let colour_type = if options.half_colour { 1 } else { 2 };
    let types: Vec<i32> = names.iter().map(|n| if n.starts_with('Z') { 2 } else { colour_type }).collect();
    let mut out = Vec::new();
    out.extend_from_slice(&[0x76, 0x2f, 0x31, 0x01]);
    let mut version = 2u32 | 0x800;
    if multipart {
        version |= 0x1000;
    } else if options.tile.is_some() {
        version |= 0x200;
    }
    out.extend_from_slice(&version.to_le_bytes());
    let chunk_lists: Vec<Vec<(i32, i32, usize, usize, usize, usize)>> =
        parts.iter().map(|(_, image)| chunks(image, options)).collect();
    for ((name, image), chunk_list) in parts.iter().zip(&chunk_lists) {
        header(&mut out, *name, image, &names, &types, options, chunk_list.len());
    }
    if multipart {
        out.push(0);
    }
    // Offset tables, then the chunks; the tables are filled in once the chunks are laid out.
    let table_start = out.len();
    let total_chunks: usize = chunk_lists.iter().map(Vec::len).sum();
    out.resize(table_start + 8 * total_chunks, 0);
    let mut entry = 0;
    for (part, ((_, image), chunk_list)) in parts.iter().zip(&chunk_lists).enumerate() {
        for &(cx, cy, x0, y0, w, h) in chunk_list {
            let offset = out.len() as u64;
            out[table_start + 8 * entry..table_start + 8 * entry + 8].copy_from_slice(&offset.to_le_bytes());
            entry += 1;
            if multipart {
                out.extend_from_slice(&(part as i32).to_le_bytes());
            }
            // A scanline chunk starts with its first line; a tile with its x, y and level 0, 0.
            let leader: &[i32] = if options.tile.is_some() { &[cx, cy, 0, 0] } else { &[cy] };
            for v in leader {
                out.extend_from_slice(&v.to_le_bytes());
            }
            let (table, data) = chunk_data(image, x0, y0, w, h, &names, &types);
            let unpacked = data.len() as u64;
            let (table, data) = if options.zip { (zip_block(table), zip_block(data)) } else { (table, data) };
            for size in [table.len() as u64, data.len() as u64, unpacked] {
                out.extend_from_slice(&size.to_le_bytes());
            }
            out.extend_from_slice(&table);
            out.extend_from_slice(&data);
        }
    }
    let mut file = std::fs::File::create(path).map_err(Error::io(path))?;
    file.write_all(&out).map_err(Error::io(path))
}

/// Each chunk as (its coordinate as the chunk header stores it: tile x/y or line y, and
/// x0, y0, width, height of its pixels in the image).
fn chunks(image: &DeepImage, options: &DeepWriteOptions) -> Vec<(i32, i32, usize, usize, usize, usize)> {
    match options.tile {
        Some(t) => {
            let t = t.max(1);
            let mut out = Vec::new();
            for ty in 0..image.height.div_ceil(t) {
                for tx in 0..image.width.div_ceil(t) {
                    let (x0, y0) = (tx * t, ty * t);
                    out.push((tx as i32, ty as i32, x0, y0, t.min(image.width - x0), t.min(image.height - y0)));
                }
            }
            out
        }
        None => (0..image.height).map(|y| (0, image.origin[1] + y as i32, 0, y, image.width, 1)).collect(),
    }
}

/// The cumulative per-line sample table and the samples (per line, per channel, per pixel).
fn chunk_data(
    image: &DeepImage,
    x0: usize,
    y0: usize,
    w: usize,
    h: usize,
    names: &[&str],
    types: &[i32],
) -> (Vec<u8>, Vec<u8>) {
    let (mut table, mut data) = (Vec::new(), Vec::new());
    for y in y0..y0 + h {
        let mut cumulative = 0i32;
        for x in x0..x0 + w {
            cumulative += image.pixel(y * image.width + x).len() as i32;
            table.extend_from_slice(&cumulative.to_le_bytes());
        }
        for (name, &kind) in names.iter().zip(types) {
            for x in x0..x0 + w {
                for s in image.pixel(y * image.width + x) {
                    let v = match *name {
                        "R" => s.rgba[0],
                        "G" => s.rgba[1],
                        "B" => s.rgba[2],
                        "A" => s.rgba[3],
                        "Z" => s.z,
                        _ => s.z_back,
                    };
                    if kind == 1 {
                        data.extend_from_slice(&half::f16::from_f32(v).to_le_bytes());
                    } else {
                        data.extend_from_slice(&v.to_le_bytes());
                    }
                }
            }
        }
    }
    (table, data)
}

#[allow(clippy::too_many_arguments)]
fn header(
    out: &mut Vec<u8>,
    name: Option<&str>,
    image: &DeepImage,
    names: &[&str],
    types: &[i32],
    options: &DeepWriteOptions,
    chunk_count: usize,
) {
    let mut attribute = |name: &str, kind: &str, value: &[u8]| {
        out.extend_from_slice(name.as_bytes());
        out.push(0);
        out.extend_from_slice(kind.as_bytes());
        out.push(0);
        out.extend_from_slice(&(value.len() as i32).to_le_bytes());
        out.extend_from_slice(value);
    };
    let mut channels = Vec::new();
    for (n, &t) in names.iter().zip(types) {
        channels.extend_from_slice(n.as_bytes());
        channels.push(0);
        channels.extend_from_slice(&t.to_le_bytes());
        channels.extend_from_slice(&[0, 0, 0, 0]);
        channels.extend_from_slice(&1i32.to_le_bytes());
        channels.extend_from_slice(&1i32.to_le_bytes());
    }
    channels.push(0);
    attribute("channels", "chlist", &channels);
    attribute("compression", "compression", &[if options.zip { 2 } else { 0 }]);
    let [x0, y0] = image.origin;
    let window: Vec<u8> = [x0, y0, x0 + image.width as i32 - 1, y0 + image.height as i32 - 1]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    attribute("dataWindow", "box2i", &window);
    attribute("displayWindow", "box2i", &window);
    attribute("lineOrder", "lineOrder", &[0]);
    attribute("pixelAspectRatio", "float", &1.0f32.to_le_bytes());
    attribute("screenWindowCenter", "v2f", &[0u8; 8]);
    attribute("screenWindowWidth", "float", &1.0f32.to_le_bytes());
    if let Some(name) = name {
        attribute("name", "string", name.as_bytes());
    }
    attribute("type", "string", if options.tile.is_some() { b"deeptile" } else { b"deepscanline" });
    attribute("version", "int", &1i32.to_le_bytes());
    attribute("chunkCount", "int", &(chunk_count as i32).to_le_bytes());
    let most = (0..image.width * image.height).map(|i| image.pixel(i).len()).max().unwrap_or(0);
    attribute("maxSamplesPerPixel", "int", &(most as i32).to_le_bytes());
    if let Some(t) = options.tile {
        let mut desc = Vec::new();
        desc.extend_from_slice(&(t as u32).to_le_bytes());
        desc.extend_from_slice(&(t as u32).to_le_bytes());
        desc.push(0);
        attribute("tiles", "tiledesc", &desc);
    }
    for (key, value) in &image.attributes {
        match value.parse::<f32>() {
            Ok(v) => attribute(key, "float", &v.to_le_bytes()),
            Err(_) => attribute(key, "string", value.as_bytes()),
        }
    }
    out.push(0);
}
