//! Shared test setup. GPU tests never skip: without a Vulkan device they fail loudly.
#![allow(dead_code)]
mod scratch;
pub mod shot;
pub use scratch::ScratchDir;

use std::path::Path;
use std::process::{Command, Output};

use exr::meta::attribute::Text;
use exr::prelude::{
    f16, AnyChannel, AnyChannels, Encoding, FlatSamples, ImageAttributes, IntegerBounds, LayerAttributes, Vec2,
    WritableImage,
};

use lensblur::image::Image;
use lensblur::vk::{Context, ContextOptions};

/// Opens the Vulkan device with validation on (the test suite always validates), or panics
/// with the reason: a missing device is a broken test machine, not a reason to skip.
pub fn gpu() -> Context {
    let options = ContextOptions { validation: true, ..ContextOptions::from_env() };
    match Context::new(&options) {
        Ok(ctx) => ctx,
        Err(e) => panic!("GPU tests need a Vulkan device with validation layers (see README): {e}"),
    }
}

/// Closes the context and fails on any validation message, including teardown ones.
pub fn finish(ctx: Context) {
    if let Err(e) = ctx.finish() {
        panic!("validation: {e}");
    }
}

/// Largest absolute difference over all channels of two same-sized images.
pub fn max_abs_diff(a: &Image, b: &Image) -> f32 {
    assert_eq!((a.width, a.height), (b.width, b.height), "image sizes differ");
    a.pixels
        .iter()
        .zip(&b.pixels)
        .flat_map(|(p, q)| (0..4).map(move |c| (p[c] - q[c]).abs()))
        .fold(0.0, f32::max)
}

/// A deterministic test pattern with HDR highlights and partial alpha.
pub fn pattern(width: usize, height: usize) -> Image {
    Image::from_fn(width, height, |x, y| {
        let h = ((x * 7919 + y * 104_729) % 1000) as f32 / 1000.0;
        let highlight = if (x * 13 + y * 7) % 97 == 0 { 20.0 } else { 0.0 };
        let alpha = if (x / 5 + y / 3) % 4 == 0 { 0.5 } else { 1.0 };
        [alpha * (h + highlight), alpha * (1.0 - h), alpha * 0.5 * h, alpha]
    })
}

/// The disparity of the single-image tests' scene (for [`pattern`]'s image): a near square
/// (0.9), a mid band (0.55) and a background ramp (0.1 at the top to 0.4 at the bottom), so
/// that the CoC takes both signs and jumps at the square's and the band's edges.
pub fn square_band_ramp(w: usize, h: usize) -> Vec<f32> {
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            if (10..22).contains(&x) && (8..20).contains(&y) {
                0.9
            } else if (28..36).contains(&x) {
                0.55
            } else {
                0.1 + 0.3 * y as f32 / h as f32
            }
        })
        .collect()
}

/// A fresh, empty scratch directory for one test (`lensblur-<suite>-<test>-<pid>`), so
/// parallel tests and earlier runs never see each other's files; removed if the test passes.
pub fn temp_dir(suite: &str, test: &str) -> ScratchDir {
    ScratchDir::new(&format!("{suite}-{test}"))
}

/// Runs the `lensblur` binary with validation on, the default device choice and `env` added.
pub fn lensblur(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_lensblur"));
    command.args(args).env("LENSBLUR_VALIDATION", "1").env_remove("LENSBLUR_DEVICE");
    for (key, value) in env {
        command.env(key, value);
    }
    command.output().unwrap()
}

/// No ICD for the Vulkan loader to find: what a machine without a GPU driver looks like.
pub const NO_VULKAN: [(&str, &str); 2] =
    [("VK_ICD_FILENAMES", "/nonexistent/icd.json"), ("VK_DRIVER_FILES", "/nonexistent/icd.json")];

pub fn half(values: impl IntoIterator<Item = f32>) -> FlatSamples {
    FlatSamples::F16(values.into_iter().map(f16::from_f32).collect())
}

pub fn float(values: impl IntoIterator<Item = f32>) -> FlatSamples {
    FlatSamples::F32(values.into_iter().collect())
}

/// One EXR part: name, data window origin and size, channels (any order; sorted here).
pub struct Part {
    pub name: Option<&'static str>,
    pub origin: (i32, i32),
    pub size: (usize, usize),
    pub channels: Vec<(String, FlatSamples)>,
}

/// Writes `channels` as one unnamed part filling the display window `size` at (0, 0).
pub fn write_single_part(path: &Path, size: (usize, usize), channels: Vec<(String, FlatSamples)>) {
    write_parts(path, size, vec![Part { name: None, origin: (0, 0), size, channels }]);
}

/// Writes `parts` into one EXR whose display window is `display` at (0, 0).
pub fn write_parts(path: &Path, display: (usize, usize), parts: Vec<Part>) {
    write_parts_with(path, ((0, 0), display), LayerAttributes::default(), parts)
}

/// Writes `parts` into one EXR with the display window `(origin, size)`; every part gets the
/// header attributes `own` (camera attributes, say) besides its name and data window.
pub fn write_parts_with(
    path: &Path,
    (origin, size): ((i32, i32), (usize, usize)),
    own: LayerAttributes,
    parts: Vec<Part>,
) {
    let layers: Vec<_> = parts
        .into_iter()
        .map(|p| {
            let mut attributes = own.clone();
            attributes.layer_name = p.name.map(Text::from);
            attributes.layer_position = Vec2(p.origin.0, p.origin.1);
            let channels: Vec<_> = p.channels.into_iter().map(|(n, s)| AnyChannel::new(n.as_str(), s)).collect();
            exr::prelude::Layer::new(p.size, attributes, Encoding::SMALL_LOSSLESS, AnyChannels::sort(channels.into()))
        })
        .collect();
    let attributes = ImageAttributes::new(IntegerBounds::new(origin, size));
    exr::prelude::Image::from_layers(attributes, layers).write().to_file(path).unwrap();
}
