//! Settings of the lens-sampling methods on `lensblur render` (`--samples`, and Virtual DSLR's
//! `--iterations`, `--highlight-sigma`, `--tilt-shift`, `--focal-planes`), resolved to a
//! [`MethodSettings`]. Each flag stands for one [`Setting`]; a flag whose setting the chosen
//! method does not declare is an error, never ignored.
use anyhow::{bail, Context as _};
use lensblur::camera::disparity_from_z;
use lensblur::render::vdslr::{FocusField, Highlight};
use lensblur::render::{Lens, Method, MethodSettings, Setting};

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

    /// The settings `method` renders a `width x height` frame through `lens` with. `physical`:
    /// the camera is physical (focal planes are distances, not disparities).
    pub fn resolve(
        &self,
        method: Method,
        lens: &Lens,
        physical: bool,
        width: usize,
        height: usize,
    ) -> anyhow::Result<MethodSettings> {
        self.check(method)?;
        let mut settings = MethodSettings::default();
        if let Some(samples) = self.samples {
            settings.vdslr.samples = samples;
            settings.multiview.samples = samples;
        }
        if let Some(iterations) = self.iterations {
            settings.vdslr.iterations = iterations;
        }
        if let Some(sigma) = self.highlight_sigma {
            if !(sigma.is_finite() && sigma >= 0.0) {
                bail!("--highlight-sigma must be a positive number (0 turns it off), got {sigma}");
            }
            settings.vdslr.highlight = (sigma > 0.0).then_some(Highlight { sigma, white: 1.0 });
        }
        if let Some(spec) = &self.tilt_shift {
            settings.vdslr.focus = tilt(spec, lens, width, height).context("--tilt-shift")?;
        }
        if let Some(spec) = &self.focal_planes {
            let planes = parse_list(spec).context("--focal-planes")?;
            let disparities = if physical {
                if let Some(bad) = planes.iter().find(|d| **d <= 0.0) {
                    bail!("--focal-planes: distances must be positive (scene units), got {bad}");
                }
                planes.into_iter().map(disparity_from_z).collect()
            } else {
                planes
            };
            settings.vdslr.focus = FocusField::Planes(disparities);
        }
        Ok(settings)
    }

    /// Refuses flags `method` does not read, and two focus fields at once (before any reading).
    pub fn check(&self, method: Method) -> anyhow::Result<()> {
        let given = [
            (Setting::Samples, self.samples.is_some()),
            (Setting::Iterations, self.iterations.is_some()),
            (Setting::HighlightSigma, self.highlight_sigma.is_some()),
            (Setting::TiltShift, self.tilt_shift.is_some()),
            (Setting::FocalPlanes, self.focal_planes.is_some()),
        ];
        if let Some((setting, _)) = given.iter().find(|(setting, on)| *on && !method.reads(*setting)) {
            let flag = flag(*setting);
            let readers: Vec<&str> = Method::readers(*setting).map(Method::name).collect();
            let methods = match readers.split_last() {
                Some((last, rest)) if !rest.is_empty() => format!("{} and {last}", rest.join(", ")),
                _ => readers.join(""),
            };
            bail!("{flag} applies to --method {methods}, not {method}: drop it or pick one of those methods");
        }
        if self.tilt_shift.is_some() && self.focal_planes.is_some() {
            bail!("--tilt-shift and --focal-planes each set the focus field: give one of them");
        }
        Ok(())
    }
}

/// The flag that gives `setting` on the command line.
pub fn flag(setting: Setting) -> &'static str {
    match setting {
        Setting::Samples => "--samples",
        Setting::Iterations => "--iterations",
        Setting::HighlightSigma => "--highlight-sigma",
        Setting::TiltShift => "--tilt-shift",
        Setting::FocalPlanes => "--focal-planes",
    }
}

/// The tilted focus field whose focus, relative to the centre, is `x` CoC pixels nearer at the
/// right edge and `y` at the bottom edge (disparity is linear in image position on any plane).
fn tilt(spec: &str, lens: &Lens, width: usize, height: usize) -> anyhow::Result<FocusField> {
    let [x, y] = parse_list(spec)?[..] else {
        bail!("expected X,Y (focus offsets in CoC pixels at the right and bottom edges), got '{spec}'");
    };
    let k = lens.coc.k_px;
    if k <= 0.0 {
        bail!("the camera does not blur (K = {k}): a tilted focal plane changes nothing");
    }
    // From the centre pixel to the edge pixel: (n - 1) / 2 pixels (a 1-pixel axis has no tilt).
    let per_pixel = |offset: f32, n: usize| if n > 1 { offset / k / ((n as f32 - 1.0) * 0.5) } else { 0.0 };
    Ok(FocusField::Tilt { gradient: [per_pixel(x, width), per_pixel(y, height)] })
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
