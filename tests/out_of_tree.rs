//! A crate outside this repository that depends on lensblur by path, with no configuration of
//! its own, builds and renders on Vulkan through the public API. The shaders' compiler used to
//! be linked through a recipe in this workspace's `.cargo/config.toml`, which dependent crates
//! never see: they failed to link (`undefined reference: glslang::...`). See docs/TOOLCHAIN.md.
//! The same crate builds `examples/render_stack.rs` as it is in this repository.
mod common;

use std::path::Path;
use std::process::Command;

// The repository root: these tests belong to the cli package (cli/Cargo.toml).
const REPO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/..");

const MANIFEST: &str = r#"[package]
name = "lensblur-dependent"
version = "0.0.0"
edition = "2021"
publish = false

[dependencies]
# The library alone: none of the command line's crates.
lensblur = { path = "REPO", default-features = false }

# Not a member of any workspace above it.
[workspace]
"#;

/// Renders a near square over a far wall with Dr.Bokeh and checks that light stays put: the
/// render of a uniform wall behind a uniform square conserves the frame's mean.
const MAIN: &str = r#"use lensblur::camera::{Aperture, CocModel};
use lensblur::image::Image;
use lensblur::render::drbokeh::{DrBokehGpu, Model};
use lensblur::render::Lens;
use lensblur::stack::{Layer, LayerStack};
use lensblur::vk::Context;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (w, h) = (48, 40);
    let near = Layer {
        name: "near".into(),
        rgba: Image::from_fn(w, h, |x, y| if (16..32).contains(&x) && (12..28).contains(&y) { [1.0, 0.2, 0.1, 1.0] } else { [0.0; 4] }),
        disparity: vec![0.8; w * h],
    };
    let far = Layer { name: "far".into(), rgba: Image::from_fn(w, h, |_, _| [0.1, 0.3, 0.9, 1.0]), disparity: vec![0.2; w * h] };
    let stack = LayerStack::new(w, h, vec![near, far])?;
    let lens = Lens { coc: CocModel::new(10.0, 0.5)?, aperture: Aperture::parse("polygon:6")? };
    let ctx = Context::from_env()?;
    let image = DrBokehGpu::new(&ctx)?.render(&stack, &lens, Model::DrBokeh)?;
    let alpha = image.pixels.iter().map(|p| p[3] as f64).sum::<f64>() / (w * h) as f64;
    ctx.finish()?;
    println!("rendered {}x{} on lensblur, mean alpha {alpha:.4}", image.width, image.height);
    Ok(())
}
"#;

#[test]
fn a_crate_outside_the_repository_builds_and_renders_through_lensblur() {
    let dir = common::temp_dir("out_of_tree", "dependent");
    std::fs::create_dir_all(dir.join("src")).unwrap();
    std::fs::write(dir.join("Cargo.toml"), MANIFEST.replace("REPO", REPO)).unwrap();
    std::fs::write(dir.join("src/main.rs"), MAIN).unwrap();
    // This repository's lock: the same crate versions, all already fetched, so --offline holds.
    std::fs::copy(Path::new(REPO).join("Cargo.lock"), dir.join("Cargo.lock")).unwrap();
    let stdout = cargo_run(&dir, &[], "the dependent crate");
    // Every pixel is covered (the wall is opaque): a mean alpha of 1 within f32 rounding.
    let line = stdout.lines().find(|l| l.starts_with("rendered 48x40 on lensblur")).unwrap_or_else(|| panic!("no report:\n{stdout}"));
    let alpha: f64 = line.rsplit(' ').next().unwrap().parse().unwrap();
    assert!((alpha - 1.0).abs() < 1e-3, "mean alpha {alpha}: {line}");

    render_stack_example_matches_the_library(&dir);
    the_library_alone_pulls_in_no_command_line_crate(&dir);
}

/// `default-features = false` is the library without the command line: its dependency tree
/// holds none of the CLI's crates (they cost a dependent build time and version conflicts).
fn the_library_alone_pulls_in_no_command_line_crate(dir: &Path) {
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let output = Command::new(cargo)
        .args(["tree", "--offline", "--prefix", "none", "--edges", "normal"])
        .current_dir(dir)
        .output()
        .unwrap();
    assert!(output.status.success(), "cargo tree: {}", String::from_utf8_lossy(&output.stderr));
    let tree = String::from_utf8_lossy(&output.stdout);
    assert!(tree.lines().any(|l| l.starts_with("lensblur ")), "lensblur missing from the tree:\n{tree}");
    for crate_name in ["clap", "indicatif", "ctrlc", "anyhow"] {
        assert!(!tree.lines().any(|l| l.starts_with(&format!("{crate_name} "))), "{crate_name} in the library's tree:\n{tree}");
    }
}

/// `examples/render_stack.rs`, copied unchanged into the dependent crate, renders a layered
/// EXR whose header carries the camera exactly as this crate's library does in-process.
fn render_stack_example_matches_the_library(dir: &Path) {
    use lensblur::camera::{Aperture, CocModel, PhysicalCamera};
    use lensblur::image::Image;
    use lensblur::render::{Lens, Method};
    use lensblur::stack::{read_rgba, write_stack, DepthKind, Layer, LayerStack, StackWriteOptions};

    std::fs::create_dir_all(dir.join("examples")).unwrap();
    std::fs::copy(Path::new(REPO).join("examples/render_stack.rs"), dir.join("examples/render_stack.rs")).unwrap();
    // A card 1.2 m away over a wall at 6 m, 50 mm f/2 focused on the card: the wall blurs by
    // ~7 px at 64 px wide.
    let (w, h) = (64, 48);
    let card = Layer {
        name: "card".into(),
        rgba: Image::from_fn(w, h, |x, y| if (20..44).contains(&x) && (14..34).contains(&y) { [0.9, 0.5, 0.1, 1.0] } else { [0.0; 4] }),
        disparity: vec![1.0 / 1.2; w * h],
    };
    let wall = Layer {
        name: "wall".into(),
        rgba: Image::from_fn(w, h, |x, y| if (x / 8 + y / 8) % 2 == 0 { [4.0, 4.0, 3.0, 1.0] } else { [0.05, 0.1, 0.2, 1.0] }),
        disparity: vec![1.0 / 6.0; w * h],
    };
    let stack = LayerStack::new(w, h, vec![card, wall]).unwrap();
    let camera = PhysicalCamera { focal_length_mm: 50.0, sensor_width_mm: 36.0, fstop: 2.0, focus_distance: 1.2 };
    let input = dir.join("stack.exr");
    let options = StackWriteOptions { depth_kind: DepthKind::Z, camera: Some(camera), ..StackWriteOptions::default() };
    write_stack(&input, &stack, &options).unwrap();
    let rendered = dir.join("rendered.exr");
    let args = ["--example", "render_stack", "--", input.to_str().unwrap(), rendered.to_str().unwrap()];
    let stdout = cargo_run(dir, &args, "render_stack");
    assert!(stdout.contains("64x48, 2 layer(s), drbokeh at f/2 focused at 1.2 m"), "{stdout}");

    // The same render in this process: the file's Z back to disparity, the header's camera.
    let ctx = common::gpu();
    let read_back = lensblur::stack::read_stack(&input, &Default::default()).unwrap().stack;
    let lens = Lens { coc: CocModel::from_physical(&camera, w).unwrap(), aperture: Aperture::Disk };
    let expected = Method::DrBokeh.render(Some(&ctx), &read_back, &lens).unwrap();
    let got = read_rgba(&rendered, None, lensblur::stack::DEFAULT_MAX_PIXELS).unwrap();
    // The same render on the same device, stored as half floats (the default, as compositors
    // take it): each sample within half's rounding, 2^-11 relative (6e-8 absolute near 0).
    let worst = got
        .pixels
        .iter()
        .flatten()
        .zip(expected.pixels.iter().flatten())
        .map(|(a, b)| (a - b).abs() / (b.abs() * 2f32.powi(-11) + 6e-8))
        .fold(0.0f32, f32::max);
    assert!(worst <= 1.0, "the example's render differs from the library's by {worst} half-float roundings");
    // Not vacuous: the wall is visibly blurred (a checker edge pixel mixes both squares).
    let edge = expected.get(8, 2);
    assert!(edge[0] > 0.3 && edge[0] < 3.7, "wall not blurred at the checker edge: {edge:?}");
    common::finish(ctx);
}

/// `cargo run --offline --quiet ARGS` in the dependent crate at `dir`, under validation;
/// its stdout once it has succeeded.
fn cargo_run(dir: &Path, args: &[&str], what: &str) -> String {
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let output = Command::new(cargo)
        .args(["run", "--offline", "--quiet"])
        .args(args)
        .current_dir(dir)
        // Its own target folder, and none of this build's settings leak in.
        .env("CARGO_TARGET_DIR", dir.join("target"))
        // A throwaway build: no debug info and no incremental state (with them it took ~700 MB
        // of the temp folder per run).
        .env("CARGO_PROFILE_DEV_DEBUG", "false")
        .env("CARGO_INCREMENTAL", "0")
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .env("LENSBLUR_VALIDATION", "1")
        .output()
        .unwrap();
    let (stdout, stderr) = (String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
    assert!(output.status.success(), "{what} failed ({}):\n{stdout}\n{stderr}", output.status);
    stdout.into_owned()
}
