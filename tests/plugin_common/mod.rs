//! Helpers shared by the plugin tests (they run real programs on real files).
#![allow(dead_code)]
use std::path::{Path, PathBuf};
use std::process::Command;

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

/// Runs `tests/interop/<script>` in headless Blender (`blender -b`) with the add-on symlinked
/// into a private BLENDER_USER_SCRIPTS and a private TMPDIR (to see what the add-on leaves
/// behind); returns stdout after checking that the script reached `done`.
pub fn blender_with_addon(dir: &Path, script: &str, done: &str) -> String {
    run_blender_script(dir, script, done, false)
}

/// [`blender_with_addon`] in Blender with a window, on a virtual X display (`xvfb-run`), with
/// simulated events (`--enable-event-simulate`): the UI paths (modal operators, Esc).
pub fn blender_ui_with_addon(dir: &Path, script: &str, done: &str) -> String {
    run_blender_script(dir, script, done, true)
}

fn run_blender_script(dir: &Path, script: &str, done: &str, ui: bool) -> String {
    let addons = dir.join("scripts/addons");
    std::fs::create_dir_all(&addons).unwrap();
    std::os::unix::fs::symlink(plugins_dir().join("blender/lensblur"), addons.join("lensblur")).unwrap();
    let (out, tmp) = (dir.join("out"), dir.join("tmp"));
    std::fs::create_dir_all(&out).unwrap();
    std::fs::create_dir_all(&tmp).unwrap();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/interop").join(script);
    let mut command = if ui {
        let mut xvfb = Command::new("xvfb-run");
        xvfb.args(["-a", "-s", "-screen 0 1280x800x24", "blender", "--enable-event-simulate"]);
        xvfb
    } else {
        let mut blender = Command::new("blender");
        blender.arg("-b");
        blender
    };
    let output = command
        .args(["--factory-startup", "--python-exit-code", "1", "--python"])
        .arg(&script)
        .arg("--")
        .arg(&out)
        .arg(env!("CARGO_BIN_EXE_lensblur"))
        .env("BLENDER_USER_SCRIPTS", dir.join("scripts"))
        .env("TMPDIR", &tmp)
        .output()
        .unwrap_or_else(|e| panic!("cannot run blender ({e}); install it (and xvfb for UI tests) with .ci/setup"));
    let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
    assert!(
        output.status.success() && stdout.contains(done),
        "blender failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    stdout
}

/// The image without a `border` pixels wide frame.
pub fn inset(img: &Image, border: usize) -> Image {
    Image::from_fn(img.width - 2 * border, img.height - 2 * border, |x, y| img.get(x + border, y + border))
}

/// The JSON a script printed after `marker` on a line of its own (`MARKER {...}`).
pub fn json_after(stdout: &str, marker: &str) -> serde_json::Value {
    let line = stdout.lines().find_map(|l| l.strip_prefix(marker).and_then(|rest| rest.strip_prefix(' ')));
    serde_json::from_str(line.unwrap_or_else(|| panic!("no {marker} in:\n{stdout}"))).unwrap()
}
