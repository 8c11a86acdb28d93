//! `plugins/oiio/lensblur-oiio`: per-layer EXRs made by oiiotool are assembled into a stack
//! with oiiotool, rendered by lensblur, and inspected/converted with oiiotool. Runs the real
//! script, oiiotool and lensblur binary. Fails, never skips, when oiiotool is missing.
mod plugin_common;

use std::path::Path;
use std::process::{Command, Output};

use plugin_common::{channel_names, fresh_dir, plugins_dir, read_rgba};

const W: usize = 64;
const H: usize = 48;
/// The in-focus front box, x0, y0, width, height (pixels).
const BOX: (usize, usize, usize, usize) = (16, 12, 32, 24);
/// 150 mm on a 36 mm sensor 64 px wide, f/1, focused at 2 m: K = 0.075 m * 266.7 px = 20 px m,
/// so the wall at 10 m has a CoC radius of 20 * |1/10 - 1/2| = 8 px, one checker square.
const CAMERA: [&str; 8] = ["--focal-length", "150", "--sensor-width", "36", "--fstop", "1", "--focus-distance", "2"];
const FRONT: [f32; 3] = [0.9, 0.1, 0.1];

fn oiiotool(args: &[&str]) {
    let status = Command::new("oiiotool")
        .args(args)
        .status()
        .unwrap_or_else(|e| panic!("cannot run oiiotool ({e}); install it with .ci/setup"));
    assert!(status.success(), "oiiotool {args:?}");
}

/// fg.exr: the red box at 2 m on an empty layer (alpha 0, Z = 1e10); bg.exr: a checker
/// wall (8 px squares) at 10 m. Both R,G,B,A,Z float, as a renderer's per-layer output.
fn make_layers(dir: &Path) {
    let (x, y, w, h) = BOX;
    let fill = format!("{w}x{h}+{x}+{y}");
    let size = format!("{W}x{H}");
    let fg = dir.join("fg.exr");
    let bg = dir.join("bg.exr");
    oiiotool(&[
        "--pattern",
        "constant:color=0,0,0,0,1e10",
        &size,
        "5",
        "--chnames",
        "R,G,B,A,Z",
        "--fill:color=0.9,0.1,0.1,1,2",
        &fill,
        "-d",
        "float",
        "-o",
        fg.to_str().unwrap(),
    ]);
    oiiotool(&[
        "--pattern",
        "checker:width=8:height=8:color1=0.8,0.8,0.8,1,10:color2=0.1,0.1,0.1,1,10",
        &size,
        "5",
        "--chnames",
        "R,G,B,A,Z",
        "-d",
        "float",
        "-o",
        bg.to_str().unwrap(),
    ]);
}

/// Runs the script with a private TMPDIR; returns its output.
fn script(dir: &Path, args: &[&str]) -> Output {
    let tmp = dir.join("tmp");
    std::fs::create_dir_all(&tmp).unwrap();
    Command::new("bash")
        .arg(plugins_dir().join("oiio/lensblur-oiio"))
        .args(["--lensblur", env!("CARGO_BIN_EXE_lensblur")])
        .args(args)
        .current_dir(dir)
        .env("TMPDIR", &tmp)
        .output()
        .unwrap()
}

fn assert_tmp_is_empty(dir: &Path) {
    let left: Vec<_> = std::fs::read_dir(dir.join("tmp")).unwrap().collect();
    assert!(left.is_empty(), "left in TMPDIR: {left:?}");
}

/// Runs the script quietly on `layers` (and `options` before them) into out.exr with CAMERA.
fn render_layers(dir: &Path, options: &[&str], layers: &[&str]) -> Output {
    let mut args = vec!["-q", "-o", "out.exr"];
    args.extend(options);
    args.extend(layers);
    args.push("--");
    args.extend(CAMERA);
    script(dir, &args)
}

/// The script must refuse `layers`, leaving no output and nothing in TMPDIR; returns stderr.
fn refusal(dir: &Path, options: &[&str], layers: &[&str]) -> String {
    let run = render_layers(dir, options, layers);
    let stderr = String::from_utf8_lossy(&run.stderr).into_owned();
    assert!(!run.status.success(), "{layers:?} accepted");
    assert!(!dir.join("out.exr").exists());
    assert_tmp_is_empty(dir);
    stderr
}

/// The script must render `layers` (the box in front of the wall, however their files are
/// named and their depth called) as make_layers' files render.
fn renders_box_over_wall(dir: &Path, options: &[&str], layers: &[&str]) {
    let run = render_layers(dir, options, layers);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let out = read_rgba(&dir.join("out.exr"));
    in_focus_box_is_untouched(&out);
    wall_is_blurred(&out, &read_rgba(&dir.join("bg.exr")));
    assert_tmp_is_empty(dir);
}

#[test]
fn oiio_script_assembles_renders_and_inspects_per_layer_exrs() {
    let dir = fresh_dir("plugin-oiio");
    make_layers(&dir);
    // Back layer first: lensblur sorts by depth, the order on the command line is free.
    let mut args =
        vec!["-o", "out.exr", "--stack", "stack.exr", "--preview", "out.png", "bg.exr", "front=fg.exr", "--"];
    args.extend(CAMERA);
    let run = script(&dir, &args);
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(run.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&run.stderr));
    assert_tmp_is_empty(&dir);
    assert!(stdout.contains("2 layer(s) front to back: front (0.0-0.0 px), bg (8.0-8.0 px)"), "{stdout}");
    assert!(stdout.contains("channel list: R, G, B, A") && stdout.contains("Stats Avg"), "{stdout}");

    let mut stack = channel_names(&dir.join("stack.exr"));
    stack.sort();
    let expected = ["bg.A", "bg.B", "bg.G", "bg.R", "bg.Z", "front.A", "front.B", "front.G", "front.R", "front.Z"];
    assert_eq!(stack, expected);
    let mut out_channels = channel_names(&dir.join("out.exr"));
    out_channels.sort();
    assert_eq!(out_channels, ["A", "B", "G", "R"], "plain RGBA output");
    assert_eq!(image::image_dimensions(dir.join("out.png")).unwrap(), (W as u32, H as u32));

    let out = read_rgba(&dir.join("out.exr"));
    in_focus_box_is_untouched(&out);
    wall_is_blurred(&out, &read_rgba(&dir.join("bg.exr")));
}

/// The box is in focus and opaque in front: every pixel keeps its colour exactly (no
/// bleeding of the blurred wall into it). 1e-5: float rounding of the composite.
fn in_focus_box_is_untouched(out: &lensblur::image::Image) {
    let (x0, y0, w, h) = BOX;
    for y in y0..y0 + h {
        for x in x0..x0 + w {
            let p = out.get(x, y);
            assert!((0..3).all(|c| (p[c] - FRONT[c]).abs() < 1e-5) && (p[3] - 1.0).abs() < 1e-5, "({x}, {y}): {p:?}");
        }
    }
}

/// Below the box (rows 40..48, at least 5 px from it), the checker's contrast falls: an 8 px
/// CoC over 8 px squares averages about two squares, so the spread of the red channel drops
/// well below half of the sharp wall's (0.35). Alpha stays 1: the wall covers the frame.
fn wall_is_blurred(out: &lensblur::image::Image, sharp: &lensblur::image::Image) {
    let spread = |img: &lensblur::image::Image| {
        let values: Vec<f32> =
            (40..H).flat_map(|y| (0..W).map(move |x| (x, y))).map(|(x, y)| img.get(x, y)[0]).collect();
        let mean = values.iter().sum::<f32>() / values.len() as f32;
        (values.iter().map(|v| (v - mean).powi(2)).sum::<f32>() / values.len() as f32).sqrt()
    };
    let (blurred, before) = (spread(out), spread(sharp));
    assert!(blurred < 0.5 * before, "std {blurred} vs sharp {before}");
    assert!(out.pixels.iter().all(|p| (p[3] - 1.0).abs() < 1e-4), "opaque result");
}

#[test]
fn oiio_script_reports_a_layer_without_depth_and_cleans_up() {
    let dir = fresh_dir("plugin-oiio-nodepth");
    make_layers(&dir);
    oiiotool(&[
        "--pattern",
        "constant:color=0.5,0.5,0.5",
        "8x8",
        "3",
        "--chnames",
        "R,G,B",
        "-o",
        dir.join("flat.exr").to_str().unwrap(),
    ]);
    let mut args = vec!["-o", "out.exr", "bg.exr", "flat.exr", "--"];
    args.extend(CAMERA);
    let run = script(&dir, &args);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success());
    assert!(stderr.contains("flat.exr: no depth channel (looked for Z or depth.Z; has: R,G,B)"), "{stderr}");
    assert!(!dir.join("out.exr").exists());
    assert_tmp_is_empty(&dir);
}

/// `--preview` with `--output-layer`: the preview is made from the named layer's colour
/// channels, found by name in the result (NAME.R or NAME.Combined.R), not from plain R,G,B
/// (which the result does not have).
#[test]
fn oiio_script_previews_the_output_layer() {
    let dir = fresh_dir("plugin-oiio-layer-preview");
    make_layers(&dir);
    let mut args = vec!["-q", "-o", "out.exr", "--preview", "out.png", "bg.exr", "front=fg.exr", "--"];
    args.extend(CAMERA);
    args.extend(["--output-layer", "Defocus"]);
    let run = script(&dir, &args);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    assert_tmp_is_empty(&dir);
    let names = channel_names(&dir.join("out.exr"));
    assert!(names.iter().all(|n| n.starts_with("Defocus.")), "only the named layer: {names:?}");
    // The in-focus box is exactly FRONT: its preview pixel is FRONT in 8-bit sRGB (+-1 level of
    // rounding), so the preview came from the colour channels, in the right order.
    let preview = image::open(dir.join("out.png")).unwrap().to_rgb8();
    let (x0, y0, w, h) = BOX;
    let got = preview.get_pixel((x0 + w / 2) as u32, (y0 + h / 2) as u32).0;
    let want = FRONT.map(|c| (lensblur::stack::ldr::linear_to_srgb(c) * 255.0).round() as i32);
    assert!((0..3).all(|c| (got[c] as i32 - want[c]).abs() <= 1), "preview {got:?} vs {want:?}");
}

/// Two layers of one name (given twice, or two files with one base name) are refused before
/// anything is assembled, naming both files.
#[test]
fn oiio_script_refuses_duplicate_layer_names() {
    let dir = fresh_dir("plugin-oiio-duplicates");
    make_layers(&dir);
    std::fs::create_dir_all(dir.join("other")).unwrap();
    std::fs::copy(dir.join("bg.exr"), dir.join("other/bg.exr")).unwrap();
    for layers in [["a=fg.exr", "a=bg.exr"], ["bg.exr", "other/bg.exr"]] {
        let mut args = vec!["-o", "out.exr", layers[0], layers[1], "--"];
        args.extend(CAMERA);
        let run = script(&dir, &args);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(!run.status.success(), "{layers:?} accepted");
        let file = layers[1].split('=').next_back().unwrap();
        assert!(stderr.contains(&format!("is used by {} and {file}", layers[0].split('=').next_back().unwrap())), "{stderr}");
        assert!(!dir.join("out.exr").exists());
        assert_tmp_is_empty(&dir);
    }
}

/// `--depth-channel NAME`: per-layer files whose depth is called `depth` render exactly as
/// with Z (the in-focus box untouched, the wall blurred); without the flag the script names
/// the depth channels it looked for and the flag.
#[test]
fn oiio_script_reads_the_depth_channel_it_is_told() {
    let dir = fresh_dir("plugin-oiio-depth-channel");
    make_layers(&dir);
    for name in ["fg", "bg"] {
        let (from, to) = (dir.join(format!("{name}.exr")), dir.join(format!("{name}_d.exr")));
        oiiotool(&[from.to_str().unwrap(), "--chnames", "R,G,B,A,depth", "-o", to.to_str().unwrap()]);
    }
    renders_box_over_wall(&dir, &["--depth-channel", "depth"], &["bg=bg_d.exr", "front=fg_d.exr"]);
    std::fs::remove_file(dir.join("out.exr")).unwrap();
    let stderr = refusal(&dir, &[], &["bg=bg_d.exr"]);
    assert!(stderr.contains("bg_d.exr: no depth channel (looked for Z or depth.Z; has: R,G,B,A,depth)"), "{stderr}");
    assert!(stderr.contains("--depth-channel"), "{stderr}");
}

/// A layer named by a dotted file name is refused with the NAME=FILE spelling to use; files
/// that call their depth Z and depth.Z mix under the default --depth-channel, and render as
/// with Z alone.
#[test]
fn oiio_script_names_dotted_files_and_mixes_depth_channel_names() {
    let dir = fresh_dir("plugin-oiio-dotted");
    make_layers(&dir);
    let (fg, dotted) = (dir.join("fg.exr"), dir.join("fg.v2.exr"));
    oiiotool(&[fg.to_str().unwrap(), "--chnames", "R,G,B,A,depth.Z", "-o", dotted.to_str().unwrap()]);
    let stderr = refusal(&dir, &[], &["bg.exr", "fg.v2.exr"]);
    assert!(
        stderr.contains("layer name 'fg.v2' (from the file name fg.v2.exr)") && stderr.contains("e.g. fg_v2=fg.v2.exr"),
        "{stderr}"
    );
    renders_box_over_wall(&dir, &[], &["bg.exr", "fg_v2=fg.v2.exr"]);
}

/// oiiotool describes and loads only the first subimage of a file: a layer file with several
/// is refused, naming how to split it, rather than half read.
#[test]
fn oiio_script_refuses_layer_files_with_several_subimages() {
    let dir = fresh_dir("plugin-oiio-subimages");
    make_layers(&dir);
    let (fg, bg) = (dir.join("fg.exr"), dir.join("bg.exr"));
    let both = dir.join("both.exr");
    oiiotool(&[fg.to_str().unwrap(), bg.to_str().unwrap(), "--siappend", "-o", both.to_str().unwrap()]);
    let stderr = refusal(&dir, &[], &["both.exr"]);
    assert!(stderr.contains("both.exr: has 2 subimages") && stderr.contains("--subimage N"), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "one message: {stderr}");
}

/// macOS ships bash 3.2: the script must not use what came with bash 4 (associative arrays,
/// mapfile/readarray, case-changing expansions, `&>>`, `|&`) nor expand an array that may be
/// empty as "${a[@]}" under `set -u` (unbound before bash 4.4).
#[test]
fn oiio_script_uses_only_bash_3_2() {
    let text = std::fs::read_to_string(plugins_dir().join("oiio/lensblur-oiio")).unwrap();
    let code: Vec<&str> = text.lines().filter(|l| !l.trim_start().starts_with('#')).collect();
    for feature in ["declare -A", "local -A", "mapfile", "readarray", ",,}", "^^}", "&>>", "|&", "coproc"] {
        let found: Vec<&&str> = code.iter().filter(|l| l.contains(feature)).collect();
        assert!(found.is_empty(), "bash 4 feature '{feature}': {found:?}");
    }
    // render_flags is empty when nothing follows `--`.
    assert!(!code.iter().any(|l| l.contains("\"${render_flags[@]}\"") && !l.contains("${render_flags[@]+")), "unguarded empty-array expansion");
}
