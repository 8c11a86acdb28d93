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
//!
//! Blender 4.2 rewrote the node ([`DefocusNode::Physical`], run here as Blender 5.0, PyPI's
//! `bpy` in the virtualenv `.ci/setup` makes): a thin lens in metres (Potmesil and
//! Chakravarty 1981, eq. 8), r_B = 0.5 |v_z - v_F| f / (N_B v_z) W / sensor, v = f d / (d - f)
//! the image distance of depth d, f = lens / 1000. Expanded, r_B = K F / (F - f) |1/z - 1/F|:
//! ours times the magnification term F / (F - f). Blender gets our Z and focus as they are and
//! the f-stop N_B = N F / (F - f), which cancels it. Its `sensor` was the sensor height on our
//! square frame (24 mm unless set), so the script sets both sensor sides.
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use super::end_to_end::{median_fields, median_steps, run_render_process};
use super::large::{layered_stack, Focus};
use super::perf::median;
use lensblur::camera::PhysicalCamera;
use lensblur::image::Image;
use lensblur::raytrace::GroundTruth;
use lensblur::stack::{read_rgba, write_png_preview, write_stack, DepthKind, Layer, LayerStack, StackWriteOptions};
use lensblur::{Error, Result};

/// The Python script run inside Blender.
const SCRIPT: &str = include_str!("../../scripts/blender_defocus.py");

/// Focal length of the comparison camera; the f-stop follows from the wanted CoC.
const LENS_MM: f32 = 100.0;
const SENSOR_MM: f32 = 36.0;

/// Which Defocus node, so which CoC formula the settings are made for (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum DefocusNode {
    /// Blender 3.4's (Debian's `blender` on PATH): the aperture in sensor widths.
    Legacy,
    /// Blender 4.2+'s, run as Blender 5.0 (PyPI's bpy [`BLENDER5_BPY`]): a physical thin lens.
    Physical,
}

/// The bpy version that runs [`DefocusNode::Physical`] (a line of `.ci/bpy-versions`).
pub const BLENDER5_BPY: &str = "5.0.1";

impl DefocusNode {
    pub const ALL: [DefocusNode; 2] = [DefocusNode::Legacy, DefocusNode::Physical];

    /// Starts the command that runs `script` in this node's Blender, headless; the script's
    /// arguments follow.
    fn command(self, script: &Path) -> Result<Command> {
        let mut command = match self {
            DefocusNode::Legacy => {
                let mut blender = Command::new("blender");
                blender.args(["-b", "--factory-startup", "--python-exit-code", "1", "--python"]);
                blender
            }
            DefocusNode::Physical => Command::new(bpy_python(BLENDER5_BPY)?),
        };
        command.arg(script).arg("--");
        Ok(command)
    }
}

/// Where `.ci/setup` makes one virtualenv per PyPI `bpy` version: $LENSBLUR_BPY_ROOT, else
/// the user cache folder's `bpy` (~/.cache/lensblur/bpy).
pub fn bpy_root() -> PathBuf {
    std::env::var_os("LENSBLUR_BPY_ROOT").map_or_else(|| lensblur::cache_dir::cache_subdir("bpy"), PathBuf::from)
}

/// The python of bpy `version`'s virtualenv; an error naming the command that makes it when
/// `.ci/setup` has not (its `.complete` stamp is written once pip succeeded).
pub fn bpy_python(version: &str) -> Result<PathBuf> {
    let venv = bpy_root().join(version);
    if !venv.join(".complete").is_file() {
        return Err(Error::input(
            &venv,
            format!("Blender's bpy {version} is not installed here: run `bash .ci/setup` (one virtualenv per line of .ci/bpy-versions, ~370 MB each)"),
        ));
    }
    Ok(venv.join("bin/python"))
}

/// The Defocus node and camera settings Blender gets, and the Z scale of its depth input.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct BlenderDefocus {
    pub node: DefocusNode,
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
    /// The settings that give `node` our CoC radii (see the module doc); square frames only.
    pub fn matching(node: DefocusNode, camera: &PhysicalCamera, width: usize, height: usize, max_coc_px: f32) -> Result<Self> {
        camera.validate()?;
        if width != height {
            return Err(Error::unsupported("the Blender comparison maps the camera for square frames only"));
        }
        let (f_stop, focus_distance, z_scale) = match node {
            DefocusNode::Legacy => {
                let z_scale = 1000.0 / camera.sensor_width_mm;
                let s_term = 2.0 * width as f32 * camera.focal_length_mm / camera.sensor_width_mm;
                (camera.fstop, 1.0 / (1.0 / (z_scale * camera.focus_distance) + 1.0 / s_term), z_scale)
            }
            DefocusNode::Physical => {
                let (focus, focal_m) = (camera.focus_distance, camera.focal_length_mm * 1e-3);
                if focus <= focal_m {
                    return Err(Error::unsupported("Blender's physical Defocus needs the focus beyond the focal length"));
                }
                (camera.fstop * focus / (focus - focal_m), focus, 1.0)
            }
        };
        Ok(Self {
            node,
            lens_mm: camera.focal_length_mm,
            sensor_mm: camera.sensor_width_mm,
            f_stop,
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
        let side = self.width.min(self.height) as f32;
        match self.node {
            DefocusNode::Legacy => {
                let aperture = 0.5 * self.lens_mm / (self.sensor_mm * self.f_stop);
                let s_term = side * 2.0 * self.lens_mm / self.sensor_mm;
                0.5 * (aperture * (s_term * (1.0 / self.focus_distance - 1.0 / z_b) - 1.0)).abs()
            }
            DefocusNode::Physical => {
                let f = self.lens_mm * 1e-3;
                let image_distance = |d: f32| f * d / (d - f);
                let (v_z, v_focus) = (image_distance(z_b), image_distance(self.focus_distance));
                let diameter_m = ((v_z - v_focus) * f / (self.f_stop * v_z)).abs();
                0.5 * diameter_m * side / (self.sensor_mm * 1e-3)
            }
        }
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
    /// Each Defocus node on the frame, in [`DefocusNode::ALL`] order, in the same run.
    pub blenders: Vec<BlenderRun>,
    /// Whole `lensblur render` processes of the layers.
    pub lensblur_seconds: Vec<f64>,
    pub lensblur_median_seconds: f64,
    /// The median of each step inside those processes (their `--json` `timings_ms`).
    pub lensblur_steps_ms: serde_json::Map<String, serde_json::Value>,
    /// Whole `lensblur render` processes of the RGB+Z file the Physical node reads (one image
    /// and its Z pass, split into layers by lensblur): what most compositors hand over.
    pub flat_seconds: Vec<f64>,
    pub flat_median_seconds: f64,
    /// The same steps for those: where a one-shot process of one image goes (issue 43).
    pub flat_steps_ms: serde_json::Map<String, serde_json::Value>,
    /// The medians of the flat file's processes' peak resident memory and page faults (their
    /// `--json` `process`).
    pub flat_process: serde_json::Map<String, serde_json::Value>,
    pub lensblur_png: PathBuf,
}

/// One Blender's Defocus node on the comparison frame.
#[derive(Clone, Debug, serde::Serialize)]
pub struct BlenderRun {
    pub blender: BlenderDefocus,
    pub version: String,
    /// Compositing time inside Blender, each render call.
    pub seconds: Vec<f64>,
    pub median_seconds: f64,
    /// The whole Blender process (start-up, loading, all renders, saving).
    pub process_seconds: f64,
    /// lensblur's median over this node's median compositing time (the goal: at most 0.5).
    pub ratio: f64,
    /// The same for lensblur's render of the flat RGB+Z (issue 43's goal: at most 1.0 at 256^2).
    pub flat_ratio: f64,
    pub png: PathBuf,
}

/// The comparison's name for `focus` on a `side`^2 frame (five layers, CoC up to
/// [`max_coc_px`]).
pub fn case_name(focus: Focus, side: usize) -> String {
    let focus_name = match focus {
        Focus::MostlyInFocus => "focused",
        Focus::FullyDefocused => "defocused",
    };
    format!("blender-{side}-5l-coc{:.0}-{focus_name}", max_coc_px(side))
}

/// Blender's Defocus `bokeh` setting for a regular polygon of `blades` (3 to 8), if it has one.
pub fn blender_bokeh(blades: u32) -> Option<&'static str> {
    ["TRIANGLE", "SQUARE", "PENTAGON", "HEXAGON", "HEPTAGON", "OCTAGON"].get((blades as usize).checked_sub(3)?).copied()
}

/// The comparison frame's inputs, written into `dir` (once per focus): the layered EXR
/// `lensblur render` reads and, per Defocus node, the RGB+Z EXR it reads and its settings.
pub struct ComparisonInputs {
    pub name: String,
    pub layered: PathBuf,
    pub camera: PhysicalCamera,
    /// (settings, RGB+Z EXR) in [`DefocusNode::ALL`] order.
    pub blenders: Vec<(BlenderDefocus, PathBuf)>,
}

impl ComparisonInputs {
    fn for_node(&self, node: DefocusNode) -> &(BlenderDefocus, PathBuf) {
        self.blenders.iter().find(|(settings, _)| settings.node == node).expect("inputs are written for every node")
    }
}

/// The comparison frame's side (the 1024^2; `bench perf --blender-side` for a quick
/// look: Blender 5.0's CPU Defocus takes minutes on 1024^2), layers and largest CoC, which
/// scales with the side (40 px at 1024).
pub const FRAME_SIDE: usize = 1024;
const FRAME_LAYERS: usize = 5;

pub fn max_coc_px(side: usize) -> f32 {
    (40.0 * side as f32 / FRAME_SIDE as f32).round().max(2.0)
}

pub fn comparison_inputs(dir: &Path, focus: Focus, side: usize) -> Result<ComparisonInputs> {
    let max_coc = max_coc_px(side);
    let (stack, lens) = layered_stack(side, side, FRAME_LAYERS, focus, max_coc)?;
    let camera = matching_camera(lens.coc.k_px, lens.coc.focus_disparity, side);
    std::fs::create_dir_all(dir).map_err(|e| Error::input(dir, format!("cannot create: {e}")))?;
    let name = case_name(focus, side);
    let layered = dir.join(format!("{name}-layers.exr"));
    write_stack(&layered, &stack, &StackWriteOptions { depth_kind: DepthKind::Z, camera: Some(camera), ..Default::default() })?;
    let mut blenders = Vec::new();
    for node in DefocusNode::ALL {
        let settings = BlenderDefocus::matching(node, &camera, side, side, max_coc)?;
        let rgbz = dir.join(format!("{name}-rgbz-{node:?}.exr").to_lowercase());
        write_rgbz(&rgbz, &stack, settings.z_scale)?;
        blenders.push((settings, rgbz));
    }
    Ok(ComparisonInputs { name, layered, camera, blenders })
}

/// Blender 3.4's Defocus with `bokeh` on the RGB+Z input: its compositing times (one per
/// render call) and version, and the whole process's time; the result saved as `png`.
pub fn time_blender(inputs: &ComparisonInputs, bokeh: &'static str, png: &Path, repeats: usize) -> Result<(Vec<f64>, String, f64)> {
    let dir = inputs.layered.parent().unwrap_or(Path::new("."));
    let (settings, rgbz) = inputs.for_node(DefocusNode::Legacy);
    let settings = BlenderDefocus { bokeh, ..*settings };
    let (report, process_seconds) = run_blender(dir, rgbz, png, &settings, repeats.max(1))?;
    Ok((report.seconds, report.version, process_seconds))
}

/// Writes the inputs into `dir`, times `repeats` runs of lensblur and of each Defocus node,
/// saves every PNG there.
pub fn compare_with_blender(exe: &Path, dir: &Path, focus: Focus, side: usize, repeats: usize) -> Result<BlenderComparison> {
    let inputs = comparison_inputs(dir, focus, side)?;
    let name = &inputs.name;
    let (ours_exr, ours_png) = (dir.join(format!("{name}-lensblur.exr")), dir.join(format!("{name}-lensblur.png")));
    let args = vec!["-o".to_string(), ours_exr.display().to_string()];
    // The flat file has no camera in its header: the flags give the layered file's.
    let flat_exr = dir.join(format!("{name}-lensblur-flat.exr"));
    let c = &inputs.camera;
    let flat_args: Vec<String> = [
        "-o", &flat_exr.display().to_string(), "--focal-length", &c.focal_length_mm.to_string(),
        "--sensor-width", &c.sensor_width_mm.to_string(), "--fstop", &c.fstop.to_string(),
        "--focus-distance", &c.focus_distance.to_string(),
    ]
    .map(String::from)
    .to_vec();
    let (_, flat_input) = inputs.for_node(DefocusNode::Physical);
    // Alternated, so that a drift of the machine's speed reaches both alike.
    let (mut lensblur_seconds, mut flat_seconds, mut layered_reports, mut flat_reports) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for _ in 0..repeats.max(1) {
        let layered = run_render_process(exe, &inputs.layered, &args, &ours_exr, &[])?;
        let flat = run_render_process(exe, flat_input, &flat_args, &flat_exr, &[])?;
        lensblur_seconds.push(layered.seconds);
        layered_reports.push(layered.report);
        flat_seconds.push(flat.seconds);
        flat_reports.push(flat.report);
    }
    write_png_preview(&ours_png, &read_rgba(&ours_exr, None, u64::MAX)?)?;
    let lensblur_median_seconds = median(&mut lensblur_seconds);
    let flat_median_seconds = median(&mut flat_seconds);
    let mut blenders = Vec::new();
    for (settings, rgbz) in &inputs.blenders {
        let png = dir.join(format!("{name}-blender-{:?}.png", settings.node).to_lowercase());
        let (report, process_seconds) = run_blender(dir, rgbz, &png, settings, repeats.max(1))?;
        let median_seconds = median(&mut report.seconds.clone());
        blenders.push(BlenderRun {
            blender: *settings,
            version: report.version,
            seconds: report.seconds,
            median_seconds,
            process_seconds,
            ratio: lensblur_median_seconds / median_seconds,
            flat_ratio: flat_median_seconds / median_seconds,
            png,
        });
    }
    Ok(BlenderComparison {
        name: inputs.name,
        side,
        layers: FRAME_LAYERS,
        max_coc_px: max_coc_px(side),
        camera: inputs.camera,
        blenders,
        lensblur_seconds,
        lensblur_median_seconds,
        lensblur_steps_ms: median_steps(&layered_reports),
        flat_seconds,
        flat_median_seconds,
        flat_steps_ms: median_steps(&flat_reports),
        flat_process: median_fields(&flat_reports, "process"),
        lensblur_png: ours_png,
    })
}

/// Blender's Defocus nodes as columns of the single-image table: (node, column name).
pub const SINGLE_IMAGE_NODES: [(DefocusNode, &str); 2] = [(DefocusNode::Legacy, "blender-3.4"), (DefocusNode::Physical, "blender-5.0")];

/// `node` on each truth's pinhole render and planar depth (the RGB+Z a Z pass gives it), set up
/// for the truth's own camera and largest CoC; the results (linear EXR, read back) and the
/// compositing seconds inside Blender of each. Inputs and results are kept in `dir`.
pub fn defocus_truths(node: DefocusNode, truths: &[GroundTruth], dir: &Path) -> Result<Vec<(Image, f64)>> {
    std::fs::create_dir_all(dir).map_err(|e| Error::input(dir, format!("cannot create: {e}")))?;
    let mut renders = Vec::new();
    for truth in truths {
        let (width, height) = (truth.pinhole.width, truth.pinhole.height);
        let disparity: Vec<f32> = truth.pinhole_depth.iter().map(|&z| 1.0 / z).collect();
        let coc = &truth.coc;
        let max_coc_px = disparity.iter().fold(0.0f32, |largest, &d| largest.max(coc.k_px * (d - coc.focus_disparity).abs()));
        let settings = BlenderDefocus::matching(node, &truth.camera, width, height, max_coc_px)?;
        let layer = Layer { name: "ViewLayer".into(), rgba: truth.pinhole.clone(), disparity };
        let stem = format!("{}-{node:?}", truth.name).to_lowercase();
        let (rgbz, result) = (dir.join(format!("{stem}-rgbz.exr")), dir.join(format!("{stem}.exr")));
        write_rgbz(&rgbz, &LayerStack::new(width, height, vec![layer])?, settings.z_scale)?;
        let (report, _) = run_blender(dir, &rgbz, &result, &settings, 1)?;
        renders.push((read_rgba(&result, None, u64::MAX)?, report.seconds[0]));
    }
    Ok(renders)
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

/// Runs the script (written into `dir`) in the Blender of `settings.node`, headless; returns
/// its report and the whole process's wall time.
fn run_blender(dir: &Path, rgbz: &Path, png: &Path, settings: &BlenderDefocus, repeats: usize) -> Result<(ScriptReport, f64)> {
    let script = dir.join("blender_defocus.py");
    std::fs::write(&script, SCRIPT).map_err(|e| Error::input(&script, format!("cannot write: {e}")))?;
    let params = serde_json::to_string(settings).map_err(|e| Error::internal(format!("Blender settings: {e}")))?;
    let start = Instant::now();
    let out = settings
        .node
        .command(&script)?
        .arg(rgbz)
        .arg(png)
        .arg(params)
        .arg(repeats.to_string())
        .output()
        .map_err(|e| Error::input(Path::new("blender"), format!("cannot run Blender ({e}); install Debian's blender and the bpy modules with `bash .ci/setup`")))?;
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
            for node in DefocusNode::ALL {
                let blender = BlenderDefocus::matching(node, &camera, 1024, 1024, 40.0).unwrap();
                for z in [0.5f32, 1.0, 1.25, 1.5, 2.0, 3.0, 10.0] {
                    let ours = k * (1.0 / z - focus_disparity).abs();
                    let theirs = blender.blender_radius(blender.z_scale * z);
                    assert!((ours - theirs).abs() <= 1e-3 * ours.max(1.0), "{node:?}, z {z}: ours {ours} px, Blender {theirs} px");
                }
            }
        }
    }

    #[test]
    fn blender_mapping_keeps_the_f_stop_and_lens() {
        let camera = matching_camera(80.0, 0.5, 1024);
        let blender = BlenderDefocus::matching(DefocusNode::Legacy, &camera, 1024, 1024, 40.0).unwrap();
        assert_eq!((blender.f_stop, blender.lens_mm, blender.sensor_mm), (camera.fstop, camera.focal_length_mm, camera.sensor_width_mm));
        assert!(blender.f_stop <= 128.0, "Blender's f-stop range ends at 128");
        assert!(blender.blur_max >= 40.0);
    }
}
