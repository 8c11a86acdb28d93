//! A crate outside this repository that depends on lensblur by path, with no configuration of
//! its own, builds and renders on Vulkan through the public API. The shaders' compiler used to
//! be linked through a recipe in this workspace's `.cargo/config.toml`, which dependent crates
//! never see: they failed to link (`undefined reference: glslang::...`). See docs/TOOLCHAIN.md.
mod common;

use std::path::Path;
use std::process::Command;

const REPO: &str = env!("CARGO_MANIFEST_DIR");

const MANIFEST: &str = r#"[package]
name = "lensblur-dependent"
version = "0.0.0"
edition = "2021"
publish = false

[dependencies]
lensblur = { path = "REPO" }

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
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let output = Command::new(cargo)
        .args(["run", "--offline", "--quiet"])
        .current_dir(&*dir)
        // Its own target folder, and none of this build's settings leak in.
        .env("CARGO_TARGET_DIR", dir.join("target"))
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .env("LENSBLUR_VALIDATION", "1")
        .output()
        .unwrap();
    let (stdout, stderr) = (String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
    assert!(output.status.success(), "the dependent crate failed ({}):\n{stdout}\n{stderr}", output.status);
    // Every pixel is covered (the wall is opaque): a mean alpha of 1 within f32 rounding.
    let line = stdout.lines().find(|l| l.starts_with("rendered 48x40 on lensblur")).unwrap_or_else(|| panic!("no report:\n{stdout}"));
    let alpha: f64 = line.rsplit(' ').next().unwrap().parse().unwrap();
    assert!((alpha - 1.0).abs() < 1e-3, "mean alpha {alpha}: {line}");
}
