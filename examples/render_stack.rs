//! Renders a layered EXR with the default method through a physical camera, using nothing but
//! lensblur's public API, and writes the defocused image as an RGBA EXR:
//!
//! ```text
//! cargo run --release --example render_stack -- IN.exr OUT.exr [FOCUS_M [FSTOP]]
//! ```
//!
//! The camera is the input header's where it has one (Blender stamps its lens; `lensblur`
//! writes all four values), else a 50 mm lens on a 36 mm sensor at f/2.8; FOCUS_M (metres)
//! and FSTOP override. Depth is read as Z in metres, the layers in any naming convention
//! `lensblur render` reads. CI builds this file in a crate outside the repository
//! (tests/out_of_tree.rs), so it must not reach anything private.
use std::path::Path;

use lensblur::camera::{Aperture, CameraHints, CocModel, PhysicalCamera};
use lensblur::render::{Lens, Method};
use lensblur::stack::{read_stack, write_image, ReadOptions, WriteOptions};
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

    let file = read_stack(Path::new(&args[0]), &ReadOptions::default())?;
    let hints = CameraHints::from_attributes(&file.info.camera);
    let camera = PhysicalCamera {
        focal_length_mm: hints.focal_length_mm.unwrap_or(50.0),
        sensor_width_mm: hints.sensor_width_mm.unwrap_or(36.0),
        fstop: fstop.or(hints.fstop).unwrap_or(2.8),
        focus_distance: focus.or(hints.focus_distance).ok_or_else(|| {
            format!("{} has no focus distance in its header: give FOCUS_M; {USAGE}", args[0])
        })?,
    };
    camera.validate()?;
    let lens = Lens { coc: CocModel::from_physical(&camera, file.stack.width)?, aperture: Aperture::Disk };

    // One device for every render of this process (here one); LENSBLUR_DEVICE picks another.
    let ctx = Context::from_env()?;
    let method = Method::default();
    let image = method.render(Some(&ctx), &file.stack, &lens)?;
    let options = WriteOptions { camera: Some(camera), ..WriteOptions::default() };
    write_image(Path::new(&args[1]), &image, &options)?;
    ctx.finish()?;
    println!(
        "{} -> {}: {}x{}, {} layer(s), {} at f/{} focused at {} m",
        args[0],
        args[1],
        image.width,
        image.height,
        file.stack.layers.len(),
        method.name(),
        camera.fstop,
        camera.focus_distance
    );
    Ok(())
}
