//! Dr.Bokeh forward renderer (paper Sec. 3.3, Eq. 3-8; DESIGN.md "Dr.Bokeh forward").
//!
//! Per layer l, output pixel x, source pixel y (all in pixels, layers front to back):
//! `C_l(x) = sum_y P_l(y) S K O / A`, `W_l(x) = sum_y a_l(y) S K O / A` with `P = I a` the
//! premultiplied colour; layer colour `C_l / W_l`; visibility `V_l(x)`; composite
//! `B(x) = sum_l V_l prod_{k<l} (1 - V_k) C_l / W_l`, alpha = `sum_l V_l prod_{k<l} (1 - V_k)`.
//!
//! Two models share every pass ([`Model`]); the per-term math is in [`math`].
//!
//! Passes (CPU reference: [`cpu`], same loops, same order):
//! 1. Search windows, on the host ([`bounds`]): per 16x16 tile and layer, the largest scatter
//!    support of a source with alpha > 0 and gather radius, dilated so a tile's window
//!    half-width covers every source tile whose support reaches it. They also give each frame
//!    tile its halo, so they are computed before any upload.
//! 2. `layer` (GPU, per layer): C_l, W_l and V_l of every pixel over its tile's window. A
//!    prepass (`glsl/drbokeh_layer_sources.comp`) stores each source's P / A(r), s and alpha
//!    once; `glsl/drbokeh_layer_disk.comp` (default model, disk aperture) and
//!    `glsl/drbokeh_layer.comp` (every other case) gather runs of two pixels per invocation.
//!    The first straightforward kernel stays as [`LayerKernel::Baseline`] for benchmarks.
//! 3. `composite` (GPU `glsl/drbokeh_composite.comp`): front-to-back blend of all layers. A
//!    forward render folds each layer in at the end of its layer pass instead (`pc.fold`, the
//!    same `drbokeh_composite_step` in the same order), so a frame tile holds one layer's
//!    intermediates, not every layer's (`gpu::Residency`); the backward reads every layer's and
//!    keeps them all.
//!
//! Large frames are rendered in frame tiles (`gpu.rs`): each uploads its core plus halo, and
//! since every pixel reads the same sources in the same order, the output is bit-identical
//! whatever the tile size. Several tiles share one submission; the tiler every method uses
//! ([`crate::render::tiler`]) plans tile side and batch size from the device's limits and
//! memory budget and retries smaller when memory runs out. The backward ([`DrBokehGpuGrad`])
//! tiles the frame the same way, by the same policy, with the same guarantee.
use std::borrow::Cow;

use crate::camera::{Aperture, CocModel, Eye, CATS_EYE_SHAPE};
use crate::render::grad::{Differentiable, Slope};
use crate::render::method::{InputKind, MethodInput, MethodSettings, MethodSpec, Renderer};
use crate::render::Lens;
use crate::vk::Context;

pub mod backward;
pub mod backward_cpu;
pub mod bounds;
pub mod cpu;
mod gpu;
mod gpu_backward;
mod kept;
pub mod math;
pub mod native;
mod params;

#[cfg(test)]
mod compat_direct;
#[cfg(test)]
mod tests;

pub use backward::BackwardOptions;
pub use backward_cpu::{backward_cpu, CpuGradients, CpuLayerGradients, DrBokehCpu};
pub use cpu::{render_cpu, render_cpu_params, render_cpu_terms, LayerTerms, Terms, Window};
pub use gpu::{DrBokehGpu, LayerKernel, RenderOptions, RenderStats, ResidentStack};
pub use gpu_backward::DrBokehGpuGrad;
pub use params::Params;

/// Dr.Bokeh in the registry: the default method, and differentiable.
pub const METHOD: MethodSpec = MethodSpec {
    name: "drbokeh",
    label: "Dr.Bokeh",
    summary: "Layered occlusion-aware gather (Vulkan); the default",
    input: InputKind::Layers,
    uses_gpu: true,
    settings: &[],
    prepare: |ctx| renderer(ctx, Model::DrBokeh),
    differentiable: Some(|ctx, slope| differentiable(ctx, Model::DrBokeh, slope)),
    fast_on_cpu: |lens| native::supports(lens, Model::DrBokeh),
};

/// Dr.Bokeh with the formulas of its released code ([`Model::Compat`]); otherwise as [`METHOD`].
pub const METHOD_COMPAT: MethodSpec = MethodSpec {
    name: "drbokeh-compat",
    label: "Dr.Bokeh (released code)",
    summary: "Dr.Bokeh with the formulas of its released code (Vulkan)",
    prepare: |ctx| renderer(ctx, Model::Compat),
    differentiable: Some(|ctx, slope| differentiable(ctx, Model::Compat, slope)),
    fast_on_cpu: crate::render::method::never_fast_on_cpu,
    ..METHOD
};

fn renderer(ctx: Option<&Context>, model: Model) -> crate::Result<Box<dyn Renderer>> {
    Ok(Box::new(DrBokehRenderer { gpu: ctx.map(DrBokehGpu::new).transpose()?, model }))
}

/// The method's renderer: its device passes, or the CPU reference without a device.
struct DrBokehRenderer {
    gpu: Option<DrBokehGpu>,
    model: Model,
}

impl Renderer for DrBokehRenderer {
    fn render(&self, input: MethodInput<'_>, lens: &Lens, options: &RenderOptions, _: &MethodSettings) -> crate::Result<crate::image::Image> {
        let stack = input.layers()?;
        match (&self.gpu, options.stack_memo) {
            // A resident stack: its scan (and upload) are made by its first render and kept for
            // the others, on the device and on the CPU path.
            (Some(gpu), Some(memo)) => {
                let resident = memo.get_or_insert_with(|| ResidentStack::new(stack, lens.coc.focus_disparity));
                Ok(gpu.render_resident(stack, &resident, lens, self.model, options)?.0)
            }
            (Some(gpu), None) => Ok(gpu.render_with(stack, lens, self.model, options)?.0),
            // Without a device: the fast CPU path where it renders the lens, else the reference.
            (None, Some(memo)) if native::supports(lens, self.model) => {
                let resident = memo.get_or_insert_with(|| ResidentStack::new(stack, lens.coc.focus_disparity));
                native::render_native(stack, lens, Some(resident.scan()))
            }
            (None, _) if native::supports(lens, self.model) => native::render_native(stack, lens, None),
            (None, _) => render_cpu(stack, lens, self.model),
        }
    }

    fn warm_up(&self, lens: &Lens) -> crate::Result<()> {
        self.gpu.as_ref().map_or(Ok(()), |gpu| gpu.compile_for(lens, self.model))
    }
}

fn differentiable(ctx: &Context, model: Model, slope: Slope) -> crate::Result<Box<dyn Differentiable>> {
    let options = match slope {
        Slope::Exact => BackwardOptions::exact(),
        Slope::Leaky => BackwardOptions::leaky(),
    };
    Ok(Box::new(DrBokehGpuGrad::new(ctx, model, options)?))
}

/// Side of the square output tile a workgroup owns, in pixels (`local_size` 16x16).
pub const TILE: usize = 16;
/// Compat scatter tail cut, in pixels past the released plateau edge `r + 1`: beyond it the
/// released soft step is below `0.1 e^-12 ~ 6e-7` of its plateau value.
pub const COMPAT_TAIL_PX: f64 = 4.0;
/// CoC range over which kernel-image weights fade in (below it the kernel is sub-pixel).
pub const KERNEL_FADE_START_PX: f64 = crate::camera::KERNEL_FADE_PX[0] as f64;
pub const KERNEL_FADE_END_PX: f64 = crate::camera::KERNEL_FADE_PX[1] as f64;
/// Step of the area table in pixels of CoC radius, and the radius it covers.
pub const AREA_STEP_PX: f64 = 1.0 / 16.0;
pub const AREA_TABLE_RADIUS_PX: f64 = 16.0;
/// Cat's-eyes in a vignetted lens's area table (`Params::area_at`), |a| evenly spaced: the
/// area is smooth in |a| (the relative area falls from 1 to 0.62 at strength 0.6), so linear
/// interpolation between 17 levels errs by ~2e-5 of it there (0.3% at the limit strength 1.5,
/// where the corner's eye keeps 14% of the disk).
pub const VIGNETTE_AREA_LEVELS: usize = 17;
/// A vignetted polygon's or ellipse's area table (`Params::area_at`): its cat's-eye depends
/// on the direction of the shift too, over half a symmetry sector (the base is symmetric about
/// its first edge normal or long axis, and repeats every sector), so it has levels of |s| times
/// directions: 9 x 9 tables (~5x the disk's 17 levels of lattice sums) interpolate the area
/// of a source's own eye to ~1% at r = 12 px at strength 1 (0.9% for a pentagon, whose 36
/// degree half sector 9 directions hold to 4.5 degrees; 5 erred by 2.5%). Small CoCs are
/// lattice-limited, as the disk's levels are: a footprint of a few pixels gains or loses whole
/// lattice points as its shape turns, which no interpolation between shapes follows (up to 17%
/// for the ellipse at r = 2.3 px on a corner at strength 1, 12% for the disk's levels).
pub const VIGNETTE_BASE_AREA_LEVELS: usize = 9;
pub const VIGNETTE_AREA_DIRECTIONS: usize = 9;

/// The middle of 16 px tile (tx, ty)'s part inside a `width` x `height` frame: where a
/// vignetted lens's shape is taken for the whole tile (`glsl/common/drbokeh_layer.glsl`,
/// `gauge_setup_rows`).
pub(crate) fn tile_middle(tx: usize, ty: usize, width: usize, height: usize) -> [f64; 2] {
    let middle = |t: usize, n: usize| (t * TILE + ((t + 1) * TILE - 1).min(n - 1)) as f64 * 0.5;
    [middle(tx, width), middle(ty, height)]
}

/// Which formulas the renderer evaluates.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Model {
    /// Fixes the released code's defects (DESIGN.md): exact in-focus pixels, occlusion in CoC
    /// pixels, visibility over the full soft CoC disk, in-image normalisation at borders.
    #[default]
    DrBokeh,
    /// The authors' released formulas, for comparison with the published method.
    Compat,
}

impl Model {
    /// The push-constant flag (`DRBOKEH_MODEL_*` in `drbokeh.glsl`).
    pub fn flag(self) -> i32 {
        match self {
            Model::DrBokeh => 0,
            Model::Compat => 1,
        }
    }
}

/// Push constants shared by every `drbokeh_*.comp` pass; mirrors `DrBokehPush` in
/// `glsl/common/drbokeh.glsl` (std430 offsets in the comments).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct DrBokehPush {
    pub width: i32,   // 0
    pub height: i32,  // 4
    pub tiles_x: i32, // 8
    pub tiles_y: i32, // 12
    /// Layer this dispatch works on (0 = front); unused by `composite`.
    pub layer: i32, // 16
    pub layer_count: i32, // 20
    /// [`Model::flag`].
    pub model: i32, // 24
    /// Side of the kernel image buffer (0 = no kernel image).
    pub kernel_size: i32, // 28
    pub k_px: f32,    // 32
    pub focus_disparity: f32, // 36
    /// Largest scatter support / gather radius over the stack, bounds the dilation loop.
    pub max_support: f32, // 40
    pub area_step: f32, // 44
    pub area_count: i32, // 48
    /// [`BackwardOptions::leaky_slope`]; read by the backward passes only.
    pub leaky_slope: f32, // 52
    /// The layer's place in the dispatch's per-layer tile buffers: `layer` where they hold
    /// every layer (the backward), 0 where they hold one (a forward render, layer by layer).
    /// The frame's tables (windows, span radii) are indexed by `layer` either way.
    pub slot: i32, // 56
    /// Layer passes: 1 folds the layer's (C, W, V) into the running composite its bindings 5
    /// and 6 hold (a forward render layer by layer), 0 writes them there.
    pub fold: i32, // 60
    /// [`Aperture::gpu_params`]: blades (0 = disk), rotation (rad), roundness, kernel flag.
    pub aperture: [f32; 4], // 64
    /// Frame tile this dispatch writes: x, y, width, height in image pixels (the whole image
    /// when untiled). Per-pixel outputs are stored core-local.
    pub core: [i32; 4], // 80
    /// Rectangle of the image uploaded for this tile (core + halo, clipped): x, y, width,
    /// height. Source buffers are indexed read-local.
    pub read: [i32; 4], // 96
}

const _: () = assert!(std::mem::size_of::<DrBokehPush>() == 112);
const _: () = assert!(std::mem::size_of::<DrBokehPush>() <= 128);

/// The lens as the renderer reads it, in f64 (GPU-form aperture plus kernel weights).
#[derive(Clone, Debug, PartialEq)]
pub struct LensView {
    pub k_px: f64,
    pub focus_disparity: f64,
    pub aperture: [f64; 4],
    pub kernel: Vec<f64>,
    pub kernel_size: usize,
    /// The GPU form of a vignetted lens's base ([`Aperture::gpu_params`]; zeros for every other
    /// lens): the ellipse's squeeze is not in [`Self::aperture`].
    pub base: [f64; 4],
    /// A vignetted polygon's or ellipse's shape at one receiver tile (`Params::receiver_lens`):
    /// its gauge is [`Eye::gauge`].
    pub eye: Option<Eye>,
}

/// Which layer-pass variant renders a lens under a model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AperturePath {
    /// Default model, disk: row spans with closed-form bounds, the Euclidean gauge.
    Disk,
    /// Default model, polygon or ellipse: row spans bounded by the row table, the shape's
    /// gauge in the rim taps.
    Gauge,
    /// Default model, ring: the disk path's gather less a second one over the obstruction
    /// (the ring's weight is `S(r) (1 - blend S(inner r))`), both with row spans.
    Ring,
    /// Default model, kernel image: the disk's row spans split into the kernel's runs
    /// ([`crate::camera::kernel_run_table`]): full-weight runs summed, zero-weight runs
    /// skipped, the kernel evaluated at the taps between.
    Kernel,
    /// Every tap evaluated (the compat model).
    PerTap,
}

impl LensView {
    pub fn new(coc: &CocModel, aperture: &Aperture) -> Self {
        let (kernel, kernel_size) = match aperture {
            Aperture::Kernel(k) => (k.weights.iter().map(|&w| w as f64).collect(), k.size),
            _ => (Vec::new(), 0),
        };
        Self {
            k_px: coc.k_px as f64,
            focus_disparity: coc.focus_disparity as f64,
            aperture: aperture.gpu_params().map(|v| v as f64),
            kernel,
            kernel_size,
            base: match aperture {
                Aperture::Vignetted { base, .. } => base.gpu_params().map(|v| v as f64),
                _ => [0.0; 4],
            },
            eye: None,
        }
    }

    /// The specialization constants of the gauge paths' shaders (`GAUGE_BLADES` and
    /// `GAUGE_VIGNETTED_BASE` in `glsl/common/gauge.glsl`): the polygon's blades, 0 for the
    /// ellipse, 1 for the cat's-eye, 2 for the vignetted disk (a cat's-eye per receiver tile);
    /// then 1 for a vignetted polygon or ellipse, whose blades (or 0) come first.
    pub fn gauge_specialization(&self) -> [u32; 2] {
        match self.aperture[0] {
            shape if shape >= 3.0 => [shape as u32, 0],
            _ if self.is_vignetted_base() => [if self.base[0] >= 3.0 { self.base[0] as u32 } else { 0 }, 1],
            _ if self.is_vignetted() => [2, 0],
            shape if shape < -0.5 => [1, 0],
            _ => [0, 0],
        }
    }

    /// Whether the aperture is a vignetted polygon or ellipse (shape -2 with a base other
    /// than the disk): its shape at a receiver tile is `Params::receiver_lens`'s.
    pub fn is_vignetted_base(&self) -> bool {
        self.is_vignetted() && self.base[0] > 0.5
    }

    /// Whether the aperture is [`Aperture::Vignetted`] (shape -2 of the GPU form): its shape
    /// depends on the frame position ([`Self::at_receiver`]).
    pub fn is_vignetted(&self) -> bool {
        self.aperture[0] < -1.5
    }

    /// The vignetted disk's cat's-eye centre `a` at frame position (x, y) of a `width` x
    /// `height` frame: half of `character::CatsEye::shift` (its disks sit at +-a), in f64.
    /// Mirrors `drbokeh_vignette_centre` in `glsl/common/drbokeh.glsl`.
    pub fn vignette_centre(&self, x: f64, y: f64, width: usize, height: usize) -> [f64; 2] {
        let (cx, cy) = ((width as f64 - 1.0) * 0.5, (height as f64 - 1.0) * 0.5);
        let scale = 0.5 * self.aperture[1] / cx.hypot(cy).max(1.0);
        [scale * (x - cx), scale * (y - cy)]
    }

    /// The vignetting disk's shift at frame position (x, y): `character::CatsEye::shift` in
    /// f64, twice [`Self::vignette_centre`].
    pub fn vignette_shift(&self, x: f64, y: f64, width: usize, height: usize) -> [f64; 2] {
        self.vignette_centre(x, y, width, height).map(|a| 2.0 * a)
    }

    /// The lens a receiver pixel (x, y) of a vignetted disk's render gathers through: the cat's-eye
    /// at the middle of its 16 px tile (the part inside the frame), so one workgroup of the
    /// layer pass shares one shape and its row bounds. Every other lens is its own.
    ///
    /// The approximation: a source's bokeh takes the shape of the tile it lands in, not of
    /// its own position (up to a CoC radius away: the shift moves by strength * r / half
    /// diagonal, ~0.03 aperture radii for r = 40 px on a 1024^2 frame at strength 0.6), and the
    /// shape steps between tiles (0.013 radii at that strength). The node grid it replaces
    /// blended four nodes' shapes 341 px apart on that frame.
    pub fn at_receiver(&self, x: usize, y: usize, width: usize, height: usize) -> Cow<'_, LensView> {
        if !self.is_vignetted() {
            return Cow::Borrowed(self);
        }
        let [mx, my] = tile_middle(x / TILE, y / TILE, width, height);
        let [ax, ay] = self.vignette_centre(mx, my, width, height);
        Cow::Owned(LensView { aperture: [CATS_EYE_SHAPE as f64, ax, ay, 0.0], ..self.clone() })
    }

    /// The layer-pass variant for this lens under `model` (from the GPU form: shape 0 = disk,
    /// 1 = ellipse, 2 = ring, >= 3 = polygon, -1 = cat's-eye; a kernel image is evaluated per
    /// tap).
    pub fn path(&self, model: Model) -> AperturePath {
        let kernel = self.aperture[3] >= 0.5 && self.kernel_size > 0;
        match model {
            Model::DrBokeh if !kernel && (-0.5..0.5).contains(&self.aperture[0]) => AperturePath::Disk,
            Model::DrBokeh if self.is_ring() => AperturePath::Ring,
            Model::DrBokeh if kernel => AperturePath::Kernel,
            Model::DrBokeh if !kernel => AperturePath::Gauge,
            _ => AperturePath::PerTap,
        }
    }

    /// Whether the aperture is [`Aperture::Ring`] (shape 2 of the GPU form).
    pub fn is_ring(&self) -> bool {
        (1.5..2.5).contains(&self.aperture[0])
    }

    /// Signed relative disparity `d - d_f`.
    #[inline]
    pub fn rel(&self, disparity: f32) -> f64 {
        disparity as f64 - self.focus_disparity
    }

    /// Signed CoC radius in pixels (positive = nearer than focus).
    #[inline]
    pub fn signed_radius(&self, disparity: f32) -> f64 {
        self.k_px * self.rel(disparity)
    }

    /// Gauge and kernel weight of the offset `x - y` seen through a CoC of radius `r` at
    /// relative disparity `rel` (mirrors `drbokeh_lens` in `drbokeh.glsl`).
    pub fn lens(&self, dx: f64, dy: f64, r: f64, rel: f64) -> (f64, f64) {
        let (u, v) = math::to_aperture_coords(dx, dy, rel);
        if let Some(eye) = &self.eye {
            return (eye.gauge(u, v), 1.0);
        }
        let g = math::gauge(&self.aperture, u, v);
        if self.is_ring() {
            return (g, math::ring_weight(g, r, self.aperture[2]));
        }
        if self.aperture[3] < 0.5 || self.kernel_size == 0 {
            return (g, 1.0);
        }
        let scale = 1.0 / (r + 0.5);
        let sample = math::kernel_sample(&self.kernel, self.kernel_size, u * scale, v * scale);
        (g, 1.0 + (sample - 1.0) * math::kernel_blend(r))
    }
}
