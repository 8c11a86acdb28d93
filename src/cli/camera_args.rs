//! Camera flags shared by `render`, `grad`, `fit-depth` and `example`: a physical camera or
//! the normalised-disparity model, and the aperture shape; both resolve to one [`Lens`].
use anyhow::{bail, Context as _};
use lensblur::camera::{Aperture, CameraHints, CocModel, PhysicalCamera};
use lensblur::render::Lens;

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
        }
    }
}

/// The lens a command renders with, and the physical camera behind it (if one was given).
pub struct ResolvedCamera {
    pub lens: Lens,
    pub physical: Option<PhysicalCamera>,
    /// Which physical parameters came from the file's header rather than flags
    /// (`focal-length`, `fstop`, `focus-distance`, `sensor-width`), for reports.
    pub from_header: Vec<&'static str>,
    /// Which came from the shot's camera file (neither a flag nor the header gave them).
    pub from_camera_file: Vec<&'static str>,
}

/// Sensor width when neither the flags nor the file say (Blender's default camera).
const DEFAULT_SENSOR_WIDTH_MM: f32 = 36.0;

impl CameraArgs {
    /// The kernel image of `--aperture image:FILE`, described for `check_output_paths`.
    pub fn files(&self) -> Vec<(&'static str, &std::path::Path)> {
        let kernel = self.aperture.strip_prefix("image:").filter(|f| !f.is_empty());
        kernel.map(|f| ("the --aperture kernel image", std::path::Path::new(f))).into_iter().collect()
    }

    /// The lens for an image `width_px` wide. `header` fills physical parameters the flags
    /// leave out (camera attributes found in the input file); flags win.
    pub fn resolve(&self, width_px: usize, header: &CameraHints) -> anyhow::Result<ResolvedCamera> {
        self.resolve_with_file(width_px, header, &CameraHints::default())
    }

    /// [`resolve`](Self::resolve) for a frame of a shot: what neither the flags nor the
    /// frame's header give comes from the shot's camera file (`camera_file`).
    pub fn resolve_with_file(&self, width_px: usize, header: &CameraHints, camera_file: &CameraHints) -> anyhow::Result<ResolvedCamera> {
        let aperture = Aperture::parse(&self.aperture).context("--aperture")?;
        if let Some(k) = self.blur {
            let Some(df) = self.focus_disparity else {
                bail!("--blur K needs --focus-disparity DF (the disparity that stays sharp)");
            };
            return Ok(ResolvedCamera {
                lens: Lens {
                    coc: CocModel::new(k, df).context("--blur K / --focus-disparity DF")?,
                    aperture,
                },
                physical: None,
                from_header: Vec::new(),
                from_camera_file: Vec::new(),
            });
        }
        let physical = self.physical(&header.or(*camera_file))?;
        let coc = CocModel::from_physical(&physical, width_px)?;
        let sources = [
            ("focal-length", self.focal_length, header.focal_length_mm, camera_file.focal_length_mm),
            ("fstop", self.fstop, header.fstop, camera_file.fstop),
            ("focus-distance", self.focus_distance, header.focus_distance, camera_file.focus_distance),
            ("sensor-width", self.sensor_width, header.sensor_width_mm, camera_file.sensor_width_mm),
        ];
        let unflagged = sources.into_iter().filter(|(_, flag, _, _)| flag.is_none());
        let (from_header, from_file): (Vec<_>, Vec<_>) = unflagged.partition(|(_, _, header, _)| header.is_some());
        Ok(ResolvedCamera {
            lens: Lens { coc, aperture },
            physical: Some(physical),
            from_header: from_header.into_iter().map(|(name, ..)| name).collect(),
            from_camera_file: from_file.into_iter().filter(|(.., file)| file.is_some()).map(|(name, ..)| name).collect(),
        })
    }

    fn physical(&self, header: &CameraHints) -> anyhow::Result<PhysicalCamera> {
        let pick = |flag: Option<f32>, header: Option<f32>, name: &str| -> anyhow::Result<f32> {
            flag.or(header).with_context(|| {
                format!(
                    "missing --{name} (the file's header has no camera): give a physical camera \
                     (--focal-length MM --fstop N --focus-distance D [--sensor-width MM]) or the \
                     normalised model (--blur K --focus-disparity DF)"
                )
            })
        };
        let camera = PhysicalCamera {
            focal_length_mm: pick(self.focal_length, header.focal_length_mm, "focal-length")?,
            sensor_width_mm: self
                .sensor_width
                .or(header.sensor_width_mm)
                .unwrap_or(DEFAULT_SENSOR_WIDTH_MM),
            fstop: pick(self.fstop, header.fstop, "fstop")?,
            focus_distance: pick(self.focus_distance, header.focus_distance, "focus-distance")?,
        };
        let flags = [
            ("focal-length", camera.focal_length_mm),
            ("sensor-width", camera.sensor_width_mm),
            ("fstop", camera.fstop),
            ("focus-distance", camera.focus_distance),
        ];
        for (flag, value) in flags {
            if !(value.is_finite() && value > 0.0) {
                bail!("--{flag} must be a positive number, got {value} (from the flag or the file's header)");
            }
        }
        camera.validate()?;
        Ok(camera)
    }
}
