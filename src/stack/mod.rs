//! Layer stacks: what every renderer consumes, and the file formats that produce them.
//!
//! In memory a stack is already normalised: layers ordered front to back, colour linear and
//! premultiplied, depth converted to *disparity* (inverse depth; 0 = infinitely far, or the
//! file's normalised disparity). The file's own depth convention is remembered in
//! [`DepthKind`] so outputs and gradients can be written back in it.
pub mod arrays;
pub mod autolayer;
pub mod deep;
pub mod depth_clean;
pub mod exr_header_order;
mod exr_decode;
pub mod exr_read;
pub mod exr_write;
pub mod exr_replace;
mod exr_zip;
pub mod file_output_slots;
pub mod file_channels;
pub mod fill;
pub mod frame_edge;
pub mod gradients;
pub mod info;
pub mod ldr;
pub mod matting;
pub mod naming;
pub mod output_format;
pub mod spill_depth;

pub use arrays::{grad_output_from_array, stack_from_arrays, stack_to_arrays, ArrayStack};
pub use autolayer::{split_into_layers, AutoLayerOptions, Matting};
pub use depth_clean::known_depth_weight;
pub use exr_read::{read_parts, read_rgba, read_stack, ReadOptions, DEFAULT_MAX_PIXELS};
pub use exr_replace::{replace_channels, ChannelReplacement, HeaderEdits};
pub use file_channels::FileChannels;
pub use exr_write::{write_image, write_named_channels, write_stack, StackNaming, StackWriteOptions, WriteOptions};
pub use info::{ExtraChannel, LayerInfo, SampleType, StackFile, StackInfo, Window};
pub use ldr::{header_size as ldr_size, is_ldr_path, read_ldr, write_ldr, write_png_preview, LdrInput};
pub use naming::Convention;
pub use output_format::OutputFormat;

use crate::image::Image;
use crate::{Error, Result};

/// Samples per task where a frame's per-sample work runs on every core (cleaning depth,
/// interleaving channels, summing keys): large enough that a task's overhead vanishes, small
/// enough that an 8K layer splits into hundreds of tasks.
pub(crate) const SAMPLES_PER_TASK: usize = 1 << 16;

/// Refuses a file whose header declares more than `max_pixels` pixels, before any pixel is
/// decoded: a forged or damaged header must not make the reader allocate gigabytes.
pub(crate) fn check_pixel_budget(path: &std::path::Path, width: u64, height: u64, max_pixels: u64) -> Result<()> {
    // Saturating: a forged size must not wrap around to a product under the budget.
    if width.saturating_mul(height) <= max_pixels {
        return Ok(());
    }
    Err(Error::input(
        path,
        format!(
            "the header declares {width}x{height} pixels, which exceeds the limit of {max_pixels}; if the file is \
             genuine, raise the limit (ReadOptions::max_pixels; --max-pixels on the command line)"
        ),
    ))
}

/// How the depth channel of a file is encoded.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DepthKind {
    /// Planar Z in scene units (Blender, Cycles, most renderers); 1e10 or inf = empty/far.
    #[default]
    Z,
    /// Normalised disparity in [0, 1], 1 = near (Dr.Bokeh style).
    Disparity,
    /// 1/z (Nuke's `far = 0` convention); 0 = infinitely far.
    InverseZ,
}

impl DepthKind {
    /// The name `--depth-kind` takes.
    pub fn name(self) -> &'static str {
        match self {
            DepthKind::Z => "z",
            DepthKind::Disparity => "disparity",
            DepthKind::InverseZ => "inverse-z",
        }
    }

    /// Why this depth encoding cannot drive a physical camera, if it cannot. A physical camera
    /// focuses at a distance in scene units and needs disparity in 1/scene-units; normalised
    /// disparity has no scale, so the blur it gives is arbitrary (a 16-bit depth PNG read so
    /// blurs a few pixels at most) and nothing else would tell the user.
    pub fn physical_camera_warning(self) -> Option<String> {
        (self == DepthKind::Disparity).then(|| {
            "depth is read as normalised disparity (--depth-kind disparity, the default for a --depth \
             image), which has no scene scale, but the camera is physical (--focal-length, --fstop, \
             --focus-distance in scene units), so the blur amount is meaningless. Say what the depth \
             holds: --depth-kind z (distance in scene units) or --depth-kind inverse-z (1/distance); \
             or keep disparity and use the normalised model (--blur K --focus-disparity DF)"
                .to_string()
        })
    }

    /// Converts one stored depth value to the renderer's disparity.
    #[inline]
    pub fn to_disparity(self, stored: f32) -> f32 {
        match self {
            DepthKind::Z => crate::camera::disparity_from_z(stored),
            DepthKind::Disparity | DepthKind::InverseZ => stored,
        }
    }

    /// The stored value for a disparity (inverse of [`Self::to_disparity`]); disparity 0
    /// becomes the far sentinel 1e10 for planar Z, as Blender writes it.
    #[inline]
    pub fn from_disparity(self, disparity: f32) -> f32 {
        match self {
            DepthKind::Z if disparity > 0.0 => 1.0 / disparity,
            DepthKind::Z => 1.0e10,
            DepthKind::Disparity | DepthKind::InverseZ => disparity,
        }
    }

    /// Derivative of disparity with respect to the stored value (chain rule for gradients).
    #[inline]
    pub fn disparity_derivative(self, stored: f32) -> f32 {
        match self {
            DepthKind::Z if stored < crate::camera::FAR_DEPTH_SENTINEL && stored.is_finite() => {
                -1.0 / (stored * stored)
            }
            DepthKind::Z => 0.0,
            DepthKind::Disparity | DepthKind::InverseZ => 1.0,
        }
    }
}

impl std::str::FromStr for DepthKind {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "z" => Ok(DepthKind::Z),
            "disparity" => Ok(DepthKind::Disparity),
            "inverse-z" | "inverse_z" | "1/z" => Ok(DepthKind::InverseZ),
            other => Err(Error::data(format!(
                "unknown depth kind '{other}' (expected z, disparity or inverse-z)"
            ))),
        }
    }
}

/// One layer of a stack.
#[derive(Clone, Debug, PartialEq)]
pub struct Layer {
    pub name: String,
    /// Linear, premultiplied RGBA.
    pub rgba: Image,
    /// Disparity per pixel (see module docs), defined everywhere (also where alpha is 0).
    pub disparity: Vec<f32>,
}

/// Layers ordered front to back, all of the same size.
#[derive(Clone, Debug, PartialEq)]
pub struct LayerStack {
    pub width: usize,
    pub height: usize,
    pub layers: Vec<Layer>,
}

impl LayerStack {
    pub fn new(width: usize, height: usize, layers: Vec<Layer>) -> Result<Self> {
        for layer in &layers {
            if layer.rgba.width != width
                || layer.rgba.height != height
                || layer.disparity.len() != width * height
            {
                return Err(Error::data(format!(
                    "layer '{}' is {}x{} but the stack is {width}x{height}",
                    layer.name, layer.rgba.width, layer.rgba.height
                )));
            }
        }
        Ok(Self {
            width,
            height,
            layers,
        })
    }

    /// Smallest and largest disparity over all pixels of all layers.
    pub fn disparity_range(&self) -> (f32, f32) {
        use rayon::prelude::*;
        // On every core, in runs: a frame's disparities are read before each render (an 8K
        // five-layer frame holds 166 M of them).
        let widen = |(lo, hi): (f32, f32), (a, b): (f32, f32)| (lo.min(a), hi.max(b));
        self.layers
            .par_iter()
            .flat_map(|l| l.disparity.par_chunks(SAMPLES_PER_TASK))
            .map(|run| run.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |range, &d| widen(range, (d, d))))
            .reduce(|| (f32::INFINITY, f32::NEG_INFINITY), widen)
    }

    /// The stack as one image: colour composited front to back with "over", disparity of
    /// the nearest layer that covers at least half of the pixel (else the nearest covering
    /// layer, else 0 = far). Exact for a single opaque layer.
    pub fn flatten(&self) -> (Image, Vec<f32>) {
        let n = self.width * self.height;
        let mut image = Image::new(self.width, self.height);
        let mut disparity = vec![0.0f32; n];
        for i in 0..n {
            let (mut rgba, mut chosen) = ([0.0f32; 4], None);
            for layer in &self.layers {
                let p = layer.rgba.pixels[i];
                let transmitted = 1.0 - rgba[3];
                for c in 0..4 {
                    rgba[c] += transmitted * p[c];
                }
                if chosen.is_none() && p[3] > 0.0 && (p[3] >= 0.5 || rgba[3] >= 0.5) {
                    chosen = Some(layer.disparity[i]);
                }
            }
            let fallback = || {
                self.layers
                    .iter()
                    .find(|l| l.rgba.pixels[i][3] > 0.0)
                    .map(|l| l.disparity[i])
            };
            image.pixels[i] = rgba;
            disparity[i] = chosen.or_else(fallback).unwrap_or(0.0);
        }
        (image, disparity)
    }

    /// Orders layers front to back by their alpha-weighted mean disparity.
    pub fn sort_front_to_back(&mut self) {
        use rayon::prelude::*;
        // Each layer's key once, on every core: the comparator used to work both keys out at
        // every comparison, a second of reading an 8K five-layer file on one core.
        let keys: Vec<f64> = self
            .layers
            .par_iter()
            .map(|l| {
                // Runs summed side by side, then added in order: the same key on every run.
                let runs: Vec<(f64, f64)> = l
                    .rgba
                    .pixels
                    .par_chunks(SAMPLES_PER_TASK)
                    .zip(l.disparity.par_chunks(SAMPLES_PER_TASK))
                    .map(|(pixels, disparity)| {
                        pixels.iter().zip(disparity).fold((0.0f64, 0.0f64), |(sum, weight), (p, d)| {
                            (sum + (p[3] * d) as f64, weight + p[3] as f64)
                        })
                    })
                    .collect();
                let (sum, weight) = runs.iter().fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
                if weight > 0.0 {
                    sum / weight
                } else {
                    0.0
                }
            })
            .collect();
        let mut order: Vec<usize> = (0..self.layers.len()).collect();
        order.sort_by(|&a, &b| keys[b].total_cmp(&keys[a]));
        let mut layers: Vec<Option<Layer>> = std::mem::take(&mut self.layers).into_iter().map(Some).collect();
        self.layers = order.into_iter().map(|i| layers[i].take().expect("each layer is placed once")).collect();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Front to back by alpha-weighted mean disparity; a transparent layer counts as far (0),
    /// equal keys keep their order, and a frame of several runs weighs every pixel.
    #[test]
    fn layers_sort_front_to_back_by_their_covered_disparity() {
        let (width, height) = (300, 400); // 120,000 pixels: two runs of the key's sums
        let layer = |name: &str, alpha: f32, near_disparity: f32| {
            let rgba = Image::from_fn(width, height, |_, y| [0.0, 0.0, 0.0, if y < 300 { alpha } else { alpha * 0.5 }]);
            // The last rows (past the first run) are the nearest: they move the key.
            let disparity = (0..width * height).map(|i| if i / width >= 350 { near_disparity } else { 0.5 }).collect();
            Layer { name: name.into(), rgba, disparity }
        };
        let layers = vec![
            layer("empty", 0.0, 9.0),
            layer("far", 1.0, 0.5),
            layer("twin-a", 1.0, 2.0),
            layer("near", 1.0, 4.0),
            layer("twin-b", 1.0, 2.0),
        ];
        let mut stack = LayerStack::new(width, height, layers).unwrap();
        stack.sort_front_to_back();
        let names: Vec<&str> = stack.layers.iter().map(|l| l.name.as_str()).collect();
        assert_eq!(names, ["near", "twin-a", "twin-b", "far", "empty"]);
    }
}
