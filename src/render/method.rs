//! Every rendering method behind one name, as `--method` and the benchmark pick them.
use std::str::FromStr;

use crate::image::Image;
use crate::render::drbokeh::{DrBokehGpu, Model, RenderOptions};
use crate::render::multiview::{Multiview, MultiviewParams};
use crate::render::vdslr::{Vdslr, VdslrParams};
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
            Method::DrBokeh | Method::DrBokehCompat | Method::Multiview | Method::Vdslr
        )
    }

    /// Renders `stack` (front to back) through `lens`. `ctx` is required by Vulkan methods.
    pub fn render(self, ctx: Option<&Context>, stack: &LayerStack, lens: &Lens) -> Result<Image> {
        self.render_with(ctx, stack, lens, &RenderOptions::default())
    }

    /// [`Self::render`] with frame tiling and progress (honoured by the tiled methods: drbokeh).
    pub fn render_with(self, ctx: Option<&Context>, stack: &LayerStack, lens: &Lens, options: &RenderOptions) -> Result<Image> {
        let gpu = || {
            ctx.ok_or_else(|| {
                Error::param(format!("method '{}' needs a Vulkan device", self.name()))
            })
        };
        let single = || stack.flatten();
        match self {
            Method::DrBokeh => Ok(DrBokehGpu::new(gpu()?)?.render_with(stack, lens, Model::DrBokeh, options)?.0),
            Method::DrBokehCompat => Ok(DrBokehGpu::new(gpu()?)?.render_with(stack, lens, Model::Compat, options)?.0),
            Method::Multiview => {
                Multiview::new(gpu()?)?.run(stack, lens, &MultiviewParams::tuned())
            }
            Method::Vdslr => {
                let (image, disparity) = single();
                Vdslr::new(gpu()?)?.run(&image, &disparity, lens, &VdslrParams::tuned())
            }
            Method::Oracle => Ok(super::oracle::render_oracle(stack, &lens.coc)),
            Method::Gather => {
                let (image, disparity) = single();
                super::gather::Gather::new(gpu()?)?.run(&image, &disparity, lens)
            }
            Method::Scatter => {
                let (image, disparity) = single();
                super::scatter::Scatter::new(gpu()?)?.run(&image, &disparity, lens)
            }
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
