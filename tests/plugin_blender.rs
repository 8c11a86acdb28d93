//! The Blender add-on (`plugins/blender/lensblur`) in real headless Blender, each test once per
//! Blender (Debian's 3.4 binary and PyPI's bpy 4.2, 4.5, 5.0, 5.3: `<test>::bpy_5_0`):
//! installed by symlink into an addons folder, driven through `bpy.ops.lensblur.defocus()`
//! on a Cycles render of three textured planes (one view layer each), and compared with
//! Cycles' own depth of field of the same scene. 15-25 s on 2 cores (the Cycles DOF
//! reference is most of it) per Blender, so it is a test file of its own:
//! `cargo test --test plugin_blender`. Fails, never skips, when Blender or a bpy is missing.
mod plugin_common;

use std::path::Path;
use std::process::Command;

use lensblur::metrics::compare;
use lensblur::render::Method;
use plugin_common::{blender_with_addon, fresh_dir, inset, json_after, plugins_dir, read_rgba, Blender};
use serde_json::Value;

struct Run {
    stdout: String,
    report: Value,
    checks: Value,
}

fn run_blender(blender: &Blender, dir: &Path) -> Run {
    let stdout = blender_with_addon(blender, dir, "blender_plugin.py", "LENSBLUR_PLUGIN_DONE");
    let json_after = |marker: &str| -> Value {
        let line = stdout.lines().find_map(|l| l.strip_prefix(marker));
        serde_json::from_str(line.unwrap_or_else(|| panic!("no {marker} in:\n{stdout}"))).unwrap()
    };
    Run { report: json_after("LENSBLUR_PLUGIN_REPORT "), checks: json_after("LENSBLUR_PLUGIN_CHECKS "), stdout }
}

test_on_every_blender!(blender_addon_matches_cycles_depth_of_field_and_reads_the_camera);
fn blender_addon_matches_cycles_depth_of_field_and_reads_the_camera(blender: &Blender) {
    let dir = fresh_dir(&format!("plugin-blender-{}", blender.name));
    let run = run_blender(blender, &dir);
    camera_was_read_from_the_scene(&run);
    operator_behaves_like_a_blender_tool(&run);
    let leftovers: Vec<_> = std::fs::read_dir(dir.join("tmp"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with("lensblur"))
        .collect();
    assert!(leftovers.is_empty(), "left in TMPDIR: {leftovers:?}");
    result_matches_cycles_dof(&blender.name, &dir.join("out"));
}

fn camera_was_read_from_the_scene(run: &Run) {
    let camera = &run.report["camera"];
    assert_eq!(camera["focal_length_mm"], 85.0, "{camera}");
    assert_eq!(camera["sensor_width_mm"], 36.0, "{camera}");
    assert_eq!(camera["fstop"], 1.0, "{camera}");
    // The focus object sits 4 m deep but off the view axis (Euclidean distance 4.016):
    // Cycles focuses at its planar depth. f32 round trip: 1e-5.
    let focus = camera["focus_distance"].as_f64().unwrap();
    assert!((focus - 4.0).abs() < 1e-5, "focus distance {focus}");
    // Five blades turned 10 degrees counter-clockwise in camera space (y up) are -10 in
    // lensblur's image space (rows grow downwards).
    assert!(run.stdout.contains("--aperture polygon:5:rotation=-10 "), "{}", run.stdout);
    let layers: Vec<&str> =
        run.report["layers"].as_array().unwrap().iter().map(|l| l["name"].as_str().unwrap()).collect();
    assert_eq!(layers, ["L_front", "L_mid", "L_back"], "every rendering view layer, front to back");
}

fn operator_behaves_like_a_blender_tool(run: &Run) {
    let c = &run.checks;
    assert_eq!(c["image_size"], serde_json::json!([160, 120]));
    assert!(
        (c["image_mean_alpha"].as_f64().unwrap() - 1.0).abs() < 1e-3,
        "the back wall covers the frame: the result is opaque ({})",
        c["image_mean_alpha"]
    );
    assert_eq!(c["image_packed"], false, "a saved result refers to its file");
    assert_eq!(c["rerun_packed"], true, "an unsaved result survives its temporary file");
    assert_eq!(c["node_image"], "lensblur_result");
    assert_eq!(c["rerun_node_image"], "lensblur_result", "the node follows the new result");
    // Blender's own images aside (Render Result; 4.5's compositor adds Viewer Node).
    let ours: Vec<&str> =
        c["images"].as_array().unwrap().iter().filter_map(|n| n.as_str()).filter(|n| n.starts_with("lensblur")).collect();
    assert_eq!(ours, ["lensblur_result"], "re-running replaces the datablock: {}", c["images"]);
    assert_eq!(c["rerun_layers"], serde_json::json!(["L_mid", "L_back"]));
    assert_eq!(c["file_layers"], serde_json::json!(["L_mid", "L_back"]), "EXR path + exclude");
    let tool_error = c["tool_error"].as_str().unwrap();
    assert!(tool_error.contains("not an OpenEXR file"), "the tool's message: {tool_error}");
    // `lensblur render` failing: the report carries its message, with the fix.
    let render_error = c["render_error"].as_str().unwrap();
    assert!(
        render_error.contains("LENSBLUR_DEVICE=no-such-gpu matches no Vulkan device")
            && render_error.contains("see `lensblur devices`"),
        "the tool's message: {render_error}"
    );
    // No focus object: the camera's focus distance is used as it is (f32 round trip: 1e-6).
    let plain = c["plain_focus_distance"].as_f64().unwrap();
    assert!((plain - 3.25).abs() < 1e-6, "plain focus distance {plain}");
    let tool_methods: Vec<&str> = Method::ALL.iter().map(|m| m.name()).collect();
    assert_eq!(c["methods"], serde_json::json!(tool_methods), "the add-on offers every method of the tool");
    assert!(c["glob_error"].as_str().unwrap().contains("available: L_front, L_mid, L_back"));
}

/// PSNR on display-encoded (sRGB) values, as everywhere in lensblur. Measured with Blender
/// 3.4.1 (seeded Cycles, 1024 samples): add-on vs Cycles DOF 33.9 dB over the frame and 41.5
/// dB inside an 8 px border (the largest CoC is 6.7 px: Cycles sees past the frame edge, the
/// stack does not); the pinhole render (no blur at all) scores 19.3 dB. Thresholds leave
/// 3-4 dB for another Cycles build's sampling noise, and the blur must earn 10 dB over none.
fn result_matches_cycles_dof(blender: &str, out: &Path) {
    let reference = read_rgba(&out.join("reference.exr"));
    let result = read_rgba(&out.join("result.exr"));
    let pinhole = read_rgba(&out.join("pinhole.exr"));
    let psnr = compare(&result, &reference).unwrap().psnr;
    let inner = compare(&inset(&result, 8), &inset(&reference, 8)).unwrap().psnr;
    let pinhole_psnr = compare(&pinhole, &reference).unwrap().psnr;
    println!("{blender}: PSNR vs Cycles DOF: add-on {psnr:.2} dB ({inner:.2} dB inside 8 px), pinhole {pinhole_psnr:.2} dB");
    assert!(psnr >= 30.0, "add-on vs Cycles DOF: {psnr:.2} dB");
    assert!(inner >= 38.0, "add-on vs Cycles DOF away from the frame edge: {inner:.2} dB");
    assert!(
        psnr >= pinhole_psnr + 10.0,
        "the blur must explain the reference: {psnr:.2} vs pinhole {pinhole_psnr:.2} dB"
    );
}

test_on_every_blender!(blender_addon_bokeh_has_the_orientation_of_cycles);
/// A 5-blade aperture turned 20 degrees in Blender must give Cycles' bokeh, not its mirror
/// image: the add-on's result is compared with Cycles DOF and with lensblur run on the same
/// stack with the rotation's sign flipped. Measured (Blender 3.4.1, display-encoded PSNR):
/// 42.2 dB vs 31.2 dB for the mirrored pentagon; 5 dB is half that gap.
fn blender_addon_bokeh_has_the_orientation_of_cycles(blender: &Blender) {
    let dir = fresh_dir(&format!("plugin-blender-bokeh-{}", blender.name));
    blender_with_addon(blender, &dir, "blender_plugin_bokeh.py", "LENSBLUR_BOKEH_DONE");
    let out = dir.join("out");
    let mirrored = out.join("mirrored.exr");
    let status = Command::new(env!("CARGO_BIN_EXE_lensblur"))
        .arg("render")
        .arg(out.join("stack.exr"))
        .arg("-o")
        .arg(&mirrored)
        .args(["--focal-length", "50", "--fstop", "0.5", "--focus-distance", "0.4"])
        .args(["--layers", "L_square", "--aperture", "polygon:5:rotation=20"])
        .status()
        .unwrap();
    assert!(status.success());
    let reference = read_rgba(&out.join("reference.exr"));
    let addon = compare(&read_rgba(&out.join("addon.exr")), &reference).unwrap().psnr;
    let wrong = compare(&read_rgba(&mirrored), &reference).unwrap().psnr;
    println!("{}: bokeh PSNR vs Cycles: add-on {addon:.2} dB, mirrored {wrong:.2} dB", blender.name);
    assert!(addon >= wrong + 5.0, "add-on {addon:.2} dB vs mirrored {wrong:.2} dB");
}

/// Runs `body` in plain Python (no bpy) after loading the add-on's camera module as `camera`,
/// with `json`, `types` and `f32` (a value rounded to 32-bit float) at hand; `body` prints a
/// JSON list of [number, text] pairs, returned parsed.
fn with_camera_module(body: &str) -> Vec<(f64, String)> {
    serde_json::from_str(&with_addon_module("camera", body, &[])).unwrap()
}

/// Runs `body` in plain Python (no bpy) after loading the add-on's module `name` (a file of the
/// add-on that imports no bpy) under its own name, with `json`, `sys`, `types` and `f32` at
/// hand and `args` as `sys.argv[2:]`; returns what it printed.
fn with_addon_module(name: &str, body: &str, args: &[&str]) -> String {
    let program = format!(
        r#"
import importlib.util, json, struct, sys, types
package = types.ModuleType("lensblur_addon")
package.__path__ = [sys.argv[1]]
sys.modules["lensblur_addon"] = package
spec = importlib.util.spec_from_file_location("lensblur_addon.{name}", sys.argv[1] + "/{name}.py")
{name} = importlib.util.module_from_spec(spec)
spec.loader.exec_module({name})
f32 = lambda v: struct.unpack("f", struct.pack("f", v))[0]
{body}
"#
    );
    let addon = plugins_dir().join("blender/lensblur");
    let output = Command::new("python3").args(["-c", &program, addon.to_str().unwrap()]).args(args).output().expect("python3");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    String::from_utf8(output.stdout).unwrap()
}

/// Blender hands f32 settings to Python widened to f64: the printed command line must show
/// the value as typed (`--fstop 1.4`, not 1.399999976158142; `rotation=0`, not -0), and each
/// spelling must read back as the same f32. Runs the add-on's camera module in plain Python
/// (it needs no bpy), so it checks values Blender cannot easily be made to produce.
#[test]
fn printed_camera_values_are_the_shortest_f32_spelling() {
    let pairs = with_camera_module(
        "values = [1.4, 2.8, 50.0, 36.0, 0.1, 3.3333333, -0.0, -10.0, 1e-7, 123456789.0]
print(json.dumps([[f32(v), camera.fmt(f32(v))] for v in values]))",
    );
    let printed: Vec<&str> = pairs.iter().map(|(_, s)| s.as_str()).collect();
    assert_eq!(printed, ["1.4", "2.8", "50", "36", "0.1", "3.3333333", "0", "-10", "1e-07", "123456790"]);
    for (value, text) in &pairs {
        let parsed: f32 = text.parse().unwrap();
        assert_eq!(parsed, *value as f32, "{text} does not read back as {value}");
    }
}

/// The Unit Scale as `--scene-unit`: Blender stores it as f32 (0.01 is 0.00999999977), the
/// add-on names the units lensblur names and spells any other scale as metres per unit; every
/// spelling parses in lensblur to the scale as Blender holds it.
#[test]
fn the_unit_scale_becomes_the_scene_unit_lensblur_parses() {
    let pairs = with_camera_module(
        "scene = lambda scale: types.SimpleNamespace(unit_settings=types.SimpleNamespace(scale_length=f32(scale)))
scales = [1.0, 0.01, 0.001, 1000.0, 0.0254, 0.3048, 0.5, 1.0 / 3.0]
print(json.dumps([[f32(s), camera.scene_unit(scene(s))] for s in scales]))",
    );
    let spelled: Vec<&str> = pairs.iter().map(|(_, s)| s.as_str()).collect();
    assert_eq!(spelled, ["m", "cm", "mm", "km", "in", "ft", "0.5", "0.33333334"]);
    for (scale, text) in &pairs {
        let unit: lensblur::camera::SceneUnit = text.parse().unwrap();
        assert_eq!(unit.metres as f32, *scale as f32, "--scene-unit {text} is not the Unit Scale {scale}");
    }
}

/// The add-on's method menu is `lensblur methods --json` of the binary it runs, so it is the
/// registry (every method, in order, with its label and one-line summary) with no copy to keep
/// in step; a binary that cannot be run leaves the default method alone, with the reason for the
/// panel. Runs the add-on's `methods` module in plain Python (it needs no bpy); the menu in
/// Blender is checked by `blender_addon_matches_cycles_depth_of_field_and_reads_the_camera`.
#[test]
fn addon_method_menu_is_what_lensblur_methods_json_lists() {
    let stdout = with_addon_module(
        "methods",
        r#"binary, missing = sys.argv[2], sys.argv[2] + "-missing"
items, error = methods.menu(lambda: binary)
cached = methods.menu(lambda: binary)[0] is items
fallback, why = methods.menu(lambda: missing)
print(json.dumps({"items": items, "error": error, "cached": cached, "fallback": fallback, "why": why}))"#,
        &[env!("CARGO_BIN_EXE_lensblur")],
    );
    let got: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let registry: Vec<[&str; 3]> = Method::ALL.iter().map(|m| [m.spec().name, m.spec().label, m.spec().summary]).collect();
    assert_eq!(got["items"], serde_json::json!(registry), "the add-on's menu vs `lensblur methods --json`");
    assert_eq!(got["error"], Value::Null);
    assert_eq!(got["cached"], true, "the tool is asked once per binary, not on every redraw");
    let why = got["why"].as_str().unwrap();
    assert!(why.contains("lensblur-missing methods --json") && why.contains("only drbokeh is offered"), "{why}");
    assert_eq!(got["fallback"], serde_json::json!([["drbokeh", "drbokeh", why]]));
    // No copy of the list is left in the add-on: the panel's menu is drawn from the tool's
    // answer, and the settings and operators hold a name. No enum lists its items through a
    // callback: with one, the bpy 4.2 module crashed (SIGSEGV) at exit.
    let addon = plugins_dir().join("blender/lensblur");
    for entry in std::fs::read_dir(&addon).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "py") {
            let source = std::fs::read_to_string(&path).unwrap();
            assert!(!source.contains("EnumProperty("), "{}: an enum property", path.display());
        }
    }
    for file in ["settings.py", "operator.py", "animation.py"] {
        let source = std::fs::read_to_string(addon.join(file)).unwrap();
        let lines: Vec<&str> = source.lines().filter(|l| l.trim_start().starts_with("method: bpy.props.")).collect();
        assert!(lines.len() == 1 && lines[0].contains("StringProperty") && lines[0].contains("default=methods.DEFAULT"), "{file}: {lines:?}");
    }
    let panel = std::fs::read_to_string(addon.join("panel.py")).unwrap();
    assert!(panel.contains("for name, label, _ in settings.method_items(context)"), "the menu draws the tool's list");
}

/// The Unit Scale (Scene > Units): the same scene built at 0.01 (one Blender unit a
/// centimetre, so the Z pass and the focus distance are in centimetres, the lens still in
/// millimetres; the add-on passes `--scene-unit cm`) must blur as the scene does in metres:
/// compared with Cycles' depth of field of the scene built at scale 1, same threshold as there
/// (measured 33.9 dB). Cycles' own render at 0.01 is not the reference: it ignores the Unit
/// Scale (its aperture is the lens' millimetres read as 1e-3 units), and the add-on's physical
/// result scored 19.7 dB against it (3.4 and 5.0 alike), the pinhole's score. Ignoring the
/// scale would make the aperture 100 times too small: next to no blur, about the pinhole's
/// 19.3 dB against the truth. On Debian's 3.4 and bpy 5.0: the code path has no version branch.
fn blender_addon_honours_the_unit_scale(blender: &Blender) {
    let dir = fresh_dir(&format!("plugin-blender-units-{}", blender.name));
    let stdout = blender_with_addon(blender, &dir, "blender_unit_scale.py", "LENSBLUR_UNITS_DONE");
    assert!(
        stdout.contains("--fstop 1 --focus-distance 400 --scene-unit cm "),
        "f/1 focused at 400 units of 1 cm (4 m): {stdout}"
    );
    let report = json_after(&stdout, "LENSBLUR_UNITS_REPORT");
    assert_eq!(report["scene_unit"]["metres"], 0.01, "{report}");
    let camera = &report["camera"];
    assert_eq!(camera["fstop"], 1.0, "the lens as set, not scaled: {camera}");
    let focus = camera["focus_distance"].as_f64().unwrap();
    assert!((focus - 400.0).abs() < 1e-3, "focus distance {focus} units (4 m), f32 round trip");
    let out = dir.join("out");
    let psnr = compare(&read_rgba(&out.join("result.exr")), &read_rgba(&out.join("reference.exr"))).unwrap().psnr;
    println!("{}: unit scale 0.01: add-on vs Cycles DOF of the scene in metres {psnr:.2} dB", blender.name);
    assert!(psnr >= 30.0, "{}: add-on at unit scale 0.01 vs Cycles DOF of the scene in metres: {psnr:.2} dB", blender.name);
}

#[test]
fn blender_addon_honours_the_unit_scale_debian() {
    blender_addon_honours_the_unit_scale(&Blender::debian());
}

#[test]
fn blender_addon_honours_the_unit_scale_bpy_5_0() {
    blender_addon_honours_the_unit_scale(&Blender::bpy("5.0.1"));
}

test_on_every_blender!(the_packaged_addon_installs_and_runs);
/// The add-on as users install it, not symlinked: on 4.2+ the Extension zip of
/// plugins/blender/build_extension.py through Install from Disk's operator, on 3.4 the legacy
/// zip (`--legacy`) through Add-ons > Install; then the operator runs on a pinhole render of the
/// test planes and its result is in the compositor. No Cycles reference (a few seconds).
fn the_packaged_addon_installs_and_runs(blender: &Blender) {
    let dir = fresh_dir(&format!("plugin-blender-install-{}", blender.name));
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();
    let builder = plugins_dir().join("blender/build_extension.py");
    let mut build = Command::new("python3");
    build.arg(&builder).arg("-o").arg(out.join("lensblur.zip"));
    if blender.name == "debian" {
        build.arg("--legacy");
    }
    let built = build.output().expect("python3");
    assert!(built.status.success(), "{}", String::from_utf8_lossy(&built.stderr));
    let script = plugin_common::interop_script("blender_install.py");
    let stdout = plugin_common::run_script(blender.script_command(&script), &dir, "LENSBLUR_INSTALL_DONE");
    let checks = json_after(&stdout, "LENSBLUR_INSTALL_CHECKS");
    assert_eq!(checks["install"], serde_json::json!(["FINISHED"]), "{checks}");
    assert_eq!(checks["enabled"], true, "{checks}");
    // Installed into this test's own folders (BLENDER_USER_EXTENSIONS or _SCRIPTS), a copy.
    let installed = checks["installed_in"].as_str().unwrap();
    assert!(installed.starts_with(dir.to_str().unwrap()) && installed.ends_with("lensblur"), "{checks}");
    assert_eq!(checks["image_size"], serde_json::json!([160, 120]), "{checks}");
    assert_eq!(checks["layers"], serde_json::json!(["L_front", "L_mid", "L_back"]), "{checks}");
    assert_eq!(checks["node_image"], "lensblur_result", "{checks}");
}
