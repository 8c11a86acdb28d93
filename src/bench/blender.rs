//! The peer comparison: Blender's Defocus compositor node (CPU) against `lensblur render` on
//! the same 1024^2 five-layer frame with CoC up to 40 px. Ours gets the layered EXR (planar Z,
//! camera in the header) and runs as a whole process; Blender gets the frame flattened to
//! RGB+Z and is timed inside Blender around `bpy.ops.render.render()` (compositing only: the
//! node tree has no Render Layers node). Both PNGs are saved for a human to compare.
//!
//! Matching the CoC. Blender 3.4's Defocus (`ConvertDepthToRadiusOperation`, then a
//! variable-size bokeh blur without the Bokeh Blur node's size scaling) gives a radius in
//! pixels, for a square frame of side W,
//!   r_B = 0.5 |A (S (1/f_B - 1/z_B) - 1)|,  A = 0.5 lens / (sensor N_B),  S = 2 W lens / sensor,
//! with lens and sensor in mm, f_B the scene camera's focus distance and z_B the Z input.
//! Ours is r = K |1/f - 1/z|, K = (lens/1000)/(2N) (lens/sensor) W, z in metres. With the same
//! lens, sensor and f-stop (N_B = N), Blender's Z in units of 1/s metres, s = 1000 / sensor,
//! gives 0.5 A S / s = K (Blender measures the aperture lens/N in sensor widths, not in scene
//! units); focusing Blender at 1/f_B = 1/(s f) + 1/S cancels the "- 1" (which would otherwise
//! put 0.5 A px of blur on the focal plane). `blur_max` is the largest CoC rounded up plus one
//! (Blender clamps radii and its search to it). Blender also smooths its radius map (Gaussian,
//! sigma min(128 A, blur_max), min-overlay so near radii do not bleed outward): its own
//! algorithm, not a setting. Checked by eye on the saved PNGs, and by
//! `blender_radius_matches_our_coc` on the formula.
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use super::end_to_end::time_render_process;
use super::large::{layered_stack, Focus};
use super::perf::median;
use crate::camera::PhysicalCamera;
use crate::stack::{read_rgba, write_png_preview, write_stack, DepthKind, Layer, LayerStack, StackWriteOptions};
use crate::{Error, Result};

/// The Python script run inside Blender.
const SCRIPT: &str = include_str!("blender_defocus.py");

/// Focal length of the comparison camera; the f-stop follows from the wanted CoC.
const LENS_MM: f32 = 100.0;
const SENSOR_MM: f32 = 36.0;

/// The Defocus node and camera settings Blender gets, and the Z scale of its depth input.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct BlenderDefocus {
    pub lens_mm: f32,
    pub sensor_mm: f32,
    pub f_stop: f32,
    pub focus_distance: f32,
    pub blur_max: f32,
    /// Blender's Z = s * our planar Z (metres).
    pub z_scale: f32,
    pub width: usize,
    pub height: usize,
    /// The node's `bokeh` shape: CIRCLE, or TRIANGLE .. OCTAGON for 3 .. 8 blades.
    pub bokeh: &'static str,
}

impl BlenderDefocus {
    /// The settings that give Blender our CoC radii (see the module doc); square frames only.
    pub fn matching(camera: &PhysicalCamera, width: usize, height: usize, max_coc_px: f32) -> Result<Self> {
        camera.validate()?;
        if width != height {
            return Err(Error::unsupported("the Blender comparison maps the camera for square frames only"));
        }
        let w = width as f32;
        let z_scale = 1000.0 / camera.sensor_width_mm;
        let s_term = 2.0 * w * camera.focal_length_mm / camera.sensor_width_mm;
        let focus_distance = 1.0 / (1.0 / (z_scale * camera.focus_distance) + 1.0 / s_term);
        Ok(Self {
            lens_mm: camera.focal_length_mm,
            sensor_mm: camera.sensor_width_mm,
            f_stop: camera.fstop,
            focus_distance,
            blur_max: max_coc_px.ceil() + 1.0,
            z_scale,
            width,
            height,
            bokeh: "CIRCLE",
        })
    }

    /// Blender's CoC radius in pixels for its depth `z_b` (the formula of the module doc,
    /// before Blender's clamps and radius-map smoothing).
    pub fn blender_radius(&self, z_b: f32) -> f32 {
        let aperture = 0.5 * self.lens_mm / (self.sensor_mm * self.f_stop);
        let s_term = self.width.min(self.height) as f32 * 2.0 * self.lens_mm / self.sensor_mm;
        0.5 * (aperture * (s_term * (1.0 / self.focus_distance - 1.0 / z_b) - 1.0)).abs()
    }
}

/// The comparison camera: LENS_MM on a SENSOR_MM sensor, focused at `1 / focus_disparity`,
/// the f-stop that gives `k_px` pixels of CoC per unit of disparity on a `width` px frame.
pub fn matching_camera(k_px: f32, focus_disparity: f32, width: usize) -> PhysicalCamera {
    let focal_px = LENS_MM / SENSOR_MM * width as f32;
    PhysicalCamera {
        focal_length_mm: LENS_MM,
        sensor_width_mm: SENSOR_MM,
        fstop: LENS_MM * 1e-3 * focal_px / (2.0 * k_px),
        focus_distance: 1.0 / focus_disparity,
    }
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct BlenderComparison {
    pub name: String,
    pub side: usize,
    pub layers: usize,
    pub max_coc_px: f32,
    pub camera: PhysicalCamera,
    pub blender: BlenderDefocus,
    pub blender_version: String,
    /// Compositing time inside Blender, each render call.
    pub blender_seconds: Vec<f64>,
    pub blender_median_seconds: f64,
    /// The whole Blender process (start-up, loading, all renders, saving).
    pub blender_process_seconds: f64,
    /// Whole `lensblur render` processes.
    pub lensblur_seconds: Vec<f64>,
    pub lensblur_median_seconds: f64,
    /// lensblur median over Blender's median compositing time (the goal: at most 0.5).
    pub ratio: f64,
    pub lensblur_png: PathBuf,
    pub blender_png: PathBuf,
}

/// The comparison's name for `focus` (the stack is 1024^2, five layers, CoC up to 40 px).
pub fn case_name(focus: Focus) -> String {
    let focus_name = match focus {
        Focus::MostlyInFocus => "focused",
        Focus::FullyDefocused => "defocused",
    };
    format!("blender-1024-5l-coc40-{focus_name}")
}

/// Blender's Defocus `bokeh` setting for a regular polygon of `blades` (3 to 8), if it has one.
pub fn blender_bokeh(blades: u32) -> Option<&'static str> {
    ["TRIANGLE", "SQUARE", "PENTAGON", "HEXAGON", "HEPTAGON", "OCTAGON"].get((blades as usize).checked_sub(3)?).copied()
}

/// The comparison frame's two inputs, written into `dir` (once per focus): the layered EXR
/// `lensblur render` reads and the RGB+Z EXR Blender reads; and the settings Blender needs.
pub struct ComparisonInputs {
    pub name: String,
    pub layered: PathBuf,
    pub rgbz: PathBuf,
    pub camera: PhysicalCamera,
    pub blender: BlenderDefocus,
}

/// Side, layers and largest CoC of the comparison frame.
const FRAME: (usize, usize, f32) = (1024, 5, 40.0);

pub fn comparison_inputs(dir: &Path, focus: Focus) -> Result<ComparisonInputs> {
    let (side, layers, max_coc_px) = FRAME;
    let (stack, lens) = layered_stack(side, side, layers, focus, max_coc_px)?;
    let camera = matching_camera(lens.coc.k_px, lens.coc.focus_disparity, side);
    let blender = BlenderDefocus::matching(&camera, side, side, max_coc_px)?;
    std::fs::create_dir_all(dir).map_err(|e| Error::input(dir, format!("cannot create: {e}")))?;
    let name = case_name(focus);
    let (layered, rgbz) = (dir.join(format!("{name}-layers.exr")), dir.join(format!("{name}-rgbz.exr")));
    write_stack(&layered, &stack, &StackWriteOptions { depth_kind: DepthKind::Z, camera: Some(camera), ..Default::default() })?;
    write_rgbz(&rgbz, &stack, blender.z_scale)?;
    Ok(ComparisonInputs { name, layered, rgbz, camera, blender })
}

/// Blender's Defocus with `bokeh` on the RGB+Z input: its compositing times (one per render
/// call) and version, and the whole process's time; the result saved as `png`.
pub fn time_blender(inputs: &ComparisonInputs, bokeh: &'static str, png: &Path, repeats: usize) -> Result<(Vec<f64>, String, f64)> {
    let dir = inputs.rgbz.parent().unwrap_or(Path::new("."));
    let settings = BlenderDefocus { bokeh, ..inputs.blender };
    let (report, process_seconds) = run_blender(dir, &inputs.rgbz, png, &settings, repeats.max(1))?;
    Ok((report.seconds, report.version, process_seconds))
}

/// Writes both inputs into `dir`, times `repeats` runs of each, saves both PNGs there.
pub fn compare_with_blender(exe: &Path, dir: &Path, focus: Focus, repeats: usize) -> Result<BlenderComparison> {
    let (side, layers, max_coc_px) = FRAME;
    let ComparisonInputs { name, layered, rgbz, camera, blender } = comparison_inputs(dir, focus)?;
    let (ours_exr, ours_png, theirs_png) =
        (dir.join(format!("{name}-lensblur.exr")), dir.join(format!("{name}-lensblur.png")), dir.join(format!("{name}-blender.png")));
    let args = vec!["-o".to_string(), ours_exr.display().to_string()];
    let mut lensblur_seconds = (0..repeats.max(1)).map(|_| time_render_process(exe, &layered, &args, &ours_exr, &[])).collect::<Result<Vec<f64>>>()?;
    write_png_preview(&ours_png, &read_rgba(&ours_exr, None, u64::MAX)?)?;
    let (report, blender_process_seconds) = run_blender(dir, &rgbz, &theirs_png, &blender, repeats.max(1))?;
    let blender_seconds = report.seconds;
    let blender_median_seconds = median(&mut blender_seconds.clone());
    let lensblur_median_seconds = median(&mut lensblur_seconds);
    Ok(BlenderComparison {
        name,
        side,
        layers,
        max_coc_px,
        camera,
        blender,
        blender_version: report.version,
        blender_seconds,
        blender_median_seconds,
        blender_process_seconds,
        lensblur_seconds,
        lensblur_median_seconds,
        ratio: lensblur_median_seconds / blender_median_seconds,
        lensblur_png: ours_png,
        blender_png: theirs_png,
    })
}

/// The frame flattened front to back, as the multilayer EXR Blender's Image node reads
/// (`ViewLayer.Combined.RGBA` + `ViewLayer.Depth.Z`), Z in Blender's units (`z_scale` / d).
fn write_rgbz(path: &Path, stack: &LayerStack, z_scale: f32) -> Result<()> {
    let (rgba, disparity) = stack.flatten();
    let disparity = disparity.iter().map(|&d| d / z_scale).collect();
    let flat = LayerStack::new(stack.width, stack.height, vec![Layer { name: "ViewLayer".into(), rgba, disparity }])?;
    write_stack(path, &flat, &StackWriteOptions { depth_kind: DepthKind::Z, ..Default::default() })
}

#[derive(serde::Deserialize)]
struct ScriptReport {
    seconds: Vec<f64>,
    version: String,
}

/// Runs Blender headless on the script (written into `dir`); returns its report and the
/// whole process's wall time.
fn run_blender(dir: &Path, rgbz: &Path, png: &Path, settings: &BlenderDefocus, repeats: usize) -> Result<(ScriptReport, f64)> {
    let script = dir.join("blender_defocus.py");
    std::fs::write(&script, SCRIPT).map_err(|e| Error::input(&script, format!("cannot write: {e}")))?;
    let params = serde_json::to_string(settings).map_err(|e| Error::internal(format!("Blender settings: {e}")))?;
    let start = Instant::now();
    let out = Command::new("blender")
        .args(["-b", "--factory-startup", "--python-exit-code", "1", "--python"])
        .arg(&script)
        .arg("--")
        .arg(rgbz)
        .arg(png)
        .arg(params)
        .arg(repeats.to_string())
        .output()
        .map_err(|e| Error::input(Path::new("blender"), format!("cannot run Blender ({e}); install Debian's blender")))?;
    let seconds = start.elapsed().as_secs_f64();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let line = stdout.lines().find_map(|l| l.strip_prefix("LENSBLUR_BLENDER "));
    match line {
        Some(json) if out.status.success() => {
            let report = serde_json::from_str(json).map_err(|e| Error::input(&script, format!("unreadable report: {e}")))?;
            Ok((report, seconds))
        }
        _ => Err(Error::input(&script, format!("Blender failed ({}):\n{stdout}\n{}", out.status, String::from_utf8_lossy(&out.stderr)))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Blender's radius equals ours at every depth of the comparison stack (near disk at 1 m,
    /// wall at 2 m) and beyond; f32 arithmetic on terms up to ~6000: 1e-3 px relative.
    #[test]
    fn blender_radius_matches_our_coc() {
        for (k, focus_disparity) in [(80.0, 0.5), (120.0, 2.0 / 3.0)] {
            let camera = matching_camera(k, focus_disparity, 1024);
            let blender = BlenderDefocus::matching(&camera, 1024, 1024, 40.0).unwrap();
            for z in [0.5f32, 1.0, 1.25, 1.5, 2.0, 3.0, 10.0] {
                let ours = k * (1.0 / z - focus_disparity).abs();
                let theirs = blender.blender_radius(blender.z_scale * z);
                assert!((ours - theirs).abs() <= 1e-3 * ours.max(1.0), "z {z}: ours {ours} px, Blender {theirs} px");
            }
        }
    }

    #[test]
    fn blender_mapping_keeps_the_f_stop_and_lens() {
        let camera = matching_camera(80.0, 0.5, 1024);
        let blender = BlenderDefocus::matching(&camera, 1024, 1024, 40.0).unwrap();
        assert_eq!((blender.f_stop, blender.lens_mm, blender.sensor_mm), (camera.fstop, camera.focal_length_mm, camera.sensor_width_mm));
        assert!(blender.f_stop <= 128.0, "Blender's f-stop range ends at 128");
        assert!(blender.blur_max >= 40.0);
    }
}
