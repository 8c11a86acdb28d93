//! Camera flags shared by `render`, `grad`, `fit-depth` and `example`: a physical camera or
//! the normalised-disparity model, and the aperture shape; both resolve to one [`Lens`].
use anyhow::{bail, Context as _};
use lensblur::camera::{Aperture, CameraHints, CocModel};
use lensblur::input::{CameraRequest, ResolvedCamera};

#[derive(clap::Args, Clone, Debug)]
pub struct CameraArgs {
    /// Focal length in mm (physical camera; Blender: Camera > Lens > Focal Length).
    #[arg(long, value_name = "MM", help_heading = "Camera")]
    pub focal_length: Option<f32>,
    /// Sensor width in mm (physical camera) [default: from the file's header, else 36 as in Blender].
    #[arg(long, value_name = "MM", help_heading = "Camera")]
    pub sensor_width: Option<f32>,
    /// Aperture f-number (physical camera): the aperture radius is focal_length / (2 N).
    #[arg(long, value_name = "N", help_heading = "Camera")]
    pub fstop: Option<f32>,
    /// Distance of the plane in focus, in scene units (physical camera).
    #[arg(long, value_name = "D", help_heading = "Camera")]
    pub focus_distance: Option<f32>,
    /// Normalised model: CoC radius in pixels per unit of disparity, r = K |d - df|.
    #[arg(long, value_name = "K", help_heading = "Camera", conflicts_with_all = ["focal_length", "fstop", "focus_distance"])]
    pub blur: Option<f32>,
    /// Normalised model: disparity of the plane in focus.
    #[arg(long, value_name = "DF", help_heading = "Camera", requires = "blur")]
    pub focus_disparity: Option<f32>,
    /// Aperture shape: disk, polygon:BLADES[:rotation=DEG][:roundness=R], anamorphic:SQUEEZE[:rotation=DEG], ring:INNER, or image:FILE.
    #[arg(
        long,
        value_name = "SHAPE",
        default_value = "disk",
        help_heading = "Camera"
    )]
    pub aperture: String,
    /// What one unit of the input's depth and of --focus-distance is: m, cm, mm, km, in, ft, or
    /// metres per unit (e.g. 0.01) [default: the header's lensblurSceneUnit, else m].
    #[arg(long, value_name = "UNIT", help_heading = "Camera")]
    pub scene_unit: Option<lensblur::camera::SceneUnit>,
}

impl Default for CameraArgs {
    /// No flags: everything from the file's header, disk aperture.
    fn default() -> Self {
        Self {
            focal_length: None,
            sensor_width: None,
            fstop: None,
            focus_distance: None,
            blur: None,
            focus_disparity: None,
            aperture: "disk".into(),
            scene_unit: None,
        }
    }
}

impl CameraArgs {
    /// The kernel image of `--aperture image:FILE`, described for `check_output_paths`.
    pub fn files(&self) -> Vec<(&'static str, &std::path::Path)> {
        let kernel = self.aperture.strip_prefix("image:").filter(|f| !f.is_empty());
        kernel.map(|f| ("the --aperture kernel image", std::path::Path::new(f))).into_iter().collect()
    }

    /// The lens for an image `width_px` wide. `header` fills physical parameters the flags
    /// leave out (camera attributes found in the input file); flags win.
    pub fn resolve(&self, width_px: usize, header: &CameraHints) -> anyhow::Result<ResolvedCamera> {
        self.request()?.resolve(width_px, header, &CameraHints::default()).map_err(flag_error)
    }

    /// The library's camera request these flags make (the policy of who wins lives there).
    pub fn request(&self) -> anyhow::Result<CameraRequest> {
        let aperture = Aperture::parse(&self.aperture).context("--aperture")?;
        let normalised = match (self.blur, self.focus_disparity) {
            (Some(k), Some(df)) => Some(CocModel::new(k, df).context("--blur K / --focus-disparity DF")?),
            (Some(_), None) => bail!("--blur K needs --focus-disparity DF (the disparity that stays sharp)"),
            (None, _) => None,
        };
        let physical = CameraHints {
            focal_length_mm: self.focal_length,
            sensor_width_mm: self.sensor_width,
            fstop: self.fstop,
            focus_distance: self.focus_distance,
        };
        Ok(CameraRequest { physical, normalised, aperture, scene_unit: self.scene_unit.clone() })
    }
}

/// The library's camera errors, worded with the flags that fix them.
pub fn flag_error(error: lensblur::Error) -> anyhow::Error {
    match error {
        lensblur::Error::MissingCamera { parameter } => anyhow::anyhow!(
            "missing --{parameter} (the file's header has no camera): give a physical camera \
             (--focal-length MM --fstop N --focus-distance D [--sensor-width MM]) or the \
             normalised model (--blur K --focus-disparity DF)"
        ),
        lensblur::Error::InvalidCamera { parameter, value } => {
            anyhow::anyhow!("--{parameter} must be a positive number, got {value} (from the flag or the file's header)")
        }
        other => other.into(),
    }
}
