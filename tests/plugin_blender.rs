//! The Blender add-on (`plugins/blender/lensblur`) in real headless Blender (Debian's 3.4):
//! installed by symlink into an addons folder, driven through `bpy.ops.lensblur.defocus()`
//! on a Cycles render of three textured planes (one view layer each), and compared with
//! Cycles' own depth of field of the same scene. 15-25 s on 2 cores (the Cycles DOF
//! reference is most of it), so it is a test file of its own:
//! `cargo test --test plugin_blender`. Fails, never skips, when Blender is missing.
mod plugin_common;

use std::path::Path;
use std::process::Command;

use lensblur::metrics::compare;
use lensblur::render::Method;
use plugin_common::{blender_with_addon, fresh_dir, inset, plugins_dir, read_rgba};
use serde_json::Value;

struct Run {
    stdout: String,
    report: Value,
    checks: Value,
}

fn run_blender(dir: &Path) -> Run {
    let stdout = blender_with_addon(dir, "blender_plugin.py", "LENSBLUR_PLUGIN_DONE");
    let json_after = |marker: &str| -> Value {
        let line = stdout.lines().find_map(|l| l.strip_prefix(marker));
        serde_json::from_str(line.unwrap_or_else(|| panic!("no {marker} in:\n{stdout}"))).unwrap()
    };
    Run { report: json_after("LENSBLUR_PLUGIN_REPORT "), checks: json_after("LENSBLUR_PLUGIN_CHECKS "), stdout }
}

#[test]
fn blender_addon_matches_cycles_depth_of_field_and_reads_the_camera() {
    let dir = fresh_dir("plugin-blender");
    let run = run_blender(&dir);
    camera_was_read_from_the_scene(&run);
    operator_behaves_like_a_blender_tool(&run);
    let leftovers: Vec<_> = std::fs::read_dir(dir.join("tmp"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with("lensblur"))
        .collect();
    assert!(leftovers.is_empty(), "left in TMPDIR: {leftovers:?}");
    result_matches_cycles_dof(&dir.join("out"));
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
    assert_eq!(
        c["images"],
        serde_json::json!(["Render Result", "lensblur_result"]),
        "re-running replaces the datablock"
    );
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
fn result_matches_cycles_dof(out: &Path) {
    let reference = read_rgba(&out.join("reference.exr"));
    let result = read_rgba(&out.join("result.exr"));
    let pinhole = read_rgba(&out.join("pinhole.exr"));
    let psnr = compare(&result, &reference).unwrap().psnr;
    let inner = compare(&inset(&result, 8), &inset(&reference, 8)).unwrap().psnr;
    let pinhole_psnr = compare(&pinhole, &reference).unwrap().psnr;
    println!("PSNR vs Cycles DOF: add-on {psnr:.2} dB ({inner:.2} dB inside 8 px), pinhole {pinhole_psnr:.2} dB");
    assert!(psnr >= 30.0, "add-on vs Cycles DOF: {psnr:.2} dB");
    assert!(inner >= 38.0, "add-on vs Cycles DOF away from the frame edge: {inner:.2} dB");
    assert!(
        psnr >= pinhole_psnr + 10.0,
        "the blur must explain the reference: {psnr:.2} vs pinhole {pinhole_psnr:.2} dB"
    );
}

/// A 5-blade aperture turned 20 degrees in Blender must give Cycles' bokeh, not its mirror
/// image: the add-on's result is compared with Cycles DOF and with lensblur run on the same
/// stack with the rotation's sign flipped. Measured (Blender 3.4.1, display-encoded PSNR):
/// 42.2 dB vs 31.2 dB for the mirrored pentagon; 5 dB is half that gap.
#[test]
fn blender_addon_bokeh_has_the_orientation_of_cycles() {
    let dir = fresh_dir("plugin-blender-bokeh");
    blender_with_addon(&dir, "blender_plugin_bokeh.py", "LENSBLUR_BOKEH_DONE");
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
    println!("bokeh PSNR vs Cycles: add-on {addon:.2} dB, mirrored {wrong:.2} dB");
    assert!(addon >= wrong + 5.0, "add-on {addon:.2} dB vs mirrored {wrong:.2} dB");
}

/// Blender hands f32 settings to Python widened to f64: the printed command line must show
/// the value as typed (`--fstop 1.4`, not 1.399999976158142; `rotation=0`, not -0), and each
/// spelling must read back as the same f32. Runs the add-on's camera module in plain Python
/// (it needs no bpy), so it checks values Blender cannot easily be made to produce.
#[test]
fn printed_camera_values_are_the_shortest_f32_spelling() {
    let program = r#"
import importlib.util, json, struct, sys, types
package = types.ModuleType("lensblur_addon")
package.__path__ = [sys.argv[1]]
sys.modules["lensblur_addon"] = package
spec = importlib.util.spec_from_file_location("lensblur_addon.camera", sys.argv[1] + "/camera.py")
camera = importlib.util.module_from_spec(spec)
spec.loader.exec_module(camera)
f32 = lambda v: struct.unpack("f", struct.pack("f", v))[0]
values = [1.4, 2.8, 50.0, 36.0, 0.1, 3.3333333, -0.0, -10.0, 1e-7, 123456789.0]
print(json.dumps([[f32(v), camera.fmt(f32(v))] for v in values]))
"#;
    let addon = plugins_dir().join("blender/lensblur");
    let output = Command::new("python3").args(["-c", program, addon.to_str().unwrap()]).output().expect("python3");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let pairs: Vec<(f64, String)> = serde_json::from_slice(&output.stdout).unwrap();
    let printed: Vec<&str> = pairs.iter().map(|(_, s)| s.as_str()).collect();
    assert_eq!(printed, ["1.4", "2.8", "50", "36", "0.1", "3.3333333", "0", "-10", "1e-07", "123456790"]);
    for (value, text) in &pairs {
        let parsed: f32 = text.parse().unwrap();
        assert_eq!(parsed, *value as f32, "{text} does not read back as {value}");
    }
}

/// The add-on's method menu (`settings.METHODS`) is the registry: every method, in order, with
/// the registry's label and one-line summary. Read from the source, so it needs no Blender.
#[test]
fn addon_method_list_is_the_registry() {
    let source = std::fs::read_to_string(plugins_dir().join("blender/lensblur/settings.py")).unwrap();
    let listed: Vec<Vec<String>> = source
        .lines()
        .skip_while(|l| !l.starts_with("METHODS = ["))
        .skip(1)
        .take_while(|l| !l.starts_with(']'))
        .map(|l| {
            let inner = l.trim().strip_prefix("(\"").and_then(|l| l.strip_suffix("\"),"));
            inner.unwrap_or_else(|| panic!("not a (name, label, summary) tuple: {l}")).split("\", \"").map(String::from).collect()
        })
        .collect();
    let registry: Vec<Vec<String>> =
        Method::ALL.iter().map(|m| [m.spec().name, m.spec().label, m.spec().summary].map(String::from).to_vec()).collect();
    assert_eq!(listed, registry, "plugins/blender/lensblur/settings.py METHODS vs `lensblur methods`");
}
