//! Renders a layered EXR with the default method through a physical camera, using nothing but
//! lensblur's public API, and writes the defocused image as an RGBA EXR:
//!
//! ```text
//! cargo run --release --example render_stack -- IN.exr OUT.exr [FOCUS_M [FSTOP]]
//! ```
//!
//! The camera: FOCUS_M (metres) and FSTOP where given, else the input header's (Blender stamps
//! its lens; `lensblur` writes all four values), else a 50 mm lens on a 36 mm sensor at f/2.8. Depth is read as Z in metres, the layers in any naming convention
//! `lensblur render` reads. CI builds this file in a crate outside the repository
//! (tests/out_of_tree.rs), so it must not reach anything private.
use std::path::Path;

use lensblur::camera::CameraHints;
use lensblur::input::{load, CameraRequest, InputOptions};
use lensblur::render::Method;
use lensblur::stack::{write_image, WriteOptions};
use lensblur::vk::Context;

const USAGE: &str = "usage: render_stack IN.exr OUT.exr [FOCUS_M [FSTOP]]";

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if !(2..=4).contains(&args.len()) {
        eprintln!("{USAGE}");
        std::process::exit(2);
    }
    if let Err(error) = render(&args) {
        eprintln!("render_stack: {error}");
        std::process::exit(1);
    }
}

fn render(args: &[String]) -> Result<(), Box<dyn std::error::Error>> {
    let number = |index: usize, what: &str| -> Result<Option<f32>, String> {
        args.get(index).map(|text| text.parse::<f32>().map_err(|_| format!("{what} '{text}' is not a number; {USAGE}"))).transpose()
    };
    let focus = number(2, "FOCUS_M")?;
    let fstop = number(3, "FSTOP")?;

    // The policy `lensblur render` applies: our values win, then the file's header, then the
    // fallback (here a 50 mm lens at f/2.8); a layered method gets a flat image auto-layered.
    let request = CameraRequest { physical: CameraHints { focus_distance: focus, fstop, ..CameraHints::default() }, ..CameraRequest::default() };
    let fallback = CameraHints { focal_length_mm: Some(50.0), fstop: Some(2.8), ..CameraHints::default() };
    let method = Method::default();
    let input = load(Path::new(&args[0]), &InputOptions::default(), &request, &fallback, method.input())
        .map_err(|error| format!("{error}; give FOCUS_M if the header has no focus distance. {USAGE}"))?;
    for warning in &input.warnings {
        eprintln!("render_stack: warning: {warning}");
    }
    let camera = input.camera.physical.expect("no normalised model was asked for");

    // One device for every render of this process (here one); LENSBLUR_DEVICE picks another.
    let ctx = Context::from_env()?;
    let image = method.render(Some(&ctx), &input.stack, &input.camera.lens)?;
    let options = WriteOptions { camera: Some(camera), ..WriteOptions::default() };
    write_image(Path::new(&args[1]), &image, &options)?;
    ctx.finish()?;
    println!(
        "{} -> {}: {}x{}, {} layer(s), {} at f/{} focused at {} m",
        args[0],
        args[1],
        image.width,
        image.height,
        input.stack.layers.len(),
        method.name(),
        camera.fstop,
        camera.focus_distance
    );
    Ok(())
}
