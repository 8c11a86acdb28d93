//! The render-farm template (plugins/openjd/lensblur-render.yaml, issue 24) through the real
//! Open Job Description runner, `openjd` from openjd-cli (.ci/setup installs it): it validates,
//! renders a focus pull in chunks with the camera file, each frame byte-identical to a
//! single-frame render, and resumes with --skip-existing, redoing only the missing frames.
mod common;

use std::os::unix::fs::MetadataExt as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use common::shot::{self, write_camera_file, write_focus_pull};

const TEMPLATE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../plugins/openjd/lensblur-render.yaml");

/// Runs `openjd` with the lensblur under test first on PATH; a missing runner fails the test.
fn openjd(args: &[&str]) -> Output {
    let bin_dir = Path::new(env!("CARGO_BIN_EXE_lensblur")).parent().unwrap();
    let path = format!("{}:{}", bin_dir.display(), std::env::var("PATH").unwrap_or_default());
    Command::new("openjd")
        .args(args)
        .env("PATH", path)
        .env("LENSBLUR_VALIDATION", "1")
        .env_remove("LENSBLUR_DEVICE")
        .output()
        .unwrap_or_else(|e| panic!("the OpenJD runner `openjd` is needed (pip install openjd-cli; .ci/setup installs it): {e}"))
}

fn succeeded(output: Output) -> String {
    let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
    assert!(output.status.success(), "openjd failed:\n{stdout}\n{}", String::from_utf8_lossy(&output.stderr));
    stdout
}

#[test]
fn the_template_passes_openjd_check() {
    let stdout = succeeded(openjd(&["check", TEMPLATE]));
    assert!(stdout.contains("passes validation checks"), "{stdout}");
}

/// Runs the template's Render step over `frames` of `dir`'s shot in chunks of 2.
fn run_template(dir: &Path, frames: &str, args: &str) -> String {
    let param = |name: &str, value: &str| format!("{name}={value}");
    let params = [
        param("Input", dir.join("shot.####.exr").to_str().unwrap()),
        param("Output", dir.join("out/defocus.####.exr").to_str().unwrap()),
        param("Frames", frames),
        param("ChunkSize", "2"),
        param("CameraFile", dir.join("shot.json").to_str().unwrap()),
        param("Args", args),
    ];
    let mut command = vec!["run", TEMPLATE, "--step", "Render"];
    for p in &params {
        command.extend(["-p", p.as_str()]);
    }
    succeeded(openjd(&command))
}

fn output(dir: &Path, frame: i64) -> PathBuf {
    dir.join(format!("out/defocus.{frame:04}.exr"))
}

#[test]
fn openjd_renders_a_focus_pull_in_chunks_like_single_renders_and_resumes_only_missing_frames() {
    let dir = common::temp_dir("openjd", "focus-pull");
    let frames: Vec<i64> = (1001..=1006).collect();
    // No camera in the headers: the focus pull comes from the camera file, as the add-on writes it.
    write_focus_pull(&dir, &frames, false);
    write_camera_file(&dir.join("shot.json"), &frames);
    std::fs::create_dir(dir.join("out")).unwrap();
    let log = run_template(&dir, "1001-1006", "");
    assert!(log.contains("Chunks run: 3"), "6 frames in chunks of 2 make 3 tasks:\n{log}");
    for (index, &frame) in frames.iter().enumerate() {
        let camera = shot::camera(index);
        let single = dir.join(format!("single.{frame}.exr"));
        let values = [camera.focal_length_mm, camera.sensor_width_mm, camera.fstop, camera.focus_distance].map(|v| v.to_string());
        let input = dir.join(format!("shot.{frame}.exr"));
        let run = common::lensblur(
            &[
                "render", input.to_str().unwrap(), "-o", single.to_str().unwrap(),
                "--focal-length", &values[0], "--sensor-width", &values[1], "--fstop", &values[2], "--focus-distance", &values[3],
            ],
            &[],
        );
        assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
        assert!(std::fs::read(output(&dir, frame)).unwrap() == std::fs::read(&single).unwrap(), "frame {frame} differs from its single render");
    }
    // Resume after losing two frames: only they are rendered again; the others keep their
    // file (same inode and modification time: an atomic rewrite would make a new inode).
    let kept: Vec<(i64, (u64, i64, i64))> = [1001, 1002, 1004, 1006]
        .map(|f| {
            let m = std::fs::metadata(output(&dir, f)).unwrap();
            (f, (m.ino(), m.mtime(), m.mtime_nsec()))
        })
        .to_vec();
    let first_run: Vec<Vec<u8>> = [1003, 1005].map(|f| std::fs::read(output(&dir, f)).unwrap()).to_vec();
    for frame in [1003, 1005] {
        std::fs::remove_file(output(&dir, frame)).unwrap();
    }
    let log = run_template(&dir, "1001-1006", "--skip-existing");
    assert_eq!(log.matches("exists, skipped").count(), 4, "{log}");
    for frame in [1003, 1005] {
        assert!(log.contains(&format!("defocus.{frame}.exr (")), "frame {frame} rendered again:\n{log}");
    }
    for (frame, before) in kept {
        let m = std::fs::metadata(output(&dir, frame)).unwrap();
        assert_eq!((m.ino(), m.mtime(), m.mtime_nsec()), before, "frame {frame} was rewritten");
    }
    for (frame, bytes) in [1003, 1005].into_iter().zip(first_run) {
        assert!(std::fs::read(output(&dir, frame)).unwrap() == bytes, "frame {frame} differs on the re-run");
    }
}
