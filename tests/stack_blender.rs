//! Interop with Blender (Debian's `blender` 3.4, run headless): a Cycles multilayer render
//! with two view layers and the compositor's File Output node are read correctly, and the
//! files we write load in Blender (image + compositor Image node) with the same pixels.
//! Blender 5's default multilayer EXR (multi-part, one part per pass) reads as the single-part
//! file of the same render. Slow (several Blender starts), so it lives in its own test file.
//! Fails, never skips, when Blender or a bpy virtualenv is missing: CI installs them.
mod common;
mod plugin_common;
use std::path::{Path, PathBuf};
use std::process::Command;

use lensblur::image::Image;
use lensblur::stack::naming::Convention;
use lensblur::stack::{
    read_stack, write_image, write_stack, DepthKind, Layer, LayerStack, ReadOptions, StackNaming,
    StackWriteOptions, WriteOptions,
};


fn script(name: &str) -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .join("tests/interop")
        .join(name)
}

/// Runs a Python script in headless Blender; returns stdout. Panics if Blender is missing,
/// fails, or the script did not reach its final marker line.
fn blender(script_name: &str, args: &[&str], done_marker: &str) -> String {
    let script = script(script_name);
    let output = Command::new("blender")
        .args([
            "-b",
            "--factory-startup",
            "--python-exit-code",
            "1",
            "--python",
        ])
        .arg(&script)
        .arg("--")
        .args(args)
        .output()
        .unwrap_or_else(|e| {
            panic!("cannot run blender ({e}); install it with: apt-get install -y blender")
        });
    let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
    assert!(
        output.status.success() && stdout.contains(done_marker),
        "blender {script_name} failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    stdout
}

fn render_scene(dir: &Path) {
    blender(
        "blender_render.py",
        &[dir.to_str().unwrap()],
        "LENSBLUR_RENDER_DONE",
    );
}

#[test]
fn blender_multilayer_render_and_file_output_nodes_are_read_correctly() {
    let dir = common::temp_dir("blender", "render");
    render_scene(&dir);
    let file = read_stack(&dir.join("render.exr"), &ReadOptions::default()).unwrap();
    let names: Vec<&str> = file.stack.layers.iter().map(|l| l.name.as_str()).collect();
    assert_eq!(
        names,
        ["Front", "Back"],
        "the Composite pass has no depth and is not a layer"
    );
    assert!(file
        .info
        .layers
        .iter()
        .all(|l| l.convention == Convention::BlenderMultilayer));
    let (front, back) = (&file.stack.layers[0], &file.stack.layers[1]);
    // The front plane is 5 m away, the back plane 10 m: disparity 0.2 and 0.1 everywhere,
    // also where the front layer is empty (Z = 1e10 there) or partly covered.
    assert!(
        front.disparity.iter().all(|&d| (d - 0.2).abs() < 1e-4),
        "{:?}",
        file.info.layers[0].disparity_range
    );
    assert!(back.disparity.iter().all(|&d| (d - 0.1).abs() < 1e-4));
    // Emission colour (1, 0.2, 0.1) at the centre; half precision: 1e-3.
    let centre = front.rgba.get(16, 12);
    assert!(
        (centre[0] - 1.0).abs() < 1e-3
            && (centre[1] - 0.2).abs() < 1e-3
            && (centre[2] - 0.1).abs() < 1e-3,
        "{centre:?}"
    );
    assert_eq!(
        front.rgba.get(0, 0)[3],
        0.0,
        "transparent film: the front layer is empty in the corner"
    );
    assert!(
        back.rgba.pixels.iter().all(|p| (p[3] - 1.0).abs() < 1e-3),
        "the back plane fills the frame"
    );
    let extras: Vec<&str> = file
        .info
        .extra_channels
        .iter()
        .map(|c| c.name.as_str())
        .collect();
    assert!(extras.contains(&"Composite.Combined.R"), "{extras:?}");

    let fo = read_stack(&dir.join("fileout_0001.exr"), &ReadOptions::default()).unwrap();
    assert!(fo.info.single_image);
    assert_eq!(fo.info.layers[0].convention, Convention::BlenderFileOutput);
    assert_eq!(fo.info.layers[0].channels.depth.as_deref(), Some("Depth.V"));
    let layer = &fo.stack.layers[0];
    // The File Output node saw the same Front layer (float here): same pixels within half rounding.
    for (a, b) in layer.rgba.pixels.iter().zip(&front.rgba.pixels) {
        assert!((0..4).all(|k| (a[k] - b[k]).abs() < 1e-3), "{a:?} vs {b:?}");
    }
    assert!(layer.disparity.iter().all(|&d| (d - 0.2).abs() < 1e-4));

    // One File Output node writing both layers with per-layer slots: colour `fg` + depth
    // `fgDepth`, colour `bg_Image` + depth `bg_Z` (Blender names the channels `fgDepth.V`...).
    let slots = read_stack(&dir.join("stack_0001.exr"), &ReadOptions::default()).unwrap();
    let names: Vec<&str> = slots.stack.layers.iter().map(|l| l.name.as_str()).collect();
    assert_eq!(names, ["fg", "bg_Image"], "front to back");
    let depth: Vec<Option<&str>> = slots.info.layers.iter().map(|l| l.channels.depth.as_deref()).collect();
    assert_eq!(depth, [Some("fgDepth.V"), Some("bg_Z.V")]);
    assert!(slots.info.layers.iter().all(|l| l.convention == Convention::BlenderFileOutput));
    assert!(!slots.info.single_image);
    for (layer, rendered, disparity) in [(&slots.stack.layers[0], front, 0.2), (&slots.stack.layers[1], back, 0.1)] {
        // Same view layers as the multilayer render (float here, half there): half rounding.
        for (a, b) in layer.rgba.pixels.iter().zip(&rendered.rgba.pixels) {
            assert!((0..4).all(|k| (a[k] - b[k]).abs() < 1e-3), "{}: {a:?} vs {b:?}", layer.name);
        }
        assert!(layer.disparity.iter().all(|&d| (d - disparity).abs() < 1e-4), "{}", layer.name);
    }
}

/// Loads `path` in Blender, pipes `layer`'s colour pass through the compositor into a plain
/// EXR, and returns (Blender's report line, the pixels Blender produced).
fn blender_roundtrip(path: &Path, layer: &str, size: (usize, usize)) -> (String, Image) {
    let out = path.with_extension("blender.exr");
    let (w, h) = (size.0.to_string(), size.1.to_string());
    let stdout = blender(
        "blender_load.py",
        &[path.to_str().unwrap(), out.to_str().unwrap(), layer, &w, &h],
        "LENSBLUR_LOAD_DONE",
    );
    let report = stdout
        .lines()
        .find(|l| l.starts_with("LENSBLUR_LOAD "))
        .unwrap_or_default()
        .to_string();
    (report, read_plain(&out))
}

/// Reads a plain RGBA EXR written by Blender (no depth) with the exr crate.
fn read_plain(path: &Path) -> Image {
    use exr::prelude::ReadChannels;
    use exr::prelude::ReadLayers;
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |size, _| Image::new(size.width(), size.height()),
            |img: &mut Image, pos, (r, g, b, a): (f32, f32, f32, f32)| {
                img.set(pos.x(), pos.y(), [r, g, b, a])
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .unwrap();
    image.layer_data.channel_data.pixels
}

#[test]
fn our_files_load_in_blender_with_the_same_pixels() {
    let dir = common::temp_dir("blender", "ours");
    let (w, h) = (12, 8);
    let colour = Image::from_fn(w, h, |x, y| [x as f32 / 16.0, y as f32 / 8.0, 0.5, 1.0]);
    let front = Image::from_fn(w, h, |x, _| {
        if x < 6 {
            [0.75, 0.125, 0.0, 1.0]
        } else {
            [0.0; 4]
        }
    });
    let layers = vec![
        Layer {
            name: "fg".into(),
            rgba: front.clone(),
            disparity: vec![0.5; w * h],
        },
        Layer {
            name: "bg".into(),
            rgba: colour.clone(),
            disparity: vec![0.1; w * h],
        },
    ];
    let stack_path = dir.join("stack.exr");
    write_stack(
        &stack_path,
        &LayerStack::new(w, h, layers).unwrap(),
        &StackWriteOptions {
            depth_kind: DepthKind::Z,
            naming: StackNaming::BlenderMultilayer,
            camera: None,
        },
    )
    .unwrap();
    let (report, pixels) = blender_roundtrip(&stack_path, "fg", (w, h));
    assert!(
        report.contains("\"MULTILAYER\"") && report.contains("\"bg\"") && report.contains("\"fg\""),
        "{report}"
    );
    assert!(
        report.contains("\"Combined\"") && report.contains("\"Depth\""),
        "Blender sees the Depth pass: {report}"
    );
    // Values are multiples of 1/16, exact in Blender's float pipeline.
    assert_eq!(pixels, front);

    let named = dir.join("named.exr");
    write_image(
        &named,
        &colour,
        &WriteOptions {
            output_layer: Some("Blurred".into()),
            ..WriteOptions::default()
        },
    )
    .unwrap();
    let (report, pixels) = blender_roundtrip(&named, "Blurred", (w, h));
    assert!(report.contains("\"Blurred\""), "{report}");
    assert_eq!(
        pixels, colour,
        "half-exact values survive Blender's Image node"
    );

    let plain = dir.join("plain.exr");
    write_image(&plain, &colour, &WriteOptions::default()).unwrap();
    let (report, pixels) = blender_roundtrip(&plain, "", (w, h));
    assert!(report.contains("\"IMAGE\""), "{report}");
    assert_eq!(pixels, colour);
}

/// Blender 5 saves a multilayer EXR multi-part unless told to interleave: one part per pass
/// (`L_front.Combined`, `L_front.Depth`, ...), colour and depth of a layer in different parts.
/// The same render saved both ways must give the same stack, sample for sample.
fn blender_5_multi_part_render_reads_as_its_single_part_twin(version: &str) {
    let blender = plugin_common::Blender::bpy(version);
    let dir = common::temp_dir("blender", &format!("multipart-{version}"));
    let output = blender.script_command(&script("blender_multipart.py")).arg(&*dir).output().unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success() && stdout.contains("LENSBLUR_MULTIPART_DONE"),
        "bpy {version}: blender_multipart.py failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let (parts, interleaved) = (dir.join("parts.exr"), dir.join("interleaved.exr"));
    let part_count = |path: &Path| exr::meta::MetaData::read_from_file(path, false).unwrap().headers.len();
    assert_eq!(part_count(&parts), 6, "Blender's default: colour and depth parts for each of the 3 view layers");
    assert_eq!(part_count(&interleaved), 1);

    let split = read_stack(&parts, &ReadOptions::default()).unwrap();
    let joined = read_stack(&interleaved, &ReadOptions::default()).unwrap();
    for file in [&split, &joined] {
        let names: Vec<&str> = file.stack.layers.iter().map(|l| l.name.as_str()).collect();
        assert_eq!(names, ["L_front", "L_mid", "L_back"], "front to back");
        assert!(file.info.layers.iter().all(|l| l.convention == Convention::BlenderMultilayer));
    }
    for (a, b) in split.stack.layers.iter().zip(&joined.stack.layers) {
        assert!(a.rgba.pixels == b.rgba.pixels, "{}: colour differs between the two layouts", a.name);
        assert!(a.disparity == b.disparity, "{}: depth differs between the two layouts", a.name);
    }
    // Not two equal misreadings: the planes' depths (1.5 m, 4 m, 15 m; Z is planar distance)
    // where each layer is opaque.
    for (layer, distance) in split.stack.layers.iter().zip([1.5f32, 4.0, 15.0]) {
        let opaque: Vec<f32> =
            layer.disparity.iter().zip(&layer.rgba.pixels).filter(|(_, p)| p[3] > 0.999).map(|(&d, _)| d).collect();
        assert!(opaque.len() > 20, "{}: only {} opaque pixels", layer.name, opaque.len());
        assert!(opaque.iter().all(|d| (d * distance - 1.0).abs() < 1e-3), "{}: disparity not 1/{distance}", layer.name);
    }
}

#[test]
fn blender_5_0_multi_part_render_reads_as_its_single_part_twin() {
    blender_5_multi_part_render_reads_as_its_single_part_twin("5.0.1");
}

#[test]
fn blender_5_3_multi_part_render_reads_as_its_single_part_twin() {
    blender_5_multi_part_render_reads_as_its_single_part_twin("5.3.0");
}
