//! Helpers shared by the plugin tests (they run real programs on real files).
#![allow(dead_code)]
use std::path::{Path, PathBuf};

use lensblur::image::Image;

#[path = "../common/scratch.rs"]
mod scratch;
pub use scratch::ScratchDir;

/// A fresh, empty directory for one test of this process, removed if the test passes.
pub fn fresh_dir(test: &str) -> ScratchDir {
    ScratchDir::new(&format!("test-{test}"))
}

/// The repository's `plugins/` folder.
pub fn plugins_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("plugins")
}

/// Reads the first RGBA layer of an EXR (plain R,G,B,A or one named layer) as written by
/// lensblur, Blender or oiiotool.
pub fn read_rgba(path: &Path) -> Image {
    use exr::prelude::{ReadChannels, ReadLayers};
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |size, _| Image::new(size.width(), size.height()),
            |img: &mut Image, pos, (r, g, b, a): (f32, f32, f32, f32)| img.set(pos.x(), pos.y(), [r, g, b, a]),
        )
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .unwrap_or_else(|e| panic!("reading {}: {e}", path.display()));
    image.layer_data.channel_data.pixels
}

/// Channel names of an EXR's first part, in file order.
pub fn channel_names(path: &Path) -> Vec<String> {
    let meta =
        exr::meta::MetaData::read_from_file(path, false).unwrap_or_else(|e| panic!("reading {}: {e}", path.display()));
    meta.headers[0].channels.list.iter().map(|c| c.name.to_string()).collect()
}
