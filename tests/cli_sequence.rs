//! `lensblur render IN.####.exr -o OUT.####.exr --frames RANGE` (issue 24): a shot in one
//! process gives, frame for frame, the bytes of single-frame renders; the camera of each frame
//! comes from its header or the camera file; failures and resumes are per frame. Validation on.
mod common;

use std::path::Path;
use std::process::Output;

use common::shot::{self, write_camera_file, write_focus_pull};
use common::temp_dir;

fn lensblur(args: &[&str]) -> Output {
    common::lensblur(args, &[])
}

fn ok(output: &Output) -> String {
    assert!(output.status.success(), "lensblur failed: {}", String::from_utf8_lossy(&output.stderr));
    String::from_utf8(output.stdout.clone()).unwrap()
}

fn text(path: &Path) -> &str {
    path.to_str().unwrap()
}

fn bytes(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Renders `input` alone to `output` with `extra` flags, in its own process.
fn render_single(input: &Path, output: &Path, extra: &[&str]) {
    ok(&lensblur(&[&["render", text(input), "-o", text(output)], extra].concat()));
}

#[test]
fn a_sequence_gives_each_frame_the_bytes_of_its_single_render() {
    let dir = temp_dir("cli-sequence", "bytes");
    let frames = [1001, 1002, 1003];
    let pattern = write_focus_pull(&dir, &frames, true);
    let report: serde_json::Value =
        serde_json::from_str(&ok(&lensblur(&["render", text(&pattern), "-o", text(&dir.join("out.%04d.exr")), "--frames", "1001-1003", "--json"])))
            .unwrap();
    assert_eq!(report["rendered"], serde_json::json!(frames));
    for (index, frame) in frames.iter().enumerate() {
        let single = dir.join(format!("single.{frame}.exr"));
        render_single(&dir.join(format!("shot.{frame}.exr")), &single, &[]);
        let sequence = dir.join(format!("out.{frame}.exr"));
        assert!(bytes(&sequence) == bytes(&single), "frame {frame} differs from its single render");
        let camera = &report["frames"][index]["camera"];
        assert_eq!(camera["focus_distance"].as_f64().unwrap() as f32, shot::camera(index).focus_distance, "{report}");
        assert_eq!(report["frames"][index]["camera_from_header"].as_array().unwrap().len(), 4, "{report}");
    }
    // A focus pull: each frame has its own blur, so no two outputs are the same.
    assert!(bytes(&dir.join("out.1001.exr")) != bytes(&dir.join("out.1003.exr")));
}

#[test]
fn frames_take_range_expressions_and_only_those_frames_are_written() {
    let dir = temp_dir("cli-sequence", "ranges");
    let all: Vec<i64> = (1..=7).collect();
    let pattern = write_focus_pull(&dir, &all, true);
    ok(&lensblur(&["render", text(&pattern), "-o", text(&dir.join("o_%03d.exr")), "--frames", "5-1:-2, 6"]));
    let mut written: Vec<String> = std::fs::read_dir(&*dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n.starts_with("o_"))
        .collect();
    written.sort();
    assert_eq!(written, ["o_001.exr", "o_003.exr", "o_005.exr", "o_006.exr"]);
}

#[test]
fn the_camera_file_gives_frames_without_a_header_camera_and_flags_still_win() {
    let dir = temp_dir("cli-sequence", "camera-file");
    let frames = [7, 8];
    let pattern = write_focus_pull(&dir, &frames, false);
    let camera_file = dir.join("shot.json");
    write_camera_file(&camera_file, &frames);
    let output = dir.join("out.####.exr");
    let run = lensblur(&[
        "render", text(&pattern), "-o", text(&output), "--frames", "7,8", "--camera-file", text(&camera_file), "--fstop", "2", "--json",
    ]);
    let report: serde_json::Value = serde_json::from_str(&ok(&run)).unwrap();
    for (index, frame) in frames.iter().enumerate() {
        let entry = &report["frames"][index];
        assert_eq!(entry["camera"]["fstop"], 2.0, "the flag wins: {entry}");
        assert_eq!(entry["camera"]["focus_distance"].as_f64().unwrap() as f32, shot::camera(index).focus_distance, "{entry}");
        assert_eq!(entry["camera_from_file"], serde_json::json!(["focal-length", "focus-distance", "sensor-width"]), "{entry}");
        // The same render with the frame's camera given as flags.
        let camera = shot::camera(index);
        let single = dir.join(format!("flags.{frame}.exr"));
        let flags = [
            ("--focal-length", camera.focal_length_mm),
            ("--sensor-width", camera.sensor_width_mm),
            ("--focus-distance", camera.focus_distance),
            ("--fstop", 2.0),
        ]
        .map(|(flag, value)| [flag.to_string(), value.to_string()]);
        let flags: Vec<&str> = flags.iter().flatten().map(String::as_str).collect();
        render_single(&dir.join(format!("shot.{frame:04}.exr")), &single, &flags);
        assert!(bytes(&dir.join(format!("out.{frame:04}.exr"))) == bytes(&single), "frame {frame}");
    }
}

#[test]
fn a_frame_missing_from_the_camera_file_is_named_before_anything_renders() {
    let dir = temp_dir("cli-sequence", "camera-missing");
    let pattern = write_focus_pull(&dir, &[1, 2, 3], false);
    let camera_file = dir.join("shot.json");
    write_camera_file(&camera_file, &[1, 3]);
    let run = lensblur(&["render", text(&pattern), "-o", text(&dir.join("out.####.exr")), "--frames", "1-3", "--camera-file", text(&camera_file)]);
    assert!(!run.status.success());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(stderr.contains("shot.json: no camera for frame(s) 2 "), "{stderr}");
    assert!(!dir.join("out.0001.exr").exists(), "nothing is rendered when the camera file lacks a frame");
}

#[test]
fn a_failed_frame_is_named_the_others_are_written_and_skip_existing_resumes() {
    let dir = temp_dir("cli-sequence", "failures");
    let pattern = write_focus_pull(&dir, &[1, 2, 4], true);
    let output = dir.join("out.####.exr");
    let run = lensblur(&["render", text(&pattern), "-o", text(&output), "--frames", "1-4", "--json"]);
    assert_eq!(run.status.code(), Some(1), "a missing frame fails the command");
    let report: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(report["rendered"], serde_json::json!([1, 2, 4]));
    assert_eq!(report["failed"][0]["frame"], 3, "{report}");
    assert!(report["failed"][0]["error"].as_str().unwrap().contains("shot.0003.exr"), "{report}");
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(stderr.contains("1 of 4 frame(s) failed:\n  frame 3: "), "{stderr}");
    // Resume: frame 3 appears, the others are left alone (a marker proves it).
    write_focus_pull(&dir, &[3], true);
    std::fs::write(dir.join("out.0002.exr"), "not rewritten").unwrap();
    let run = lensblur(&["render", text(&pattern), "-o", text(&output), "--frames", "1-4", "--skip-existing", "--json"]);
    let report: serde_json::Value = serde_json::from_str(&ok(&run)).unwrap();
    assert_eq!(report["rendered"], serde_json::json!([3]));
    assert_eq!(report["skipped"], serde_json::json!([1, 2, 4]));
    assert_eq!(std::fs::read_to_string(dir.join("out.0002.exr")).unwrap(), "not rewritten");
}

#[test]
fn sequence_mistakes_say_what_to_do() {
    let dir = temp_dir("cli-sequence", "mistakes");
    let pattern = write_focus_pull(&dir, &[1], true);
    let out = dir.join("out.####.exr");
    for (args, expected) in [
        (vec!["render", text(&pattern), "-o", text(&out)], "is a frame pattern: say which frames to render with --frames"),
        (vec!["render", text(&pattern), "-o", text(&dir.join("out.exr")), "--frames", "1"], "-o must name every frame's file with a frame number pattern"),
        (vec!["render", text(&pattern), "-o", text(&out), "--frames", "3-1"], "'3-1': a descending range needs a negative step"),
        (vec!["render", text(&pattern), "-o", text(&pattern), "--frames", "1"], "is the input file"),
        (vec!["render", text(&pattern), "-o", text(&dir.join("missing/out.####.exr")), "--frames", "1"], "does not exist; create it first"),
        (vec!["render", text(&dir.join("shot.0001.exr")), "-o", text(&out), "--skip-existing"], "--frames"),
    ] {
        let run = lensblur(&args);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(!run.status.success() && stderr.contains(expected), "{args:?}: {stderr}");
    }
}

/// Writes frames `frames` of a shot whose subject's left edge is at `subject_x(frame)`, every
/// frame with the camera of the pull's first frame; returns the pattern.
fn write_shot(dir: &Path, frames: &[i64], subject_x: impl Fn(i64) -> usize) -> std::path::PathBuf {
    for &frame in frames {
        let options = lensblur::stack::StackWriteOptions { camera: Some(shot::camera(0)), ..Default::default() };
        lensblur::stack::write_stack(&dir.join(format!("shot.{frame:04}.exr")), &shot::stack(subject_x(frame)), &options).unwrap();
    }
    dir.join("shot.####.exr")
}

/// The R, G, B, A samples of an output, pixel by pixel.
fn read_rgba(path: &Path) -> Vec<[f32; 4]> {
    let file = exr::prelude::read_all_flat_layers_from_file(path).unwrap();
    let channel = |name: &str| -> Vec<f32> {
        let list = &file.layer_data[0].channel_data.list;
        list.iter().find(|c| c.name.to_string() == name).unwrap().sample_data.values_as_f32().collect()
    };
    let (r, g, b, a) = (channel("R"), channel("G"), channel("B"), channel("A"));
    (0..r.len()).map(|i| [r[i], g[i], b[i], a[i]]).collect()
}

/// Temporal stability of the sampled methods: each pixel draws its lens samples from a set
/// picked by its screen position alone, never by the frame or the run, so a still shot gives
/// identical frames (no flicker), byte for byte whatever the chunking and however often it runs.
#[test]
fn sampled_methods_give_a_still_shot_identical_frames_whatever_the_chunking() {
    let dir = temp_dir("cli-sequence", "still");
    let pattern = write_shot(&dir, &[1, 2, 3], |_| 20);
    for method in ["vdslr", "multiview"] {
        let whole = dir.join(format!("{method}.####.exr"));
        ok(&lensblur(&["render", text(&pattern), "-o", text(&whole), "--frames", "1-3", "--method", method]));
        let first = bytes(&dir.join(format!("{method}.0001.exr")));
        for frame in [2, 3] {
            assert!(bytes(&dir.join(format!("{method}.{frame:04}.exr"))) == first, "{method}: frame {frame} of a still shot differs");
        }
        // Chunks of 2 and 1, as a farm would split the shot, in separate processes.
        let chunked = dir.join(format!("{method}-chunked.####.exr"));
        for chunk in ["1-2", "3"] {
            ok(&lensblur(&["render", text(&pattern), "-o", text(&chunked), "--frames", chunk, "--method", method]));
        }
        for frame in 1..=3 {
            let name = |suffix: &str| dir.join(format!("{method}{suffix}.{frame:04}.exr"));
            assert!(bytes(&name("-chunked")) == bytes(&name("")), "{method}: frame {frame} depends on the chunking");
        }
    }
}

/// No crawl: when the subject moves, the sample noise far from it stays exactly where it was.
/// Focus is on the (sharp) subject, so the wall with its highlights is blurred by sampling
/// (6.7 px CoC). Columns 56.. are 20 px right of the subject's right edge in both frames, well
/// beyond that CoC, so nothing there changes but the frame number. That region does depend on
/// the samples (another sample count changes it), so its equality is the pattern's doing.
#[test]
fn sampled_noise_stays_put_where_a_moving_shot_does_not_change() {
    let dir = temp_dir("cli-sequence", "crawl");
    let pattern = write_shot(&dir, &[1, 2], |frame| if frame == 1 { 20 } else { 22 });
    for method in ["vdslr", "multiview"] {
        let output = dir.join(format!("{method}.####.exr"));
        ok(&lensblur(&["render", text(&pattern), "-o", text(&output), "--frames", "1-2", "--method", method]));
        let frames = [1, 2].map(|frame| read_rgba(&dir.join(format!("{method}.{frame:04}.exr"))));
        let far = |pixels: &[[f32; 4]]| -> Vec<[f32; 4]> {
            pixels.iter().enumerate().filter(|(i, _)| i % shot::WIDTH >= 56).map(|(_, p)| *p).collect()
        };
        assert!(far(&frames[0]) == far(&frames[1]), "{method}: pixels away from the moving subject changed (crawling noise)");
        assert!(frames[0] != frames[1], "{method}: the subject moved, the frames must differ");
        let other_samples = dir.join(format!("{method}-samples.exr"));
        ok(&lensblur(&["render", text(&dir.join("shot.0001.exr")), "-o", text(&other_samples), "--method", method, "--samples", "16"]));
        assert!(far(&read_rgba(&other_samples)) != far(&frames[0]), "{method}: the compared region does not depend on the samples");
    }
}
