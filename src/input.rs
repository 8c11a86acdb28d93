//! A render's input, the way a caller hands it over: a file (a layered EXR in any naming
//! convention, or a PNG/JPEG with a depth image), what the caller says about the camera, and
//! which kind of input the method takes. [`load`] reads the file, resolves the camera (the
//! caller's values win, then the file's header, then a shot's camera file) and, when a layered
//! method is handed one flat image, splits it into layers (auto-layering spaces layers by CoC,
//! so the camera is resolved first). The command line is one caller of this; a library user
//! gets the same policy without rewriting it.
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use crate::camera::{Aperture, CameraHints, CocModel, PhysicalCamera, SceneUnit, SCENE_UNIT_ATTRIBUTE};
use crate::stack::gradients::{stored_depth_gradient, StackGradients};
use crate::render::{InputKind, Lens};
use crate::stack::arrays::ArrayStack;
use crate::image::Image;
use crate::stack::frame_edge::{extend_beyond_frame, frame_margin};
use crate::stack::deep::{deep_to_layers, is_deep_exr, read_deep_files, DeepImage, DeepLayerOptions, DeepReadOptions};
use crate::stack::{
    is_ldr_path, read_ldr, read_stack, split_into_layers, AutoLayerOptions, DepthKind, FileChannels, Layer,
    LayerStack, ReadOptions, StackInfo, DEFAULT_MAX_PIXELS,
};
use crate::error::InputMismatch;
use crate::{Error, Result};

/// What kind of source a render reads, decided once from the path and the options (a deep
/// file by its header's type, a PNG/JPEG by its extension): every reader, refusal and
/// description matches on this instead of asking the file again. Arrays handed over in memory
/// are the fourth kind ([`crate::stack::arrays`], [`crate::job::RenderJob::load_arrays`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SourceKind {
    /// An OpenEXR file of flat images: layers in any naming convention, or one image with Z.
    Exr,
    /// A PNG/JPEG, with its depth in a separate grey image.
    Image,
    /// A deep OpenEXR file, or several merged (`InputOptions::merge`).
    Deep,
}

impl SourceKind {
    /// The kind of `path` read with `options`.
    pub fn of(path: &Path, options: &InputOptions) -> Self {
        Self::of_path(path, !options.merge.is_empty())
    }

    /// The kind of `path`; `merged`: other deep files are merged with it (which makes it deep).
    pub fn of_path(path: &Path, merged: bool) -> Self {
        if merged || is_deep_exr(path) {
            SourceKind::Deep
        } else if is_ldr_path(path) {
            SourceKind::Image
        } else {
            SourceKind::Exr
        }
    }
}

/// What a caller says about the camera. The physical parameters it leaves out come from the
/// file's header, then from a shot's camera file; `normalised` replaces the physical camera.
#[derive(Clone, Debug, Default)]
pub struct CameraRequest {
    /// Physical parameters given by the caller (each optional).
    pub physical: CameraHints,
    /// The normalised model (CoC pixels per unit of disparity, focus disparity): no physical
    /// camera, and nothing is taken from the header.
    pub normalised: Option<CocModel>,
    pub aperture: Aperture,
    /// What one unit of the input's depth (and of the focus distance) is; None: the file's
    /// header attribute [`SCENE_UNIT_ATTRIBUTE`], else metres.
    pub scene_unit: Option<SceneUnit>,
}

/// The lens a render uses, and the physical camera behind it (if any).
#[derive(Clone, Debug)]
pub struct ResolvedCamera {
    pub lens: Lens,
    pub physical: Option<PhysicalCamera>,
    /// Which physical parameters came from the file's header rather than the caller, by key
    /// (`focal-length`, `fstop`, `focus-distance`, `sensor-width`), for reports.
    pub from_header: Vec<&'static str>,
    /// Which came from the shot's camera file (neither the caller nor the header gave them).
    pub from_camera_file: Vec<&'static str>,
    /// The unit of depth and focus distance the physical camera was scaled to.
    pub scene_unit: SceneUnit,
    /// The unit came from the file's header rather than the caller.
    pub scene_unit_from_header: bool,
}

/// Sensor width when neither the caller nor the file says (Blender's default camera).
pub const DEFAULT_SENSOR_WIDTH_MM: f32 = 36.0;

impl CameraRequest {
    /// The camera for an image `width_px` wide: the caller's values, else the header's, else
    /// the camera file's. A physical parameter none of them gives is
    /// [`Error::MissingCamera`]; one that is not a positive number is [`Error::InvalidCamera`].
    pub fn resolve(&self, width_px: usize, header: &CameraHints, camera_file: &CameraHints) -> Result<ResolvedCamera> {
        self.resolve_in(width_px, header, camera_file, None)
    }

    /// [`Self::resolve`] with the scene unit the file's header gives, if any (the caller's
    /// [`CameraRequest::scene_unit`] wins; metres if neither says).
    pub fn resolve_in(
        &self,
        width_px: usize,
        header: &CameraHints,
        camera_file: &CameraHints,
        header_unit: Option<SceneUnit>,
    ) -> Result<ResolvedCamera> {
        let aperture = self.aperture.clone();
        let scene_unit_from_header = self.scene_unit.is_none() && header_unit.is_some();
        let scene_unit = self.scene_unit.clone().or(header_unit).unwrap_or_default();
        if let Some(coc) = self.normalised {
            let lens = Lens { coc, aperture };
            return Ok(ResolvedCamera {
                lens,
                physical: None,
                from_header: Vec::new(),
                from_camera_file: Vec::new(),
                scene_unit,
                scene_unit_from_header,
            });
        }
        let given = &self.physical;
        let sources = [
            ("focal-length", given.focal_length_mm, header.focal_length_mm, camera_file.focal_length_mm),
            ("fstop", given.fstop, header.fstop, camera_file.fstop),
            ("focus-distance", given.focus_distance, header.focus_distance, camera_file.focus_distance),
            ("sensor-width", given.sensor_width_mm, header.sensor_width_mm, camera_file.sensor_width_mm),
        ];
        let mut values = [0.0f32; 4];
        for (value, (parameter, given, header, file)) in values.iter_mut().zip(sources) {
            *value = match given.or(header).or(file) {
                Some(v) => v,
                None if parameter == "sensor-width" => DEFAULT_SENSOR_WIDTH_MM,
                None => return Err(Error::MissingCamera { parameter }),
            };
            if !(value.is_finite() && *value > 0.0) {
                return Err(Error::InvalidCamera { parameter, value: *value });
            }
        }
        let [focal_length_mm, fstop, focus_distance, sensor_width_mm] = values;
        let physical = PhysicalCamera { focal_length_mm, sensor_width_mm, fstop, focus_distance };
        physical.validate()?;
        let coc = CocModel::from_physical_in(&physical, width_px, &scene_unit)?;
        let unflagged = sources.into_iter().filter(|(_, given, _, _)| given.is_none());
        let (from_header, from_file): (Vec<_>, Vec<_>) = unflagged.partition(|(_, _, header, _)| header.is_some());
        Ok(ResolvedCamera {
            lens: Lens { coc, aperture },
            physical: Some(physical),
            from_header: from_header.into_iter().map(|(name, ..)| name).collect(),
            from_camera_file: from_file.into_iter().filter(|(.., file)| file.is_some()).map(|(name, ..)| name).collect(),
            scene_unit,
            scene_unit_from_header,
        })
    }
}

/// How to read an input file and split a flat image into layers.
#[derive(Clone, Debug, PartialEq)]
pub struct InputOptions {
    /// Layers of an EXR to use, by name or glob; None: every layer with colour, alpha and depth.
    pub layers: Option<Vec<String>>,
    /// How depth is stored; None: planar Z for an EXR, normalised disparity for a depth image.
    pub depth_kind: Option<DepthKind>,
    /// The depth image of a PNG/JPEG input (required for one; refused for an EXR).
    pub depth_image: Option<PathBuf>,
    /// Files whose header declares more pixels are refused before any pixel is read.
    pub max_pixels: u64,
    /// Set NaN/Inf colour and alpha samples to 0 (with a warning) instead of refusing the file.
    pub replace_nonfinite: bool,
    pub auto_layer: AutoLayerOptions,
    /// Deep files merged with the input as Nuke's DeepMerge does (the input must be deep too).
    pub merge: Vec<PathBuf>,
    /// How deep files are read: sample budget, which parts.
    pub deep: DeepReadOptions,
    /// How deep samples become layers.
    pub deep_layers: DeepLayerOptions,
    /// Flatten deep input first (a compositor's DeepToImage: colour over, depth of the nearest
    /// layer covering half the pixel) and treat it as one image: what a flat-only defocus sees.
    pub deep_flatten: bool,
}

impl Default for InputOptions {
    fn default() -> Self {
        Self {
            layers: None,
            depth_kind: None,
            depth_image: None,
            max_pixels: DEFAULT_MAX_PIXELS,
            replace_nonfinite: false,
            auto_layer: AutoLayerOptions::default(),
            merge: Vec::new(),
            deep: DeepReadOptions::default(),
            deep_layers: DeepLayerOptions::default(),
            deep_flatten: false,
        }
    }
}

/// A loaded input, ready for a renderer.
pub struct LoadedInput {
    pub stack: LayerStack,
    /// Header facts of an EXR input (None for PNG/JPEG).
    pub info: Option<StackInfo>,
    pub depth_kind: DepthKind,
    pub camera: ResolvedCamera,
    /// The single input image was split into this many layers.
    pub auto_layered: Option<usize>,
    /// `stack` holds the frame this many pixels inside its edge, on a canvas guessed beyond
    /// it (an auto-layered image: [`extend_beyond_frame`]); the render is cut back by it.
    pub frame_margin: usize,
    /// What the caller should tell the user: the file's own warnings (replaced samples,
    /// ignored channels) and a depth encoding that cannot drive a physical camera.
    pub warnings: Vec<String>,
    pub read_time: Duration,
    pub layering_time: Duration,
    /// Deep samples read (all merged files), for a deep input.
    pub deep_samples: Option<u64>,
}

/// Reads `path`, resolves the camera (`camera_file`: the frame's entry of a shot's camera
/// file, or the default for none) and, when `wants` is [`InputKind::Layers`] and the file holds
/// one image, splits it into layers.
pub fn load(
    path: &Path,
    options: &InputOptions,
    camera: &CameraRequest,
    camera_file: &CameraHints,
    wants: InputKind,
) -> Result<LoadedInput> {
    ReadInput::read(path, options)?.into_loaded(options, camera, camera_file, wants)
}

/// An input read once, before its camera is resolved and it is layered: what [`load`] reads,
/// and what a resident session keeps between renders (a render with another camera re-layers
/// it only where the layering depends on the camera).
#[derive(Clone)]
pub struct ReadInput {
    path: PathBuf,
    source: ReadSource,
    read_time: Duration,
}

#[derive(Clone)]
enum ReadSource {
    /// An EXR (layers or one image) or a PNG/JPEG with its depth image.
    Flat { stack: LayerStack, info: Option<StackInfo>, depth_kind: DepthKind, warnings: Vec<String> },
    /// Deep samples: their layers are spaced by the camera's CoC.
    Deep(DeepImage),
    /// Arrays handed over in memory (no header).
    Arrays(ArrayStack),
}

impl ReadInput {
    /// Reads `path` as `options` say (its [`SourceKind`] decides the reader).
    pub fn read(path: &Path, options: &InputOptions) -> Result<Self> {
        let start = Instant::now();
        let source = if SourceKind::of(path, options) == SourceKind::Deep {
            ReadSource::Deep(read_deep(path, options)?)
        } else {
            let (stack, info, depth_kind, warnings) = read(path, options)?;
            ReadSource::Flat { stack, info, depth_kind, warnings }
        };
        Ok(Self { path: path.to_path_buf(), source, read_time: start.elapsed() })
    }

    /// A stack handed over as arrays ([`crate::stack::arrays`]).
    pub fn from_arrays(arrays: ArrayStack) -> Self {
        Self { path: PathBuf::new(), source: ReadSource::Arrays(arrays), read_time: Duration::ZERO }
    }

    /// The camera `request` resolves to for this input: the caller's values, then the header's,
    /// then `camera_file`'s.
    pub fn camera(&self, request: &CameraRequest, camera_file: &CameraHints) -> Result<ResolvedCamera> {
        let none = CameraHints::default();
        match &self.source {
            ReadSource::Flat { stack, info, .. } => {
                let hints = info.as_ref().map(|i| CameraHints::from_attributes(&i.camera)).unwrap_or_default();
                let unit = info.as_ref().and_then(|i| header_scene_unit(&i.camera, &self.path)).transpose()?;
                request.resolve_in(stack.width, &hints, camera_file, unit)
            }
            ReadSource::Deep(image) => {
                let unit = header_scene_unit(&image.attributes, &self.path).transpose()?;
                request.resolve_in(image.width, &CameraHints::from_attributes(&image.attributes), camera_file, unit)
            }
            ReadSource::Arrays(arrays) => request.resolve_in(arrays.stack.width, &none, &none, None),
        }
    }

    /// Width and height in pixels (the data window as read).
    pub fn size(&self) -> (usize, usize) {
        match &self.source {
            ReadSource::Flat { stack, .. } => (stack.width, stack.height),
            ReadSource::Deep(image) => (image.width, image.height),
            ReadSource::Arrays(arrays) => (arrays.stack.width, arrays.stack.height),
        }
    }

    /// Whether the stack a method taking `wants` renders depends on the camera's CoC: a flat
    /// image split into layers by CoC, or deep samples clustered by it. True layers do not.
    pub fn layering_depends_on_camera(&self, wants: InputKind) -> bool {
        match &self.source {
            ReadSource::Flat { stack, info, .. } => {
                info.as_ref().map_or(true, |i| i.single_image) && stack.layers.len() == 1 && wants == InputKind::Layers
            }
            ReadSource::Deep(_) => true,
            ReadSource::Arrays(arrays) => {
                arrays.single_image && arrays.stack.layers.len() == 1 && wants == InputKind::Layers
            }
        }
    }

    /// The input of one render through `camera` (from [`Self::camera`]), this read kept for the
    /// next: the stack is copied, then layered for `wants`.
    pub fn loaded(&self, options: &InputOptions, camera: ResolvedCamera, wants: InputKind) -> Result<LoadedInput> {
        self.clone().finish(options, camera, wants)
    }

    /// [`load`]'s second half: the camera resolved, the stack layered for `wants`.
    pub fn into_loaded(self, options: &InputOptions, request: &CameraRequest, camera_file: &CameraHints, wants: InputKind) -> Result<LoadedInput> {
        let camera = self.camera(request, camera_file)?;
        self.finish(options, camera, wants)
    }

    fn finish(self, options: &InputOptions, camera: ResolvedCamera, wants: InputKind) -> Result<LoadedInput> {
        let start = Instant::now();
        let read_time = self.read_time;
        let (stack, info, depth_kind, mut warnings, auto_layered, frame_margin, deep_samples) = match self.source {
            ReadSource::Flat { stack, info, depth_kind, warnings } => {
                let single = info.as_ref().map_or(true, |i| i.single_image) && stack.layers.len() == 1;
                let (stack, auto_layered, frame_margin) = layers_for(stack, single, &camera.lens.coc, wants, &options.auto_layer);
                (stack, info, depth_kind, warnings, auto_layered, frame_margin, None)
            }
            ReadSource::Deep(image) => {
                let (stack, auto_layered, frame_margin) = deep_layers(&image, &camera.lens.coc, options, wants)?;
                (stack, None, DepthKind::Z, Vec::new(), auto_layered, frame_margin, Some(image.samples.len() as u64))
            }
            ReadSource::Arrays(arrays) => {
                let (stack, auto_layered, frame_margin) =
                    layers_for(arrays.stack, arrays.single_image, &camera.lens.coc, wants, &options.auto_layer);
                (stack, None, arrays.depth_kind, Vec::new(), auto_layered, frame_margin, None)
            }
        };
        if camera.physical.is_some() && deep_samples.is_none() {
            warnings.extend(depth_kind.physical_camera_warning());
        }
        let layering_time = start.elapsed();
        Ok(LoadedInput { stack, info, depth_kind, camera, auto_layered, frame_margin, warnings, read_time, layering_time, deep_samples })
    }
}

/// The scene unit a header's [`SCENE_UNIT_ATTRIBUTE`] names, if it has one; a value that is
/// no unit is an error naming the file (a silent fallback to metres would blur 100x wrong).
fn header_scene_unit(attributes: &std::collections::BTreeMap<String, String>, path: &Path) -> Option<Result<SceneUnit>> {
    let text = attributes.get(SCENE_UNIT_ATTRIBUTE)?;
    Some(text.parse::<SceneUnit>().map_err(|e| Error::input(path, format!("header attribute {SCENE_UNIT_ATTRIBUTE}: {e}"))))
}

/// A deep input and the deep files merged with it, samples read and checked.
fn read_deep(path: &Path, options: &InputOptions) -> Result<DeepImage> {
    let paths: Vec<PathBuf> = std::iter::once(path.to_path_buf()).chain(options.merge.iter().cloned()).collect();
    if let Some(flat) = paths.iter().find(|p| SourceKind::of_path(p, false) != SourceKind::Deep) {
        if !flat.exists() {
            return Err(Error::Io { path: flat.clone(), source: std::io::Error::from(std::io::ErrorKind::NotFound) });
        }
        return Err(Error::input(flat, "is not a deep OpenEXR file: only deep files merge (DeepMerge)"));
    }
    read_deep_files(&paths, &DeepReadOptions { max_pixels: options.max_pixels, ..options.deep.clone() })
}

/// Deep samples clustered into layers spaced by `coc`. A method that takes one image gets the
/// deep pixels flattened, with the depth of the nearest layer.
fn deep_layers(image: &DeepImage, coc: &CocModel, options: &InputOptions, wants: InputKind) -> Result<(LayerStack, Option<usize>, usize)> {
    let stack = deep_to_layers(image, coc, &options.deep_layers)?;
    if wants == InputKind::Layers && !options.deep_flatten {
        return Ok((stack, None, 0));
    }
    let (rgba, disparity) = stack.flatten();
    let flat = LayerStack::new(image.width, image.height, vec![Layer { name: "flattened".into(), rgba, disparity }])?;
    Ok(layers_for(flat, true, coc, wants, &options.auto_layer))
}

/// The stack a method taking `wants` renders: `stack` itself, or, when it is one flat image
/// (`single`) and the method takes layers, that image split into layers spaced by CoC under
/// `coc` (how many: the second value), on a canvas extended beyond the frame by the third
/// value on every side when `options` guess what lies there ([`extend_beyond_frame`]).
pub fn layers_for(
    stack: LayerStack,
    single: bool,
    coc: &CocModel,
    wants: InputKind,
    options: &AutoLayerOptions,
) -> (LayerStack, Option<usize>, usize) {
    if !(single && wants == InputKind::Layers && stack.layers.len() == 1) {
        return (stack, None, 0);
    }
    let flat = &stack.layers[0];
    let (layered, count, margin) = auto_layers(&flat.rgba, &flat.disparity, coc, options);
    (layered, Some(count), margin)
}

/// The frame size `path`'s header declares (an EXR's display window, a PNG's or JPEG's size),
/// read without the pixels; None where the header does not say (the read reports why).
pub fn declared_frame_size(path: &Path) -> Option<(usize, usize)> {
    if crate::stack::is_ldr_path(path) {
        let (width, height) = crate::stack::ldr_size(path, u64::MAX).ok()?;
        return Some((width as usize, height as usize));
    }
    crate::stack::exr_read::declared_size(path)
}

/// One flat image split into layers spaced by CoC under `coc` (how many: the second value),
/// on a canvas extended beyond the frame by the third value on every side when `options`
/// guess what lies there ([`extend_beyond_frame`]): what a render job renders of it.
pub fn auto_layers(image: &Image, disparity: &[f32], coc: &CocModel, options: &AutoLayerOptions) -> (LayerStack, usize, usize) {
    let layered = split_into_layers(image, disparity, coc, options);
    let count = layered.layers.len();
    if !options.guess_beyond_frame {
        return (layered, count, 0);
    }
    let margin = frame_margin(disparity, coc, image.width, image.height);
    (extend_beyond_frame(layered, margin), count, margin)
}

/// Refuses, before any read, an input that `writer` (`"grad writes its gradients"`) could not
/// write back channel by channel into an EXR laid out like the input: a deep EXR (or a `merge`
/// of them), whose samples are no layer's channels, or a PNG/JPEG, which has no depth channel.
pub fn require_channel_stack(path: &Path, options: &InputOptions, writer: &str) -> Result<()> {
    let (kind, why, hint) = match SourceKind::of(path, options) {
        SourceKind::Deep => {
            ("a deep EXR", "a deep file's samples are no layer's channels", "; from deep data, Nuke's DeepToImage (one per layer) makes one")
        }
        SourceKind::Image => ("a PNG/JPEG image", "it has no depth channel", ""),
        SourceKind::Exr => return Ok(()),
    };
    Err(Error::input(
        path,
        format!(
            "is {kind}: {writer} channel by channel into an EXR laid out like its input, and {why}. \
             Give it a layered EXR stack (layer.R,G,B,A,Z, or a plain R,G,B,A,Z image){hint}"
        ),
    ))
}

/// Reads `path` as [`load`] does, without resolving a camera or splitting layers: the stack
/// (disparity), the EXR's header facts, the depth convention used, and the file's warnings.
pub fn read(path: &Path, options: &InputOptions) -> Result<(LayerStack, Option<StackInfo>, DepthKind, Vec<String>)> {
    if SourceKind::of(path, options) == SourceKind::Image {
        let Some(depth_path) = &options.depth_image else {
            return Err(Error::InputMismatch { path: path.into(), mismatch: InputMismatch::MissingDepthImage });
        };
        if options.layers.is_some() {
            return Err(Error::InputMismatch { path: path.into(), mismatch: InputMismatch::LayersOfSingleImage });
        }
        let kind = options.depth_kind.unwrap_or(DepthKind::Disparity);
        let ldr = read_ldr(path, depth_path, kind, options.max_pixels)?;
        let (w, h) = (ldr.image.width, ldr.image.height);
        let layer = Layer { name: "image".into(), rgba: ldr.image, disparity: ldr.disparity };
        return Ok((LayerStack::new(w, h, vec![layer])?, None, kind, Vec::new()));
    }
    if options.depth_image.is_some() {
        return Err(Error::InputMismatch { path: path.into(), mismatch: InputMismatch::DepthImageBesideStack });
    }
    let kind = options.depth_kind.unwrap_or(DepthKind::Z);
    let read = ReadOptions {
        layers: options.layers.clone(),
        depth_kind: kind,
        max_pixels: options.max_pixels,
        replace_nonfinite: options.replace_nonfinite,
    };
    let file = read_stack(path, &read)?;
    let warnings = file.info.warnings.clone();
    Ok((file.stack, Some(file.info), kind, warnings))
}

impl LoadedInput {
    /// The frame's width and height: the stack's, less the canvas guessed beyond the frame.
    pub fn frame_size(&self) -> (usize, usize) {
        (self.stack.width - 2 * self.frame_margin, self.stack.height - 2 * self.frame_margin)
    }

    /// Gradients of a render of this input, mapped onto every channel of the file it came
    /// from (its names; multi-part inputs as `<part>.<channel>`): colour and alpha as stored
    /// (premultiplied), depth through the file's depth convention and the reader's fill,
    /// zero for channels that do not reach the render. Fails for a PNG/JPEG input (its
    /// channels are not a stack's) or a stack that was auto-layered.
    pub fn gradient_channels(&self, grads: &StackGradients) -> Result<Vec<(String, Vec<f32>)>> {
        let Some(info) = &self.info else {
            let kind = if self.deep_samples.is_some() { "a deep EXR" } else { "a PNG/JPEG" };
            return Err(Error::unsupported(format!("gradients map onto the channels of an EXR stack; this input is {kind}")));
        };
        if self.auto_layered.is_some() {
            return Err(Error::unsupported(crate::stack::arrays::AUTO_LAYERED_GRADIENTS));
        }
        let mut channels = FileChannels::zeroed(info);
        for (layer, grad) in self.stack.layers.iter().zip(&grads.layers) {
            let Some(names) = channels.layer(&layer.name) else { continue };
            for (c, name) in names.colour.iter().enumerate() {
                if let Some(name) = name {
                    channels.set(name, grad.rgba.iter().map(|g| g[c]).collect());
                }
            }
            if let Some(name) = &names.depth {
                let Some(read) = info.layers.iter().find(|l| l.name == layer.name) else { continue };
                channels.set(name, stored_depth_gradient(self.depth_kind, layer, &read.depth_weights, &grad.disparity)?);
            }
        }
        Ok(channels.into_list())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hints(focal: Option<f32>, fstop: Option<f32>, focus: Option<f32>) -> CameraHints {
        CameraHints { focal_length_mm: focal, sensor_width_mm: None, fstop, focus_distance: focus }
    }

    #[test]
    fn the_callers_values_win_then_the_header_then_the_camera_file() {
        let request = CameraRequest { physical: hints(Some(85.0), None, None), ..CameraRequest::default() };
        let header = hints(Some(50.0), Some(2.0), None);
        let file = hints(Some(35.0), Some(4.0), Some(3.0));
        let camera = request.resolve(1000, &header, &file).unwrap();
        let physical = camera.physical.unwrap();
        assert_eq!((physical.focal_length_mm, physical.fstop, physical.focus_distance), (85.0, 2.0, 3.0));
        assert_eq!(physical.sensor_width_mm, DEFAULT_SENSOR_WIDTH_MM);
        assert_eq!(camera.from_header, ["fstop"]);
        assert_eq!(camera.from_camera_file, ["focus-distance"]);
        // K = (f / 2N) (f / sensor) width, in pixels per unit of disparity (f in metres).
        let k = 0.085 / (2.0 * 2.0) * (85.0 / 36.0) * 1000.0;
        assert!((camera.lens.coc.k_px - k).abs() < 1e-3 * k, "{} vs {k}", camera.lens.coc.k_px);
        assert!((camera.lens.coc.focus_disparity - 1.0 / 3.0).abs() < 1e-6);
    }

    #[test]
    fn a_missing_or_invalid_parameter_is_a_typed_error_naming_it() {
        let request = CameraRequest::default();
        let error = request.resolve(100, &hints(Some(50.0), None, Some(2.0)), &CameraHints::default()).unwrap_err();
        assert!(matches!(error, Error::MissingCamera { parameter: "fstop" }), "{error:?}");
        let request = CameraRequest { physical: hints(None, Some(-2.0), None), ..CameraRequest::default() };
        let error = request.resolve(100, &hints(Some(50.0), None, Some(2.0)), &CameraHints::default()).unwrap_err();
        assert!(matches!(error, Error::InvalidCamera { parameter: "fstop", value } if value == -2.0), "{error:?}");
    }

    #[test]
    fn the_scene_unit_scales_the_blur_and_the_callers_unit_wins_over_the_headers() {
        let request = CameraRequest { physical: hints(Some(50.0), Some(2.0), Some(300.0)), ..CameraRequest::default() };
        let none = CameraHints::default();
        let metres = request.resolve(1000, &none, &none).unwrap();
        assert_eq!((metres.scene_unit.name.as_str(), metres.scene_unit_from_header), ("m", false));
        let from_header = request.resolve_in(1000, &none, &none, Some("cm".parse().unwrap())).unwrap();
        assert!(from_header.scene_unit_from_header);
        // Depth in centimetres: the same lens blurs 100 times more per unit of 1/depth.
        let ratio = from_header.lens.coc.k_px / metres.lens.coc.k_px;
        assert!((ratio - 100.0).abs() < 1e-3, "{ratio}");
        let given = CameraRequest { scene_unit: Some("mm".parse().unwrap()), ..request };
        let camera = given.resolve_in(1000, &none, &none, Some("cm".parse().unwrap())).unwrap();
        assert_eq!((camera.scene_unit.name.as_str(), camera.scene_unit_from_header), ("mm", false));
    }

    #[test]
    fn the_normalised_model_takes_nothing_from_the_header() {
        let coc = CocModel::new(12.0, 0.25).unwrap();
        let request = CameraRequest { normalised: Some(coc), ..CameraRequest::default() };
        let camera = request.resolve(100, &hints(Some(50.0), Some(2.0), Some(3.0)), &CameraHints::default()).unwrap();
        assert!(camera.physical.is_none() && camera.from_header.is_empty());
        assert_eq!((camera.lens.coc.k_px, camera.lens.coc.focus_disparity), (12.0, 0.25));
    }

    #[test]
    fn options_that_do_not_fit_the_files_kind_are_typed_refusals_before_any_read() {
        // No file exists at these paths: each refusal comes before reading.
        let refusal = |path: &str, options: InputOptions| {
            let result = load(Path::new(path), &options, &CameraRequest::default(), &CameraHints::default(), InputKind::Layers);
            match result {
                Err(Error::InputMismatch { path: p, mismatch }) if p == Path::new(path) => mismatch,
                other => panic!("{path}: {:?}", other.map(|_| ())),
            }
        };
        assert_eq!(refusal("photo.png", InputOptions::default()), InputMismatch::MissingDepthImage);
        let with_depth = || InputOptions { depth_image: Some("depth.png".into()), ..InputOptions::default() };
        let layers = InputOptions { layers: Some(vec!["fg".into()]), ..with_depth() };
        assert_eq!(refusal("photo.jpg", layers), InputMismatch::LayersOfSingleImage);
        assert_eq!(refusal("shot.exr", with_depth()), InputMismatch::DepthImageBesideStack);
    }
}
