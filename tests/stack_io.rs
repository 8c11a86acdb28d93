//! EXR/PNG stack I/O: every naming convention read back from files generated in code,
//! our writers read back by our reader, and every documented error.
mod common;
use std::path::Path;

use common::{float, half, write_parts, Part};
use exr::prelude::FlatSamples;
use lensblur::image::Image;
use lensblur::stack::naming::Convention;
use lensblur::stack::{
    read_ldr, read_stack, write_image, write_png_preview, write_stack, DepthKind, ExtraChannel,
    Layer, LayerStack, ReadOptions, SampleType, StackNaming, StackWriteOptions, WriteOptions,
    DEFAULT_MAX_PIXELS,
};

const W: usize = 8;
const H: usize = 6;


/// Colour of layer `l` at pixel i (distinct per layer and pixel, exact in half precision).
fn colour(l: usize, i: usize, c: usize) -> f32 {
    ((l * 7 + i * 3 + c * 5) % 32) as f32 / 32.0
}

/// Channels of one layer: RGBA with names from `names`, half colour; depth float.
fn layer_channels(
    l: usize,
    names: [&str; 5],
    depth: impl Fn(usize) -> f32,
    alpha: impl Fn(usize) -> f32,
    n: usize,
) -> Vec<(String, FlatSamples)> {
    let mut out: Vec<(String, FlatSamples)> = (0..3)
        .map(|c| {
            (
                names[c].to_string(),
                half((0..n).map(|i| colour(l, i, c) * alpha(i))),
            )
        })
        .collect();
    out.push((names[3].to_string(), half((0..n).map(&alpha))));
    out.push((names[4].to_string(), float((0..n).map(depth))));
    out
}

fn names(prefix: &str, long: bool, depth: &str) -> [String; 5] {
    let base = if long {
        ["red", "green", "blue", "alpha"]
    } else {
        ["R", "G", "B", "A"]
    };
    [0, 1, 2, 3]
        .map(|i| format!("{prefix}{}", base[i]))
        .into_iter()
        .chain([format!("{prefix}{depth}")])
        .collect::<Vec<_>>()
        .try_into()
        .unwrap()
}

fn as_refs(n: &[String; 5]) -> [&str; 5] {
    [
        n[0].as_str(),
        n[1].as_str(),
        n[2].as_str(),
        n[3].as_str(),
        n[4].as_str(),
    ]
}

fn opaque(_: usize) -> f32 {
    1.0
}

fn assert_layer(layer: &Layer, l: usize, disparity: f32) {
    for (i, p) in layer.rgba.pixels.iter().enumerate() {
        for c in 0..3 {
            // Values are multiples of 1/32, exact in half precision.
            assert_eq!(
                p[c],
                colour(l, i, c) * p[3],
                "layer {} pixel {i} channel {c}",
                layer.name
            );
        }
    }
    assert!(
        layer
            .disparity
            .iter()
            .all(|&d| (d - disparity).abs() < 1e-6),
        "layer {} disparity",
        layer.name
    );
}

#[test]
fn blender_multilayer_with_half_colour_and_float_depth() {
    let dir = common::temp_dir("stack-io", "blender");
    let path = dir.join("render.exr");
    let n = W * H;
    // The back view layer is opaque at z = 10; the front one covers the left half at z = 2,
    // with Z = 1e10 where it is empty, as Cycles writes it.
    let front_alpha = |i: usize| if i % W < W / 2 { 1.0 } else { 0.0 };
    let front_depth = |i: usize| if i % W < W / 2 { 2.0 } else { 1.0e10 };
    let mut channels = layer_channels(
        0,
        as_refs(&names("Front.Combined.", false, "Z").map(|s| s.replace("Combined.Z", "Depth.Z"))),
        front_depth,
        front_alpha,
        n,
    );
    channels.extend(layer_channels(
        1,
        as_refs(&names("Back.Combined.", false, "Z").map(|s| s.replace("Combined.Z", "Depth.Z"))),
        |_| 10.0,
        opaque,
        n,
    ));
    channels.push(("Back.Normal.X".into(), float((0..n).map(|i| i as f32))));
    channels.push(("Back.Normal.Z".into(), float((0..n).map(|_| 1.0))));
    write_single_part(&path, channels);

    let file = read_stack(&path, &ReadOptions::default()).unwrap();
    let stack = &file.stack;
    assert_eq!(
        stack
            .layers
            .iter()
            .map(|l| l.name.as_str())
            .collect::<Vec<_>>(),
        ["Front", "Back"]
    );
    assert_layer(&stack.layers[1], 1, 0.1);
    assert_layer(&stack.layers[0], 0, 0.5);
    assert!(file
        .info
        .layers
        .iter()
        .all(|l| l.convention == Convention::BlenderMultilayer));
    assert_eq!(
        file.info.layers[0].stored_depth_range,
        Some((2.0, 2.0)),
        "1e10 on empty pixels is not counted"
    );
    assert!(!file.info.single_image);
    let extras: Vec<&str> = file
        .info
        .extra_channels
        .iter()
        .map(|c| c.name.as_str())
        .collect();
    assert_eq!(
        extras,
        ["Back.Normal.X", "Back.Normal.Z"],
        "normals are passed through, not rendered"
    );
    assert_eq!(file.info.extra_channels[0].values[5], 5.0);
}

#[test]
fn blender_file_output_value_depth() {
    let dir = common::temp_dir("stack-io", "fileoutput");
    let path = dir.join("out.exr");
    let n = W * H;
    let channels = layer_channels(
        2,
        ["Image.R", "Image.G", "Image.B", "Image.A", "Depth.V"],
        |_| 4.0,
        opaque,
        n,
    );
    write_single_part(&path, channels);
    let file = read_stack(&path, &ReadOptions::default()).unwrap();
    assert_eq!(file.stack.layers.len(), 1);
    assert_layer(&file.stack.layers[0], 2, 0.25);
    assert_eq!(
        file.info.layers[0].convention,
        Convention::BlenderFileOutput
    );
    assert!(file.info.single_image, "one layer means single-image input");
}

/// One single-part file of `channels` at W x H.
fn write_single_part(path: &Path, channels: Vec<(String, FlatSamples)>) {
    common::write_single_part(path, (W, H), channels);
}

#[test]
fn file_output_node_depth_slots_pair_with_colour_slots_by_name() {
    // One File Output node writing a stack: colour slots `fg`, `bg_Image`, depth slots
    // `fgDepth` and `bg_Z` (value sockets, so `.V`).
    let dir = common::temp_dir("stack-io", "slots");
    let path = dir.join("slots.exr");
    let n = W * H;
    let mut channels = layer_channels(0, ["fg.R", "fg.G", "fg.B", "fg.A", "fgDepth.V"], |_| 2.0, opaque, n);
    channels.extend(layer_channels(
        1,
        ["bg_Image.R", "bg_Image.G", "bg_Image.B", "bg_Image.A", "bg_Z.V"],
        |_| 8.0,
        opaque,
        n,
    ));
    write_single_part(&path, channels.clone());
    let file = read_stack(&path, &ReadOptions::default()).unwrap();
    let names: Vec<&str> = file.stack.layers.iter().map(|l| l.name.as_str()).collect();
    assert_eq!(names, ["fg", "bg_Image"]);
    assert_layer(&file.stack.layers[0], 0, 0.5);
    assert_layer(&file.stack.layers[1], 1, 0.125);
    assert!(file.info.layers.iter().all(|l| l.convention == Convention::BlenderFileOutput));
    assert_eq!(file.info.layers[1].channels.depth.as_deref(), Some("bg_Z.V"));
    assert!(!file.info.single_image && file.info.extra_channels.is_empty(), "{:?}", file.info.extra_channels);

    // A second depth slot for `fg`: which one is meant cannot be known, so the file is refused
    // (by default and when fg is asked for), naming both slots; bg alone still reads.
    channels.push(("fg_Z.V".to_string(), float((0..n).map(|_| 3.0))));
    write_single_part(&path, channels);
    for layers in [None, Some(vec!["fg".to_string()])] {
        let options = ReadOptions { layers, ..ReadOptions::default() };
        let message = read_stack(&path, &options).unwrap_err().to_string();
        assert!(
            message.contains("layer 'fg'") && message.contains("'fgDepth'") && message.contains("'fg_Z'"),
            "{message}"
        );
    }
    let options = ReadOptions { layers: Some(vec!["bg*".to_string()]), ..ReadOptions::default() };
    assert_eq!(read_stack(&path, &options).unwrap().stack.layers.len(), 1);
}

#[test]
fn only_a_file_holding_one_image_is_a_single_image() {
    // Two layers and the flat composite (`R,G,B,A,Z`, layer `All`).
    let dir = common::temp_dir("stack-io", "single");
    let path = dir.join("stack.exr");
    let n = W * H;
    let mut channels = layer_channels(0, as_refs(&names("fg.", false, "Z")), |_| 2.0, opaque, n);
    channels.extend(layer_channels(1, as_refs(&names("bg.", false, "Z")), |_| 8.0, opaque, n));
    channels.extend(layer_channels(2, ["R", "G", "B", "A", "Z"], |_| 2.0, opaque, n));
    write_single_part(&path, channels);
    for (layers, single) in [(None, false), (Some("fg"), false), (Some("fg,bg"), false), (Some("All"), true)] {
        let layers = layers.map(|l| l.split(',').map(String::from).collect());
        let options = ReadOptions { layers: layers.clone(), ..ReadOptions::default() };
        let file = read_stack(&path, &options).unwrap();
        assert_eq!(file.info.single_image, single, "--layers {layers:?}");
    }
}

#[test]
fn oiio_long_names_and_inverse_z() {
    let dir = common::temp_dir("stack-io", "long");
    let path = dir.join("nuke.exr");
    let n = W * H;
    let mut channels = layer_channels(0, as_refs(&names("fg.", true, "depth")), |_| 0.5, opaque, n);
    channels.extend(layer_channels(
        1,
        as_refs(&names("bg.", false, "Z")),
        |_| 0.0,
        opaque,
        n,
    ));
    write_single_part(&path, channels);
    let options = ReadOptions {
        depth_kind: DepthKind::InverseZ,
        ..ReadOptions::default()
    };
    let file = read_stack(&path, &options).unwrap();
    assert_eq!(file.stack.layers[0].name, "fg");
    assert_layer(&file.stack.layers[0], 0, 0.5);
    assert_layer(&file.stack.layers[1], 1, 0.0);
    assert!(file
        .info
        .layers
        .iter()
        .all(|l| l.convention == Convention::LayerDotChannel));
}

#[test]
fn unprefixed_rgbz_is_one_single_image_layer() {
    let dir = common::temp_dir("stack-io", "plain");
    let path = dir.join("plain.exr");
    let n = W * H;
    let mut channels = layer_channels(
        3,
        ["R", "G", "B", "A", "Z"],
        |i| 1.0 + (i % W) as f32,
        opaque,
        n,
    );
    channels.retain(|(name, _)| name != "A");
    write_single_part(&path, channels);
    let file = read_stack(&path, &ReadOptions::default()).unwrap();
    let layer = &file.stack.layers[0];
    assert!(file.info.single_image);
    assert_eq!(file.info.layers[0].convention, Convention::Unprefixed);
    assert!(
        layer.rgba.pixels.iter().all(|p| p[3] == 1.0),
        "no alpha channel means opaque"
    );
    assert!((layer.disparity[3] - 0.25).abs() < 1e-6);
}

#[test]
fn multi_part_files_name_layers_after_parts_and_place_data_windows() {
    let dir = common::temp_dir("stack-io", "multipart");
    let path = dir.join("parts.exr");
    // The front part only stores a 3x2 window at (2, 1); outside it the layer is transparent.
    let front = layer_channels(0, ["R", "G", "B", "A", "Z"], |_| 2.0, opaque, 6);
    let back = layer_channels(
        1,
        ["R", "G", "B", "A", "Z"],
        |_| f32::INFINITY,
        opaque,
        W * H,
    );
    write_parts(
        &path,
        (W, H),
        vec![
            Part {
                name: Some("back"),
                origin: (0, 0),
                size: (W, H),
                channels: back,
            },
            Part {
                name: Some("front"),
                origin: (2, 1),
                size: (3, 2),
                channels: front,
            },
        ],
    );
    let file = read_stack(&path, &ReadOptions::default()).unwrap();
    let [front, back] = &file.stack.layers[..] else {
        panic!("two layers expected")
    };
    assert_eq!((front.name.as_str(), back.name.as_str()), ("front", "back"));
    assert!(
        back.disparity.iter().all(|&d| d == 0.0),
        "infinite Z is infinitely far"
    );
    for y in 0..H {
        for x in 0..W {
            let inside = (2..5).contains(&x) && (1..3).contains(&y);
            let p = front.rgba.get(x, y);
            assert_eq!(p[3], if inside { 1.0 } else { 0.0 }, "({x},{y})");
            if inside {
                let i = (y - 1) * 3 + (x - 2);
                assert_eq!(p[0], colour(0, i, 0), "data placed at its window ({x},{y})");
            }
            // Transparent pixels get depth from the covered ones (push-pull fill).
            assert!((front.disparity[y * W + x] - 0.5).abs() < 1e-6);
        }
    }
    assert!(file
        .info
        .layers
        .iter()
        .all(|l| l.convention == Convention::MultiPart));
    assert_eq!(file.info.layers[0].data_window.x, 2);
}

#[test]
fn transparent_pixels_get_depth_from_nearby_opaque_ones() {
    let dir = common::temp_dir("stack-io", "fill");
    let path = dir.join("fill.exr");
    // Left column at z = 1, right column at z = 4, the middle transparent with junk Z.
    let alpha = |i: usize| {
        if i % W == 0 || i % W == W - 1 {
            1.0
        } else {
            0.0
        }
    };
    let depth = |i: usize| match i % W {
        0 => 1.0,
        x if x == W - 1 => 4.0,
        _ => -3.0,
    };
    let channels = layer_channels(0, as_refs(&names("a.", false, "Z")), depth, alpha, W * H);
    write_single_part(&path, channels);
    let file = read_stack(&path, &ReadOptions::default()).unwrap();
    let d = &file.stack.layers[0].disparity;
    for (i, &v) in d.iter().enumerate() {
        // Filled values are convex combinations of the known disparities 1 and 0.25.
        assert!((0.25..=1.0).contains(&v), "pixel {i}: {v}");
    }
    assert!(
        d[1] > d[W - 2],
        "the fill follows the nearer side on the left, farther on the right"
    );
}

#[test]
fn layer_selection_by_name_and_glob_in_any_order() {
    let dir = common::temp_dir("stack-io", "select");
    let path = dir.join("sel.exr");
    let mut channels = Vec::new();
    for (l, name) in ["fg_hair", "fg_body", "bg"].iter().enumerate() {
        channels.extend(layer_channels(
            l,
            as_refs(&names(&format!("{name}."), false, "Z")),
            move |_| 1.0 + l as f32,
            opaque,
            W * H,
        ));
    }
    write_single_part(&path, channels);
    let options = ReadOptions {
        layers: Some(vec!["bg".into(), "fg_h*".into()]),
        ..ReadOptions::default()
    };
    let file = read_stack(&path, &options).unwrap();
    let names: Vec<&str> = file.stack.layers.iter().map(|l| l.name.as_str()).collect();
    assert_eq!(
        names,
        ["fg_hair", "bg"],
        "front to back by depth, whatever the order asked"
    );
    let extras = file
        .info
        .extra_channels
        .iter()
        .filter(|c| c.name.starts_with("fg_body."))
        .count();
    assert_eq!(extras, 5, "unselected layers are passed through");

    let options = ReadOptions {
        layers: Some(vec!["nope".into()]),
        ..ReadOptions::default()
    };
    let message = read_stack(&path, &options).unwrap_err().to_string();
    assert!(
        message.contains("no layer matches 'nope'")
            && ["fg_hair", "fg_body", "bg"]
                .iter()
                .all(|n| message.contains(n)),
        "{message}"
    );
}

#[test]
fn errors_name_the_problem() {
    let dir = common::temp_dir("stack-io", "errors");
    // The I/O cause is the error's source (printed after it by the CLI), not its message.
    let missing = lensblur::error::full_message(
        &read_stack(&dir.join("missing.exr"), &ReadOptions::default()).unwrap_err(),
    );
    assert!(
        missing.contains("missing.exr") && missing.to_lowercase().contains("no such file"),
        "{missing}"
    );

    let not_exr = dir.join("text.exr");
    std::fs::write(&not_exr, "hello").unwrap();
    let message = read_stack(&not_exr, &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(message.contains("not an OpenEXR file"), "{message}");

    let no_depth = dir.join("nodepth.exr");
    let mut channels = layer_channels(
        0,
        as_refs(&names("fg.", false, "Z")),
        |_| 1.0,
        opaque,
        W * H,
    );
    channels.retain(|(n, _)| n != "fg.Z");
    write_single_part(&no_depth, channels);
    let message = read_stack(&no_depth, &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("no layer has both colour and depth")
            && message.contains("'fg' [fg.R, fg.G, fg.B, fg.A]"),
        "{message}"
    );
    let options = ReadOptions {
        layers: Some(vec!["fg".into()]),
        ..ReadOptions::default()
    };
    let message = read_stack(&no_depth, &options).unwrap_err().to_string();
    assert!(
        message.contains("layer 'fg' has no depth") && message.contains("fg.R"),
        "{message}"
    );

    let nan = dir.join("nan.exr");
    let mut channels = layer_channels(
        0,
        as_refs(&names("fg.", false, "Z")),
        |_| 1.0,
        opaque,
        W * H,
    );
    channels[1].1 = half((0..W * H).map(|i| if i < 3 { f32::NAN } else { 0.5 }));
    write_single_part(&nan, channels);
    let message = read_stack(&nan, &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("layer 'fg' channel 'fg.G' has 3 NaN/Inf"),
        "{message}"
    );

    let options = ReadOptions {
        max_pixels: 10,
        ..ReadOptions::default()
    };
    let message = read_stack(&nan, &options).unwrap_err().to_string();
    assert!(message.contains("exceeds the limit"), "{message}");
}

fn sample_stack() -> LayerStack {
    let front = Image::from_fn(W, H, |x, _| {
        if x < 4 {
            [0.5, 0.25, 0.125, 1.0]
        } else if x == 4 {
            [0.25, 0.0, 0.5, 0.5]
        } else {
            [0.0; 4]
        }
    });
    let back = Image::from_fn(W, H, |x, y| [x as f32 / 8.0, y as f32 / 8.0, 0.75, 1.0]);
    let layers = vec![
        Layer {
            name: "fg".into(),
            rgba: front,
            disparity: vec![0.5; W * H],
        },
        Layer {
            name: "bg".into(),
            rgba: back,
            disparity: (0..W * H).map(|i| 0.1 + (i % W) as f32 * 0.01).collect(),
        },
    ];
    LayerStack::new(W, H, layers).unwrap()
}

#[test]
fn written_stacks_read_back_identically_in_every_naming_and_depth_kind() {
    let dir = common::temp_dir("stack-io", "stack_rt");
    for naming in [StackNaming::BlenderMultilayer, StackNaming::LayerDotChannel, StackNaming::MultiPart] {
        for kind in [DepthKind::Z, DepthKind::InverseZ, DepthKind::Disparity] {
            let path = dir.join(format!("{naming:?}-{kind:?}.exr"));
            let stack = sample_stack();
            write_stack(
                &path,
                &stack,
                &StackWriteOptions {
                    depth_kind: kind,
                    naming,
                    camera: None,
                },
            )
            .unwrap();
            let back = read_stack(
                &path,
                &ReadOptions {
                    depth_kind: kind,
                    ..ReadOptions::default()
                },
            )
            .unwrap();
            assert_eq!(back.stack.layers.len(), 2);
            for (a, b) in stack.layers.iter().zip(&back.stack.layers) {
                assert_eq!(a.name, b.name);
                assert_eq!(a.rgba, b.rgba, "float colour round-trips exactly");
                for (i, (&da, &db)) in a.disparity.iter().zip(&b.disparity).enumerate() {
                    // 1/(1/d) in f32: a few ulps. Empty pixels are refilled from covered ones.
                    if a.rgba.pixels[i][3] > 0.0 {
                        assert!(
                            (da - db).abs() < 1e-6,
                            "{naming:?} {kind:?} pixel {i}: {da} vs {db}"
                        );
                    }
                }
            }
            // Read back in the convention it was written in, which writes back the same way.
            assert!(back.info.layers.iter().all(|l| StackNaming::for_convention(l.convention) == naming));
        }
    }
}

#[test]
fn written_images_carry_names_precision_and_pass_through_channels() {
    let dir = common::temp_dir("stack-io", "image_rt");
    let image = Image::from_fn(W, H, |x, y| [x as f32 / 3.0, y as f32 / 7.0, 0.1, 1.0]);
    let extra = ExtraChannel {
        name: "CryptoObject00.R".into(),
        sample_type: SampleType::Float,
        values: (0..W * H).map(|i| i as f32 * 1.5).collect(),
    };
    let camera = lensblur::camera::PhysicalCamera {
        focal_length_mm: 85.0,
        sensor_width_mm: 23.5,
        fstop: 1.8,
        focus_distance: 2.5,
    };
    let options = WriteOptions {
        output_layer: Some("Blurred".into()),
        sample_type: SampleType::Half,
        extra_channels: vec![extra],
        camera: Some(camera),
        ..WriteOptions::default()
    };
    let path = dir.join("out.exr");
    write_image(&path, &image, &options).unwrap();
    // The camera stamped into the header comes back through the reader's attribute map.
    let (_, attributes) = lensblur::stack::read_parts(&path, 1 << 20).unwrap();
    assert_eq!(
        lensblur::camera::CameraHints::from_attributes(&attributes),
        lensblur::camera::CameraHints::from_camera(&camera)
    );
    let read = exr::prelude::read_all_flat_layers_from_file(&path).unwrap();
    let channels = &read.layer_data[0].channel_data.list;
    let names: Vec<String> = channels.iter().map(|c| c.name.to_string()).collect();
    assert_eq!(
        names,
        [
            "Blurred.Combined.A",
            "Blurred.Combined.B",
            "Blurred.Combined.G",
            "Blurred.Combined.R",
            "CryptoObject00.R"
        ]
    );
    assert!(
        matches!(channels[3].sample_data, FlatSamples::F16(_)),
        "colour written as half"
    );
    let red: Vec<f32> = channels[3].sample_data.values_as_f32().collect();
    // Half precision: relative error below 2^-11.
    assert!(image
        .pixels
        .iter()
        .zip(&red)
        .all(|(p, &r)| (p[0] - r).abs() <= p[0].abs() / 2048.0));
    let crypto: Vec<f32> = channels[4].sample_data.values_as_f32().collect();
    assert_eq!(
        crypto,
        (0..W * H).map(|i| i as f32 * 1.5).collect::<Vec<_>>(),
        "pass-through is bit exact"
    );
    assert_eq!(
        read.layer_data[0].encoding.compression,
        exr::prelude::Compression::ZIP16
    );

    let plain = dir.join("plain.exr");
    write_image(
        &plain,
        &image,
        &WriteOptions {
            sample_type: SampleType::Float,
            ..WriteOptions::default()
        },
    )
    .unwrap();
    let read = exr::prelude::read_all_flat_layers_from_file(&plain).unwrap();
    let names: Vec<String> = read.layer_data[0]
        .channel_data
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    assert_eq!(names, ["A", "B", "G", "R"]);
}

#[test]
fn failed_writes_leave_nothing_behind() {
    let dir = common::temp_dir("stack-io", "atomic");
    let image = Image::new(W, H);
    let bad = ExtraChannel {
        name: "R".into(),
        sample_type: SampleType::Float,
        values: vec![0.0; W * H],
    };
    let path = dir.join("collide.exr");
    let error = write_image(
        &path,
        &image,
        &WriteOptions {
            extra_channels: vec![bad],
            ..WriteOptions::default()
        },
    )
    .unwrap_err();
    assert!(error.to_string().contains("collides"), "{error}");
    let short = ExtraChannel {
        name: "X".into(),
        sample_type: SampleType::Float,
        values: vec![0.0; 3],
    };
    assert!(write_image(
        &path,
        &image,
        &WriteOptions {
            extra_channels: vec![short],
            ..WriteOptions::default()
        }
    )
    .is_err());
    assert!(write_image(
        &dir.join("no/such/dir/x.exr"),
        &image,
        &WriteOptions::default()
    )
    .is_err());
    let left: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
    assert!(left.is_empty(), "no partial or temporary files: {left:?}");
}

#[test]
fn ldr_inputs_are_decoded_to_linear_and_depth_images_follow_the_depth_kind() {
    let dir = common::temp_dir("stack-io", "ldr");
    let colour = image::RgbImage::from_fn(4, 2, |x, _| image::Rgb([(x * 80) as u8, 128, 255]));
    colour.save(dir.join("photo.png")).unwrap();
    let depth16 = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(4, 2, |x, _| {
        image::Luma([(x * 20000) as u16])
    });
    depth16.save(dir.join("depth.png")).unwrap();
    let input = read_ldr(
        &dir.join("photo.png"),
        &dir.join("depth.png"),
        DepthKind::Disparity,
        DEFAULT_MAX_PIXELS,
    )
    .unwrap();
    // sRGB 128/255 is 0.2158 linear (IEC 61966-2-1).
    assert!(
        (input.image.pixels[0][1] - 0.2158).abs() < 1e-3,
        "{:?}",
        input.image.pixels[0]
    );
    assert!(
        (input.disparity[3] - 60000.0 / 65535.0).abs() < 1e-6,
        "16-bit precision is kept"
    );
    let as_z = read_ldr(&dir.join("photo.png"), &dir.join("depth.png"), DepthKind::Z, DEFAULT_MAX_PIXELS).unwrap();
    assert_eq!(as_z.disparity[0], 0.0, "z = 0 (no data) is far");
    assert!((as_z.disparity[1] - 65535.0 / 20000.0).abs() < 1e-3);

    let small = image::GrayImage::new(3, 2);
    small.save(dir.join("small.png")).unwrap();
    let message = read_ldr(&dir.join("photo.png"), &dir.join("small.png"), DepthKind::Z, DEFAULT_MAX_PIXELS)
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("depth is 3x2 but the image is 4x2"),
        "{message}"
    );

    let preview = dir.join("preview.png");
    write_png_preview(&preview, &input.image).unwrap();
    let back = image::open(&preview).unwrap().to_rgba8();
    assert_eq!(
        back.get_pixel(1, 0).0,
        [80, 128, 255, 255],
        "encode(decode(v)) = v for 8-bit values"
    );
}
