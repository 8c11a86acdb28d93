//! The aperture cases of `bench perf` (group `apertures`): whole `lensblur render` processes
//! of the Blender comparison's 1024^2 five-layer frame (CoC up to 40 px) with every aperture
//! kind, against the disk on the same frame and, where Blender's Defocus node has the shape
//! (its `bokeh` setting: CIRCLE, TRIANGLE .. OCTAGON), against Blender's compositing time, in
//! one run. Medians of `repeats` processes; ratios of medians.
use std::path::{Path, PathBuf};

use super::blender::{blender_bokeh, comparison_inputs, time_blender, FRAME_SIDE};
use super::end_to_end::time_render_process;
use super::large::Focus;
use super::perf::median;
use lensblur::image::Image;
use lensblur::stack::write_png_preview;
use lensblur::Result;

/// One aperture case: the `render` flags after `-o OUT`, and Blender's shape if it has one.
#[derive(Clone, Debug)]
pub struct ApertureCase {
    pub name: String,
    pub args: Vec<String>,
    pub blender_bokeh: Option<&'static str>,
}

/// The cases, the disk first (the others' reference). `kernel_png`: where the image kernel is
/// written (a five-pointed star, 64^2).
pub fn aperture_cases(kernel_png: &Path) -> Result<Vec<ApertureCase>> {
    write_star_kernel(kernel_png)?;
    let case = |name: &str, args: &[&str], bokeh: Option<&'static str>| ApertureCase {
        name: name.to_string(),
        args: args.iter().map(|a| a.to_string()).collect(),
        blender_bokeh: bokeh,
    };
    let image = format!("image:{}", kernel_png.display());
    Ok(vec![
        case("disk", &["--aperture", "disk"], Some("CIRCLE")),
        case("polygon:6", &["--aperture", "polygon:6"], blender_bokeh(6)),
        case("polygon:8", &["--aperture", "polygon:8"], blender_bokeh(8)),
        case("polygon:5:rotation=10", &["--aperture", "polygon:5:rotation=10"], blender_bokeh(5)),
        case("polygon:9:roundness=0.5", &["--aperture", "polygon:9:roundness=0.5"], None),
        case("anamorphic:1.8", &["--aperture", "anamorphic:1.8"], None),
        case("ring:0.2", &["--aperture", "ring:0.2"], None),
        case("ring:0.5", &["--aperture", "ring:0.5"], None),
        case("ring:0.8", &["--aperture", "ring:0.8"], None),
        case("image:star", &["--aperture", &image], None),
        case("cats-eye 0.6 (disk)", &["--cats-eye", "0.6"], None),
        case("cats-eye 0.6 (polygon:6)", &["--aperture", "polygon:6", "--cats-eye", "0.6"], None),
        case("cats-eye 0.6 (anamorphic:1.8)", &["--aperture", "anamorphic:1.8", "--cats-eye", "0.6"], None),
    ])
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct ApertureTiming {
    pub name: String,
    pub args: Vec<String>,
    pub lensblur_seconds: Vec<f64>,
    pub lensblur_median_seconds: f64,
    /// Median over the disk's median on the same frame (the goal: <= 1.5 for procedural
    /// apertures, <= 3 for image kernels).
    pub ratio_to_disk: f64,
    pub blender_bokeh: Option<&'static str>,
    pub blender_median_seconds: Option<f64>,
    /// lensblur's median over Blender's median compositing time (the goal: <= 0.5).
    pub ratio_to_blender: Option<f64>,
}

/// Times the disk and every `wanted` case on the defocused comparison frame written into
/// `dir`; Blender's Defocus too where it has the shape and `blender` is set. `progress` gets
/// each finished case.
pub fn compare_apertures(
    exe: &Path,
    dir: &Path,
    repeats: usize,
    blender: bool,
    wanted: &dyn Fn(&str) -> bool,
    progress: &dyn Fn(&ApertureTiming),
) -> Result<Vec<ApertureTiming>> {
    let inputs = comparison_inputs(dir, Focus::FullyDefocused, FRAME_SIDE)?;
    let mut cases = aperture_cases(&dir.join("aperture-star.png"))?;
    // The disk (first) is every ratio's reference.
    let mut index = 0;
    cases.retain(|case| {
        index += 1;
        index == 1 || wanted(&case.name)
    });
    let output: PathBuf = dir.join("aperture-case.exr");
    let mut timings: Vec<ApertureTiming> = Vec::new();
    for case in cases {
        let mut args = vec!["-o".to_string(), output.display().to_string()];
        args.extend(case.args.iter().cloned());
        let mut seconds = (0..repeats.max(1))
            .map(|_| time_render_process(exe, &inputs.layered, &args, &output, &[]))
            .collect::<Result<Vec<f64>>>()?;
        let lensblur_median_seconds = median(&mut seconds.clone());
        let disk = timings.first().map_or(lensblur_median_seconds, |d| d.lensblur_median_seconds);
        let blender_median_seconds = match (blender, case.blender_bokeh) {
            (true, Some(bokeh)) => {
                let png = dir.join(format!("aperture-blender-{}.png", bokeh.to_lowercase()));
                let (mut blender_seconds, _, _) = time_blender(&inputs, bokeh, &png, repeats)?;
                Some(median(&mut blender_seconds))
            }
            _ => None,
        };
        let timing = ApertureTiming {
            name: case.name,
            args: case.args,
            lensblur_median_seconds,
            ratio_to_disk: lensblur_median_seconds / disk,
            blender_bokeh: case.blender_bokeh,
            blender_median_seconds,
            ratio_to_blender: blender_median_seconds.map(|b| lensblur_median_seconds / b),
            lensblur_seconds: {
                seconds.sort_by(f64::total_cmp);
                seconds
            },
        };
        progress(&timing);
        timings.push(timing);
    }
    Ok(timings)
}

/// A five-pointed star, anti-aliased by 4x4 sub-samples: an image kernel with no closed form.
fn write_star_kernel(path: &Path) -> Result<()> {
    let side = 64;
    let star = |u: f32, v: f32| {
        let (r, angle) = (u.hypot(v), v.atan2(u) + std::f32::consts::FRAC_PI_2);
        // Radius of the star's outline at this angle: 1 at the points, 0.45 between them.
        let sector = std::f32::consts::TAU / 5.0;
        let folded = (angle.rem_euclid(sector) / sector - 0.5).abs() * 2.0;
        r <= 0.45 + 0.55 * folded
    };
    let image = Image::from_fn(side, side, |x, y| {
        let mut inside = 0.0;
        for sy in 0..4 {
            for sx in 0..4 {
                let u = ((x * 4 + sx) as f32 + 0.5) / (side * 4) as f32 * 2.0 - 1.0;
                let v = ((y * 4 + sy) as f32 + 0.5) / (side * 4) as f32 * 2.0 - 1.0;
                inside += if star(u, v) { 1.0 / 16.0 } else { 0.0 };
            }
        }
        [inside, inside, inside, 1.0]
    });
    write_png_preview(path, &image)
}
