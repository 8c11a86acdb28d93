//! The Blender add-on on a shot (issue 24), in real headless Blender (Debian's 3.4 and PyPI's
//! bpy 4.2, 4.5, 5.0, 5.3, a test each: `<test>::bpy_5_0`): a 5-frame focus pull
//! (focus distance and f-stop animated) of three planes, one view layer each, through
//! `bpy.ops.lensblur.defocus_animation` (layers rendered per frame, the camera file written
//! from the animated camera, one `lensblur render --frames`, an image-sequence Image node);
//! every frame compared with Cycles' own depth of field of that frame. Also the setup
//! warnings, a stale Render Result, and the "Render on farm" job bundle run through `openjd`.
//! About 40 s per Blender on 2 cores (five 1024-sample Cycles references are most of it):
//! `cargo test --test plugin_blender_animation`. Fails, never skips, when Blender, a bpy or
//! openjd is missing.
mod plugin_common;

use std::path::Path;
use std::process::Command;

use lensblur::metrics::compare;
use plugin_common::{blender_with_addon, fresh_dir, inset, json_after, read_rgba, Blender};
use serde_json::{json, Value};

test_on_every_blender!(a_focus_pull_from_blender_matches_cycles_depth_of_field_frame_by_frame);
/// Display-encoded PSNR per frame. Measured (Blender 3.4.1, seeded Cycles, 1024 samples):
/// 39.8, 40.2, 42.8, 38.7, 38.6 dB over the frame (38.8, 39.4, 42.2, 38.3, 37.9 inside a
/// 10 px border). The add-on renders the layers overscanned (Cycles' lens sees past the frame
/// edge, a stack of the frame alone does not: 32.2, 32.8, 35.8, 36.1, 36.1 dB before), so the
/// issue's 36 dB holds over the whole frame, with 2.6 dB left for another Cycles build's noise.
fn a_focus_pull_from_blender_matches_cycles_depth_of_field_frame_by_frame(blender: &Blender) {
    let dir = fresh_dir(&format!("plugin-blender-animation-{}", blender.name));
    let checks = json_after(&blender_with_addon(blender, &dir, "blender_animation.py", "LENSBLUR_ANIMATION_DONE"), "LENSBLUR_ANIMATION_CHECKS");
    let out = dir.join("out");
    for frame in 1..=5 {
        let result = read_rgba(&out.join(format!("shot/defocus.{frame:04}.exr")));
        let reference = read_rgba(&out.join(format!("reference.{frame:04}.exr")));
        let psnr = compare(&result, &reference).unwrap().psnr;
        let inner = compare(&inset(&result, 10), &inset(&reference, 10)).unwrap().psnr;
        println!("{}: frame {frame}: add-on vs Cycles DOF {psnr:.2} dB, {inner:.2} dB inside 10 px", blender.name);
        assert!(psnr >= 36.0, "{}: frame {frame}: {psnr:.2} dB over the frame ({inner:.2} dB inside 10 px)", blender.name);
    }
    the_camera_file_follows_the_animation(&checks, &out);
    the_result_is_an_image_sequence_node(&checks);
    setups_without_layers_and_stale_renders_are_warned_about(&checks);
    the_farm_bundle_runs_through_openjd(&out.join("farm"));
}

fn the_camera_file_follows_the_animation(checks: &Value, out: &Path) {
    let frames = &checks["camera_file"]["frames"];
    let focus: Vec<f64> = (1..=5).map(|f| frames[f.to_string()]["focus_distance"].as_f64().unwrap()).collect();
    assert_eq!(focus, [2.0, 3.0, 4.0, 8.0, 15.0], "{frames}");
    // f/1 to f/2 between frames 1 and 5 (Blender's default Bezier easing in between).
    let fstop: Vec<f64> = (1..=5).map(|f| frames[f.to_string()]["fstop"].as_f64().unwrap()).collect();
    assert_eq!((fstop[0], fstop[4]), (1.0, 2.0), "{frames}");
    assert!(fstop.windows(2).all(|w| w[0] < w[1]), "f-stop animated: {fstop:?}");
    assert_eq!(frames["3"]["focal_length_mm"], 85.0);
    // The layers are overscanned and the sensor in the camera file spans them: 36 mm over the
    // frame's width, the same pixel size.
    let layers = lensblur::stack::read_stack(&out.join("shot/layers.0003.exr"), &Default::default()).unwrap().stack;
    let frame = read_rgba(&out.join("shot/defocus.0003.exr"));
    assert!(layers.width > frame.width && layers.width - frame.width == layers.height - frame.height, "overscan on every side");
    let sensor = frames["3"]["sensor_width_mm"].as_f64().unwrap();
    let expected = 36.0 * layers.width as f64 / frame.width as f64;
    assert!((sensor - expected).abs() < 1e-3, "sensor {sensor} mm for {} px over a {} px frame", layers.width, frame.width);
}

fn the_result_is_an_image_sequence_node(checks: &Value) {
    let sequence = &checks["sequence"];
    assert_eq!(sequence["source"], "SEQUENCE");
    assert_eq!(sequence["node_image"], "lensblur_sequence");
    // Start at frame 1, file number = scene frame, 5 frames long.
    assert_eq!(sequence["node_frames"], json!([1, 0, 5]));
    assert_eq!(sequence["rendered"], json!([1, 2, 3, 4, 5]));
    assert_eq!(sequence["size_at_frame_4"], json!([160, 120]));
    assert_eq!(sequence["current_frame"], 1, "the scene is back on the frame it was on");
    assert_eq!(sequence["warnings"], json!([]), "a layered setup gets no warning");
}

fn setups_without_layers_and_stale_renders_are_warned_about(checks: &Value) {
    let bad = checks["bad_setup_warnings"].to_string();
    assert!(bad.contains("Film > Transparent is off") && bad.contains("render again"), "{bad}");
    assert!(bad.contains("has Depth of Field on") && bad.contains("blurs them again"), "{bad}");
    let stale = checks["stale_warnings"].to_string();
    assert!(stale.contains("it shows frame 3, the scene is at frame 4): render again"), "{stale}");
    assert_eq!(checks["fresh_warnings"], json!([]), "the Render Result of the current frame is not stale");
}

/// The bundle is what `deadline bundle submit` takes: the binary's template and Deadline's
/// parameter_values.json. Run here through `openjd run` with those values, it renders the
/// frames the add-on's layers and camera file give, as `lensblur render --frames` does.
fn the_farm_bundle_runs_through_openjd(farm: &Path) {
    let bundle = farm.join("farm-bundle");
    let template = std::fs::read_to_string(bundle.join("template.yaml")).unwrap();
    assert_eq!(template, include_str!("../plugins/openjd/lensblur-render.yaml"), "the template is the repository's");
    let values: Value = serde_json::from_str(&std::fs::read_to_string(bundle.join("parameter_values.json")).unwrap()).unwrap();
    let params: Vec<(String, String)> = values["parameterValues"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| (p["name"].as_str().unwrap().to_string(), p["value"].to_string().trim_matches('"').to_string()))
        .collect();
    let param = |name: &str| params.iter().find(|(n, _)| n == name).map(|(_, v)| v.clone()).unwrap();
    assert_eq!(param("Frames"), "2-3");
    let bin_dir = Path::new(env!("CARGO_BIN_EXE_lensblur")).parent().unwrap();
    let mut openjd = Command::new("openjd");
    openjd.args(["run", bundle.join("template.yaml").to_str().unwrap(), "--step", "Render"]);
    for (name, value) in &params {
        openjd.args(["-p", &format!("{name}={value}")]);
    }
    let path = format!("{}:{}", bin_dir.display(), std::env::var("PATH").unwrap_or_default());
    let run = openjd.env("PATH", path).output().expect("openjd (pip install openjd-cli; .ci/setup installs it)");
    let log = String::from_utf8_lossy(&run.stdout);
    assert!(run.status.success() && log.contains("Chunks run: 2"), "{log}");
    // The same frames rendered directly from the bundle's values.
    let direct = farm.join("direct.####.exr");
    let args: Vec<String> = param("Args").split_whitespace().map(String::from).collect();
    let status = Command::new(env!("CARGO_BIN_EXE_lensblur"))
        .args(["render", &param("Input"), "-o", direct.to_str().unwrap(), "--frames", "2-3", "--camera-file", &param("CameraFile")])
        .args(&args)
        .status()
        .unwrap();
    assert!(status.success());
    for frame in [2, 3] {
        let farm_frame = std::fs::read(farm.join(format!("defocus.{frame:04}.exr"))).unwrap();
        let direct_frame = std::fs::read(farm.join(format!("direct.{frame:04}.exr"))).unwrap();
        assert!(farm_frame == direct_frame, "frame {frame} from the farm bundle differs");
    }
}

/// Esc in the add-on cancels its `RenderJob` (plugins/blender/lensblur/job.py, no bpy, so it
/// runs in plain Python here): lensblur is stopped mid-sequence, the frames it finished are
/// whole, and no partial or temporary file is left. Progress comes from its stderr as it runs.
#[test]
fn a_cancelled_render_job_leaves_only_complete_frames() {
    let dir = fresh_dir("plugin-blender-cancel");
    let frames: Vec<i64> = (1..=40).collect();
    for &frame in &frames {
        let options = lensblur::stack::StackWriteOptions {
            camera: Some(lensblur::camera::PhysicalCamera { focal_length_mm: 50.0, sensor_width_mm: 3.0, fstop: 1.0, focus_distance: 2.0 }),
            ..Default::default()
        };
        let stack = lensblur::stack::LayerStack::new(
            64,
            48,
            vec![lensblur::stack::Layer { name: "plate".into(), rgba: lensblur::image::Image::from_fn(64, 48, |x, y| [(x % 7) as f32 / 7.0, (y % 5) as f32 / 5.0, 0.5, 1.0]), disparity: vec![0.3; 64 * 48] }],
        )
        .unwrap();
        lensblur::stack::write_stack(&dir.join(format!("shot.{frame:04}.exr")), &stack, &options).unwrap();
    }
    let program = r#"
import importlib.util, json, os, sys, time, types
addon, binary, shot = sys.argv[1:4]
package = types.ModuleType("lensblur_addon")
package.__path__ = [addon]
sys.modules["lensblur_addon"] = package
for name in ("errors", "job"):
    spec = importlib.util.spec_from_file_location(f"lensblur_addon.{name}", f"{addon}/{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[f"lensblur_addon.{name}"] = module
    spec.loader.exec_module(module)
job = sys.modules["lensblur_addon.job"].RenderJob([
    binary, "render", f"{shot}/shot.####.exr", "-o", f"{shot}/out.####.exr", "--frames", "1-40",
    "--method", "vdslr", "--samples", "1024", "--json"])
while job.progress()[0] < 2 and job.poll() is None:
    time.sleep(0.01)
seen = job.progress()
job.cancel()
print(json.dumps({"seen": seen, "returncode": job.proc.returncode, "files": sorted(os.listdir(shot))}))
"#;
    let addon = plugin_common::plugins_dir().join("blender/lensblur");
    let output = Command::new("python3")
        .args(["-c", program, addon.to_str().unwrap(), env!("CARGO_BIN_EXE_lensblur"), dir.to_str().unwrap()])
        .output()
        .expect("python3");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    // The job prints the command it runs first; the result is the last line.
    let stdout = String::from_utf8_lossy(&output.stdout);
    let result: Value = serde_json::from_str(stdout.lines().last().unwrap_or_default()).unwrap();
    assert_eq!(result["seen"][1], 40, "progress counts the job's frames: {result}");
    assert_ne!(result["returncode"], 0, "cancelled before the end: {result}");
    let files: Vec<&str> = result["files"].as_array().unwrap().iter().map(|f| f.as_str().unwrap()).collect();
    let outputs: Vec<&&str> = files.iter().filter(|f| f.starts_with("out.")).collect();
    assert!(files.iter().all(|f| !f.ends_with(".tmp")), "a temporary was left: {files:?}");
    assert!((2..40).contains(&outputs.len()), "stopped mid-sequence after 2 frames: {outputs:?}");
    for output in outputs {
        read_rgba(&dir.join(output)); // whole: it decodes
    }
}
