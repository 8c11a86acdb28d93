//! Deep files through OpenEXR's core library ([`super::ffi`]), checked before use: the
//! library reads and decompresses chunks; every count it hands back is checked here against
//! the data window, the chunk's bytes and the sample budget before a sample is unpacked, and
//! every depth before it is kept. A refusal names the file, the part and the pixel.
use std::collections::BTreeMap;
use std::path::Path;

use super::ffi::{ChannelType, DeepFile, PartHeader};
use super::{merge, DeepFileInfo, DeepImage, DeepPartInfo, DeepReadOptions, DeepSample, PartChoice};
use crate::{Error, Result};

/// Channel names for colour, alpha, depth and back depth: the standard short names, then the
/// long ones some tools write.
const CHANNEL_NAMES: [&[&str]; 6] =
    [&["R", "red"], &["G", "green"], &["B", "blue"], &["A", "alpha"], &["Z", "depth"], &["ZBack", "zback"]];

/// Reads the deep parts of `path` that `options.part` chooses into one deep image.
pub fn read_deep(path: &Path, options: &DeepReadOptions) -> Result<DeepImage> {
    let file = DeepFile::open(path).map_err(|e| Error::input(path, e))?;
    let headers = headers(&file, path)?;
    let chosen = choose_parts(&headers, &options.part, path)?;
    let mut images = Vec::new();
    let mut budget = options.max_samples;
    for index in chosen {
        let (image, _) = read_part(&file, path, index, &headers[index], options.max_pixels, budget)?;
        budget -= image.samples.len() as u64;
        images.push(image);
    }
    merge(images, options.max_pixels)
}

/// Every part's header, sample counts and depth range (`lensblur info`); parts that are not
/// deep are listed and skipped.
pub fn deep_info(path: &Path, options: &DeepReadOptions) -> Result<DeepFileInfo> {
    let file = DeepFile::open(path).map_err(|e| Error::input(path, e))?;
    let headers = headers(&file, path)?;
    let mut parts = Vec::new();
    let mut attributes = BTreeMap::new();
    let mut budget = options.max_samples;
    for (index, header) in headers.iter().enumerate() {
        for (key, value) in &header.attributes {
            attributes.entry(key.clone()).or_insert_with(|| value.clone());
        }
        let mut info = DeepPartInfo {
            index,
            name: header.name.clone(),
            storage: match header.deep_tiled {
                Some(true) => "deep tiled",
                Some(false) => "deep scanline",
                None => "not deep (skipped)",
            }
            .into(),
            data_window: header.data_window,
            display_window: header.display_window,
            channels: header.channels.iter().map(|(name, kind, _)| format!("{name} ({kind:?})")).collect(),
            compression: compression_name(header.compression).into(),
            samples: 0,
            max_samples_per_pixel: 0,
            covered_pixels: 0,
            depth_range: None,
            volumetric_samples: 0,
        };
        if header.deep_tiled.is_some() {
            let (image, counts) = read_part(&file, path, index, header, options.max_pixels, budget)?;
            budget -= image.samples.len() as u64;
            info.samples = image.samples.len() as u64;
            info.max_samples_per_pixel = counts.iter().copied().max().unwrap_or(0);
            info.covered_pixels = counts.iter().filter(|&&c| c > 0).count() as u64;
            info.volumetric_samples = image.samples.iter().filter(|s| s.z_back > s.z).count() as u64;
            info.depth_range = image.samples.iter().fold(None, |range, s| {
                let [lo, hi] = range.unwrap_or([f32::INFINITY, f32::NEG_INFINITY]);
                Some([lo.min(s.z), hi.max(s.z_back)])
            });
        }
        parts.push(info);
    }
    Ok(DeepFileInfo { path: path.to_path_buf(), parts, attributes })
}

fn compression_name(code: i32) -> &'static str {
    ["none", "rle", "zips", "zip", "piz", "pxr24", "b44", "b44a", "dwaa", "dwab"]
        .get(code as usize)
        .copied()
        .unwrap_or("unknown")
}

fn headers(file: &DeepFile, path: &Path) -> Result<Vec<PartHeader>> {
    let count = file.part_count().map_err(|e| Error::input(path, e))?;
    (0..count).map(|p| file.header(p).map_err(|e| Error::input(path, format!("part {p}: {e}")))).collect()
}

fn choose_parts(headers: &[PartHeader], choice: &PartChoice, path: &Path) -> Result<Vec<usize>> {
    let deep: Vec<usize> = (0..headers.len()).filter(|&i| headers[i].deep_tiled.is_some()).collect();
    let names = || {
        headers
            .iter()
            .enumerate()
            .map(|(i, h)| format!("{i} '{}'", h.name.as_deref().unwrap_or("-")))
            .collect::<Vec<_>>()
            .join(", ")
    };
    match choice {
        _ if deep.is_empty() => Err(Error::input(path, "holds no deep part")),
        PartChoice::First => Ok(vec![deep[0]]),
        PartChoice::All => Ok(deep),
        PartChoice::Named(name) => {
            let found = headers
                .iter()
                .position(|h| h.name.as_deref() == Some(name.as_str()))
                .or_else(|| name.parse::<usize>().ok());
            match found {
                Some(i) if deep.contains(&i) => Ok(vec![i]),
                _ => Err(Error::input(path, format!("has no deep part '{name}' (parts: {})", names()))),
            }
        }
    }
}

/// Where each of the six channels we use sits in the part's channel list.
fn channel_slots(header: &PartHeader, path: &Path, part: &str) -> Result<[Option<usize>; 6]> {
    let mut slots = [None; 6];
    for (slot, names) in slots.iter_mut().zip(CHANNEL_NAMES) {
        *slot = header.channels.iter().position(|(n, ..)| names.iter().any(|m| n.eq_ignore_ascii_case(m)));
    }
    let missing: Vec<&str> =
        [0, 1, 2, 3, 4].iter().filter(|&&s| slots[s].is_none()).map(|&s| CHANNEL_NAMES[s][0]).collect();
    if !missing.is_empty() {
        return Err(Error::input(
            path,
            format!("{part}: no deep channel {} (needs R, G, B, A and Z; ZBack is optional)", missing.join(", ")),
        ));
    }
    for (name, kind, sampling) in &header.channels {
        if *sampling != [1, 1] {
            return Err(Error::input(
                path,
                format!(
                    "{part}: channel {name} is subsampled ({}x{}), which deep data cannot be",
                    sampling[0], sampling[1]
                ),
            ));
        }
        if *kind == ChannelType::Uint && slots.iter().flatten().any(|&s| &header.channels[s].0 == name) {
            return Err(Error::input(
                path,
                format!("{part}: channel {name} holds integers; colour, alpha and depth must be half or float"),
            ));
        }
    }
    Ok(slots)
}

/// Reads one deep part onto its display window; also returns each data-window pixel's count.
fn read_part(
    file: &DeepFile,
    path: &Path,
    index: usize,
    header: &PartHeader,
    max_pixels: u64,
    max_samples: u64,
) -> Result<(DeepImage, Vec<u64>)> {
    let part = match &header.name {
        Some(name) => format!("part {index} '{name}'"),
        None => format!("part {index}"),
    };
    let tiled = header.deep_tiled.ok_or_else(|| Error::input(path, format!("{part} is not deep")))?;
    let [x0, y0, x1, y1] = header.data_window;
    let [dx0, dy0, dx1, dy1] = header.display_window;
    let size = |a: i32, b: i32| if b >= a { (i64::from(b) - i64::from(a) + 1) as u64 } else { 0 };
    let (w, h) = (size(x0, x1), size(y0, y1));
    let (dw, dh) = (size(dx0, dx1), size(dy0, dy1));
    for (what, a, b) in [("data", w, h), ("display", dw, dh)] {
        if a == 0 || b == 0 || a.saturating_mul(b) > max_pixels {
            return Err(Error::input(
                path,
                format!("{part}: the {what} window is {a}x{b} pixels, outside 1..={max_pixels} (raise --max-pixels for a genuine larger file)"),
            ));
        }
    }
    let slots = channel_slots(header, path, &part)?;
    let bytes: Vec<usize> = header.channels.iter().map(|(_, kind, _)| kind.bytes()).collect();
    let sample_bytes: u64 = bytes.iter().sum::<usize>() as u64;
    let (w, h) = (w as usize, h as usize);
    let mut counts = vec![0u64; w * h];
    // Samples with the data-window pixel they belong to, in chunk order.
    let mut read: Vec<(u32, DeepSample)> = Vec::new();
    let [cw, ch] = header.chunk_size;
    if cw <= 0 || ch <= 0 {
        return Err(Error::input(path, format!("{part}: chunk size {cw}x{ch}")));
    }
    let mut chunk_starts = Vec::new();
    if tiled {
        for ty in 0..h.div_ceil(ch as usize) {
            for tx in 0..w.div_ceil(cw as usize) {
                chunk_starts.push([tx as i32, ty as i32]);
            }
        }
    } else {
        let mut y = i64::from(y0);
        while y <= i64::from(y1) {
            chunk_starts.push([x0, y as i32]);
            y += i64::from(ch);
        }
    }
    let mut total = 0u64;
    for at in chunk_starts {
        let budget_bytes = (max_samples - total).saturating_mul(sample_bytes);
        let chunk = file
            .read_chunk(index, tiled.then_some(header.chunk_size), at, header.data_window, budget_bytes)
            .map_err(|e| budget_or_input(path, &part, e, max_samples))?;
        let [cx, cy] = chunk.start;
        let [cwid, chei] = [chunk.size[0] as usize, chunk.size[1] as usize];
        let pixel_name = |x: usize, y: usize| format!("{part} pixel ({}, {})", cx as usize + x, cy as usize + y);
        // Per line: cumulative counts must start at >= 0 and never decrease.
        let mut line_totals = Vec::with_capacity(chei);
        for y in 0..chei {
            let line = &chunk.cumulative_counts[y * cwid..(y + 1) * cwid];
            let mut previous = 0i32;
            for (x, &c) in line.iter().enumerate() {
                if c < previous {
                    return Err(Error::input(
                        path,
                        format!(
                            "{}: the sample count table is inconsistent (cumulative count {c} after {previous})",
                            pixel_name(x, y)
                        ),
                    ));
                }
                previous = c;
            }
            line_totals.push(previous as u64);
        }
        let chunk_samples: u64 = line_totals.iter().sum();
        if total + chunk_samples > max_samples {
            return Err(budget_error(path, &part, max_samples));
        }
        if chunk_samples * sample_bytes != chunk.data.len() as u64 {
            return Err(Error::input(
                path,
                format!(
                    "{}: the sample count table is inconsistent with the data: it counts {chunk_samples} samples \
                     ({} bytes) in the chunk, which holds {} bytes",
                    pixel_name(0, 0),
                    chunk_samples * sample_bytes,
                    chunk.data.len()
                ),
            ));
        }
        total += chunk_samples;
        let mut line_start = 0usize;
        for y in 0..chei {
            let line = &chunk.cumulative_counts[y * cwid..(y + 1) * cwid];
            let n = line_totals[y] as usize;
            // Each channel's samples for the whole line, one after another.
            let mut channel_start = Vec::with_capacity(bytes.len());
            let mut at = line_start;
            for b in &bytes {
                channel_start.push(at);
                at += n * b;
            }
            let value = |slot: usize, k: usize| -> f32 {
                let c = slot;
                let o = channel_start[c] + k * bytes[c];
                let d = &chunk.data;
                match header.channels[c].1 {
                    ChannelType::Half => half::f16::from_le_bytes([d[o], d[o + 1]]).to_f32(),
                    _ => f32::from_le_bytes([d[o], d[o + 1], d[o + 2], d[o + 3]]),
                }
            };
            let mut previous = 0usize;
            for x in 0..cwid {
                let end = line[x] as usize;
                let pixel = ((cy - y0) as usize + y) * w + (cx - x0) as usize + x;
                counts[pixel] += (end - previous) as u64;
                for k in previous..end {
                    let get = |s: usize| slots[s].map(|c| value(c, k));
                    let rgba = [get(0), get(1), get(2), get(3)].map(|v| v.unwrap_or(0.0));
                    let z = get(4).unwrap_or(0.0);
                    let z_back = get(5).unwrap_or(z);
                    check_sample(&rgba, z, z_back)
                        .map_err(|why| Error::input(path, format!("{}: {why}", pixel_name(x, y))))?;
                    read.push((pixel as u32, DeepSample { rgba, z, z_back: z_back.max(z) }));
                }
                previous = end;
            }
            line_start = at;
        }
    }
    // The part on its display window: pixels outside the data window have no samples.
    let (dw, dh) = (dw as usize, dh as usize);
    let to_display = |pixel: usize| -> Option<usize> {
        let x = x0 as i64 + (pixel % w) as i64 - dx0 as i64;
        let y = y0 as i64 + (pixel / w) as i64 - dy0 as i64;
        (x >= 0 && y >= 0 && (x as usize) < dw && (y as usize) < dh).then(|| y as usize * dw + x as usize)
    };
    let mut display_counts = vec![0u64; dw * dh];
    for (pixel, &c) in counts.iter().enumerate() {
        if let Some(d) = to_display(pixel) {
            display_counts[d] += c;
        }
    }
    let mut offsets = Vec::with_capacity(dw * dh + 1);
    offsets.push(0u64);
    for c in &display_counts {
        offsets.push(offsets.last().copied().unwrap_or(0) + c);
    }
    let mut fill: Vec<u64> = offsets[..dw * dh].to_vec();
    let mut samples = vec![DeepSample { rgba: [0.0; 4], z: 0.0, z_back: 0.0 }; *offsets.last().unwrap_or(&0) as usize];
    for (pixel, sample) in read {
        if let Some(d) = to_display(pixel as usize) {
            samples[fill[d] as usize] = sample;
            fill[d] += 1;
        }
    }
    let image = DeepImage {
        width: dw,
        height: dh,
        origin: [dx0, dy0],
        offsets,
        samples,
        attributes: header.attributes.clone(),
    };
    Ok((image, counts))
}

/// What makes a sample unusable, if anything.
fn check_sample(rgba: &[f32; 4], z: f32, z_back: f32) -> std::result::Result<(), String> {
    if z.is_nan() || z <= 0.0 {
        return Err(format!("Z is {z}; depth must be a positive number (a distance in front of the camera)"));
    }
    if z.is_finite() && !(1.0 / z).is_finite() {
        // Disparity (1 / Z) is what the renderers take; a denormal Z overflows it.
        return Err(format!("Z is {z}, too close to the camera to render (1 / Z overflows)"));
    }
    if z_back.is_nan() || z_back < z {
        return Err(format!("ZBack {z_back} is in front of Z {z}; a sample ends behind where it starts"));
    }
    if rgba.iter().any(|v| !v.is_finite()) {
        return Err(format!("colour or alpha is not finite ({rgba:?})"));
    }
    Ok(())
}

fn budget_error(path: &Path, part: &str, max_samples: u64) -> Error {
    Error::input(
        path,
        format!("{part}: holds more than {max_samples} deep samples, the limit; if the file is genuine, raise --max-samples"),
    )
}

/// The chunk reader's refusals, with the budget one worded as the others.
fn budget_or_input(path: &Path, part: &str, message: String, max_samples: u64) -> Error {
    if message.contains("sample budget") {
        return budget_error(path, part, max_samples);
    }
    Error::input(path, format!("{part}: {message}"))
}
