//! Shared test setup. GPU tests never skip: without a Vulkan device they fail loudly.
#![allow(dead_code)]
use std::path::PathBuf;
use std::process::{Command, Output};

use lensblur::image::Image;
use lensblur::vk::{Context, ContextOptions};

/// Opens the Vulkan device with validation on (the test suite always validates), or panics
/// with the reason: a missing device is a broken test machine, not a reason to skip.
pub fn gpu() -> Context {
    let options = ContextOptions { validation: true, ..ContextOptions::from_env() };
    match Context::new(&options) {
        Ok(ctx) => ctx,
        Err(e) => panic!("GPU tests need a Vulkan device with validation layers (see README): {e}"),
    }
}

/// Closes the context and fails on any validation message, including teardown ones.
pub fn finish(ctx: Context) {
    if let Err(e) = ctx.finish() {
        panic!("validation: {e}");
    }
}

/// Largest absolute difference over all channels of two same-sized images.
pub fn max_abs_diff(a: &Image, b: &Image) -> f32 {
    assert_eq!((a.width, a.height), (b.width, b.height), "image sizes differ");
    a.pixels
        .iter()
        .zip(&b.pixels)
        .flat_map(|(p, q)| (0..4).map(move |c| (p[c] - q[c]).abs()))
        .fold(0.0, f32::max)
}

/// A deterministic test pattern with HDR highlights and partial alpha.
pub fn pattern(width: usize, height: usize) -> Image {
    Image::from_fn(width, height, |x, y| {
        let h = ((x * 7919 + y * 104_729) % 1000) as f32 / 1000.0;
        let highlight = if (x * 13 + y * 7) % 97 == 0 { 20.0 } else { 0.0 };
        let alpha = if (x / 5 + y / 3) % 4 == 0 { 0.5 } else { 1.0 };
        [alpha * (h + highlight), alpha * (1.0 - h), alpha * 0.5 * h, alpha]
    })
}

/// A fresh, empty scratch directory for one test (`lensblur-<suite>-<test>-<pid>`), so
/// parallel tests and earlier runs never see each other's files.
pub fn temp_dir(suite: &str, test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lensblur-{suite}-{test}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs the `lensblur` binary with validation on, the default device choice and `env` added.
pub fn lensblur(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_lensblur"));
    command.args(args).env("LENSBLUR_VALIDATION", "1").env_remove("LENSBLUR_DEVICE");
    for (key, value) in env {
        command.env(key, value);
    }
    command.output().unwrap()
}

/// No ICD for the Vulkan loader to find: what a machine without a GPU driver looks like.
pub const NO_VULKAN: [(&str, &str); 2] =
    [("VK_ICD_FILENAMES", "/nonexistent/icd.json"), ("VK_DRIVER_FILES", "/nonexistent/icd.json")];
