//! `lensblur render` (and `grad`, `fit-depth`) on bad input, through the real binary: every
//! case must exit non-zero with a message naming the file (and layer/channel where there is
//! one) and what to do, without panicking, and must leave no output and no temporary file
//! behind.
mod common;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use exr::prelude::{AnyChannel, AnyChannels, Encoding, FlatSamples, LayerAttributes, WritableImage};
use lensblur::camera::PhysicalCamera;
use lensblur::image::Image;
use lensblur::render::Method;
use lensblur::stack::{write_image, write_stack, Layer, LayerStack, StackWriteOptions, WriteOptions};

const CAMERA: PhysicalCamera =
    PhysicalCamera { focal_length_mm: 50.0, sensor_width_mm: 3.0, fstop: 1.0, focus_distance: 4.0 };
const W: usize = 16;
const H: usize = 12;


fn listing(dir: &Path) -> BTreeSet<String> {
    std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect()
}

fn lensblur(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lensblur")).args(args).env("LENSBLUR_VALIDATION", "1").output().unwrap()
}

/// Renders `input` into `dir/out.exr` with `extra` flags and checks the refusal: non-zero
/// exit, no panic, every `needle` in the message, and the directory exactly as before.
fn refused(dir: &Path, input: &Path, extra: &[&str], needles: &[&str]) -> String {
    let before = listing(dir);
    let out = dir.join("out.exr");
    let mut args = vec!["render", input.to_str().unwrap(), "-o", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    let output = lensblur(&args);
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(!output.status.success(), "{args:?} succeeded; stderr: {stderr}");
    assert!(!stderr.contains("panicked"), "{args:?} panicked: {stderr}");
    for needle in needles {
        assert!(stderr.contains(needle), "{args:?}: message lacks '{needle}': {stderr}");
    }
    assert!(!out.exists(), "{args:?} left an output");
    assert_eq!(listing(dir), before, "{args:?} left a file behind (temporary?)");
    stderr
}

fn rendered(dir: &Path, input: &Path, extra: &[&str]) -> String {
    let out = dir.join("ok.exr");
    let mut args = vec!["render", input.to_str().unwrap(), "-o", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    let output = lensblur(&args);
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(output.status.success(), "{args:?} failed: {stderr}");
    assert!(out.exists());
    std::fs::remove_file(&out).unwrap();
    stderr
}

fn layer(name: &str, disparity: f32, colour: [f32; 4]) -> Layer {
    Layer { name: name.into(), rgba: Image::from_fn(W, H, |_, _| colour), disparity: vec![disparity; W * H] }
}

/// A valid two-layer stack with the camera in its header (renders without flags).
fn valid_stack(dir: &Path) -> PathBuf {
    let path = dir.join("shot.exr");
    let stack = LayerStack::new(W, H, vec![layer("fg", 0.5, [0.9, 0.2, 0.1, 1.0]), layer("bg", 0.25, [0.1, 0.5, 0.8, 1.0])])
        .unwrap();
    write_stack(&path, &stack, &StackWriteOptions { camera: Some(CAMERA), ..StackWriteOptions::default() }).unwrap();
    path
}

fn exr_layer(name: Option<&str>, size: (usize, usize), channels: Vec<(&str, Vec<f32>)>) -> exr::prelude::Layer<AnyChannels<FlatSamples>> {
    let list: Vec<AnyChannel<FlatSamples>> =
        channels.into_iter().map(|(n, v)| AnyChannel::new(n, FlatSamples::F32(v))).collect();
    let attributes = name.map(LayerAttributes::named).unwrap_or_default();
    exr::prelude::Layer::new(size, attributes, Encoding::SMALL_LOSSLESS, AnyChannels::sort(list.into()))
}

/// Writes a single-part EXR with exactly these float channels (W x H).
fn write_channels(path: &Path, channels: Vec<(&str, Vec<f32>)>) {
    exr::prelude::Image::from_layer(exr_layer(None, (W, H), channels)).write().to_file(path).unwrap();
}

/// A plain R,G,B,A,Z image, opaque grey, with `edit` applied to the named channel's samples.
fn plain_with(path: &Path, channel: &str, edit: impl Fn(&mut Vec<f32>)) {
    let mut channels: Vec<(&str, Vec<f32>)> =
        ["R", "G", "B", "A"].into_iter().map(|n| (n, vec![if n == "A" { 1.0 } else { 0.5 }; W * H])).collect();
    channels.push(("Z", vec![3.0; W * H]));
    for (name, values) in &mut channels {
        if *name == channel {
            edit(values);
        }
    }
    write_channels(path, channels);
}

const BLUR: [&str; 4] = ["--blur", "8", "--focus-disparity", "0.3"];

#[test]
fn missing_empty_truncated_and_garbage_files_are_refused() {
    let dir = common::temp_dir("bad-input", "files");
    refused(&dir, &dir.join("nope.exr"), &[], &["nope.exr", "No such file"]);
    let empty = dir.join("empty.exr");
    std::fs::write(&empty, b"").unwrap();
    refused(&dir, &empty, &[], &["empty.exr", "not an OpenEXR file"]);
    let garbage = dir.join("garbage.exr");
    std::fs::write(&garbage, (0..4096u32).map(|i| (i.wrapping_mul(2654435761) >> 13) as u8).collect::<Vec<_>>()).unwrap();
    refused(&dir, &garbage, &[], &["garbage.exr", "not an OpenEXR file"]);
    let valid = std::fs::read(valid_stack(&dir)).unwrap();
    // Magic number, then noise: the header parser must reject it, not panic.
    let mut noisy = valid[..4].to_vec();
    noisy.extend((0..2048u32).map(|i| (i.wrapping_mul(40503) >> 7) as u8));
    let noise = dir.join("noise.exr");
    std::fs::write(&noise, noisy).unwrap();
    refused(&dir, &noise, &[], &["noise.exr", "EXR"]);
    for (name, len) in [("cut-header.exr", 40), ("cut-offsets.exr", valid.len() / 3), ("cut-pixels.exr", valid.len() - 7)] {
        let cut = dir.join(name);
        std::fs::write(&cut, &valid[..len]).unwrap();
        refused(&dir, &cut, &[], &[name, "EXR"]);
    }
}

#[test]
fn a_huge_header_is_refused_before_allocating_and_the_budget_is_a_flag() {
    let dir = common::temp_dir("bad-input", "huge");
    let valid = valid_stack(&dir);
    // 100000 x 100000 pixels (40 GB of RGBA): reading it would abort on allocation.
    let huge = dir.join("huge.exr");
    std::fs::write(&huge, patch_box(&std::fs::read(&valid).unwrap(), b"displayWindow\0box2i\0", 99_999, 99_999, 0)).unwrap();
    refused(&dir, &huge, &[], &["huge.exr", "100000x100000", "--max-pixels"]);
    refused(&dir, &valid, &["--max-pixels", "100"], &["shot.exr", "16x12", "--max-pixels"]);
    rendered(&dir, &valid, &["--max-pixels", "192", "--method", "oracle"]);
}

/// Sets xMax, yMax of the `nth` box2i attribute called `name` (a byte-level header edit).
fn patch_box(bytes: &[u8], name: &[u8], x_max: i32, y_max: i32, nth: usize) -> Vec<u8> {
    let at = bytes.windows(name.len()).enumerate().filter(|(_, w)| *w == name).nth(nth).unwrap().0;
    let values = at + name.len() + 4; // the attribute size (16), then xMin, yMin, xMax, yMax
    let mut out = bytes.to_vec();
    out[values + 8..values + 12].copy_from_slice(&x_max.to_le_bytes());
    out[values + 12..values + 16].copy_from_slice(&y_max.to_le_bytes());
    out
}

/// Deep files render (tests/deep_input.rs); one whose header lacks what OpenEXR requires of a
/// deep part is refused before any pixel is read, naming the file and the missing attribute.
#[test]
fn malformed_deep_exr_is_refused_naming_what_is_missing() {
    let dir = common::temp_dir("bad-input", "deep");
    let deep = dir.join("deep.exr");
    std::fs::write(&deep, deep_scanline_file()).unwrap();
    refused(&dir, &deep, &[], &["deep.exr", "chunkCount", "deep"]);
}

/// `grad` and `fit-depth` write their result channel by channel into an EXR laid out like the
/// input: a deep EXR (the Weta sample) or a PNG is refused before it is read, saying why and
/// what to give instead, and nothing is written.
#[test]
fn grad_and_fit_depth_refuse_deep_and_png_inputs_saying_what_to_give_instead() {
    let dir = common::temp_dir("bad-input", "channel-stack");
    let deep = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join("tests/data/openexr-deep/Balls.exr");
    let png = dir.join("photo.png");
    image::RgbImage::new(W as u32, H as u32).save(&png).unwrap();
    let target = valid_stack(&dir);
    let before = listing(&dir);
    let camera = ["--focal-length", "50", "--fstop", "2", "--focus-distance", "4"];
    for (input, kind) in [(deep.as_path(), "is a deep EXR"), (png.as_path(), "is a PNG/JPEG image")] {
        for (command, with) in [("grad", "--grad-output"), ("fit-depth", "--target")] {
            let out = dir.join("out.exr");
            let mut args = vec![command, input.to_str().unwrap(), with, target.to_str().unwrap(), "-o", out.to_str().unwrap()];
            args.extend(camera);
            let output = lensblur(&args);
            let stderr = String::from_utf8_lossy(&output.stderr);
            assert!(!output.status.success(), "{args:?} succeeded");
            for needle in [input.to_str().unwrap(), kind, "channel by channel", "layer.R,G,B,A,Z"] {
                assert!(stderr.contains(needle), "{args:?}: message lacks '{needle}': {stderr}");
            }
            assert_eq!(listing(&dir), before, "{args:?} left a file behind");
        }
    }
}

/// A hand-made single-part deep scanline file: its header without the `chunkCount` attribute
/// OpenEXR 2 requires of deep parts, an offset table, no chunks.
fn deep_scanline_file() -> Vec<u8> {
    fn attribute(out: &mut Vec<u8>, name: &str, kind: &str, value: &[u8]) {
        for text in [name, kind] {
            out.extend_from_slice(text.as_bytes());
            out.push(0);
        }
        out.extend_from_slice(&(value.len() as i32).to_le_bytes());
        out.extend_from_slice(value);
    }
    let ints = |v: &[i32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let floats = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let mut out = vec![0x76, 0x2f, 0x31, 0x01, 2, 0x08, 0, 0]; // version 2, "non-image" (deep) bit
    let mut channels = Vec::new();
    for name in ["A", "B", "G", "R", "Z"] {
        channels.extend_from_slice(name.as_bytes());
        channels.extend_from_slice(&[0]);
        channels.extend_from_slice(&ints(&[2, 0, 1, 1])); // float, pLinear + reserved, sampling 1x1
    }
    channels.push(0);
    attribute(&mut out, "channels", "chlist", &channels);
    attribute(&mut out, "compression", "compression", &[0]);
    attribute(&mut out, "dataWindow", "box2i", &ints(&[0, 0, 3, 3]));
    attribute(&mut out, "displayWindow", "box2i", &ints(&[0, 0, 3, 3]));
    attribute(&mut out, "lineOrder", "lineOrder", &[0]);
    attribute(&mut out, "pixelAspectRatio", "float", &floats(&[1.0]));
    attribute(&mut out, "screenWindowCenter", "v2f", &floats(&[0.0, 0.0]));
    attribute(&mut out, "screenWindowWidth", "float", &floats(&[1.0]));
    attribute(&mut out, "type", "string", b"deepscanline");
    attribute(&mut out, "version", "int", &ints(&[1]));
    attribute(&mut out, "maxSamplesPerPixel", "int", &ints(&[4]));
    out.push(0);
    out.extend(std::iter::repeat(0u8).take(8 * 4));
    out
}

#[test]
fn missing_channels_and_unknown_layers_name_what_exists() {
    let dir = common::temp_dir("bad-input", "channels");
    let no_depth = dir.join("no-depth.exr");
    write_image(&no_depth, &Image::from_fn(W, H, |_, _| [0.5, 0.5, 0.5, 1.0]), &WriteOptions::default()).unwrap();
    refused(&dir, &no_depth, &BLUR, &["no-depth.exr", "depth", "R, G, B, A", "Z channel"]);
    let no_colour = dir.join("no-colour.exr");
    let opaque = vec![1.0; W * H];
    write_channels(
        &no_colour,
        vec![("fg.Z", vec![2.0; W * H]), ("bg.R", opaque.clone()), ("bg.G", opaque.clone()), ("bg.B", opaque.clone()), ("bg.Z", vec![5.0; W * H])],
    );
    let mut flags = BLUR.to_vec();
    flags.extend(["--layers", "fg,bg"]);
    refused(&dir, &no_colour, &flags, &["no-colour.exr", "layer 'fg'", "colour (R, G, B)", "fg.Z"]);
    let valid = valid_stack(&dir);
    refused(&dir, &valid, &["--layers", "fg,nope"], &["shot.exr", "'nope'", "available layers: bg, fg"]);
}

#[test]
fn non_finite_colour_or_alpha_is_named_and_can_be_replaced() {
    let dir = common::temp_dir("bad-input", "nonfinite");
    let nan = dir.join("nan.exr");
    plain_with(&nan, "G", |v| v[..3].fill(f32::NAN));
    refused(&dir, &nan, &BLUR, &["nan.exr", "channel 'G'", "3 NaN/Inf", "--replace-nonfinite"]);
    let inf = dir.join("inf-alpha.exr");
    plain_with(&inf, "A", |v| v[5] = f32::INFINITY);
    refused(&dir, &inf, &BLUR, &["inf-alpha.exr", "channel 'A'", "1 NaN/Inf"]);
    let mut flags = BLUR.to_vec();
    flags.extend(["--replace-nonfinite", "--method", "oracle"]);
    let warning = rendered(&dir, &nan, &flags);
    assert!(warning.contains("warning") && warning.contains("'G'") && warning.contains("3"), "{warning}");
}

#[test]
fn bad_depth_is_refused_but_far_sentinels_render() {
    let dir = common::temp_dir("bad-input", "depth");
    for (name, value) in [("negative.exr", -2.0f32), ("zero.exr", 0.0), ("nan-depth.exr", f32::NAN), ("minus-inf.exr", f32::NEG_INFINITY)] {
        let path = dir.join(name);
        plain_with(&path, "Z", |v| v[7] = value);
        refused(&dir, &path, &BLUR, &[name, "channel 'Z'", "1 covered pixel", "--depth-kind"]);
    }
    let disparity = dir.join("negative-disparity.exr");
    plain_with(&disparity, "Z", |v| v[0] = -0.5);
    let mut flags = BLUR.to_vec();
    flags.extend(["--depth-kind", "disparity"]);
    refused(&dir, &disparity, &flags, &["negative-disparity.exr", "channel 'Z'"]);
    let far = dir.join("far.exr");
    plain_with(&far, "Z", |v| {
        v[..W].fill(1e10);
        v[W..2 * W].fill(f32::INFINITY);
    });
    let mut flags = BLUR.to_vec();
    flags.extend(["--method", "oracle"]);
    rendered(&dir, &far, &flags);
}

#[test]
fn non_positive_camera_parameters_name_the_flag() {
    let dir = common::temp_dir("bad-input", "camera");
    let valid = valid_stack(&dir);
    for (flag, value) in [("--fstop", "0"), ("--fstop", "-2"), ("--focal-length", "0"), ("--focus-distance", "-1"), ("--focus-distance", "0")] {
        let arg = format!("{flag}={value}");
        refused(&dir, &valid, &[arg.as_str()], &[flag, "must be a positive number"]);
    }
    refused(&dir, &valid, &["--blur=-3", "--focus-disparity", "0.3"], &["--blur"]);
}

#[test]
fn mismatched_part_sizes_are_refused() {
    let dir = common::temp_dir("bad-input", "parts");
    let path = dir.join("parts.exr");
    let part = |name: &'static str, z: f32| {
        exr_layer(
            Some(name),
            (W, H),
            vec![("R", vec![0.5; W * H]), ("G", vec![0.5; W * H]), ("B", vec![0.5; W * H]), ("A", vec![1.0; W * H]), ("Z", vec![z; W * H])],
        )
    };
    let image = exr::prelude::Image::from_layers(exr::prelude::ImageAttributes::new(exr::prelude::IntegerBounds::from_dimensions((W, H))), vec![part("fg", 2.0), part("bg", 5.0)]);
    image.write().to_file(&path).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let mismatched = dir.join("mismatched.exr");
    std::fs::write(&mismatched, patch_box(&bytes, b"displayWindow\0box2i\0", 31, 23, 1)).unwrap();
    refused(&dir, &mismatched, &BLUR, &["mismatched.exr", "16x12", "32x24"]);
}

#[test]
fn a_missing_output_directory_is_refused_before_rendering() {
    let dir = common::temp_dir("bad-input", "outdir");
    let valid = valid_stack(&dir);
    let out = dir.join("no-such-dir").join("out.exr");
    let output = lensblur(&["render", valid.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success() && !stderr.contains("panicked"), "{stderr}");
    assert!(stderr.contains("no-such-dir") && stderr.contains("does not exist"), "{stderr}");
    assert!(!out.exists() && !dir.join("no-such-dir").exists());
    assert_eq!(listing(&dir), BTreeSet::from(["shot.exr".to_string()]));
}

/// Fuzzing finding (`params` target, remap to an infinite disparity): a CoC far beyond any frame
/// (`--far-blur 1e38`, `--blur 1e30`) overflowed the search-window arithmetic of drbokeh,
/// drbokeh-compat, multiview, scatter and oracle (a panic in debug builds, wrapped windows in
/// release). Every method, and the backward pass, now refuses it before rendering.
#[test]
fn a_circle_of_confusion_no_renderer_can_draw_is_refused() {
    let dir = common::temp_dir("bad-input", "huge-coc");
    let valid = valid_stack(&dir);
    for method in Method::ALL.iter().map(|m| m.name()) {
        refused(&dir, &valid, &["--blur", "1e30", "--focus-disparity", "0.3", "--method", method], &["circle of confusion", "4096 px", "--max-blur"]);
    }
    refused(&dir, &valid, &["--blur", "8", "--focus-disparity", "0.3", "--far-blur", "1e38"], &["circle of confusion", "--max-blur"]);
    refused(&dir, &valid, &["--blur", "8", "--focus-disparity", "3e38", "--far-blur", "3e38"], &["circle of confusion"]);
    // The way out the message names: the same remap with the blur clamped renders.
    rendered(&dir, &valid, &["--blur", "8", "--focus-disparity", "0.3", "--far-blur", "1e38", "--max-blur", "6"]);
    let g = dir.join("g.exr");
    write_image(&g, &Image::from_fn(W, H, |_, _| [0.1, -0.2, 0.3, 0.0]), &WriteOptions::default()).unwrap();
    let grads = dir.join("grads.exr");
    let args = ["grad", valid.to_str().unwrap(), "--grad-output", g.to_str().unwrap(), "-o", grads.to_str().unwrap(), "--blur", "1e30", "--focus-disparity", "0.3"];
    command_refused(&dir, &args, &["circle of confusion"]);
}

/// Runs `args` (any subcommand) and checks the refusal: non-zero exit, no panic, every
/// `needle` in the message, and the directory exactly as before (same names, same bytes).
fn command_refused(dir: &Path, args: &[&str], needles: &[&str]) {
    let before: Vec<(String, Vec<u8>)> = listing(dir).into_iter().map(|n| (n.clone(), std::fs::read(dir.join(&n)).unwrap())).collect();
    let output = lensblur(args);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success(), "{args:?} succeeded; stderr: {stderr}");
    assert!(!stderr.contains("panicked"), "{args:?} panicked: {stderr}");
    for needle in needles {
        assert!(stderr.contains(needle), "{args:?}: message lacks '{needle}': {stderr}");
    }
    let after: Vec<(String, Vec<u8>)> = listing(dir).into_iter().map(|n| (n.clone(), std::fs::read(dir.join(&n)).unwrap())).collect();
    assert!(before == after, "{args:?} changed the directory: {:?}", listing(dir));
}

/// A 16x12 PNG photo and its depth image in `dir`.
fn ldr_pair(dir: &Path) -> (PathBuf, PathBuf) {
    let (photo, depth) = (dir.join("photo.png"), dir.join("depth.png"));
    image::RgbImage::from_fn(W as u32, H as u32, |x, y| image::Rgb([(x * 15) as u8, (y * 20) as u8, 90])).save(&photo).unwrap();
    image::GrayImage::from_fn(W as u32, H as u32, |x, _| image::Luma([if x < 8 { 220 } else { 40 }])).save(&depth).unwrap();
    (photo, depth)
}

#[test]
fn an_output_on_any_input_or_on_another_output_is_refused() {
    let dir = common::temp_dir("bad-input", "collide");
    let shot = valid_stack(&dir);
    let (photo, depth) = ldr_pair(&dir);
    let kernel = dir.join("kernel.png");
    std::fs::copy(&depth, &kernel).unwrap();
    let (g, target) = (dir.join("g.exr"), dir.join("target.exr"));
    std::fs::copy(&shot, &g).unwrap();
    std::fs::copy(&shot, &target).unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    // The same file spelled another way (`dir/./depth.png`) is still the same file.
    let depth_again = s(&dir.join(".").join("depth.png"));
    let (photo, depth, shot, kernel, g, target) = (s(&photo), s(&depth), s(&shot), s(&kernel), s(&g), s(&target));
    command_refused(&dir, &["render", &photo, "--depth", &depth, "-o", &depth_again, "--blur", "4", "--focus-disparity", "0.5"], &["-o", "depth.png", "is the --depth input file"]);
    let aperture = format!("image:{kernel}");
    command_refused(&dir, &["render", &shot, "-o", &kernel, "--aperture", &aperture], &["-o", "kernel.png", "is the --aperture kernel image"]);
    let out_png = s(&dir.join("out.png"));
    command_refused(&dir, &["render", &shot, "-o", &out_png, "--preview", &out_png], &["--preview", "out.png", "is the same file as -o"]);
    command_refused(&dir, &["render", &shot, "-o", &shot], &["-o", "shot.exr", "is the input file"]);
    command_refused(&dir, &["grad", &shot, "--grad-output", &g, "-o", &g], &["-o", "g.exr", "is the --grad-output input file"]);
    command_refused(&dir, &["grad", &photo, "--depth", &depth, "--grad-output", &g, "-o", &depth], &["is the --depth input file"]);
    command_refused(&dir, &["fit-depth", &shot, "--target", &target, "-o", &target], &["-o", "target.exr", "is the --target input file"]);
    command_refused(&dir, &["fit-depth", &shot, "--target", &target, "-o", &shot], &["is the input file"]);
    // --debug-out names its files after the layers: checked once the stack is read, before
    // anything renders (the debug folder here holds the aperture image as `layers.png`).
    let debug = common::temp_dir("bad-input", "collide-debug");
    let debug_kernel = debug.join("layers.png");
    std::fs::copy(&kernel, &debug_kernel).unwrap();
    let (debug_s, aperture) = (s(&debug), format!("image:{}", s(&debug_kernel)));
    let out_coc = s(&debug.join("coc.png"));
    command_refused(&debug, &["render", &shot, "-o", &out_coc, "--debug-out", &debug_s], &["--debug-out", "coc.png", "is the same file as -o"]);
    let out_exr = s(&dir.join("debug-test.exr"));
    command_refused(&debug, &["render", &shot, "-o", &out_exr, "--aperture", &aperture, "--debug-out", &debug_s], &["--debug-out", "layers.png", "is the --aperture kernel image"]);
    assert!(!dir.join("debug-test.exr").exists());
}

#[test]
fn input_options_that_do_not_fit_the_file_are_refused_naming_the_flag() {
    let dir = common::temp_dir("bad-input", "mismatch");
    let shot = valid_stack(&dir);
    let (photo, depth) = ldr_pair(&dir);
    let depth_s = depth.to_str().unwrap();
    // The library's typed refusal (lensblur::InputMismatch), reworded by the CLI with the flag.
    refused(&dir, &photo, &BLUR, &["photo.png", "needs its depth image", "--depth DEPTH.png"]);
    refused(&dir, &photo, &["--depth", depth_s, "--layers", "fg", "--blur", "4", "--focus-disparity", "0.5"], &["--layers", "photo.png", "single image"]);
    refused(&dir, &shot, &["--depth", depth_s], &["--depth is for PNG/JPEG inputs", "shot.exr", "carries its depth"]);
}

#[test]
fn png_and_depth_images_over_the_pixel_budget_are_refused_from_their_headers() {
    let dir = common::temp_dir("bad-input", "ldr-budget");
    let (photo, depth) = ldr_pair(&dir);
    let ldr_refused = |photo: &Path, depth: &Path, extra: &[&str], needles: &[&str]| {
        let mut args = vec!["--depth", depth.to_str().unwrap(), "--blur", "4", "--focus-disparity", "0.5"];
        args.extend_from_slice(extra);
        refused(&dir, photo, &args, needles)
    };
    ldr_refused(&photo, &depth, &["--max-pixels", "100"], &["photo.png", "16x12", "--max-pixels"]);
    // A small photo with a depth image over the budget: the depth header is checked too.
    let small = dir.join("small.png");
    image::RgbImage::new(4, 3).save(&small).unwrap();
    ldr_refused(&small, &depth, &["--max-pixels", "100"], &["depth.png", "16x12", "--max-pixels"]);
    // A PNG whose header declares 100000x100000 pixels and holds no pixel data: the budget
    // refuses it from the header alone (decoding would fail on the data, or allocate 40 GB).
    let huge = dir.join("huge.png");
    std::fs::write(&huge, png_header_only(100_000, 100_000)).unwrap();
    ldr_refused(&huge, &depth, &[], &["huge.png", "100000x100000", "--max-pixels"]);
    let mut args = vec!["--depth", depth.to_str().unwrap(), "--blur", "4", "--focus-disparity", "0.5"];
    args.extend(["--max-pixels", "192", "--method", "gather"]);
    rendered(&dir, &photo, &args);
}

/// PNG signature, an IHDR chunk (8-bit RGB) of the given size, an IDAT chunk holding only a
/// zlib header, then IEND: a valid header with no image data.
fn png_header_only(width: u32, height: u32) -> Vec<u8> {
    fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
        out.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let start = out.len();
        out.extend_from_slice(kind);
        out.extend_from_slice(data);
        out.extend_from_slice(&crc32(&out[start..]).to_be_bytes());
    }
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&width.to_be_bytes());
    ihdr.extend_from_slice(&height.to_be_bytes());
    ihdr.extend_from_slice(&[8, 2, 0, 0, 0]);
    chunk(&mut png, b"IHDR", &ihdr);
    chunk(&mut png, b"IDAT", &[0x78, 0x9c]);
    chunk(&mut png, b"IEND", &[]);
    png
}

/// CRC-32 (IEEE), as PNG chunks carry it.
fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 == 1 { (crc >> 1) ^ 0xEDB8_8320 } else { crc >> 1 };
        }
    }
    !crc
}

/// Starts `lensblur ARGS`, waits until `moment` returns true (polled every millisecond, at
/// most 60 s), sends `signal` and returns what the process printed and its exit status.
fn signalled(args: &[&str], signal: &str, moment: impl Fn() -> bool) -> Output {
    let child = Command::new(env!("CARGO_BIN_EXE_lensblur"))
        .args(args)
        .env("LENSBLUR_VALIDATION", "1")
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    while !moment() && start.elapsed() < std::time::Duration::from_secs(60) {
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    let killed = Command::new("kill").args([&format!("-{signal}"), &child.id().to_string()]).status().unwrap();
    assert!(killed.success());
    child.wait_with_output().unwrap()
}

#[test]
fn an_interrupted_render_exits_130_and_leaves_nothing() {
    let dir = common::temp_dir("bad-input", "interrupt");
    let (w, h) = (128, 128);
    let layers = vec![Layer { name: "wall".into(), rgba: Image::from_fn(w, h, |x, _| [x as f32 / 128.0, 0.5, 0.2, 1.0]), disparity: vec![0.9; w * h] }];
    let input = dir.join("big.exr");
    write_stack(&input, &LayerStack::new(w, h, layers).unwrap(), &StackWriteOptions::default()).unwrap();
    let out = dir.join("out.exr");
    // The f64 CPU reference at a 54 px CoC needs ~3 s of CPU time (measured): a signal 300 ms
    // after the start lands mid-render. A hexagon keeps the render on the reference: through a
    // disk the fast CPU path renders this frame in under 300 ms. SIGTERM and SIGHUP are what a
    // job system or a closed terminal sends; they must clean up like Ctrl-C.
    let args = [
        "render",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--device",
        "cpu",
        "--aperture",
        "polygon:6",
        "--blur",
        "60",
        "--focus-disparity",
        "0",
    ];
    for signal in ["INT", "TERM", "HUP"] {
        let start = std::time::Instant::now();
        let output = signalled(&args, signal, || start.elapsed() > std::time::Duration::from_millis(300));
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(130), "SIG{signal}: finished before the signal? {stderr}");
        assert!(stderr.contains("interrupted; no output written"), "SIG{signal}: {stderr}");
        assert_eq!(listing(&dir), BTreeSet::from(["big.exr".to_string()]), "SIG{signal}");
    }
}

#[test]
fn an_interrupt_while_the_output_is_written_leaves_nothing() {
    let dir = common::temp_dir("bad-input", "interrupt-write");
    // 2048 x 2048 float RGBA: a 64 MiB EXR whose ZIP compression takes far longer than the
    // millisecond between polls, so the signal lands while the temporary file is being written.
    let (w, h) = (2048, 2048);
    let layers = vec![Layer { name: "wall".into(), rgba: Image::from_fn(w, h, |x, y| [((x * 31 + y * 17) % 256) as f32 / 255.0, 0.5, 0.2, 1.0]), disparity: vec![0.5; w * h] }];
    let input = dir.join("big.exr");
    write_stack(&input, &LayerStack::new(w, h, layers).unwrap(), &StackWriteOptions::default()).unwrap();
    let out = dir.join("out.exr");
    let args = ["render", input.to_str().unwrap(), "-o", out.to_str().unwrap(), "--method", "oracle", "--blur", "0", "--focus-disparity", "0"];
    let writing = || listing(&dir).iter().any(|n| n.starts_with(".out.exr.") && n.ends_with(".tmp"));
    let output = signalled(&args, "INT", writing);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(130), "{stderr}");
    assert!(stderr.contains("interrupted; no output written"), "{stderr}");
    assert_eq!(listing(&dir), BTreeSet::from(["big.exr".to_string()]));
}
