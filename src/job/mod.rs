//! One render, described once for every front end: the input and how to read it, the camera,
//! the method and its settings, the lens character and the options that cut the work. The
//! command line (one file or a shot's frames), the Python package and a resident session all
//! build a [`RenderJob`], have it checked once ([`RenderJob::new`], before any file is read),
//! and run it; no front end assembles a render of its own.
//!
//! Messages name the job's options by their snake_case names in backticks (`` `samples` ``,
//! `` `tilt_shift` ``), which is how Python spells them; a front end with other spellings (the
//! command line's `--samples`) rewrites the backticked names with [`spell_options`].
use std::borrow::Cow;
use std::path::Path;
use std::time::{Duration, Instant};

use crate::camera::{disparity_from_z, CameraHints, FocusField};
use crate::character::Character;
use crate::image::Image;
use crate::input::{load, CameraRequest, InputOptions, ReadInput};
pub use crate::input::LoadedInput;
use crate::render::placement::{place, place_frame, small_frame_on_cpu, DevicePreference, Placement};
use crate::render::tiler::{RenderOptions, StackMemo};
use crate::render::vdslr::Highlight;
use crate::render::{Lens, Method, MethodSettings, Renderer, Setting};
use crate::stack::arrays::ArrayStack;
use crate::stack::LayerStack;
use crate::vk::{Context, ContextOptions};
use crate::{Error, Result};

pub mod options;
pub use options::{CameraValues, JobOptions, OptionSet, FILE_OPTIONS, RENDER_OPTIONS};

/// The settings of the lens-sampling methods as a caller gives them; `None` keeps the method's
/// tuned default. A setting the chosen method does not read is refused, never ignored.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MethodOptions {
    /// Lens samples per pixel (vdslr, multiview); rounded up to a square.
    pub samples: Option<u32>,
    /// Intersection search iterations per lens ray (vdslr).
    pub iterations: Option<u32>,
    /// Highlight weighting of the colour blend, sigma in linear units; 0 turns it off (vdslr).
    pub highlight_sigma: Option<f32>,
    /// A tilted focal plane: focus offsets in CoC pixels at the right and bottom frame edges,
    /// linear across the frame and zero at its centre (positive = focused nearer) (vdslr).
    pub tilt_shift: Option<[f32; 2]>,
    /// Several focal planes at once: distances in scene units for a physical camera,
    /// disparities for the normalised model; the first becomes the camera's focus (vdslr).
    pub focal_planes: Option<Vec<f32>>,
}

impl MethodOptions {
    /// The option name of `setting`, as messages and Python spell it.
    pub fn option_name(setting: Setting) -> &'static str {
        match setting {
            Setting::Samples => "samples",
            Setting::Iterations => "iterations",
            Setting::HighlightSigma => "highlight_sigma",
            Setting::TiltShift => "tilt_shift",
            Setting::FocalPlanes => "focal_planes",
        }
    }

    fn given(&self) -> [(Setting, bool); 5] {
        [
            (Setting::Samples, self.samples.is_some()),
            (Setting::Iterations, self.iterations.is_some()),
            (Setting::HighlightSigma, self.highlight_sigma.is_some()),
            (Setting::TiltShift, self.tilt_shift.is_some()),
            (Setting::FocalPlanes, self.focal_planes.is_some()),
        ]
    }

    /// Refuses settings `method` does not read, two focus fields at once and values out of
    /// range, before any reading.
    pub fn check(&self, method: Method) -> Result<()> {
        if let Some((setting, _)) = self.given().into_iter().find(|(setting, on)| *on && !method.reads(*setting)) {
            let readers: Vec<&str> = Method::readers(setting).map(Method::name).collect();
            let methods = match readers.split_last() {
                Some((last, rest)) if !rest.is_empty() => format!("{} and {last}", rest.join(", ")),
                _ => readers.join(""),
            };
            return Err(Error::invalid(
                "method settings",
                format!(
                    "`{}` applies to `method` {methods}, not {method}: drop it or pick one of those methods",
                    Self::option_name(setting)
                ),
            ));
        }
        if self.tilt_shift.is_some() && self.focal_planes.is_some() {
            return Err(Error::invalid("method settings", "`tilt_shift` and `focal_planes` each set the focus field: give one of them"));
        }
        if let Some(sigma) = self.highlight_sigma {
            if !(sigma.is_finite() && sigma >= 0.0) {
                return Err(Error::invalid(
                    "method settings",
                    format!("`highlight_sigma` must be a positive number (0 turns it off), got {sigma}"),
                ));
            }
        }
        if let Some([x, y]) = self.tilt_shift {
            if !(x.is_finite() && y.is_finite()) {
                return Err(Error::invalid("method settings", format!("`tilt_shift` must be two finite numbers, got {x},{y}")));
            }
        }
        match &self.focal_planes {
            Some(planes) if planes.is_empty() => {
                Err(Error::invalid("method settings", "`focal_planes` needs at least one plane"))
            }
            Some(planes) if planes.iter().any(|d| !d.is_finite()) => {
                Err(Error::invalid("method settings", format!("`focal_planes` must be finite numbers, got {planes:?}")))
            }
            _ => Ok(()),
        }
    }

    /// The settings `method` renders a `width x height` frame through `lens` with; `physical`:
    /// the camera is physical (focal planes are distances, not disparities).
    pub fn resolve(&self, lens: &Lens, physical: bool, width: usize, height: usize) -> Result<MethodSettings> {
        let mut settings = MethodSettings::default();
        if let Some(samples) = self.samples {
            settings.samples = samples;
        }
        if let Some(iterations) = self.iterations {
            settings.iterations = iterations;
        }
        if let Some(sigma) = self.highlight_sigma {
            settings.highlight = (sigma > 0.0).then_some(Highlight { sigma, white: 1.0 });
        }
        if let Some([x, y]) = self.tilt_shift {
            settings.focus = tilt(x, y, lens, width, height)?;
        }
        if let Some(planes) = &self.focal_planes {
            let disparities = if physical {
                if let Some(bad) = planes.iter().find(|d| **d <= 0.0) {
                    return Err(Error::invalid(
                        "method settings",
                        format!("`focal_planes`: distances must be positive (scene units), got {bad}"),
                    ));
                }
                planes.iter().copied().map(disparity_from_z).collect()
            } else {
                planes.clone()
            };
            settings.focus = FocusField::Planes(disparities);
        }
        Ok(settings)
    }

    /// The focus field these options ask for, before the lens is known (for the checks).
    fn focus_kind(&self) -> FocusField {
        if self.tilt_shift.is_some() {
            FocusField::Tilt { gradient: [0.0, 0.0] }
        } else if let Some(planes) = &self.focal_planes {
            FocusField::Planes(planes.clone())
        } else {
            FocusField::Plane
        }
    }
}

/// The tilted focus field whose focus, relative to the centre, is `x` CoC pixels nearer at the
/// right edge and `y` at the bottom edge (disparity is linear in image position on any plane).
fn tilt(x: f32, y: f32, lens: &Lens, width: usize, height: usize) -> Result<FocusField> {
    let k = lens.coc.k_px;
    if k <= 0.0 {
        return Err(Error::invalid(
            "method settings",
            format!("`tilt_shift`: the camera does not blur (K = {k}): a tilted focal plane changes nothing"),
        ));
    }
    // From the centre pixel to the edge pixel: (n - 1) / 2 pixels (a 1-pixel axis has no tilt).
    let per_pixel = |offset: f32, n: usize| if n > 1 { offset / k / ((n as f32 - 1.0) * 0.5) } else { 0.0 };
    Ok(FocusField::Tilt { gradient: [per_pixel(x, width), per_pixel(y, height)] })
}

/// Everything one render needs but the pixels. Build it, check it once with [`RenderJob::new`]
/// (before any file is read), then [`load`](RenderJob::load) inputs and
/// [`render`](RenderJob::render) them: a shot renders every frame with one job.
#[derive(Clone, Debug, Default)]
pub struct JobSpec {
    pub method: Method,
    /// What the caller says about the camera (the rest comes from the input's header).
    pub camera: CameraRequest,
    /// How a file is read and a flat image split into layers.
    pub input: InputOptions,
    pub method_options: MethodOptions,
    /// Lens character and artist controls (blur remap, focus pick, bloom, chromatic
    /// aberration, cat's-eye).
    pub character: Character,
    /// The input carries this many extra pixels on every side (overscan): rendered, then cut
    /// from the result.
    pub overscan: usize,
    /// Frame tile side in pixels on the Vulkan device (`None`: the largest that fits).
    pub tile: Option<usize>,
    /// Most bytes the render may hold, host and device together.
    pub max_memory: Option<u64>,
    /// Where a Vulkan method runs.
    pub device: DevicePreference,
}

/// A checked [`JobSpec`]: every front end renders through one of these.
#[derive(Clone, Debug)]
pub struct RenderJob {
    spec: JobSpec,
}

/// A render of one input with its lens character applied, and what the reports and debug
/// views describe.
pub struct Rendered<'a> {
    /// The defocused frame, overscan and the canvas guessed beyond the frame included (see
    /// [`RenderJob::output`]).
    pub image: Image,
    /// The stack as rendered (after the blur remap and bloom).
    pub prepared: Cow<'a, LayerStack>,
    /// The lens as rendered (after a focus pick).
    pub lens: Lens,
    /// The focus field the method rendered.
    pub focus: FocusField,
    /// Building the method's pipelines ([`RenderJob::render`]; zero on a prepared renderer).
    pub prepare_time: Duration,
    /// The render itself, after the pipelines were built.
    pub render_time: Duration,
}

impl RenderJob {
    /// Checks everything that needs no input: the method's settings, the character's values,
    /// tiling against where the method runs, and controls that exclude each other.
    pub fn new(spec: JobSpec) -> Result<Self> {
        spec.method_options.check(spec.method)?;
        spec.character.validate()?;
        spec.character.check_focus_field(&spec.method_options.focus_kind())?;
        let tiling = match (spec.tile, spec.max_memory) {
            (Some(_), _) => Some("tile"),
            (None, Some(_)) => Some("max_memory"),
            (None, None) => None,
        };
        if let Some(option) = tiling {
            if !spec.method.uses_gpu() {
                return Err(Error::invalid(
                    "tiling",
                    format!(
                        "`{option}` cuts the frames of the Vulkan methods; {} runs on the CPU over whole layers, untiled (drop it)",
                        spec.method
                    ),
                ));
            }
            if spec.device == DevicePreference::Cpu {
                return Err(Error::invalid(
                    "tiling",
                    format!("`{option}` cuts the frames of the Vulkan renderers; `device` cpu runs the CPU reference over the whole frame (drop one)"),
                ));
            }
        }
        if spec.tile == Some(0) {
            return Err(Error::invalid("tiling", "`tile` must be at least 1 pixel"));
        }
        let mut spec = spec;
        // An overscanned input carries what lies beyond the frame: nothing to guess. A
        // cat's-eye's shift is measured from the frame's centre to its corners: a canvas
        // extended beyond the frame would move the corners.
        if spec.overscan > 0 || spec.character.cats_eye.is_some() {
            spec.input.auto_layer.guess_beyond_frame = false;
        }
        // The first focal plane stands for the camera's focus: what reports and the other
        // controls' checks see.
        if let Some(&first) = spec.method_options.focal_planes.as_ref().and_then(|p| p.first()) {
            match &mut spec.camera.normalised {
                Some(coc) => coc.focus_disparity = first,
                None => spec.camera.physical.focus_distance = Some(first),
            }
        }
        Ok(Self { spec })
    }

    pub fn spec(&self) -> &JobSpec {
        &self.spec
    }

    pub fn method(&self) -> Method {
        self.spec.method
    }

    /// Compiles on `ctx` the pipelines this job's render will dispatch ([`Renderer::warm_up`]),
    /// for a caller that can do it while the input is read and layered: the pipelines follow
    /// the method, the aperture and the lens character, all known before the file is. The
    /// context keeps them for the render's own renderer.
    pub fn warm_up(&self, ctx: &Context) -> Result<()> {
        let (_, lens) = self.method_lens()?;
        self.spec.method.prepare(Some(ctx))?.warm_up(&lens)
    }

    /// The character left for the method's passes and the lens they render through, at any
    /// CoC (known before the file is read: what the pipelines and the placement follow).
    fn method_lens(&self) -> Result<(Character, Lens)> {
        let lens = Lens { coc: crate::camera::CocModel::new(1.0, 0.5)?, aperture: self.spec.camera.aperture.clone() };
        Ok(self.spec.character.for_method(self.spec.method, &lens))
    }

    /// Where the method runs: the Vulkan device (`LENSBLUR_DEVICE` picks one), or the CPU
    /// reference, with the reason (see [`place`]).
    pub fn place(&self) -> Result<Placement> {
        place(self.spec.method, self.spec.device, &ContextOptions::from_env())
    }

    /// [`Self::place`] for a one-shot render of one frame of `frame` pixels (None where
    /// unknown): a small frame whose method renders the job's lens fast on the CPU, with no
    /// further lens character and no device tiling asked for (`tile`, `max_memory`), opens no
    /// device ([`place_frame`]).
    pub fn place_frame(&self, frame: Option<(usize, usize)>) -> Result<Placement> {
        let (lens, frame) = self.frame_for_cpu(frame)?;
        place_frame(self.spec.method, self.spec.device, &ContextOptions::from_env(), &lens, frame)
    }

    /// Whether [`Self::place_frame`] renders a frame of `frame` pixels on the CPU, opening no
    /// device (a resident [`crate::session::Session`] on a CPU device follows it too).
    pub fn small_frame_on_cpu(&self, frame: Option<(usize, usize)>) -> Result<bool> {
        let (lens, frame) = self.frame_for_cpu(frame)?;
        Ok(small_frame_on_cpu(self.spec.method, self.spec.device, &ContextOptions::from_env(), &lens, frame))
    }

    /// The lens the method renders through and `frame`, or None for the frame where a lens
    /// character or device tiling (`tile`, `max_memory`) keeps the render on the device.
    fn frame_for_cpu(&self, frame: Option<(usize, usize)>) -> Result<(Lens, Option<(usize, usize)>)> {
        let (look, lens) = self.method_lens()?;
        let device_tiling = self.spec.tile.is_some() || self.spec.max_memory.is_some();
        Ok((lens, frame.filter(|_| look == Character::default() && !device_tiling)))
    }

    /// Reads `path` for this job: the camera resolved (the job's values, then the header, then
    /// `camera_file`: a shot's entry for the frame) and a flat image split into layers for a
    /// layered method.
    pub fn load(&self, path: &Path, camera_file: &CameraHints) -> Result<LoadedInput> {
        load(path, &self.spec.input, &self.spec.camera, camera_file, self.spec.method.input())
    }

    /// Takes a stack handed over as arrays ([`crate::stack::arrays`]) for this job: the camera
    /// is the job's alone (arrays have no header).
    pub fn load_arrays(&self, arrays: ArrayStack) -> Result<LoadedInput> {
        ReadInput::from_arrays(arrays).into_loaded(&self.spec.input, &self.spec.camera, &CameraHints::default(), self.spec.method.input())
    }

    /// The method's settings for a loaded input (a tilt and focal planes depend on its lens
    /// and size).
    pub fn settings(&self, loaded: &LoadedInput) -> Result<MethodSettings> {
        let (width, height) = loaded.frame_size();
        self.spec.method_options.resolve(&loaded.camera.lens, loaded.camera.physical.is_some(), width, height)
    }

    /// How many method renders [`Self::render`] makes of `loaded` (x3 for chromatic
    /// aberration, x grid nodes for cat's-eye), for progress displays.
    pub fn render_count(&self, loaded: &LoadedInput) -> usize {
        let (look, lens) = self.spec.character.for_method(self.spec.method, &loaded.camera.lens);
        look.render_count(&loaded.stack, &lens)
    }

    /// Renders `loaded` on `ctx` (the CPU reference without one); `progress` is called after
    /// each finished tile with (tiles done, tiles in all) of the current method render.
    pub fn render<'a>(
        &self,
        ctx: Option<&Context>,
        loaded: &'a LoadedInput,
        progress: Option<&(dyn Fn(usize, usize) + Sync)>,
    ) -> Result<Rendered<'a>> {
        let start = Instant::now();
        let renderer = self.spec.method.prepare(ctx)?;
        let prepare_time = start.elapsed();
        Ok(Rendered { prepare_time, ..self.render_with(renderer.as_ref(), loaded, progress)? })
    }

    /// [`Self::render`] on a renderer the job's method prepared once ([`Method::prepare`]), for
    /// callers that render many times on one device (Python, a resident session).
    pub fn render_with<'a>(
        &self,
        renderer: &dyn Renderer,
        loaded: &'a LoadedInput,
        progress: Option<&(dyn Fn(usize, usize) + Sync)>,
    ) -> Result<Rendered<'a>> {
        self.render_resident(renderer, loaded, progress, None)
    }

    /// [`Self::render_with`] on an input the caller holds unchanged from render to render (a
    /// resident session), with `memo` kept for it ([`StackMemo`]: the caller makes a new one when
    /// it replaces the input). The method keeps in it what it may reuse, for renders that hand
    /// it the input's own stack (not one the lens character changed).
    pub fn render_resident<'a>(
        &self,
        renderer: &dyn Renderer,
        loaded: &'a LoadedInput,
        progress: Option<&(dyn Fn(usize, usize) + Sync)>,
        memo: Option<&StackMemo>,
    ) -> Result<Rendered<'a>> {
        let start = Instant::now();
        let method = self.spec.method;
        let settings = self.settings(loaded)?;
        let character = &self.spec.character;
        character.check_focus_field(settings.focus(method))?;
        let (prepared, lens) = character.prepare_framed(&loaded.stack, &loaded.camera.lens, loaded.frame_margin)?;
        let (look, lens) = character.for_method(method, &lens);
        let options = RenderOptions { tile: self.spec.tile, max_memory: self.spec.max_memory, progress, ..RenderOptions::default() };
        let render = |s: &LayerStack, l: &Lens| {
            // Only the held stack itself: a remapped or bloomed copy is another stack.
            let memo = memo.filter(|_| std::ptr::eq(s, &loaded.stack));
            method.render_prepared(renderer, s, l, &RenderOptions { stack_memo: memo, ..options }, &settings)
        };
        let image = look.render_prepared(&render, &prepared, &lens)?;
        let focus = settings.focus(method).clone();
        Ok(Rendered { image, prepared, lens, focus, prepare_time: Duration::ZERO, render_time: start.elapsed() })
    }

    /// The frame a caller keeps: `image`, a render of `loaded`, without the overscan margin
    /// and the canvas guessed beyond the frame ([`LoadedInput::frame_margin`]).
    pub fn output<'i>(&self, image: &'i Image, loaded: &LoadedInput) -> Result<Cow<'i, Image>> {
        let overscan = self.spec.overscan;
        match overscan + loaded.frame_margin {
            0 => Ok(Cow::Borrowed(image)),
            margin => image.without_border(margin).map(Cow::Owned).ok_or_else(|| {
                Error::invalid(
                    "overscan",
                    format!(
                        "`overscan` {overscan} cuts {overscan} px from each side of a {}x{} frame: nothing is left (give the margin the input was rendered with)",
                        image.width - 2 * loaded.frame_margin,
                        image.height - 2 * loaded.frame_margin
                    ),
                )
            }),
        }
    }
}

/// `message` with every backticked option name (`` `tilt_shift` ``) spelled by `spell`, for a
/// front end whose options are named otherwise (the command line: `--tilt-shift`). Backticked
/// text that is not a lowercase snake_case name is kept as it is.
pub fn spell_options(message: &str, spell: impl Fn(&str) -> String) -> String {
    let mut out = String::with_capacity(message.len());
    let mut rest = message;
    while let Some(open) = rest.find('`') {
        let after = &rest[open + 1..];
        let Some(close) = after.find('`') else { break };
        let name = &after[..close];
        out.push_str(&rest[..open]);
        if !name.is_empty() && name.chars().all(|c| c.is_ascii_lowercase() || c == '_' || c.is_ascii_digit()) {
            out.push_str(&spell(name));
        } else {
            out.push_str(&rest[open..open + close + 2]);
        }
        rest = &after[close + 1..];
    }
    out.push_str(rest);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn option_names_are_spelled_by_the_front_end_and_other_code_is_kept() {
        let flag = |name: &str| format!("--{}", name.replace('_', "-"));
        let message = "`tilt_shift` and `focal_planes` each set the focus field; see `lensblur methods`";
        assert_eq!(
            spell_options(message, flag),
            "--tilt-shift and --focal-planes each set the focus field; see `lensblur methods`"
        );
        assert_eq!(spell_options("no names here", flag), "no names here");
        assert_eq!(spell_options("an `unclosed quote", flag), "an `unclosed quote");
    }

    #[test]
    fn a_setting_the_method_does_not_read_is_refused_naming_its_readers() {
        let spec = JobSpec { method_options: MethodOptions { samples: Some(64), ..Default::default() }, ..Default::default() };
        let error = RenderJob::new(spec).unwrap_err().to_string();
        assert_eq!(error, "`samples` applies to `method` multiview and vdslr, not drbokeh: drop it or pick one of those methods");
        let both = MethodOptions { tilt_shift: Some([1.0, 0.0]), focal_planes: Some(vec![2.0]), ..Default::default() };
        let error = RenderJob::new(JobSpec { method: Method::Vdslr, method_options: both, ..Default::default() }).unwrap_err();
        assert!(error.to_string().contains("each set the focus field"), "{error}");
    }

    #[test]
    fn tiling_is_refused_where_nothing_would_read_it() {
        let spec = JobSpec { method: Method::Oracle, tile: Some(64), ..Default::default() };
        assert!(RenderJob::new(spec).unwrap_err().to_string().starts_with("`tile` cuts the frames"));
        let spec = JobSpec { device: DevicePreference::Cpu, max_memory: Some(1 << 30), ..Default::default() };
        assert!(RenderJob::new(spec).unwrap_err().to_string().contains("`device` cpu"));
    }

    #[test]
    fn the_canvas_beyond_the_frame_is_left_out_where_the_frame_is_not_the_whole_story() {
        let guesses = |spec: JobSpec| RenderJob::new(spec).unwrap().spec().input.auto_layer.guess_beyond_frame;
        assert!(guesses(JobSpec::default()));
        // The input holds what lies beyond; a cat's-eye measures its shift to the frame's corners.
        assert!(!guesses(JobSpec { overscan: 8, ..Default::default() }));
        let cats_eye = Character { cats_eye: Some(crate::character::CatsEye::new(0.5).unwrap()), ..Default::default() };
        assert!(!guesses(JobSpec { character: cats_eye, ..Default::default() }));
    }

    #[test]
    fn the_first_focal_plane_becomes_the_cameras_focus() {
        let planes = MethodOptions { focal_planes: Some(vec![1.5, 6.0]), ..Default::default() };
        let job = RenderJob::new(JobSpec { method: Method::Vdslr, method_options: planes, ..Default::default() }).unwrap();
        assert_eq!(job.spec().camera.physical.focus_distance, Some(1.5));
    }
}
