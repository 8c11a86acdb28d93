//! Every rendering method behind one name, as `--method` and the benchmark pick them.
use std::str::FromStr;

use crate::image::Image;
use crate::render::drbokeh::{render_cpu, DrBokehGpu, Model, RenderOptions};
use crate::render::gather::{render_gather_cpu, Gather};
use crate::render::scatter::{render_scatter_cpu, Scatter};
use crate::render::multiview::{render_multiview_cpu, Multiview, MultiviewParams};
use crate::render::vdslr::{render_vdslr_cpu, FocusField, Vdslr, VdslrParams};
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

/// A rendering method.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Dr.Bokeh's layered occlusion-aware gather (the default; Vulkan).
    DrBokeh,
    /// Dr.Bokeh with the formulas of its released code (Vulkan).
    DrBokehCompat,
    /// Lee et al. 2009: lens rays traced through the layers (Vulkan).
    Multiview,
    /// Virtual DSLR (Yang et al. 2016): pseudo ray tracing of one image + depth (Vulkan).
    Vdslr,
    /// Per-layer disk blur composited with "over" (CPU; the classical layered approach).
    Oracle,
    /// Blender-Defocus-like single-image gather (baseline; Vulkan).
    Gather,
    /// BokehMe's classical single-image scatter (baseline; Vulkan).
    Scatter,
}

/// The method `lensblur render` uses unless told otherwise: Dr.Bokeh.
impl Default for Method {
    fn default() -> Self {
        Method::DrBokeh
    }
}

impl Method {
    pub const ALL: [Method; 7] = [
        Method::DrBokeh,
        Method::DrBokehCompat,
        Method::Multiview,
        Method::Vdslr,
        Method::Oracle,
        Method::Gather,
        Method::Scatter,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Method::DrBokeh => "drbokeh",
            Method::DrBokehCompat => "drbokeh-compat",
            Method::Multiview => "multiview",
            Method::Vdslr => "vdslr",
            Method::Oracle => "oracle",
            Method::Gather => "gather",
            Method::Scatter => "scatter",
        }
    }

    pub fn input(self) -> InputKind {
        match self {
            Method::DrBokeh | Method::DrBokehCompat | Method::Multiview | Method::Oracle => {
                InputKind::Layers
            }
            Method::Vdslr | Method::Gather | Method::Scatter => InputKind::SingleImage,
        }
    }

    /// Whether the method runs on the Vulkan device (and so needs a [`Context`]).
    pub fn uses_gpu(self) -> bool {
        matches!(
            self,
            Method::DrBokeh
                | Method::DrBokehCompat
                | Method::Multiview
                | Method::Vdslr
                | Method::Gather
                | Method::Scatter
        )
    }

    /// Renders `stack` (front to back) through `lens` with the default settings. Vulkan
    /// methods run on `ctx`; without one they run their CPU reference (same formulas, f64 for
    /// Dr.Bokeh; slow, for machines without a usable Vulkan device).
    pub fn render(self, ctx: Option<&Context>, stack: &LayerStack, lens: &Lens) -> Result<Image> {
        self.render_with(ctx, stack, lens, &RenderOptions::default(), &MethodSettings::default())
    }

    /// [`Self::render`] with frame tiling and progress (honoured by the tiled methods: drbokeh)
    /// and the settings of the methods that have any.
    pub fn render_with(
        self,
        ctx: Option<&Context>,
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
        let single = || stack.flatten();
        let (vdslr, multiview) = (&settings.vdslr, &settings.multiview);
        match (self, ctx) {
            (Method::DrBokeh | Method::DrBokehCompat, Some(ctx)) => {
                Ok(DrBokehGpu::new(ctx)?.render_with(stack, lens, self.drbokeh_model(), options)?.0)
            }
            (Method::DrBokeh | Method::DrBokehCompat, None) => render_cpu(stack, lens, self.drbokeh_model()),
            (Method::Multiview, Some(ctx)) => Multiview::new(ctx)?.run(stack, lens, multiview),
            (Method::Multiview, None) => render_multiview_cpu(stack, lens, multiview),
            (Method::Vdslr, ctx) => {
                let (image, disparity) = single();
                match ctx {
                    Some(ctx) => Vdslr::new(ctx)?.run(&image, &disparity, lens, vdslr),
                    None => render_vdslr_cpu(&image, &disparity, lens, vdslr),
                }
            }
            (Method::Oracle, _) => Ok(super::oracle::render_oracle(stack, lens)),
            (Method::Gather, ctx) => {
                let (image, disparity) = single();
                match ctx {
                    Some(ctx) => Gather::new(ctx)?.run(&image, &disparity, lens),
                    None => Ok(render_gather_cpu(&image, &disparity, lens)),
                }
            }
            (Method::Scatter, ctx) => {
                let (image, disparity) = single();
                match ctx {
                    Some(ctx) => Scatter::new(ctx)?.run(&image, &disparity, lens),
                    None => Ok(render_scatter_cpu(&image, &disparity, lens)),
                }
            }
        }
    }
}

/// Settings of the methods that take any (the lens-sampling renderers); the rest have none.
#[derive(Clone, Debug, PartialEq)]
pub struct MethodSettings {
    pub vdslr: VdslrParams,
    pub multiview: MultiviewParams,
}

impl Default for MethodSettings {
    /// What `--method` and the benchmark use: each method's tuned parameters.
    fn default() -> Self {
        Self { vdslr: VdslrParams::tuned(), multiview: MultiviewParams::tuned() }
    }
}

impl MethodSettings {
    /// The focus field `method` renders with: only Virtual DSLR edits its disparity map.
    pub fn focus(&self, method: Method) -> &FocusField {
        match method {
            Method::Vdslr => &self.vdslr.focus,
            _ => &FocusField::Plane,
        }
    }
}

impl Method {
    fn drbokeh_model(self) -> Model {
        if self == Method::DrBokehCompat {
            Model::Compat
        } else {
            Model::DrBokeh
        }
    }
}

impl FromStr for Method {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        Method::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Method::ALL.iter().map(|m| m.name()).collect();
                Error::param(format!(
                    "unknown method '{s}' (available: {})",
                    names.join(", ")
                ))
            })
    }
}

impl serde::Serialize for Method {
    fn serialize<S: serde::Serializer>(
        &self,
        serializer: S,
    ) -> std::result::Result<S::Ok, S::Error> {
        serializer.serialize_str(self.name())
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
