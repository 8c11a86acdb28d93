//! LDR inputs and previews: PNG/JPEG colour is sRGB-encoded, so it is decoded to linear
//! before any blur (blurring encoded values darkens highlights) and encoded again on output.
use std::path::Path;

use super::{DepthKind, OutputFormat};
use crate::atomic_file::write_atomically;
use super::depth_clean::image_depth_to_disparity;
use crate::image::Image;
use crate::{Error, Result};

/// An LDR photo with its depth map, both already converted for the renderer.
#[derive(Clone, Debug, PartialEq)]
pub struct LdrInput {
    /// Linear, premultiplied RGBA.
    pub image: Image,
    /// Disparity per pixel (see [`read_ldr`] for how depth images are interpreted).
    pub disparity: Vec<f32>,
}

/// sRGB transfer function, decode (IEC 61966-2-1).
#[inline]
pub fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// sRGB transfer function, encode.
#[inline]
pub fn linear_to_srgb(v: f32) -> f32 {
    if v <= 0.003_130_8 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

fn reader(path: &Path) -> Result<image::ImageReader<std::io::BufReader<std::fs::File>>> {
    if !path.exists() {
        return Err(Error::input(path, "file not found"));
    }
    let io = Error::io(path);
    image::ImageReader::open(path).map_err(io)?.with_guessed_format().map_err(io)
}

/// Width and height from the file's header alone, refused above `max_pixels`.
pub fn header_size(path: &Path, max_pixels: u64) -> Result<(u32, u32)> {
    let (w, h) = reader(path)?
        .into_dimensions()
        .map_err(|e| Error::input(path, format!("cannot read the image header: {e}")))?;
    super::check_pixel_budget(path, w.into(), h.into(), max_pixels)?;
    Ok((w, h))
}

/// Decodes the whole image, which must have the size its header declared (checked above).
fn decode(path: &Path, size: (u32, u32)) -> Result<image::DynamicImage> {
    let image = reader(path)?.decode().map_err(|e| Error::input(path, format!("cannot decode image: {e}")))?;
    if (image.width(), image.height()) != size {
        return Err(Error::input(path, "decoded size differs from the header's; the file is damaged"));
    }
    Ok(image)
}

/// Depth image samples normalised to [0, 1] (8- or 16-bit, first channel of grey images).
fn depth_values(depth: &image::DynamicImage) -> Vec<f32> {
    if depth.color().bits_per_pixel() / u16::from(depth.color().channel_count()) > 8 {
        depth
            .to_luma16()
            .pixels()
            .map(|p| f32::from(p.0[0]) / 65535.0)
            .collect()
    } else {
        depth
            .to_luma8()
            .pixels()
            .map(|p| f32::from(p.0[0]) / 255.0)
            .collect()
    }
}

/// Reads a PNG/JPEG and its depth image. Depth values `v` in [0, 1] mean, by kind:
/// `disparity` (1 = near, 0 = far), `inverse-z` (1/z, 0 = far), `z` (z = v; 0 = no data,
/// treated as infinitely far). Both headers are checked (size under `max_pixels`, the same
/// size) before either image is decoded.
pub fn read_ldr(path: &Path, depth_path: &Path, depth_kind: DepthKind, max_pixels: u64) -> Result<LdrInput> {
    let (w, h) = header_size(path, max_pixels)?;
    let (dw, dh) = header_size(depth_path, max_pixels)?;
    if (dw, dh) != (w, h) {
        return Err(Error::input(depth_path, format!("depth is {dw}x{dh} but the image is {w}x{h}")));
    }
    let colour = decode(path, (w, h))?.to_rgba32f();
    let depth = decode(depth_path, (w, h))?;
    let (w, h) = (w as usize, h as usize);
    let pixels = colour
        .pixels()
        .map(|p| {
            let [r, g, b, a] = p.0;
            [
                srgb_to_linear(r) * a,
                srgb_to_linear(g) * a,
                srgb_to_linear(b) * a,
                a,
            ]
        })
        .collect();
    let disparity = depth_values(&depth)
        .into_iter()
        .map(|v| image_depth_to_disparity(depth_kind, v))
        .collect();
    Ok(LdrInput {
        image: Image {
            width: w,
            height: h,
            pixels,
        },
        disparity,
    })
}

/// Writes an 8-bit sRGB PNG preview (un-premultiplied, clipped to [0, 1]).
pub fn write_png_preview(path: &Path, image: &Image) -> Result<()> {
    write_encoded(path, image, image::ImageFormat::Png)
}

/// Whether `path` names an 8-bit format [`write_ldr`] writes (PNG or JPEG, by extension).
pub fn is_ldr_path(path: &Path) -> bool {
    ldr_format(path).is_some()
}

/// The extension rule is [`OutputFormat`]'s, so inputs and outputs agree on what a PNG is.
fn ldr_format(path: &Path) -> Option<image::ImageFormat> {
    match OutputFormat::from_extension(path)? {
        OutputFormat::Png => Some(image::ImageFormat::Png),
        OutputFormat::Jpeg => Some(image::ImageFormat::Jpeg),
        OutputFormat::Exr => None,
    }
}

/// Writes an 8-bit sRGB PNG (with alpha) or JPEG (over black), chosen by the extension:
/// the LDR counterpart of the linear inputs `read_ldr` takes.
pub fn write_ldr(path: &Path, image: &Image) -> Result<()> {
    let format = ldr_format(path)
        .ok_or_else(|| Error::input(path, "8-bit output must end in .png, .jpg or .jpeg"))?;
    write_encoded(path, image, format)
}

fn write_encoded(path: &Path, image: &Image, format: image::ImageFormat) -> Result<()> {
    let encode = |v: f32| (linear_to_srgb(v.clamp(0.0, 1.0)) * 255.0).round() as u8;
    let with_alpha = format != image::ImageFormat::Jpeg;
    let mut bytes = Vec::with_capacity(image.pixels.len() * 4);
    for p in &image.pixels {
        let a = p[3].clamp(0.0, 1.0);
        // PNG stores straight alpha; JPEG has none, so it gets the premultiplied colour (over black).
        let straight = |c: f32| {
            if !with_alpha {
                c
            } else if a > 0.0 {
                c / a
            } else {
                0.0
            }
        };
        bytes.extend_from_slice(&[
            encode(straight(p[0])),
            encode(straight(p[1])),
            encode(straight(p[2])),
        ]);
        if with_alpha {
            bytes.push((a * 255.0).round() as u8);
        }
    }
    let colour = if with_alpha {
        image::ExtendedColorType::Rgba8
    } else {
        image::ExtendedColorType::Rgb8
    };
    let (w, h) = (image.width as u32, image.height as u32);
    write_atomically(path, |file| {
        image::write_buffer_with_format(file, &bytes, w, h, colour, format)
            .map_err(|e| Error::input(path, format!("cannot write {format:?}: {e}")))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trips() {
        for i in 0..=255 {
            let v = i as f32 / 255.0;
            assert!((linear_to_srgb(srgb_to_linear(v)) - v).abs() < 1e-5, "{v}");
        }
        // Mid grey 0.5 encoded is about 0.214 linear (the standard's reference value).
        assert!((srgb_to_linear(0.5) - 0.214_041).abs() < 1e-4);
    }
}
