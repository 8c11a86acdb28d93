//! Interop with OpenImageIO (`oiiotool`, `iinfo` from Debian's `openimageio-tools`): files
//! it writes are read correctly, files we write it reads. These fail, never skip, when the
//! tools are missing: CI installs them.
mod common;
use std::path::Path;
use std::process::Command;

use lensblur::image::Image;
use lensblur::stack::naming::Convention;
use lensblur::stack::{
    read_stack, write_image, write_stack, DepthKind, Layer, LayerStack, ReadOptions, SampleType,
    StackNaming, StackWriteOptions, WriteOptions,
};


/// Runs a tool and returns its stdout; panics (test failure) if it is missing or fails.
fn tool(program: &str, args: &[&str]) -> String {
    let output = Command::new(program)
        .args(args)
        .output()
        .unwrap_or_else(|e| {
            panic!(
                "cannot run {program} ({e}); install it with: apt-get install -y openimageio-tools"
            )
        });
    assert!(
        output.status.success(),
        "{program} {args:?} failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8_lossy(&output.stdout).into_owned()
}

fn s(path: &Path) -> &str {
    path.to_str().unwrap()
}

#[test]
fn oiiotool_layer_dot_channel_files_read_correctly() {
    let dir = common::temp_dir("oiio", "layers");
    let path = dir.join("layers.exr");
    #[rustfmt::skip]
    tool("oiiotool", &[
        "--pattern", "constant:color=0.5,0.25,0.125,1,3", "16x12", "5", "--chnames", "fg.R,fg.G,fg.B,fg.A,fg.Z",
        "--pattern", "constant:color=0.125,0.25,0.75,1,10", "16x12", "5", "--chnames", "bg.red,bg.green,bg.blue,bg.alpha,bg.depth",
        "--chappend", "-d", "half", "-o", s(&path),
    ]);
    let file = read_stack(&path, &ReadOptions::default()).unwrap();
    let [fg, bg] = &file.stack.layers[..] else {
        panic!("two layers expected, got {}", file.stack.layers.len())
    };
    assert_eq!((fg.name.as_str(), bg.name.as_str()), ("fg", "bg"));
    // Multiples of 1/8 are exact in half; 1/3 of a half-exact 3 is f32-exact to 1e-6.
    assert!(fg.rgba.pixels.iter().all(|p| *p == [0.5, 0.25, 0.125, 1.0]));
    assert!(
        bg.rgba
            .pixels
            .iter()
            .all(|p| *p == [0.125, 0.25, 0.75, 1.0]),
        "long names map by name"
    );
    assert!(fg.disparity.iter().all(|&d| (d - 1.0 / 3.0).abs() < 1e-6));
    assert!(bg.disparity.iter().all(|&d| (d - 0.1).abs() < 1e-6));
    assert!(file
        .info
        .layers
        .iter()
        .all(|l| l.convention == Convention::LayerDotChannel));
}

#[test]
fn oiiotool_multi_part_files_use_part_names() {
    let dir = common::temp_dir("oiio", "parts");
    let path = dir.join("parts.exr");
    #[rustfmt::skip]
    tool("oiiotool", &[
        "--pattern", "constant:color=0.5,0.5,0.5,1,2", "8x6", "5", "--chnames", "R,G,B,A,Z", "--attrib", "oiio:subimagename", "near",
        "--pattern", "constant:color=0.25,0.5,1,1,8", "8x6", "5", "--chnames", "R,G,B,A,Z", "--attrib", "oiio:subimagename", "far",
        "--siappend", "-d", "float", "-o", s(&path),
    ]);
    let file = read_stack(&path, &ReadOptions::default()).unwrap();
    let names: Vec<&str> = file.stack.layers.iter().map(|l| l.name.as_str()).collect();
    assert_eq!(names, ["near", "far"]);
    assert!(file
        .info
        .layers
        .iter()
        .all(|l| l.convention == Convention::MultiPart));
    assert!(file.stack.layers[1]
        .rgba
        .pixels
        .iter()
        .all(|p| *p == [0.25, 0.5, 1.0, 1.0]));
    assert!(file.stack.layers[1].disparity.iter().all(|&d| d == 0.125));
}

#[test]
fn oiiotool_data_windows_are_placed_in_the_display_window() {
    let dir = common::temp_dir("oiio", "window");
    let path = dir.join("window.exr");
    #[rustfmt::skip]
    tool("oiiotool", &[
        "--pattern", "constant:color=1,0.5,0.25,1,4", "10x8", "5", "--chnames", "R,G,B,A,Z",
        "--origin", "+3+2", "--fullsize", "20x16+0+0", "-d", "half", "-o", s(&path),
    ]);
    let file = read_stack(&path, &ReadOptions::default()).unwrap();
    let layer = &file.stack.layers[0];
    assert_eq!((file.stack.width, file.stack.height), (20, 16));
    assert!(file.info.single_image);
    assert_eq!(file.info.layers[0].data_window.x, 3);
    for y in 0..16 {
        for x in 0..20 {
            let inside = (3..13).contains(&x) && (2..10).contains(&y);
            let expected = if inside {
                [1.0, 0.5, 0.25, 1.0]
            } else {
                [0.0; 4]
            };
            assert_eq!(layer.rgba.get(x, y), expected, "({x},{y})");
        }
    }
    assert!(
        layer.disparity.iter().all(|&d| d == 0.25),
        "outside the data window depth is filled from inside"
    );
}

#[test]
fn oiiotool_parts_with_different_data_windows_share_the_display_window() {
    // OpenEXR itself refuses parts with different display windows, so sizes can only differ
    // in data windows: a small part must land at its offset in the common frame.
    let dir = common::temp_dir("oiio", "partwindows");
    let path = dir.join("partwindows.exr");
    #[rustfmt::skip]
    tool("oiiotool", &[
        "--pattern", "constant:color=0.5,0.5,0.5,1,8", "8x6", "5", "--chnames", "R,G,B,A,Z", "--attrib", "oiio:subimagename", "back",
        "--pattern", "constant:color=1,0,0,1,2", "4x3", "5", "--chnames", "R,G,B,A,Z", "--origin", "+2+1", "--fullsize", "8x6+0+0",
        "--attrib", "oiio:subimagename", "front", "--siappend", "-o", s(&path),
    ]);
    let file = read_stack(&path, &ReadOptions::default()).unwrap();
    let front = &file.stack.layers[0];
    assert_eq!(front.name, "front");
    assert_eq!((front.rgba.width, front.rgba.height), (8, 6));
    assert_eq!(front.rgba.get(2, 1), [1.0, 0.0, 0.0, 1.0]);
    assert_eq!(front.rgba.get(5, 3), [1.0, 0.0, 0.0, 1.0]);
    assert_eq!(front.rgba.get(1, 1)[3], 0.0);
    assert_eq!(front.rgba.get(6, 4)[3], 0.0);
}

#[test]
fn render_outputs_keep_oiio_layer_names_parts_and_windows() {
    let dir = common::temp_dir("oiio", "render-names");
    let (layers, parts) = (dir.join("layers.exr"), dir.join("parts.exr"));
    #[rustfmt::skip]
    tool("oiiotool", &[
        "--pattern", "constant:color=0.5,0.25,0.125,1,3", "16x12", "5", "--chnames", "fg.R,fg.G,fg.B,fg.A,fg.Z",
        "--pattern", "constant:color=0.125,0.25,0.75,1,10", "16x12", "5", "--chnames", "bg.R,bg.G,bg.B,bg.A,bg.Z",
        "--chappend", "--origin", "-2+3", "--fullsize", "16x12-2+3", "-d", "half", "-o", s(&layers),
    ]);
    #[rustfmt::skip]
    tool("oiiotool", &[
        "--pattern", "constant:color=0.5,0.5,0.5,1,2", "8x6", "5", "--chnames", "R,G,B,A,Z", "--attrib", "oiio:subimagename", "near",
        "--pattern", "constant:color=0.25,0.5,1,1,8", "8x6", "5", "--chnames", "R,G,B,A,Z", "--attrib", "oiio:subimagename", "far",
        "--siappend", "-d", "float", "-o", s(&parts),
    ]);
    let render = |input: &Path, output: &Path| {
        let run = Command::new(env!("CARGO_BIN_EXE_lensblur"))
            .args(["render", s(input), "-o", s(output), "--output-layer", "dof", "--method", "oracle"])
            .args(["--blur", "10", "--focus-disparity", "0.1"])
            .output()
            .unwrap();
        assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    };
    let out = dir.join("layers-dof.exr");
    render(&layers, &out);
    let info = tool("iinfo", &["-v", s(&out)]);
    for line in ["channel list: dof.R, dof.G, dof.B, dof.A", "full/display origin: -2, 3", "pixel data origin: x=-2, y=3"] {
        assert!(info.contains(line), "'{line}' missing in:\n{info}");
    }
    // The constant layers stay constant under any blur: oiiotool sees fg over bg.
    let stats = tool("oiiotool", &[s(&out), "--ch", "dof.R,dof.G,dof.B,dof.A", "--printstats"]);
    assert_eq!(stats_line(&stats, "Stats Max:"), [0.5, 0.25, 0.125, 1.0], "{stats}");

    let out = dir.join("parts-dof.exr");
    render(&parts, &out);
    let info = tool("iinfo", &["-v", s(&out)]);
    for line in ["channel list: R, G, B, A", "oiio:subimagename: \"dof\""] {
        assert!(info.contains(line), "'{line}' missing in:\n{info}");
    }
}

fn stats_line(stats: &str, key: &str) -> Vec<f64> {
    let line = stats
        .lines()
        .find(|l| l.trim_start().starts_with(key))
        .unwrap_or_else(|| panic!("no '{key}' in:\n{stats}"));
    line.split_whitespace()
        .filter_map(|w| w.parse().ok())
        .collect()
}

#[test]
fn our_outputs_read_back_in_oiiotool() {
    let dir = common::temp_dir("oiio", "ours");
    let image = Image::filled(12, 10, [0.25, 0.5, 0.75, 1.0]);
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
    let info = tool("iinfo", &["-v", s(&plain)]);
    assert!(
        info.contains("12 x   10, 4 channel, float openexr")
            && info.contains("compression: \"zip\""),
        "{info}"
    );
    let stats = tool("oiiotool", &["--stats", s(&plain)]);
    assert_eq!(stats_line(&stats, "Stats Min:"), [0.25, 0.5, 0.75, 1.0]);
    assert_eq!(stats_line(&stats, "Stats Max:"), [0.25, 0.5, 0.75, 1.0]);

    let named = dir.join("named.exr");
    write_image(
        &named,
        &image,
        &WriteOptions {
            output_layer: Some("Blur".into()),
            ..WriteOptions::default()
        },
    )
    .unwrap();
    let info = tool("iinfo", &["-v", s(&named)]);
    assert!(
        info.contains("half openexr") && info.contains("Blur.Combined.R"),
        "{info}"
    );

    let front = Image::from_fn(12, 10, |x, _| {
        if x < 6 {
            [0.5, 0.0, 0.0, 1.0]
        } else {
            [0.0; 4]
        }
    });
    let layers = vec![
        Layer {
            name: "fg".into(),
            rgba: front,
            disparity: vec![0.5; 120],
        },
        Layer {
            name: "bg".into(),
            rgba: image.clone(),
            disparity: vec![0.125; 120],
        },
    ];
    let stack_path = dir.join("stack.exr");
    write_stack(
        &stack_path,
        &LayerStack::new(12, 10, layers).unwrap(),
        &StackWriteOptions {
            depth_kind: DepthKind::Z,
            naming: StackNaming::BlenderMultilayer,
            camera: None,
        },
    )
    .unwrap();
    let info = tool("iinfo", &["-v", s(&stack_path)]);
    for name in ["fg.Combined.R", "fg.Depth.Z", "bg.Combined.A", "bg.Depth.Z"] {
        assert!(info.contains(name), "{name} missing in:\n{info}");
    }
    let depth = tool(
        "oiiotool",
        &[s(&stack_path), "--ch", "fg.Depth.Z", "--printstats"],
    );
    // Covered pixels store z = 1/0.5 = 2; empty ones Blender's 1e10 sentinel.
    assert_eq!(stats_line(&depth, "Stats Min:"), [2.0]);
    assert_eq!(stats_line(&depth, "Stats Max:"), [1.0e10]);
}

/// Our ZIP blocks (`exr_zip.rs`, libdeflate) as OpenEXR's own library reads them: every sample
/// exact, through oiiotool rewriting the file uncompressed, for float and half, over an odd
/// size whose last block is short, with smooth rows (compressed blocks) and noise (blocks the
/// coding would not shrink, stored raw as the format asks).
#[test]
fn openexr_reads_our_zip_blocks_sample_for_sample() {
    let dir = common::temp_dir("oiio", "zip-blocks");
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut noise = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        f32::from_bits(((state >> 41) as u32) | 0x3f80_0000) - 1.0
    };
    let (width, height) = (77, 53);
    let image = Image::from_fn(width, height, |x, y| {
        if y < 20 {
            let v = x as f32 * 0.013 + y as f32 * 0.5;
            [v, v * 2.0, 100.0 - v, 1.0]
        } else {
            [noise() * 40.0, noise(), noise() * 0.001, noise()]
        }
    });
    for (sample_type, tolerance) in [(SampleType::Float, 0.0f32), (SampleType::Half, 1.0 / 1024.0)] {
        let ours = dir.join("ours.exr");
        write_image(&ours, &image, &WriteOptions { sample_type, ..WriteOptions::default() }).unwrap();
        let theirs = dir.join("theirs.exr");
        tool("oiiotool", &[s(&ours), "--compression", "none", "-o", s(&theirs)]);
        let back = lensblur::stack::read_rgba(&theirs, None, u64::MAX).unwrap();
        assert_eq!((back.width, back.height), (width, height));
        for (i, (a, b)) in image.pixels.iter().zip(&back.pixels).enumerate() {
            for c in 0..4 {
                // Half rounds to 11 significant bits: relative error up to 2^-11.
                let allowed = tolerance * a[c].abs().max(1e-3);
                assert!((a[c] - b[c]).abs() <= allowed, "{sample_type:?} pixel {i} channel {c}: wrote {}, OpenEXR read {}", a[c], b[c]);
            }
        }
    }
}

/// Tiled files as OpenImageIO writes them (what `maketx`-style textures and tiled renders
/// hand over) read sample for sample: plain tiles whose last row and column are partial, and a
/// mip-mapped texture (`-otex`), whose largest level is the image and whose smaller levels are
/// not read.
#[test]
fn oiiotool_tiled_and_mip_mapped_files_read_sample_for_sample() {
    let dir = common::temp_dir("oiio", "tiled");
    let (width, height) = (83, 45);
    let image = Image::from_fn(width, height, |x, y| [x as f32 * 0.25 - 3.0, y as f32 * 1.5, (x * y) as f32 * 0.01, 0.5 + 0.005 * x as f32]);
    let ours = dir.join("scanlines.exr");
    write_image(&ours, &image, &WriteOptions { sample_type: SampleType::Float, ..WriteOptions::default() }).unwrap();
    for (name, args) in [
        ("tiles.exr", vec!["--tile", "16", "16", "--compression", "zip"]),
        ("tall-tiles.exr", vec!["--tile", "8", "32", "--compression", "piz"]),
        ("texture.exr", vec!["-otex"]),
    ] {
        let theirs = dir.join(name);
        let mut command = vec![s(&ours)];
        command.extend(args.iter().copied());
        if args != ["-otex"] {
            command.push("-o");
        }
        command.push(s(&theirs));
        tool("oiiotool", &command);
        let info = tool("oiiotool", &["--info", "-v", s(&theirs)]);
        assert!(info.contains("tile size"), "{name} is tiled: {info}");
        if name == "texture.exr" {
            assert!(info.contains("MIP-map levels"), "{name} is mip-mapped: {info}");
        }
        let back = lensblur::stack::read_rgba(&theirs, None, u64::MAX).unwrap();
        assert_eq!((back.width, back.height), (width, height), "{name}");
        for (i, (a, b)) in image.pixels.iter().zip(&back.pixels).enumerate() {
            assert_eq!(a, b, "{name} pixel {i}");
        }
    }
}
