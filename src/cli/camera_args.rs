//! Camera flags shared by `render`, `grad`, `fit-depth` and `example`: a physical camera or
//! the normalised-disparity model, and the aperture shape; both resolve to one [`Lens`].
use anyhow::{bail, Context as _};
use lensblur::camera::{Aperture, CocModel, PhysicalCamera};
use lensblur::render::Lens;

#[derive(clap::Args, Clone, Debug)]
pub struct CameraArgs {
    /// Focal length in mm (physical camera; Blender: Camera > Lens > Focal Length).
    #[arg(long, value_name = "MM", help_heading = "Camera")]
    pub focal_length: Option<f32>,
    /// Sensor width in mm (physical camera; Blender's default is 36).
    #[arg(long, value_name = "MM", default_value_t = 36.0, help_heading = "Camera")]
    pub sensor_width: f32,
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
    /// Aperture shape: disk, polygon:BLADES[:rotation=DEG][:roundness=R], or image:FILE.
    #[arg(long, value_name = "SHAPE", default_value = "disk", help_heading = "Camera")]
    pub aperture: String,
}

impl CameraArgs {
    /// The lens for an image `width_px` wide. `from_file` fills physical parameters the flags
    /// leave out (camera attributes found in the input's header); flags win.
    pub fn resolve(&self, width_px: usize, from_file: Option<&PhysicalCamera>) -> anyhow::Result<Lens> {
        let aperture = Aperture::parse(&self.aperture).context("--aperture")?;
        let coc = match self.blur {
            Some(k) => {
                let Some(df) = self.focus_disparity else {
                    bail!("--blur K needs --focus-disparity DF (the disparity that stays sharp)");
                };
                CocModel::new(k, df)?
            }
            None => CocModel::from_physical(&self.physical(from_file)?, width_px)?,
        };
        Ok(Lens { coc, aperture })
    }

    fn physical(&self, from_file: Option<&PhysicalCamera>) -> anyhow::Result<PhysicalCamera> {
        let pick = |flag: Option<f32>, header: Option<f32>, name: &str| -> anyhow::Result<f32> {
            flag.or(header).with_context(|| {
                format!(
                    "missing --{name}: give a physical camera (--focal-length MM --fstop N --focus-distance D \
                     [--sensor-width MM]) or the normalised model (--blur K --focus-disparity DF)"
                )
            })
        };
        let camera = PhysicalCamera {
            focal_length_mm: pick(self.focal_length, from_file.map(|c| c.focal_length_mm), "focal-length")?,
            sensor_width_mm: self.sensor_width,
            fstop: pick(self.fstop, from_file.map(|c| c.fstop), "fstop")?,
            focus_distance: pick(self.focus_distance, from_file.map(|c| c.focus_distance), "focus-distance")?,
        };
        camera.validate()?;
        Ok(camera)
    }
}
