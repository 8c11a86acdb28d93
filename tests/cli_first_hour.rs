//! What a new user trips over in the first hour (issue 27), through the real binary: output
//! formats follow the extension, unit-less depth with a physical camera is named, `info` takes
//! a PNG and its depth, errors say each thing once, help text names things consistently,
//! benchmarks write to the user cache, reports say where the camera came from, and fit-depth
//! counts and estimates its iterations.
mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use lensblur::camera::PhysicalCamera;
use lensblur::image::Image;
use lensblur::stack::{write_image, write_stack, Layer, LayerStack, StackWriteOptions, WriteOptions};

/// A tiny sensor so a 32 px wide frame gets a few pixels of blur.
const CAMERA: PhysicalCamera =
    PhysicalCamera { focal_length_mm: 50.0, sensor_width_mm: 3.0, fstop: 1.4, focus_distance: 4.0 };
const W: usize = 32;
const H: usize = 24;

fn run(dir: &Path, args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_lensblur"));
    command.args(args).current_dir(dir).env("LENSBLUR_VALIDATION", "1").env_remove("LENSBLUR_DEVICE");
    for (key, value) in env {
        command.env(key, value);
    }
    command.output().unwrap()
}

/// stdout and stderr of a command that must succeed.
fn ok(dir: &Path, args: &[&str], env: &[(&str, &str)]) -> (String, String) {
    let output = run(dir, args, env);
    let (stdout, stderr) =
        (String::from_utf8_lossy(&output.stdout).into_owned(), String::from_utf8_lossy(&output.stderr).into_owned());
    assert!(output.status.success(), "{args:?} failed: {stderr}");
    (stdout, stderr)
}

/// stderr of a command that must fail.
fn refused(dir: &Path, args: &[&str]) -> String {
    let output = run(dir, args, &[]);
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(!output.status.success(), "{args:?} succeeded");
    assert!(!stderr.contains("panicked"), "{args:?} panicked: {stderr}");
    stderr
}

/// A subject at 2 m over a wall at 4 m (in focus), the camera stamped in the header.
fn stamped_stack(dir: &Path) -> PathBuf {
    let subject = Image::from_fn(W, H, |x, y| if (8..20).contains(&x) && (6..18).contains(&y) { [0.9, 0.2, 0.1, 1.0] } else { [0.0; 4] });
    let wall = Image::from_fn(W, H, |x, y| if (x / 4 + y / 4) % 2 == 0 { [0.8, 0.8, 0.5, 1.0] } else { [0.1, 0.1, 0.5, 1.0] });
    let layers = vec![
        Layer { name: "subject".into(), rgba: subject, disparity: vec![0.5; W * H] },
        Layer { name: "wall".into(), rgba: wall, disparity: vec![0.25; W * H] },
    ];
    let path = dir.join("shot.exr");
    let stack = LayerStack::new(W, H, layers).unwrap();
    write_stack(&path, &stack, &StackWriteOptions { camera: Some(CAMERA), ..StackWriteOptions::default() }).unwrap();
    path
}

/// An sRGB photo and a 16-bit grey depth image (near on the left), as phones and depth
/// estimators write them.
fn photo_and_depth(dir: &Path) -> (PathBuf, PathBuf) {
    let (w, h) = (W as u32, H as u32);
    let photo = image::RgbImage::from_fn(w, h, |x, y| image::Rgb([(x * 8) as u8, (y * 10) as u8, 128]));
    let depth = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(w, h, |x, _| image::Luma([if x < 16 { 60000 } else { 9000 }]));
    let (photo_path, depth_path) = (dir.join("photo.png"), dir.join("depth.png"));
    photo.save(&photo_path).unwrap();
    depth.save(&depth_path).unwrap();
    (photo_path, depth_path)
}

fn magic(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap()[..4].to_vec()
}

const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];
const PNG_MAGIC: [u8; 4] = [0x89, b'P', b'N', b'G'];
const JPEG_MAGIC: [u8; 3] = [0xff, 0xd8, 0xff];

#[test]
fn the_output_extension_picks_the_format_and_others_are_refused() {
    let dir = common::temp_dir("first-hour", "formats");
    let shot = stamped_stack(&dir);
    let shot = shot.to_str().unwrap();
    for (name, flag_message) in [("out.tif", "'.tif' is not a format -o writes"), ("out.noext", "'.noext' is not a format -o writes"), ("out", "-o has no extension")] {
        let stderr = refused(&dir, &["render", shot, "-o", name]);
        for needle in [name, flag_message, ".exr (linear float)", ".png (8-bit sRGB)", ".jpg/.jpeg", "nothing was rendered"] {
            assert!(stderr.contains(needle), "-o {name}: '{needle}' missing: {stderr}");
        }
        assert!(!dir.join(name).exists(), "-o {name} was written");
    }
    let stderr = refused(&dir, &["render", shot, "-o", "ok.exr", "--preview", "a.tif"]);
    assert!(stderr.contains("a.tif: '.tif' is not a format --preview writes") && !stderr.contains(".exr"), "{stderr}");
    assert!(!dir.join("ok.exr").exists(), "nothing is rendered when the preview's name is refused");
    let stderr = refused(&dir, &["bench", "quality", "--quick", "--sheet", "sheet.jpg"]);
    assert!(stderr.contains("'.jpg' is not a format --sheet writes") && stderr.contains("use .png (8-bit sRGB);"), "{stderr}");
    let stderr = refused(&dir, &["grad", shot, "--grad-output", shot, "-o", "grads.png"]);
    assert!(stderr.contains("'.png' is not a format -o writes") && stderr.contains("use .exr (linear float);"), "{stderr}");

    // Each accepted name gets the bytes its extension names, previews included.
    ok(&dir, &["render", shot, "-o", "a.exr", "--preview", "a.jpg"], &[]);
    ok(&dir, &["render", shot, "-o", "b.PNG", "--preview", "b.jpeg"], &[]);
    ok(&dir, &["render", shot, "-o", "c.jpg", "--preview", "c.png"], &[]);
    assert_eq!(magic(&dir.join("a.exr")), EXR_MAGIC);
    assert_eq!(magic(&dir.join("b.PNG")), PNG_MAGIC);
    assert_eq!(magic(&dir.join("c.png")), PNG_MAGIC);
    for jpeg in ["a.jpg", "b.jpeg", "c.jpg"] {
        assert_eq!(magic(&dir.join(jpeg))[..3], JPEG_MAGIC, "{jpeg}");
    }
}

#[test]
fn a_physical_camera_on_unitless_depth_is_named_with_the_depth_kind_to_give() {
    let dir = common::temp_dir("first-hour", "unitless");
    let (photo, depth) = photo_and_depth(&dir);
    let (photo, depth) = (photo.to_str().unwrap(), depth.to_str().unwrap());
    let physical = ["--focal-length", "50", "--fstop", "2", "--focus-distance", "3"];
    let base = ["render", photo, "--depth", depth, "-o", "out.png"];
    let (_, stderr) = ok(&dir, &[&base[..], &physical[..]].concat(), &[]);
    for needle in ["warning", "normalised disparity", "no scene scale", "--depth-kind z", "--depth-kind inverse-z", "--blur K"] {
        assert!(stderr.contains(needle), "'{needle}' missing: {stderr}");
    }
    // Depth with a scale, or the normalised model, is what the warning asks for: no warning.
    let (_, stderr) = ok(&dir, &[&base[..], &physical[..], &["--depth-kind", "inverse-z"]].concat(), &[]);
    assert!(!stderr.contains("warning"), "{stderr}");
    let (_, stderr) = ok(&dir, &[&base[..], &["--blur", "6", "--focus-disparity", "0.5"]].concat(), &[]);
    assert!(!stderr.contains("warning"), "{stderr}");
}

#[test]
fn info_describes_a_png_and_takes_its_depth_image() {
    let dir = common::temp_dir("first-hour", "info");
    let (photo, depth) = photo_and_depth(&dir);
    let (photo, depth) = (photo.to_str().unwrap(), depth.to_str().unwrap());
    let (stdout, _) = ok(&dir, &["info", photo], &[]);
    assert!(stdout.contains(&format!("PNG/JPEG image {W}x{H}")) && stdout.contains("--depth DEPTH.png"), "{stdout}");
    let (stdout, _) = ok(&dir, &["info", photo, "--depth", depth, "--json"], &[]);
    let report: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let range = &report["disparity_range"];
    // 16-bit samples 9000 and 60000 read as normalised disparity.
    assert!((range[0].as_f64().unwrap() - 9000.0 / 65535.0).abs() < 1e-4, "{report}");
    assert!((range[1].as_f64().unwrap() - 60000.0 / 65535.0).abs() < 1e-4, "{report}");
    assert_eq!(report["depth_kind"], "disparity");
    // A non-EXR, non-PNG file: the advice names what lensblur reads, valid for every command.
    std::fs::write(dir.join("notes.txt"), "not an image").unwrap();
    let stderr = refused(&dir, &["info", "notes.txt"]);
    assert!(stderr.contains("not an OpenEXR file") && stderr.contains("PNG/JPEG images with their depth image"), "{stderr}");
}

#[test]
fn errors_say_the_file_and_the_cause_once() {
    let dir = common::temp_dir("first-hour", "errors");
    let shot = stamped_stack(&dir);
    let stderr = refused(&dir, &["render", "nofile.exr", "-o", "out.exr"]);
    assert_eq!(stderr, "lensblur: error: nofile.exr: No such file or directory (os error 2)\n");
    let stderr = refused(&dir, &["info", "nofile.exr"]);
    assert_eq!(stderr, "lensblur: error: nofile.exr: No such file or directory (os error 2)\n");
    let stderr = refused(&dir, &["render", shot.to_str().unwrap(), "--layers", "branch", "-o", "out.exr"]);
    assert_eq!(
        stderr,
        format!("lensblur: error: {}: no layer matches 'branch'; available layers: subject, wall\n", shot.display())
    );
    let stderr = refused(&dir, &["grad", shot.to_str().unwrap(), "--grad-output", "missing.exr", "-o", "g.exr"]);
    assert_eq!(stderr, "lensblur: error: --grad-output: missing.exr: No such file or directory (os error 2)\n");
}

#[test]
fn grad_names_each_of_its_files_once_and_the_same_everywhere() {
    let dir = common::temp_dir("first-hour", "grad-help");
    let (help, _) = ok(&dir, &["grad", "--help"], &[]);
    assert!(
        help.contains("Usage: lensblur grad [OPTIONS] --grad-output <DL_DB.exr> --output <GRADS.exr> <STACK.exr>"),
        "{help}"
    );
    // One name per file: the stack, the incoming gradient dL/dB (an input) and the gradients out.
    for other in ["<INPUT>", "<OUTPUT>", "<G.exr>", "G (--grad-output)", "FILE's", "g.exr", "OUT"] {
        assert!(!help.contains(other), "grad --help still says '{other}': {help}");
    }
    assert!(help.contains("--grad-output <DL_DB.exr>  Input:"), "{help}");
}

/// The flags listed under `heading` in a `--help` text (up to the next heading).
fn flags_under<'a>(help: &'a str, heading: &str) -> Vec<&'a str> {
    let mut lines = help.lines().skip_while(|l| *l != heading).skip(1);
    let section = lines.by_ref().take_while(|l| l.is_empty() || l.starts_with(' '));
    section.filter_map(|l| l.trim_start().split([' ', ',']).find(|w| w.starts_with("--"))).collect()
}

#[test]
fn help_headings_hold_the_flags_they_name() {
    let dir = common::temp_dir("first-hour", "headings");
    let (render, _) = ok(&dir, &["render", "--help"], &[]);
    assert!(flags_under(&render, "Method:").contains(&"--method"), "{render}");
    assert!(!flags_under(&render, "Output:").contains(&"--method"), "{render}");
    let (perf, _) = ok(&dir, &["bench", "perf", "--help"], &[]);
    assert!(flags_under(&perf, "Performance:").contains(&"--groups"), "{perf}");
}

/// Every command's `--help` ends with examples of that command (the kit's hidden ones too):
/// what a new user copies first.
#[test]
fn every_command_shows_examples_of_itself() {
    let dir = common::temp_dir("first-hour", "examples");
    let (top, _) = ok(&dir, &["--help"], &[]);
    let listed: Vec<&str> = top
        .lines()
        .skip_while(|l| *l != "Commands:")
        .skip(1)
        .take_while(|l| !l.is_empty())
        .filter_map(|l| l.split_whitespace().next())
        .filter(|&c| c != "help")
        .collect();
    assert!(listed.len() >= 10 && listed.contains(&"render") && listed.contains(&"info"), "{top}");
    for command in listed.iter().copied().chain(["self-check", "gpu-timings"]) {
        let (help, _) = ok(&dir, &[command, "--help"], &[]);
        let examples: Vec<&str> = help.lines().skip_while(|l| *l != "Examples:").skip(1).take_while(|l| l.starts_with("  ")).collect();
        assert!(!examples.is_empty(), "`lensblur {command} --help` shows no examples:\n{help}");
        let own = format!("lensblur {command}");
        assert!(examples.iter().any(|e| e.contains(&own)), "`lensblur {command} --help`: no example runs `{own}`:\n{help}");
    }
}

#[test]
fn benchmarks_write_to_the_user_cache_not_the_current_folder() {
    let dir = common::temp_dir("first-hour", "bench-dirs");
    let cache = dir.join("cache");
    let cache_env = [("XDG_CACHE_HOME", cache.to_str().unwrap())];
    let (bench, _) = ok(&dir, &["bench", "quality", "--help"], &cache_env);
    let expected = |name: &str| format!("[default: {}]", cache.join("lensblur").join(name).display());
    assert!(bench.contains(&expected("gt-cache")), "{bench}");
    let (perf, _) = ok(&dir, &["bench", "perf", "--help"], &cache_env);
    assert!(perf.contains(&expected("perf")), "{perf}");
    assert!(!bench.contains("target/") && !perf.contains("target/"), "no default under the current folder");

    // A real (tiny, one CPU method) benchmark run: the ground truth lands in the cache,
    // nothing in the folder it was started from.
    let work = dir.join("work");
    std::fs::create_dir(&work).unwrap();
    ok(&work, &["bench", "quality", "--quick", "--scenes", "small-coc", "--methods", "oracle"], &cache_env);
    assert_eq!(std::fs::read_dir(&work).unwrap().count(), 0, "bench wrote into the current folder");
    let cached = std::fs::read_dir(cache.join("lensblur").join("gt-cache")).map(|d| d.count()).unwrap_or(0);
    assert!(cached > 0, "no ground truth cached under $XDG_CACHE_HOME/lensblur/gt-cache");
}

#[test]
fn reports_say_where_the_camera_came_from_and_print_plain_numbers() {
    let dir = common::temp_dir("first-hour", "report");
    let shot = stamped_stack(&dir);
    let shot = shot.to_str().unwrap();
    let (stdout, _) = ok(&dir, &["render", shot, "-o", "out.exr"], &[]);
    let camera_line = stdout.lines().nth(1).unwrap_or_default();
    assert_eq!(
        camera_line,
        format!(
            "camera 50 mm, f/1.4, focus distance 4, sensor width 3 mm, aperture disk (focal-length, fstop, \
             focus-distance, sensor-width from {shot}'s header); scene unit m"
        )
    );
    let (stdout, _) = ok(&dir, &["render", shot, "-o", "out.exr", "--fstop", "2", "--aperture", "polygon:6:rotation=15", "--json"], &[]);
    let report: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(report["aperture"], "polygon:6:rotation=15");
    assert_eq!(report["camera_from_header"], serde_json::json!(["focal-length", "focus-distance", "sensor-width"]));
    // f32 values print as written (1.4, not 1.399999976158142); timings to the microsecond.
    assert!(stdout.contains("\"fstop\": 2.0") || stdout.contains("\"fstop\": 2"), "{stdout}");
    for (name, value) in report["timings_ms"].as_object().unwrap() {
        let ms = value.as_f64().unwrap();
        assert!(value.to_string().len() <= 16, "timing {name} = {value} prints binary noise");
        assert!(((ms * 1e3).round() - ms * 1e3).abs() < 1e-6, "timing {name} = {value} is not whole microseconds");
    }
    let (stdout, _) = ok(&dir, &["render", shot, "-o", "out.exr", "--json"], &[]);
    assert!(stdout.contains("\"fstop\": 1.4,"), "{stdout}");
    let unclamped: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    // The reported CoC is the one rendered: --max-blur's clamp shows (the README's character
    // command printed the unclamped 37.7 px under --max-blur 12).
    let (stdout, _) = ok(&dir, &["render", shot, "-o", "out.exr", "--json", "--max-blur", "1"], &[]);
    let clamped: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert!(unclamped["coc_range_px"][1].as_f64().unwrap() > 2.0, "{unclamped}");
    assert!(clamped["coc_range_px"][1].as_f64().unwrap() <= 1.0 + 1e-4, "{clamped}");
}

#[test]
fn fit_depth_counts_its_steps_and_says_how_long_it_will_take() {
    let dir = common::temp_dir("first-hour", "fit-eta");
    let shot = stamped_stack(&dir);
    let target = dir.join("target.exr");
    let image = Image::from_fn(W, H, |x, y| [0.1 + 0.02 * x as f32, 0.1 + 0.02 * y as f32, 0.4, 1.0]);
    write_image(&target, &image, &WriteOptions::default()).unwrap();
    let args = ["fit-depth", shot.to_str().unwrap(), "--target", target.to_str().unwrap(), "-o", "fitted.exr", "--iters", "3"];
    let (stdout, stderr) = ok(&dir, &args, &[]);
    assert!(stdout.contains("in 3 iterations"), "{stdout}");
    let eta: Vec<&str> = stderr.lines().filter(|l| l.starts_with("fitting depth: 3 iterations at about")).collect();
    assert_eq!(eta.len(), 1, "one estimate line: {stderr}");
    assert!(eta[0].contains("s to go") && eta[0].contains("--iters N"), "{stderr}");
    // --json keeps stderr for errors: no estimate there.
    let (_, stderr) = ok(&dir, &[&args[..], &["--json"]].concat(), &[]);
    assert!(!stderr.contains("fitting depth"), "{stderr}");

    // The bar, drawn only on a terminal: under `script` (a pseudo-terminal) every frame counts
    // steps out of 3 (it showed 1/4 .. 4/4), starting at 0/3, with an ETA.
    let command = format!("{} {}", env!("CARGO_BIN_EXE_lensblur"), args.join(" "));
    let output = Command::new("script")
        .args(["-qec", &command, "/dev/null"])
        .current_dir(&dir)
        .env("LENSBLUR_VALIDATION", "1")
        .output()
        .expect("script (util-linux) runs the command on a pseudo-terminal");
    let terminal = String::from_utf8_lossy(&output.stdout).replace('\r', "\n");
    assert!(output.status.success(), "{terminal}");
    let frames: Vec<&str> = terminal.lines().filter_map(|l| l.split("iteration ").nth(1)?.split(' ').next()).collect();
    assert!(frames.contains(&"0/3"), "{terminal}");
    assert!(frames.iter().all(|f| matches!(*f, "0/3" | "1/3" | "2/3" | "3/3")), "{frames:?}");
    assert!(terminal.contains("ETA"), "{terminal}");
}
