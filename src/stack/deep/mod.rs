//! Deep OpenEXR images (DESIGN.md, "Deep images"): every pixel a list of samples, each
//! premultiplied RGBA at a depth Z (a volume from Z to ZBack when ZBack > Z).
//!
//! - [`read_deep`] (feature `deep`): deep scanline and deep tiled files, single- and multi-part,
//!   half or float channels, read through OpenEXR's core C library (`ffi`, the only `unsafe`)
//!   and checked here before use: the sample-count table against the data window, the chunk's
//!   bytes and a sample budget; Z that is NaN or negative; ZBack before Z.
//! - [`merge`]: several deep images into one, as Nuke's DeepMerge does (samples side by side).
//! - [`layers`]: deep pixels to the layer stack the layered renderers take.
//! - [`mod@write`]: a small writer of uncompressed deep scanline files (tests, benchmark, fuzz seeds).
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::{Error, Result};

#[cfg(feature = "deep")]
mod ffi;
pub mod layers;
#[cfg(feature = "deep")]
mod read;
pub mod write;

pub use layers::{deep_to_layers, DeepLayerOptions};
#[cfg(feature = "deep")]
pub use read::read_deep;
pub use write::{write_deep, DeepWriteOptions};

/// Samples a file may hold before it is refused unread (`--max-samples`): 1 << 28 samples is
/// about 7 GB as the renderer holds them, far beyond any real frame (a 4K frame at 16 samples
/// per pixel is 1.3e8).
pub const DEFAULT_MAX_SAMPLES: u64 = 1 << 28;

/// One deep sample: premultiplied colour and alpha, and its depth span in scene units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeepSample {
    pub rgba: [f32; 4],
    pub z: f32,
    /// Equal to `z` for a point sample (also when the file has no ZBack).
    pub z_back: f32,
}

/// A deep image on its display window: the samples of pixel `i` are
/// `samples[offsets[i]..offsets[i + 1]]`, in the order they were read.
#[derive(Clone, Debug, PartialEq)]
pub struct DeepImage {
    pub width: usize,
    pub height: usize,
    /// The display window's top-left corner in the file's coordinates.
    pub origin: [i32; 2],
    pub offsets: Vec<u64>,
    pub samples: Vec<DeepSample>,
    /// Float, int and string header attributes (the first part read, then the others').
    pub attributes: BTreeMap<String, String>,
}

impl DeepImage {
    pub fn pixel(&self, index: usize) -> &[DeepSample] {
        &self.samples[self.offsets[index] as usize..self.offsets[index + 1] as usize]
    }

    /// The deep image of a layer stack: one point sample per layer in every pixel the layer
    /// covers (alpha > 0), at the depth its disparity gives (infinitely far for disparity 0).
    pub fn from_stack(stack: &crate::stack::LayerStack) -> Self {
        let n = stack.width * stack.height;
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0u64);
        let mut samples = Vec::new();
        for i in 0..n {
            for layer in &stack.layers {
                let rgba = layer.rgba.pixels[i];
                if rgba[3] > 0.0 {
                    let d = layer.disparity[i];
                    let z = if d > 0.0 { 1.0 / d } else { f32::INFINITY };
                    samples.push(DeepSample { rgba, z, z_back: z });
                }
            }
            offsets.push(samples.len() as u64);
        }
        Self { width: stack.width, height: stack.height, origin: [0, 0], offsets, samples, attributes: BTreeMap::new() }
    }

    /// Front-to-back "over" of every pixel's samples sorted by depth: the flat image a
    /// compositor's DeepToImage gives (volumes are not split: each is composited whole at its
    /// front).
    pub fn flatten(&self) -> crate::image::Image {
        let mut image = crate::image::Image::new(self.width, self.height);
        let mut sorted = Vec::new();
        for (i, out) in image.pixels.iter_mut().enumerate() {
            sorted.clear();
            sorted.extend_from_slice(self.pixel(i));
            sorted.sort_by(|a, b| a.z.total_cmp(&b.z).then(a.z_back.total_cmp(&b.z_back)));
            for s in &sorted {
                let transmitted = 1.0 - out[3];
                for c in 0..4 {
                    out[c] += transmitted * s.rgba[c];
                }
            }
        }
        image
    }
}

/// Which parts of a multi-part file to read.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum PartChoice {
    /// The first deep part (the left view of a stereo file, by the usual order).
    #[default]
    First,
    /// Every deep part, merged as separate inputs would be.
    All,
    /// The part of this name, or at this index.
    Named(String),
}

impl std::str::FromStr for PartChoice {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        Ok(match s {
            "" => return Err(Error::invalid("deep part", "empty part name (give a name, an index, 'first' or 'all')")),
            "first" => PartChoice::First,
            "all" => PartChoice::All,
            name => PartChoice::Named(name.to_string()),
        })
    }
}

/// How to read deep files.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeepReadOptions {
    /// Refuse a file (or a merge of files) holding more samples than this, before decoding
    /// the chunk that passes it.
    pub max_samples: u64,
    /// Refuse a part whose data window has more pixels than this, before reading it.
    pub max_pixels: u64,
    pub part: PartChoice,
}

impl Default for DeepReadOptions {
    fn default() -> Self {
        Self { max_samples: DEFAULT_MAX_SAMPLES, max_pixels: super::DEFAULT_MAX_PIXELS, part: PartChoice::First }
    }
}

/// What `info` tells about one deep part.
#[derive(Clone, Debug, serde::Serialize)]
pub struct DeepPartInfo {
    pub index: usize,
    pub name: Option<String>,
    /// "deep scanline", "deep tiled", or the kind of a part that is not deep (skipped).
    pub storage: String,
    /// Inclusive corners (x0, y0, x1, y1).
    pub data_window: [i32; 4],
    pub display_window: [i32; 4],
    pub channels: Vec<String>,
    pub compression: String,
    pub samples: u64,
    pub max_samples_per_pixel: u64,
    /// Pixels of the data window with at least one sample.
    pub covered_pixels: u64,
    pub depth_range: Option<[f32; 2]>,
    pub volumetric_samples: u64,
}

/// A file's deep facts, part by part (`lensblur info`).
#[derive(Clone, Debug, serde::Serialize)]
pub struct DeepFileInfo {
    pub path: PathBuf,
    pub parts: Vec<DeepPartInfo>,
    pub attributes: BTreeMap<String, String>,
}

/// Whether `path` is an OpenEXR file holding deep data, from its first eight bytes (the
/// version field's "non-image" bit), without any C library; false for anything unreadable.
pub fn is_deep_exr(path: &Path) -> bool {
    use std::io::Read;
    let mut head = [0u8; 8];
    let read = std::fs::File::open(path).and_then(|mut f| f.read_exact(&mut head));
    read.is_ok()
        && head[..4] == [0x76, 0x2f, 0x31, 0x01]
        && u32::from_le_bytes([head[4], head[5], head[6], head[7]]) & 0x800 != 0
}

/// Whether `info` shows a header attribute: the camera and scene-unit ones the renderer reads
/// (the required ones are shown as part facts already).
pub fn is_reported_attribute(key: &str) -> bool {
    const REQUIRED: [&str; 12] = [
        "channels",
        "compression",
        "dataWindow",
        "displayWindow",
        "lineOrder",
        "pixelAspectRatio",
        "screenWindowCenter",
        "screenWindowWidth",
        "name",
        "type",
        "version",
        "chunkCount",
    ];
    !REQUIRED.contains(&key)
}

/// The refusal for a deep file when the library was built without the `deep` feature.
pub fn deep_unsupported(path: &Path) -> Error {
    Error::input(
        path,
        "is a deep OpenEXR file; this build of lensblur reads deep files only with the `deep` feature \
         (on by default for the command line; it needs OpenEXR's core library, libopenexr-dev)",
    )
}

/// Several deep images as one, as Nuke's DeepMerge does: every pixel holds all their samples.
/// The result covers the union of their display windows, refused beyond `max_pixels` (two
/// small windows far apart span a huge one).
pub fn merge(images: Vec<DeepImage>, max_pixels: u64) -> Result<DeepImage> {
    let Some(first) = images.first() else {
        return Err(Error::data("no deep image to merge"));
    };
    if images.len() == 1 {
        return Ok(images.into_iter().next().expect("one image"));
    }
    let x0 = images.iter().map(|i| i.origin[0]).min().unwrap_or(first.origin[0]);
    let y0 = images.iter().map(|i| i.origin[1]).min().unwrap_or(first.origin[1]);
    let x1 = images.iter().map(|i| i.origin[0] as i64 + i.width as i64).max().unwrap_or(0);
    let y1 = images.iter().map(|i| i.origin[1] as i64 + i.height as i64).max().unwrap_or(0);
    let (width, height) = ((x1 - x0 as i64) as usize, (y1 - y0 as i64) as usize);
    if (width as u64).saturating_mul(height as u64) > max_pixels {
        return Err(Error::data(format!(
            "the merged display windows span {width}x{height} pixels, more than the limit of {max_pixels} (--max-pixels)"
        )));
    }
    let mut counts = vec![0u64; width * height];
    let index = |image: &DeepImage, i: usize| {
        let (x, y) = (i % image.width, i / image.width);
        let gx = (image.origin[0] - x0) as usize + x;
        let gy = (image.origin[1] - y0) as usize + y;
        gy * width + gx
    };
    for image in &images {
        for i in 0..image.width * image.height {
            counts[index(image, i)] += image.offsets[i + 1] - image.offsets[i];
        }
    }
    let mut offsets = Vec::with_capacity(width * height + 1);
    offsets.push(0u64);
    for c in &counts {
        offsets.push(offsets.last().copied().unwrap_or(0) + c);
    }
    let total = *offsets.last().unwrap_or(&0) as usize;
    let mut samples = vec![DeepSample { rgba: [0.0; 4], z: 0.0, z_back: 0.0 }; total];
    let mut fill: Vec<u64> = offsets[..width * height].to_vec();
    let mut attributes = BTreeMap::new();
    for image in &images {
        for (key, value) in &image.attributes {
            attributes.entry(key.clone()).or_insert_with(|| value.clone());
        }
        for i in 0..image.width * image.height {
            let target = index(image, i);
            for s in image.pixel(i) {
                samples[fill[target] as usize] = *s;
                fill[target] += 1;
            }
        }
    }
    Ok(DeepImage { width, height, origin: [x0, y0], offsets, samples, attributes })
}

/// Reads and merges `paths` (one deep image per file, or per part with [`PartChoice::All`]),
/// with the sample budget over all of them.
#[cfg(feature = "deep")]
pub fn read_deep_files(paths: &[PathBuf], options: &DeepReadOptions) -> Result<DeepImage> {
    let mut images = Vec::with_capacity(paths.len());
    let mut budget = options.max_samples;
    for path in paths {
        let image = read_deep(path, &DeepReadOptions { max_samples: budget, ..options.clone() })?;
        budget -= image.samples.len() as u64;
        images.push(image);
    }
    merge(images, options.max_pixels)
}

/// Without the `deep` feature every deep file is refused, naming the feature.
#[cfg(not(feature = "deep"))]
pub fn read_deep_files(paths: &[PathBuf], _options: &DeepReadOptions) -> Result<DeepImage> {
    Err(deep_unsupported(paths.first().map_or(Path::new(""), |p| p.as_path())))
}

/// Without the `deep` feature every deep file is refused, naming the feature.
#[cfg(not(feature = "deep"))]
pub fn deep_info(path: &Path, _options: &DeepReadOptions) -> Result<DeepFileInfo> {
    Err(deep_unsupported(path))
}

#[cfg(feature = "deep")]
pub use read::deep_info;
