//! Settings of the lens-sampling methods on `lensblur render` (`--samples`, and Virtual DSLR's
//! `--iterations`, `--highlight-sigma`, `--tilt-shift`, `--focal-planes`), parsed into the
//! library's [`MethodOptions`]. Each flag stands for one [`Setting`]; the render job refuses a
//! setting the chosen method does not declare, never ignores it.
use anyhow::{bail, Context as _};
use lensblur::job::MethodOptions;
use lensblur::render::Setting;

use super::camera_args::CameraArgs;

#[derive(clap::Args, Clone, Debug, Default)]
pub struct MethodArgs {
    /// Lens samples per pixel of the ray-based methods (vdslr [default: 512], multiview
    /// [default: 512]); rounded up to a square.
    #[arg(long, value_name = "M", help_heading = "Method")]
    pub samples: Option<u32>,
    /// vdslr: intersection search iterations T per lens ray [default: 10].
    #[arg(long, value_name = "T", help_heading = "Method")]
    pub iterations: Option<u32>,
    /// vdslr: Eq. 5 highlight weighting, sigma in linear units (white = 1); 0 turns it off
    /// [default: off].
    #[arg(long, value_name = "S", allow_hyphen_values = true, help_heading = "Method")]
    pub highlight_sigma: Option<f32>,
    /// vdslr: tilted focal plane: focus offsets in CoC pixels at the right (X) and bottom (Y)
    /// frame edges, linear across the frame and zero at its centre (positive = focused nearer).
    #[arg(long, value_name = "X,Y", allow_hyphen_values = true, help_heading = "Method")]
    pub tilt_shift: Option<String>,
    /// vdslr: several focal planes at once: distances in scene units (physical camera) or
    /// disparities (--blur); replaces --focus-distance / --focus-disparity.
    #[arg(long, value_name = "D1,D2,...", help_heading = "Method")]
    pub focal_planes: Option<String>,
}

impl MethodArgs {
    /// `--focal-planes` stands for the focus: the first plane becomes the camera's focus
    /// (what the report and the other controls' checks see), so none must be given.
    pub fn apply_to_camera(&self, camera: &mut CameraArgs) -> anyhow::Result<()> {
        let Some(planes) = &self.focal_planes else {
            return Ok(());
        };
        if camera.focus_distance.is_some() || camera.focus_disparity.is_some() {
            bail!("--focal-planes replaces --focus-distance / --focus-disparity: give one or the other");
        }
        let first = parse_list(planes).context("--focal-planes")?[0];
        if camera.blur.is_some() {
            camera.focus_disparity = Some(first);
        } else {
            camera.focus_distance = Some(first);
        }
        Ok(())
    }

    /// The library's method options these flags give (parsed here; checked by the job).
    pub fn options(&self) -> anyhow::Result<MethodOptions> {
        let tilt_shift = match &self.tilt_shift {
            Some(spec) => {
                let [x, y] = parse_list(spec).context("--tilt-shift")?[..] else {
                    bail!("--tilt-shift: expected X,Y (focus offsets in CoC pixels at the right and bottom edges), got '{spec}'");
                };
                Some([x, y])
            }
            None => None,
        };
        Ok(MethodOptions {
            samples: self.samples,
            iterations: self.iterations,
            highlight_sigma: self.highlight_sigma,
            tilt_shift,
            focal_planes: self.focal_planes.as_deref().map(parse_list).transpose().context("--focal-planes")?,
        })
    }
}

/// The flag that gives `setting` on the command line.
pub fn flag(setting: Setting) -> String {
    super::words::flag(MethodOptions::option_name(setting))
}

/// A comma-separated list of finite numbers.
fn parse_list(spec: &str) -> anyhow::Result<Vec<f32>> {
    let values: Vec<f32> = spec
        .split(',')
        .map(|v| v.trim().parse::<f32>().ok().filter(|v| v.is_finite()))
        .collect::<Option<_>>()
        .with_context(|| format!("'{spec}' is not a comma-separated list of numbers"))?;
    Ok(values)
}
