//! The rendering-method interface: what every method declares once ([`MethodSpec`]), how it
//! renders ([`Renderer`]) and the settings a caller may give it ([`MethodSettings`], which each
//! method turns into its own parameters). It names no method: each method's module declares
//! its spec, and the list of methods is [`Method::ALL`] (in `registry.rs`); the CLI's
//! `--method` and flag checks, the benchmark, the tests and the Blender add-on all read it.
use std::str::FromStr;

use crate::camera::FocusField;
use crate::image::Image;
use crate::render::grad::{Differentiable, Slope};
use crate::render::tiler::{RenderOptions, RenderStats};
use crate::render::Lens;
use crate::stack::LayerStack;
use crate::vk::Context;
use crate::{Error, Result};

/// What a method reads. Single-image methods get the stack flattened to one RGBA + disparity
/// image (exact when the input was a single image), so they never see hidden surfaces.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum InputKind {
    Layers,
    SingleImage,
}

/// A method-specific setting a user may give (the CLI maps each to one flag). A method lists
/// the ones it reads in [`MethodSpec::settings`]; giving any other is refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Setting {
    /// Lens samples per pixel.
    Samples,
    /// Intersection search iterations per lens ray.
    Iterations,
    /// Highlight weighting of the colour blend.
    HighlightSigma,
    /// A tilted focal plane (a focus field).
    TiltShift,
    /// Several focal planes at once (a focus field).
    FocalPlanes,
}

impl Setting {
    pub const ALL: [Setting; 5] =
        [Setting::Samples, Setting::Iterations, Setting::HighlightSigma, Setting::TiltShift, Setting::FocalPlanes];

    /// Whether the setting replaces the focal plane by a focus field.
    pub fn is_focus_field(self) -> bool {
        matches!(self, Setting::TiltShift | Setting::FocalPlanes)
    }
}

/// The input handed to a [`Renderer`], of the kind its method declares.
#[derive(Clone, Copy)]
pub enum MethodInput<'a> {
    Layers(&'a LayerStack),
    SingleImage { image: &'a Image, disparity: &'a [f32] },
}

impl<'a> MethodInput<'a> {
    /// The layers, for a layered method (an error names a caller that broke the contract).
    pub fn layers(self) -> Result<&'a LayerStack> {
        match self {
            MethodInput::Layers(stack) => Ok(stack),
            MethodInput::SingleImage { .. } => Err(Error::unsupported("a layered method was handed a single image".to_string())),
        }
    }

    /// The image and its disparity, for a single-image method.
    pub fn single_image(self) -> Result<(&'a Image, &'a [f32])> {
        match self {
            MethodInput::SingleImage { image, disparity } => Ok((image, disparity)),
            MethodInput::Layers(_) => Err(Error::unsupported("a single-image method was handed layers".to_string())),
        }
    }
}

/// A method made ready to render many frames: its Vulkan pipelines built once on a device, or
/// its CPU reference (same formulas; slow) without one.
pub trait Renderer: Send + Sync {
    fn render(&self, input: MethodInput<'_>, lens: &Lens, options: &RenderOptions, settings: &MethodSettings) -> Result<Image>;

    /// Compiles now the device pipelines a render through `lens`'s aperture will dispatch (its
    /// CoC does not matter), so that a caller can do it while the input is still being read.
    /// A driver that compiles at creation (lavapipe) otherwise compiles them at the first
    /// render. The context keeps them: any renderer of the method on it finds them compiled.
    /// Nothing to do for a method whose pipelines compile at its first dispatch cheaply.
    fn warm_up(&self, _lens: &Lens) -> Result<()> {
        Ok(())
    }
}

impl<F> Renderer for F
where
    F: Fn(MethodInput<'_>, &Lens, &RenderOptions, &MethodSettings) -> Result<Image> + Send + Sync,
{
    fn render(&self, input: MethodInput<'_>, lens: &Lens, options: &RenderOptions, settings: &MethodSettings) -> Result<Image> {
        self(input, lens, options, settings)
    }
}

/// A single-image baseline's pass on the Vulkan device ([`crate::render::gather::Gather`],
/// [`crate::render::scatter::Scatter`]): one image and its per-pixel disparity in, the
/// defocused image out.
pub trait SingleImageGpu: Send + Sync + 'static {
    /// Renders `image` (linear, premultiplied) with per-pixel `disparity` through `lens` on frame
    /// tiles cut as `options` says; the same pixels for every tile size.
    fn run_with(&self, image: &Image, disparity: &[f32], lens: &Lens, options: &RenderOptions) -> Result<(Image, RenderStats)>;

    /// [`Self::run_with`] with the default options (tiles as large as the device allows).
    fn run(&self, image: &Image, disparity: &[f32], lens: &Lens) -> Result<Image> {
        Ok(self.run_with(image, disparity, lens, &RenderOptions::default())?.0)
    }
}

/// The renderer of a single-image baseline (gather, scatter): its one tiled pass on the device
/// when `gpu` was made, else its CPU reference.
pub(crate) fn single_image_baseline<G: SingleImageGpu>(gpu: Option<G>, cpu: fn(&Image, &[f32], &Lens) -> Image) -> Box<dyn Renderer> {
    Box::new(move |input: MethodInput<'_>, lens: &Lens, options: &RenderOptions, _: &MethodSettings| {
        let (image, disparity) = input.single_image()?;
        match &gpu {
            Some(gpu) => Ok(gpu.run_with(image, disparity, lens, options)?.0),
            None => Ok(cpu(image, disparity, lens)),
        }
    })
}

/// Everything about one method, declared once.
pub struct MethodSpec {
    /// The `--method` value.
    pub name: &'static str,
    /// A short display name (the Blender add-on's menu).
    pub label: &'static str,
    /// One line: what the method does and where it runs.
    pub summary: &'static str,
    pub input: InputKind,
    /// Whether it runs on the Vulkan device (without one it falls back to its CPU reference).
    pub uses_gpu: bool,
    /// The method-specific settings it reads.
    pub settings: &'static [Setting],
    /// Makes the renderer: on `ctx` when given, else the CPU reference.
    pub prepare: fn(Option<&Context>) -> Result<Box<dyn Renderer>>,
    /// Makes its backward pass on `ctx` (`lensblur grad`, `fit-depth`), if it has one.
    pub differentiable: Option<fn(&Context, Slope) -> Result<Box<dyn Differentiable>>>,
    /// Whether its CPU path renders a lens as fast as its device passes would on a small frame
    /// (without a device it renders that lens through a fast path, not only its reference):
    /// a one-shot render of a small frame then opens no device ([`crate::render::placement`]).
    pub fast_on_cpu: fn(&Lens) -> bool,
}

/// [`MethodSpec::fast_on_cpu`] of a method whose CPU path is its reference alone.
pub fn never_fast_on_cpu(_: &Lens) -> bool {
    false
}

/// A rendering method: a handle on its [`MethodSpec`] in the registry.
#[derive(Clone, Copy)]
pub struct Method(pub(crate) &'static MethodSpec);

/// The method `lensblur render` uses unless told otherwise: Dr.Bokeh.
impl Default for Method {
    fn default() -> Self {
        Method::DrBokeh
    }
}

impl PartialEq for Method {
    fn eq(&self, other: &Self) -> bool {
        self.name() == other.name()
    }
}

impl Eq for Method {}

impl std::fmt::Debug for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Method({})", self.name())
    }
}

impl Method {
    pub fn spec(self) -> &'static MethodSpec {
        self.0
    }

    pub fn name(self) -> &'static str {
        self.0.name
    }

    pub fn input(self) -> InputKind {
        self.0.input
    }

    /// Whether the method runs on the Vulkan device (and so needs a [`Context`]).
    pub fn uses_gpu(self) -> bool {
        self.0.uses_gpu
    }

    /// Whether its CPU path renders `lens` fast ([`MethodSpec::fast_on_cpu`]).
    pub fn fast_on_cpu(self, lens: &Lens) -> bool {
        (self.0.fast_on_cpu)(lens)
    }

    /// Whether the method has a backward pass.
    pub fn is_differentiable(self) -> bool {
        self.0.differentiable.is_some()
    }

    /// The method's backward pass on `ctx`; an [`Error::Unsupported`] naming the methods that
    /// have one when it has none.
    pub fn differentiable(self, ctx: &Context, slope: Slope) -> Result<Box<dyn Differentiable>> {
        match self.0.differentiable {
            Some(make) => make(ctx, slope),
            None => Err(Error::unsupported(self.differentiable_error())),
        }
    }

    /// "method 'x' has no backward pass; use drbokeh or drbokeh-compat or gausspsf".
    pub fn differentiable_error(self) -> String {
        format!("method '{}' has no backward pass; use {}", self.name(), Method::differentiable_names().join(" or "))
    }

    /// The names of the registered methods with a backward pass, in registry order.
    pub fn differentiable_names() -> Vec<&'static str> {
        Method::ALL.iter().filter(|m| m.is_differentiable()).map(|m| m.name()).collect()
    }

    /// Whether the method reads `setting`.
    pub fn reads(self, setting: Setting) -> bool {
        self.0.settings.contains(&setting)
    }

    /// The registered methods that read `setting`, in registry order.
    pub fn readers(setting: Setting) -> impl Iterator<Item = Method> {
        Method::ALL.iter().copied().filter(move |m| m.reads(setting))
    }

    /// The method ready to render many frames (see [`Renderer`]).
    pub fn prepare(self, ctx: Option<&Context>) -> Result<Box<dyn Renderer>> {
        (self.0.prepare)(ctx)
    }

    /// Renders `stack` (front to back) through `lens` with the default settings. Vulkan
    /// methods run on `ctx`; without one they run their CPU reference (same formulas, f64 for
    /// Dr.Bokeh; slow, for machines without a usable Vulkan device).
    pub fn render(self, ctx: Option<&Context>, stack: &LayerStack, lens: &Lens) -> Result<Image> {
        self.render_with(ctx, stack, lens, &RenderOptions::default(), &MethodSettings::default())
    }

    /// [`Self::render`] with frame tiling, memory cap and progress (honoured by every method on
    /// a Vulkan device, through [`crate::render::tiler`]; the CPU references render the whole
    /// frame at once) and the settings of the methods that have any.
    pub fn render_with(
        self,
        ctx: Option<&Context>,
        stack: &LayerStack,
        lens: &Lens,
        options: &RenderOptions,
        settings: &MethodSettings,
    ) -> Result<Image> {
        self.render_prepared(self.prepare(ctx)?.as_ref(), stack, lens, options, settings)
    }

    /// [`Self::render_with`] on a renderer this method's [`Self::prepare`] made once, for a
    /// caller rendering many frames on one device (the Python package's `Renderer`).
    pub fn render_prepared(
        self,
        renderer: &dyn Renderer,
        stack: &LayerStack,
        lens: &Lens,
        options: &RenderOptions,
        settings: &MethodSettings,
    ) -> Result<Image> {
        // Every method sizes windows or kernels from the largest CoC: refuse one no render can
        // finish (or whose integer window arithmetic would overflow) before any work.
        let (lo, hi) = stack.disparity_range();
        if lo <= hi {
            lens.coc.check_renderable(lo, hi)?;
        }
        match self.input() {
            InputKind::Layers => renderer.render(MethodInput::Layers(stack), lens, options, settings),
            InputKind::SingleImage => {
                let (image, disparity) = stack.flatten();
                renderer.render(MethodInput::SingleImage { image: &image, disparity: &disparity }, lens, options, settings)
            }
        }
    }
}

/// The method-specific settings a caller may give, in no method's terms: each method that reads
/// any turns them into its own parameters (`VdslrParams::from_settings`,
/// `MultiviewParams::from_settings`); the others read none. Which [`Setting`]s a method reads
/// is in its spec, and the front ends refuse any other.
#[derive(Clone, Debug, PartialEq)]
pub struct MethodSettings {
    /// Lens samples per pixel ([`Setting::Samples`]; rounded up to a square number of strata).
    pub samples: u32,
    /// Intersection search steps per lens ray ([`Setting::Iterations`]).
    pub iterations: u32,
    /// Highlight weighting of the colour blend ([`Setting::HighlightSigma`]); `None`: off.
    pub highlight: Option<Highlight>,
    /// The focus field ([`Setting::TiltShift`], [`Setting::FocalPlanes`]); the plane of the
    /// lens by default.
    pub focus: FocusField,
}

impl Default for MethodSettings {
    /// What `--method` and the benchmark use: the values the lens-sampling methods are tuned
    /// for (`VdslrParams::tuned`, `MultiviewParams::tuned`, which their modules' tests check
    /// these give).
    fn default() -> Self {
        Self { samples: 512, iterations: 10, highlight: None, focus: FocusField::Plane }
    }
}

impl MethodSettings {
    /// The focus field `method` renders with: the plane, unless it reads a focus-field setting
    /// (Virtual DSLR edits its disparity map).
    pub fn focus(&self, method: Method) -> &FocusField {
        if Setting::ALL.into_iter().any(|s| s.is_focus_field() && method.reads(s)) {
            &self.focus
        } else {
            &FocusField::Plane
        }
    }
}

/// Highlight weighting of the colour blend (Virtual DSLR's Eq. 5),
/// `w = exp(-(min(m, white) - white)^2 / (2 sigma^2))` with `m` the largest RGB component of a
/// sample. The paper's reference 255 is the top of its 8-bit range; on linear HDR data that top
/// is display `white` (1.0 by default), and everything at or above it gets full weight (a
/// Gaussian centred at white would wrongly *down*-weight brighter-than-white highlights).
/// `sigma` is in the same linear units. Linear data already integrates radiance, so the
/// weighting is an optional stylisation, off by default.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Highlight {
    pub sigma: f32,
    pub white: f32,
}

impl FromStr for Method {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        Method::ALL.iter().copied().find(|m| m.name() == s).ok_or_else(|| {
            let names: Vec<&str> = Method::ALL.iter().map(|m| m.name()).collect();
            Error::invalid("method", format!("unknown method '{s}' (available: {})", names.join(", ")))
        })
    }
}

impl serde::Serialize for Method {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> std::result::Result<S::Ok, S::Error> {
        serializer.serialize_str(self.name())
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
