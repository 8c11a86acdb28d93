//! `lensblur render` end to end: the binary on files written by our own writers, with the
//! Vulkan validation layer on (any validation message fails the command).
mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use lensblur::camera::{Aperture, CocModel, PhysicalCamera};
use lensblur::image::Image;
use lensblur::render::drbokeh::{DrBokehGpu, Model};
use lensblur::render::Lens;
use exr::prelude::FlatSamples;
use lensblur::stack::{
    write_image, write_stack, ExtraChannel, Layer, LayerStack, SampleType, StackWriteOptions,
    WriteOptions,
};

/// A tiny sensor so that a 48 px wide image gets visible blur: K = 0.025 m * (50/3 * 48) = 20 px.
const CAMERA: PhysicalCamera = PhysicalCamera {
    focal_length_mm: 50.0,
    sensor_width_mm: 3.0,
    fstop: 1.0,
    focus_distance: 4.0,
};


fn lensblur(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lensblur"))
        .args(args)
        .env("LENSBLUR_VALIDATION", "1")
        .output()
        .unwrap()
}

fn ok(output: Output) -> String {
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "lensblur failed: {stderr}");
    String::from_utf8(output.stdout).unwrap()
}

/// The `--json` report of a command that must succeed.
fn json_report(output: Output) -> serde_json::Value {
    serde_json::from_str(&ok(output)).unwrap()
}

/// The report's layer names, front to back.
fn layer_names(report: &serde_json::Value) -> Vec<&str> {
    report["layers"].as_array().unwrap().iter().map(|l| l["name"].as_str().unwrap()).collect()
}

/// A subject at 2 m in front of a wall at 4 m (in focus), 48x40: CoC of the subject ~6 px.
fn two_layer_stack() -> LayerStack {
    let (w, h) = (48, 40);
    let subject = Image::from_fn(w, h, |x, y| {
        let inside = (14..30).contains(&x) && (10..30).contains(&y);
        if inside {
            [0.9, 0.2 + 0.01 * y as f32, 0.1, 1.0]
        } else {
            [0.0; 4]
        }
    });
    let wall = Image::from_fn(w, h, |x, y| {
        let c = if (x / 4 + y / 4) % 2 == 0 { 0.8 } else { 0.1 };
        [c, c, 1.0 - c, 1.0]
    });
    let layers = vec![
        Layer {
            name: "subject".into(),
            rgba: subject,
            disparity: vec![0.5; w * h],
        },
        Layer {
            name: "wall".into(),
            rgba: wall,
            disparity: vec![0.25; w * h],
        },
    ];
    LayerStack::new(w, h, layers).unwrap()
}

fn write_input(dir: &Path, camera: Option<PhysicalCamera>) -> PathBuf {
    let path = dir.join("shot.exr");
    write_stack(
        &path,
        &two_layer_stack(),
        &StackWriteOptions {
            camera,
            ..StackWriteOptions::default()
        },
    )
    .unwrap();
    path
}

/// Reads channels R, G, B, A of an output (which has no depth, so it is no stack).
fn read_image(path: &Path, prefix: &str) -> Image {
    let file = exr::prelude::read_all_flat_layers_from_file(path).unwrap();
    let layer = &file.layer_data[0];
    let channel = |name: &str| -> Vec<f32> {
        let c = layer
            .channel_data
            .list
            .iter()
            .find(|c| c.name.to_string() == format!("{prefix}{name}"))
            .unwrap();
        c.sample_data.values_as_f32().collect()
    };
    let (r, g, b, a) = (channel("R"), channel("G"), channel("B"), channel("A"));
    let (w, h) = (layer.size.0, layer.size.1);
    Image {
        width: w,
        height: h,
        pixels: (0..w * h).map(|i| [r[i], g[i], b[i], a[i]]).collect(),
    }
}

#[test]
fn render_matches_the_library_and_reads_the_camera_from_the_header() {
    let dir = common::temp_dir("cli-render", "header");
    let input = write_input(&dir, Some(CAMERA));
    let out = dir.join("out.exr");
    let report = json_report(lensblur(&[
        "render",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--json",
    ]));
    assert_eq!(report["method"], "drbokeh");
    // Front to back, whatever order the file lists them in.
    let names = layer_names(&report);
    assert_eq!(names, ["subject", "wall"]);
    let coc = CocModel::from_physical(&CAMERA, 48).unwrap();
    assert!(
        (report["k_px"].as_f64().unwrap() - coc.k_px as f64).abs() < 1e-3,
        "K from the header: {report}"
    );
    // The wall is in focus (0 px), the subject at |0.5 - 0.25| K.
    let max_coc = report["coc_range_px"][1].as_f64().unwrap();
    assert!((max_coc - 0.25 * coc.k_px as f64).abs() < 1e-3, "{report}");

    let ctx = common::gpu();
    let expected = DrBokehGpu::new(&ctx)
        .unwrap()
        .render(
            &two_layer_stack(),
            &Lens {
                coc,
                aperture: Aperture::Disk,
            },
            Model::DrBokeh,
        )
        .unwrap();
    // Same device, same code, float output: identical up to the EXR float round trip (exact).
    let got = read_image(&out, "");
    assert!(
        common::max_abs_diff(&got, &two_layer_stack().layers[1].rgba) > 0.05,
        "the subject's blur changes the image"
    );
    assert!(
        common::max_abs_diff(&got, &expected) < 1e-6,
        "{}",
        common::max_abs_diff(&got, &expected)
    );
    common::finish(ctx);
}

#[test]
fn flags_override_the_header_and_missing_camera_is_a_clear_error() {
    let dir = common::temp_dir("cli-render", "flags");
    let input = write_input(&dir, None);
    let out = dir.join("out.exr");
    let failed = lensblur(&[
        "render",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(!failed.status.success());
    let message = String::from_utf8_lossy(&failed.stderr);
    assert!(
        message.contains("--focal-length") && message.contains("--blur"),
        "{message}"
    );
    assert!(!out.exists(), "a failed render must not leave an output");

    let report = json_report(lensblur(&[
        "render",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--json",
        "--blur",
        "20",
        "--focus-disparity",
        "0.5",
        "--method",
        "oracle",
    ]));
    assert_eq!(report["k_px"].as_f64().unwrap(), 20.0);
    assert_eq!(report["method"], "oracle");
    // Focus on the subject now: the wall is the blurred one, at 0.25 * 20 = 5 px.
    assert!(
        (report["layers"][1]["coc_range_px"][0].as_f64().unwrap() - 5.0).abs() < 1e-4,
        "{report}"
    );
}

#[test]
fn output_naming_half_pass_through_and_preview() {
    let dir = common::temp_dir("cli-render", "naming");
    let input = dir.join("comp.exr");
    // A plain RGBZ image with a cryptomatte-like pass: single image, auto-layered.
    let (w, h) = (40, 32);
    let image = Image::from_fn(w, h, |x, _| {
        if x < 20 {
            [1.0, 0.5, 0.2, 1.0]
        } else {
            [0.1, 0.2, 0.9, 1.0]
        }
    });
    let depth = (0..w * h)
        .map(|i| if i % w < 20 { 1.5 } else { 6.0 })
        .collect::<Vec<f32>>();
    let matte = (0..w * h).map(|i| (i % 7) as f32).collect::<Vec<f32>>();
    let extra = vec![
        ExtraChannel {
            name: "Z".into(),
            sample_type: SampleType::Float,
            values: depth,
        },
        ExtraChannel {
            name: "crypto.R".into(),
            sample_type: SampleType::Float,
            values: matte.clone(),
        },
    ];
    write_image(
        &input,
        &image,
        &WriteOptions {
            sample_type: SampleType::Float,
            extra_channels: extra,
            camera: Some(CAMERA),
            ..WriteOptions::default()
        },
    )
    .unwrap();
    let out = dir.join("blurred.exr");
    let preview = dir.join("blurred.png");
    let report = json_report(lensblur(&[
        "render",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--output-layer",
        "Defocus",
        "--half",
        "--keep-channels",
        "--preview",
        preview.to_str().unwrap(),
        "--json",
        "--blur",
        "30",
        "--focus-disparity",
        "0.667",
    ]));
    assert_eq!(report["auto_layered"], true, "{report}");
    assert!(
        report["layers"].as_array().unwrap().len() >= 2,
        "two depths give at least two layers: {report}"
    );
    assert!(preview.exists());

    let (parts, _) = lensblur::stack::read_parts(&out, 1 << 24).unwrap();
    let channels: Vec<(String, SampleType)> = parts[0]
        .channels
        .iter()
        .map(|c| (c.name.clone(), c.sample_type))
        .collect();
    for c in ["R", "G", "B", "A"] {
        assert!(
            channels.contains(&(format!("Defocus.Combined.{c}"), SampleType::Half)),
            "{channels:?}"
        );
    }
    assert!(
        channels.iter().any(|(n, _)| n == "crypto.R"),
        "pass kept: {channels:?}"
    );
    let blurred = read_image(&out, "Defocus.Combined.");
    // The near half (x < 20, in focus) keeps its colour; the far half bleeds nothing into it
    // beyond the near layer's own edge band.
    let p = blurred.get(5, 16);
    assert!(
        (p[0] - 1.0).abs() < 2e-3 && (p[2] - 0.2).abs() < 2e-3,
        "in-focus pixel changed: {p:?} (half precision: 1e-3)"
    );
    let kept = exr::prelude::read_all_flat_layers_from_file(&out).unwrap();
    let channel = kept.layer_data[0]
        .channel_data
        .list
        .iter()
        .find(|c| c.name.to_string() == "crypto.R")
        .unwrap();
    let values: Vec<f32> = channel.sample_data.values_as_f32().collect();
    assert_eq!(
        values, matte,
        "pass-through channels are copied bit for bit"
    );
}

/// Display window origin of the convention inputs: not (0, 0), so losing it shows.
const ORIGIN: (i32, i32) = (-3, 5);

/// The channels of `layer`: colour `{colour}R..A`, planar depth `depth`.
fn layer_samples(layer: &Layer, colour: &str, depth: &str) -> Vec<(String, FlatSamples)> {
    let mut out: Vec<(String, FlatSamples)> = ["R", "G", "B", "A"]
        .iter()
        .enumerate()
        .map(|(c, name)| (format!("{colour}{name}"), common::float(layer.rgba.pixels.iter().map(|p| p[c]))))
        .collect();
    out.push((depth.to_string(), common::float(layer.disparity.iter().map(|d| 1.0 / d))));
    out
}

/// `two_layer_stack` (or, for `plain`, its wall alone) in one naming convention, on a
/// display window at ORIGIN.
fn write_convention_input(path: &Path, convention: &str) {
    let stack = two_layer_stack();
    let size = (stack.width, stack.height);
    let part = |name: Option<&'static str>, channels| common::Part { name, origin: ORIGIN, size, channels };
    let [subject, wall] = &stack.layers[..] else { unreachable!("two layers") };
    let parts = match convention {
        "blender" => {
            let mut channels = layer_samples(subject, "subject.Combined.", "subject.Depth.Z");
            channels.extend(layer_samples(wall, "wall.Combined.", "wall.Depth.Z"));
            vec![part(None, channels)]
        }
        "layer-dot" => {
            let mut channels = layer_samples(subject, "subject.", "subject.Z");
            channels.extend(layer_samples(wall, "wall.", "wall.Z"));
            vec![part(None, channels)]
        }
        "multi-part" => {
            vec![part(Some("subject"), layer_samples(subject, "", "Z")), part(Some("wall"), layer_samples(wall, "", "Z"))]
        }
        _ => vec![part(None, layer_samples(wall, "", "Z"))],
    };
    common::write_parts_with(path, (ORIGIN, size), exr::prelude::LayerAttributes::default(), parts);
}

#[test]
fn output_layer_follows_the_input_convention_on_the_input_display_window() {
    let dir = common::temp_dir("cli-render", "convention");
    let expected = [
        ("blender", None, "dof.Combined."),
        ("layer-dot", None, "dof."),
        ("multi-part", Some("dof"), ""),
        ("plain", None, "dof.Combined."),
    ];
    let mut rendered = Vec::new();
    for (convention, part, prefix) in expected {
        let input = dir.join(format!("{convention}.exr"));
        write_convention_input(&input, convention);
        let (named, plain) = (dir.join(format!("{convention}-dof.exr")), dir.join(format!("{convention}-plain.exr")));
        for (out, layer) in [(&named, Some("dof")), (&plain, None)] {
            let mut args = vec!["render", input.to_str().unwrap(), "-o", out.to_str().unwrap(), "--method", "oracle"];
            args.extend(["--blur", "20", "--focus-disparity", "0.25"]);
            args.extend(layer.iter().flat_map(|l| ["--output-layer", *l]));
            ok(lensblur(&args));
            let meta = exr::meta::MetaData::read_from_file(out, false).unwrap();
            let [header] = &meta.headers[..] else { panic!("{convention}: one part expected") };
            let window = header.shared_attributes.display_window;
            assert_eq!((window.position.x(), window.position.y()), ORIGIN, "{convention}: display window origin kept");
            assert_eq!((window.size.x(), window.size.y()), (48, 40), "{convention}");
            assert_eq!(header.own_attributes.layer_position, window.position, "{convention}: data = display window");
            let (want_part, want_prefix) = if layer.is_some() { (part, prefix) } else { (None, "") };
            assert_eq!(header.own_attributes.layer_name.as_ref().map(|t| t.to_string()).as_deref(), want_part, "{convention}");
            let mut names: Vec<String> = header.channels.list.iter().map(|c| c.name.to_string()).collect();
            names.sort();
            assert_eq!(names, ["A", "B", "G", "R"].map(|c| format!("{want_prefix}{c}")), "{convention} --output-layer {layer:?}");
        }
        let image = read_image(&named, prefix);
        assert_eq!(image, read_image(&plain, ""), "{convention}: the name changes nothing else");
        rendered.push(image);
    }
    // The three stacks are the same layers in different names: the same render.
    assert_eq!(rendered[0], rendered[1]);
    assert_eq!(rendered[0], rendered[2]);
}

#[test]
fn one_layer_picked_out_of_a_stack_is_not_auto_layered() {
    let dir = common::temp_dir("cli-render", "pick");
    let input = write_input(&dir, Some(CAMERA));
    let out = dir.join("out.exr");
    let report = json_report(lensblur(&[
        "render",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--layers",
        "subject",
        "--method",
        "oracle",
        "--json",
    ]));
    assert_eq!(report["auto_layered"], false, "{report}");
    let names = layer_names(&report);
    assert_eq!(names, ["subject"]);
}

#[test]
fn keep_channels_with_a_png_input_is_refused() {
    let dir = common::temp_dir("cli-render", "keep-ldr");
    let (photo, depth, out) = (dir.join("photo.png"), dir.join("depth.png"), dir.join("out.exr"));
    image::RgbImage::from_pixel(8, 6, image::Rgb([200, 100, 50])).save(&photo).unwrap();
    image::GrayImage::from_pixel(8, 6, image::Luma([128])).save(&depth).unwrap();
    let failed = lensblur(&[
        "render",
        photo.to_str().unwrap(),
        "--depth",
        depth.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--keep-channels",
        "--blur",
        "4",
        "--focus-disparity",
        "0.5",
    ]);
    assert!(!failed.status.success());
    let message = String::from_utf8_lossy(&failed.stderr);
    assert!(message.contains("--keep-channels") && message.contains("photo.png"), "{message}");
    assert!(!out.exists(), "no output after a refusal");
}

#[test]
fn ldr_input_with_depth_image_renders_to_jpeg() {
    let dir = common::temp_dir("cli-render", "ldr");
    let (w, h) = (32u32, 24u32);
    let colour = image::RgbImage::from_fn(w, h, |x, y| {
        image::Rgb([(x * 8) as u8, (y * 10) as u8, 128])
    });
    let depth =
        image::GrayImage::from_fn(w, h, |x, _| image::Luma([if x < 16 { 230 } else { 40 }]));
    let (photo, depth_path, out) = (
        dir.join("photo.png"),
        dir.join("depth.png"),
        dir.join("out.jpg"),
    );
    colour.save(&photo).unwrap();
    depth.save(&depth_path).unwrap();
    ok(lensblur(&[
        "render",
        photo.to_str().unwrap(),
        "--depth",
        depth_path.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--blur",
        "8",
        "--focus-disparity",
        "0.9",
    ]));
    let result = image::open(&out).unwrap();
    assert_eq!((result.width(), result.height()), (w, h));
}

#[test]
fn refuses_to_overwrite_the_input_and_names_bad_flags() {
    let dir = common::temp_dir("cli-render", "refuse");
    let input = write_input(&dir, Some(CAMERA));
    let before = std::fs::read(&input).unwrap();
    let failed = lensblur(&[
        "render",
        input.to_str().unwrap(),
        "-o",
        input.to_str().unwrap(),
    ]);
    assert!(!failed.status.success());
    assert!(String::from_utf8_lossy(&failed.stderr).contains("is the input file"));
    assert_eq!(std::fs::read(&input).unwrap(), before, "input untouched");

    let bad = lensblur(&[
        "render",
        input.to_str().unwrap(),
        "-o",
        dir.join("x.exr").to_str().unwrap(),
        "--method",
        "magic",
    ]);
    assert!(
        String::from_utf8_lossy(&bad.stderr).contains("available: drbokeh"),
        "{}",
        String::from_utf8_lossy(&bad.stderr)
    );
    let missing = lensblur(&[
        "render",
        dir.join("nope.exr").to_str().unwrap(),
        "-o",
        dir.join("x.exr").to_str().unwrap(),
    ]);
    assert!(String::from_utf8_lossy(&missing.stderr).contains("nope.exr"));
}

/// `--overscan PX`: the input's outer PX pixels are blurred like the rest and cut from the
/// output (and preview): the frame equals the whole render less its border, pixel for pixel.
#[test]
fn overscan_blurs_the_margin_and_cuts_it_from_the_output() {
    let dir = common::temp_dir("cli-render", "overscan");
    let input = write_input(&dir, Some(CAMERA));
    let (whole, cut) = (dir.join("whole.exr"), dir.join("cut.exr"));
    ok(lensblur(&["render", input.to_str().unwrap(), "-o", whole.to_str().unwrap()]));
    let preview = dir.join("cut.png");
    ok(lensblur(&[
        "render", input.to_str().unwrap(), "-o", cut.to_str().unwrap(), "--overscan", "6", "--preview", preview.to_str().unwrap(),
    ]));
    let (whole, cut) = (read_image(&whole, ""), read_image(&cut, ""));
    assert_eq!((cut.width, cut.height), (48 - 12, 40 - 12));
    assert_eq!(Some(cut), whole.without_border(6), "the cut output is the whole render less 6 px a side");
    assert_eq!(image::image_dimensions(&preview).unwrap(), (36, 28));
    // A margin that leaves nothing, and unblurred channels that would not line up, are refused.
    let too_big = lensblur(&["render", input.to_str().unwrap(), "-o", dir.join("x.exr").to_str().unwrap(), "--overscan", "20"]);
    let stderr = String::from_utf8_lossy(&too_big.stderr);
    assert!(!too_big.status.success() && stderr.contains("--overscan 20") && stderr.contains("48x40"), "{stderr}");
    assert!(!dir.join("x.exr").exists(), "nothing is written");
    let kept = lensblur(&["render", input.to_str().unwrap(), "-o", dir.join("y.exr").to_str().unwrap(), "--overscan", "2", "--keep-channels"]);
    let stderr = String::from_utf8_lossy(&kept.stderr);
    assert!(!kept.status.success() && stderr.contains("--keep-channels"), "{stderr}");
}
