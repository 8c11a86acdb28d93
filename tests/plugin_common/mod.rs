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
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join("plugins")
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

/// A Blender the interop scripts run in: Debian's `blender` binary (3.4) or PyPI's `bpy` module
/// of one version in its virtualenv (made by `.ci/setup`, listed in `.ci/bpy-versions`).
pub struct Blender {
    /// What test names and scratch folders call it: `debian` or the bpy version.
    pub name: String,
    /// The venv's python for a bpy module; None for Debian's binary.
    python: Option<PathBuf>,
}

impl Blender {
    pub fn debian() -> Self {
        Blender { name: "debian".into(), python: None }
    }

    /// The bpy `version` in its virtualenv; panics, with the command that makes it, when the
    /// venv is missing or the version is not one `.ci/setup` installs.
    pub fn bpy(version: &str) -> Self {
        let listed = bpy_versions();
        assert!(listed.iter().any(|v| v == version), "bpy {version} is not in .ci/bpy-versions ({listed:?})");
        let python = lensblur_dev::bench::blender::bpy_python(version).unwrap_or_else(|e| panic!("{e}"));
        Blender { name: format!("bpy-{version}"), python: Some(python) }
    }

    /// A command that runs `script` with `args` after it (`sys.argv[sys.argv.index("--") + 1:]`
    /// in the script), exiting non-zero when the script raises.
    pub fn script_command(&self, script: &Path) -> Command {
        let mut command = match &self.python {
            Some(python) => Command::new(python),
            None => {
                let mut blender = Command::new("blender");
                blender.args(["-b", "--factory-startup", "--python-exit-code", "1", "--python"]);
                blender
            }
        };
        command.arg(script).arg("--");
        command
    }
}

/// The bpy versions of `.ci/bpy-versions` (its first column).
pub fn bpy_versions() -> Vec<String> {
    let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join(".ci/bpy-versions");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    text.lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .map(|l| l.split_whitespace().next().unwrap().to_string())
        .collect()
}

/// One `#[test]` per Blender for `fn $check(blender: &Blender)`: `$check::debian` (Debian's
/// 3.4 binary) and one per bpy version, so a failure names the version; plus a test that the
/// versions here are those `.ci/setup` installs.
#[macro_export]
macro_rules! test_on_every_blender {
    ($check:ident) => {
        $crate::test_on_every_blender!($check; bpy_4_2 => "4.2.23", bpy_4_5 => "4.5.15", bpy_5_0 => "5.0.1", bpy_5_3 => "5.3.0");
    };
    ($check:ident; $($test:ident => $version:literal),*) => {
        mod $check {
            use crate::plugin_common::{bpy_versions, Blender};

            #[test]
            fn debian() {
                super::$check(&Blender::debian())
            }

            $(
                #[test]
                fn $test() {
                    super::$check(&Blender::bpy($version))
                }
            )*

            #[test]
            fn the_versions_are_those_ci_setup_installs() {
                assert_eq!(bpy_versions(), [$($version),*], ".ci/bpy-versions vs tests/plugin_common/mod.rs");
            }
        }
    };
}

/// Runs `tests/interop/<script>` in `blender` (headless) with the add-on symlinked into a
/// private BLENDER_USER_SCRIPTS and a private TMPDIR (to see what the add-on leaves behind);
/// returns stdout after checking that the script reached `done`.
pub fn blender_with_addon(blender: &Blender, dir: &Path, script: &str, done: &str) -> String {
    install_addon_link(dir);
    run_script(blender.script_command(&interop_script(script)), dir, done)
}

/// [`blender_with_addon`] in Debian's Blender with a window, on a virtual X display
/// (`xvfb-run`), with simulated events (`--enable-event-simulate`): the UI paths (modal
/// operators, Esc).
pub fn blender_ui_with_addon(dir: &Path, script: &str, done: &str) -> String {
    install_addon_link(dir);
    let mut xvfb = Command::new("xvfb-run");
    xvfb.args(["-a", "-s", "-screen 0 1280x800x24", "blender", "--enable-event-simulate"])
        .args(["--factory-startup", "--python-exit-code", "1", "--python"])
        .arg(interop_script(script))
        .arg("--");
    run_script(xvfb, dir, done)
}

pub fn interop_script(script: &str) -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join("tests/interop").join(script)
}

fn install_addon_link(dir: &Path) {
    let addons = dir.join("scripts/addons");
    std::fs::create_dir_all(&addons).unwrap();
    std::os::unix::fs::symlink(plugins_dir().join("blender/lensblur"), addons.join("lensblur")).unwrap();
}

/// Runs `command OUT LENSBLUR_BINARY` with the user's Blender folders (scripts, config,
/// extensions) and TMPDIR inside `dir`.
pub fn run_script(mut command: Command, dir: &Path, done: &str) -> String {
    let (out, tmp) = (dir.join("out"), dir.join("tmp"));
    std::fs::create_dir_all(&out).unwrap();
    std::fs::create_dir_all(&tmp).unwrap();
    let output = command
        .arg(&out)
        .arg(env!("CARGO_BIN_EXE_lensblur"))
        .env("BLENDER_USER_SCRIPTS", dir.join("scripts"))
        .env("BLENDER_USER_CONFIG", dir.join("config"))
        .env("BLENDER_USER_EXTENSIONS", dir.join("extensions"))
        .env("TMPDIR", &tmp)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {command:?} ({e}); install Blender, xvfb and the bpy modules with .ci/setup"));
    let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
    assert!(
        output.status.success() && stdout.contains(done),
        "blender failed ({}):\n{stdout}\n{}",
        output.status,
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
