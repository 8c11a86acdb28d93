//! GPU host code of the Dr.Bokeh forward renderer. The frame is cut into tiles: each uploads
//! its core plus the halo its search windows reach, records the layer passes and the composite
//! of `glsl/drbokeh_*.comp`, and reads its core back; several tiles share one submission
//! ([`crate::render::tiler`], the tiler every method uses). Every pixel reads the same sources
//! in the same order whatever the tiling, so the output is bit-identical for every tile size and
//! batch size. The CPU reference of the same passes is [`super::cpu`]; `Params` (validation,
//! lens, area table, push constants) and the search windows are shared with it.
use std::sync::{Arc, Mutex};

use rayon::prelude::*;

use super::bounds::{scanned_windows_and_ranges, search_tiles, span_radii, SourceRanges, StackScan, NO_SPAN_RADII};
use super::kept::KeptTables;
use super::{AperturePath, DrBokehPush, LensView, Model, Params, TILE};
use crate::camera::{aperture_row_table, closed_form_gauge, kernel_run_table, Aperture, EMPTY_APERTURE_ROW};
use crate::image::Image;
use crate::render::tiler::{
    crop_rows, run_batches, run_tiled, store_core, Footprint, FrameTiling, TilePlan, TileRoom,
};
use crate::render::Lens;
use crate::shaders;
use crate::stack::LayerStack;
use crate::tile_grid::Rect;
use crate::vk::{Binding, Buffer, CommandBatch, ComputePipeline, Context, PipelineVariants, ReadBack, Slot, TexelFormat};
use crate::{Error, Result};

/// Bytes per read pixel of one layer: uploaded rgba + disparity ([`INPUT_BYTES_PER_PIXEL`]),
/// and its intermediates ([`WORK_BYTES_PER_PIXEL`]).
pub(crate) const READ_BYTES_PER_PIXEL: u64 = INPUT_BYTES_PER_PIXEL + WORK_BYTES_PER_PIXEL;
/// Bytes per read pixel of one layer's upload: rgba + disparity.
pub(crate) const INPUT_BYTES_PER_PIXEL: u64 = 20;
/// Bytes per read pixel of one layer's intermediates: prepass P / A + (s, alpha), block prefix
/// + suffix of (P / A, alpha).
pub(crate) const WORK_BYTES_PER_PIXEL: u64 = 24 + 40;
/// Bytes per core pixel of one layer: written (C, W) + V.
pub(crate) const CORE_BYTES_PER_PIXEL: u64 = 20;
pub(crate) const VEC4: u64 = 16;

/// What renders of one stack keep for the next (a resident stack refocused: a session's
/// [`crate::render::tiler::StackMemo`], the GPU kit's forward cases): the pass over its pixels
/// that bounds the searches ([`StackScan`]), and, where a render took the whole frame as one
/// tile, the layers it uploaded. Those are the stack's own pixels, which no camera, aperture
/// or lens setting changes, so the next render of the frame as one tile binds them instead of
/// copying the stack to the device again. A render cut into several tiles lets them go first
/// (their memory is the tiles'), and a render on another device uploads its own.
pub struct ResidentStack {
    scan: StackScan,
    upload: Mutex<Option<LayerUpload>>,
}

/// A read rect of every layer on the device: one buffer of colours and one of disparities per
/// layer ([`Residency::LayerByLayer`]).
#[derive(Clone)]
pub(crate) struct LayerUpload {
    read: Rect,
    rgba: Vec<Buffer>,
    disparity: Vec<Buffer>,
}

impl LayerUpload {
    fn of(buffers: &ForwardBuffers) -> Self {
        Self { read: buffers.read, rgba: buffers.rgba.clone(), disparity: buffers.disparity.clone() }
    }
}

impl ResidentStack {
    /// Scans `stack` (see [`StackScan::new`]); nothing is on the device until a render keeps it.
    pub fn new(stack: &LayerStack, focus_disparity: f32) -> Self {
        Self { scan: StackScan::new(stack, focus_disparity), upload: Mutex::new(None) }
    }

    pub fn scan(&self) -> &StackScan {
        &self.scan
    }

    /// Whether a render's upload of the stack is kept on the device.
    pub fn holds_upload(&self) -> bool {
        self.kept().is_some()
    }

    /// Device bytes of the kept upload (0 when none is kept): memory a render binding it holds
    /// from before it began, which its [`RenderStats::peak_device_bytes`] does not count.
    pub fn upload_bytes(&self) -> u64 {
        self.kept().as_ref().map_or(0, |kept| kept.rgba.iter().chain(&kept.disparity).map(Buffer::size).sum())
    }

    fn kept(&self) -> std::sync::MutexGuard<'_, Option<LayerUpload>> {
        self.upload.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// The kept upload, if it holds `read` of `layers` layers on `ctx`'s device.
    fn upload_of(&self, ctx: &Context, read: Rect, layers: usize) -> Option<LayerUpload> {
        let fits = |kept: &LayerUpload| {
            kept.read == read && kept.rgba.len() == layers && kept.rgba.iter().all(|buffer| buffer.is_on(ctx))
        };
        self.kept().clone().filter(fits)
    }

    fn keep(&self, upload: LayerUpload) {
        *self.kept() = Some(upload);
    }

    fn release(&self) {
        self.kept().take();
    }
}

/// The Dr.Bokeh pipelines on one device; build once, render many stacks.
pub struct DrBokehGpu {
    ctx: Context,
    kernel: LayerKernel,
    /// Specialized by whether the lens is vignetted (`SOURCES_VIGNETTED`), made on first use.
    sources: PipelineVariants,
    /// Row block sums of the prepass for the disk path's interior spans.
    blocks: ComputePipeline,
    layer: ComputePipeline,
    /// The optimised kernel's span paths: disk (default model, disk aperture) and gauge
    /// (default model, polygon or ellipse); `None` for the baseline.
    layer_disk: Option<ComputePipeline>,
    /// Specialized per shape (blades, or the ellipse), made on first use.
    layer_gauge: Option<PipelineVariants>,
    /// The disk path's gather less the ring's obstruction's.
    layer_ring: Option<ComputePipeline>,
    /// Kernel images under the default model, per tap.
    layer_kernel: Option<ComputePipeline>,
    composite: ComputePipeline,
}

/// How a frame tile's per-layer buffers hold the layers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Residency {
    /// Every layer's upload and intermediates at once, layer-major, composited at the end: the
    /// backward pass reads every layer's intermediates.
    Stacked,
    /// Every layer's upload in a buffer of its own, and one layer's intermediates, reused by
    /// the layers one after another (front first); each layer pass folds its layer into the
    /// running composite (`fold`), so no layer's (C, W, V) is stored. A forward render's tile
    /// then holds the stack's rect once plus one layer's work, not five times the stack: the
    /// larger the frame, the more of it fits one tile.
    LayerByLayer,
}

/// Which layer-pass kernel renders (same results within f32 rounding).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LayerKernel {
    /// The per-source prepass and the optimised gathers (`drbokeh_layer.comp`).
    #[default]
    Optimised,
    /// The first straightforward gather (`drbokeh_layer_naive.comp`): the benchmark baseline.
    Baseline,
    /// [`LayerKernel::Optimised`] with every disk-path tap of the window evaluated in full
    /// (radii [0, f32::MAX]): the reference its cheap interior (block sums, another summation
    /// order) and trimmed rows agree with within f32 rounding. Forward renders only.
    OptimisedNoInterior,
}

pub use crate::render::tiler::{RenderOptions, RenderStats};

/// Bindings of `drbokeh_layer.comp` (and its disk path): the sources, the lens tables, the
/// prepass's per-source terms and block sums, read at lane-varying addresses in the tap
/// loops, are texel buffers.
const LAYER_SLOTS: [Slot; 13] = {
    use Slot::{Storage, Texels};
    use TexelFormat::{Float, Vec2, Vec4};
    [
        Texels(Vec4),
        Texels(Float),
        Storage,
        Texels(Float),
        Texels(Float),
        Storage,
        Storage,
        Texels(Vec4),
        Texels(Vec2),
        Storage,
        Texels(Vec4),
        Texels(Vec4),
        Texels(Vec2),
    ]
};

/// Bindings of `drbokeh_layer_gauge.comp` and `drbokeh_layer_kernel.comp`: the layer pass's
/// and the aperture's row table (the kernel image's runs, [`kernel_run_table`]).
const LAYER_GAUGE_SLOTS: [Slot; 14] = Slot::concat(LAYER_SLOTS, [Slot::Texels(TexelFormat::Vec4)]);

/// Bindings of `drbokeh_layer_sources.comp` (inputs as texels) and of
/// `drbokeh_layer_blocks.comp` (the prepass's outputs as texels).
const SOURCES_SLOTS: [Slot; 5] = [
    Slot::Texels(TexelFormat::Vec4),
    Slot::Texels(TexelFormat::Float),
    Slot::Texels(TexelFormat::Float),
    Slot::Storage,
    Slot::Storage,
];
const BLOCKS_SLOTS: [Slot; 5] =
    [Slot::Texels(TexelFormat::Vec4), Slot::Texels(TexelFormat::Vec2), Slot::Storage, Slot::Storage, Slot::Storage];

impl DrBokehGpu {
    pub fn new(ctx: &Context) -> Result<Self> {
        Self::with_kernel(ctx, LayerKernel::Optimised)
    }

    pub fn with_kernel(ctx: &Context, kernel: LayerKernel) -> Result<Self> {
        let push = std::mem::size_of::<super::DrBokehPush>();
        let (layer, layer_disk, layer_gauge, layer_ring, layer_kernel) = match kernel {
            LayerKernel::Optimised | LayerKernel::OptimisedNoInterior => (
                ComputePipeline::with_slots(ctx, &shaders::DRBOKEH_LAYER, &LAYER_SLOTS, push)?,
                Some(ComputePipeline::with_slots(ctx, &shaders::DRBOKEH_LAYER_DISK, &LAYER_SLOTS, push)?),
                Some(PipelineVariants::new(ctx, &shaders::DRBOKEH_LAYER_GAUGE, &LAYER_GAUGE_SLOTS, push)?),
                Some(ComputePipeline::with_slots(ctx, &shaders::DRBOKEH_LAYER_RING, &LAYER_SLOTS, push)?),
                Some(ComputePipeline::with_slots(ctx, &shaders::DRBOKEH_LAYER_KERNEL, &LAYER_GAUGE_SLOTS, push)?),
            ),
            LayerKernel::Baseline => (ComputePipeline::new(ctx, &shaders::DRBOKEH_LAYER_NAIVE, 7, push)?, None, None, None, None),
        };
        Ok(Self {
            ctx: ctx.clone(),
            kernel,
            sources: PipelineVariants::new(ctx, &shaders::DRBOKEH_LAYER_SOURCES, &SOURCES_SLOTS, push)?,
            blocks: ComputePipeline::with_slots(ctx, &shaders::DRBOKEH_LAYER_BLOCKS, &BLOCKS_SLOTS, push)?,
            layer,
            layer_disk,
            layer_gauge,
            layer_ring,
            layer_kernel,
            composite: ComputePipeline::with_slots(ctx, &shaders::DRBOKEH_COMPOSITE, &[Slot::Texels(TexelFormat::Vec4), Slot::Texels(TexelFormat::Float), Slot::Storage], push)?,
        })
    }

    pub fn context(&self) -> &Context {
        &self.ctx
    }

    /// Renders `stack` through `lens`: premultiplied linear RGBA, HDR unclamped.
    pub fn render(&self, stack: &LayerStack, lens: &Lens, model: Model) -> Result<Image> {
        Ok(self.render_with(stack, lens, model, &RenderOptions::default())?.0)
    }

    pub fn render_with(
        &self,
        stack: &LayerStack,
        lens: &Lens,
        model: Model,
        options: &RenderOptions,
    ) -> Result<(Image, RenderStats)> {
        self.render_resident(stack, &ResidentStack::new(stack, lens.coc.focus_disparity), lens, model, options)
    }

    /// [`Self::render_with`] from what an earlier render of `stack` kept ([`ResidentStack`]: a
    /// resident stack refocused): the pass over every pixel that bounds the searches is not
    /// made again, nor, for a frame rendered as one tile, the stack's upload. The image is the
    /// same, bit for bit.
    pub fn render_resident(
        &self,
        stack: &LayerStack,
        resident: &ResidentStack,
        lens: &Lens,
        model: Model,
        options: &RenderOptions,
    ) -> Result<(Image, RenderStats)> {
        let scan = &resident.scan;
        if !scan.fits(stack) {
            return Err(Error::invalid(
                "stack scan",
                format!("it was made from another stack than this {}x{} one of {} layer(s): make it from the stack it renders", stack.width, stack.height, stack.layers.len()),
            ));
        }
        let params = Params::with_range(stack, lens, model, scan.disparity_range())?;
        let (windows, ranges) = scanned_windows_and_ranges(&params, stack, scan);
        let max_window = windows.iter().copied().max().unwrap_or(0);
        // Layer by layer: the stack's rect, one layer's work, the running composite.
        let footprint = |tile: usize| {
            let read = (tile.min(params.width.max(params.height)) as u64 + 2 * max_window as u64).pow(2);
            let core = (tile as u64).pow(2);
            let layers = params.layer_count as u64;
            Footprint {
                largest_binding: read.max(core) * VEC4,
                total: layers * read * INPUT_BYTES_PER_PIXEL + read * WORK_BYTES_PER_PIXEL + core * (VEC4 + 4),
            }
        };
        let interior = self.kernel != LayerKernel::OptimisedNoInterior;
        let frame = ForwardFrame::new(stack, &params, &lens.aperture, &windows, interior.then_some(ranges));
        // Work bound: every layer's square of the largest search window (span paths do less).
        let work = params.layer_count as u64 * (2 * max_window.max(0) as u64 + 1).pow(2);
        let tiling = params.tiling().with_work(work);
        self.compile_passes(&params.lens, params.model)?;
        run_tiled(&self.ctx, &tiling, options, footprint, |plan| self.render_tiles(&frame, resident, &tiling, plan, options))
    }

    /// One attempt at the frame: its tiles in batches of `plan.tiles_per_batch`, each tile's
    /// core read back into the image once its batch has run. A frame of one tile binds the
    /// upload `resident` kept, or keeps its own there.
    fn render_tiles(
        &self,
        frame: &ForwardFrame,
        resident: &ResidentStack,
        tiling: &FrameTiling,
        plan: TilePlan,
        options: &RenderOptions,
    ) -> Result<(Image, RenderStats)> {
        let (ctx, params) = (&self.ctx, frame.params);
        frame.begin_attempt();
        let one_tile = tiling.cores(plan.tile).len() == 1;
        if !one_tile {
            resident.release();
        }
        let mut image = Image::new(params.width, params.height);
        let max_halo = frame.windows.iter().copied().max().unwrap_or(0).max(0) as usize;
        let room = TileRoom { core: tiling.room(plan.tile, 0), read: tiling.room(plan.tile, max_halo) };
        // A one-tile frame's fresh upload, kept once its batch has run (a copy recorded into a
        // batch that never ran would leave the buffers undefined).
        let mut uploaded = None;
        let record = |batch: &mut CommandBatch, core: Rect| {
            let read = core.grown(halo(params, frame.windows, core), params.width, params.height);
            let kept = if one_tile { resident.upload_of(ctx, read, params.layer_count) } else { None };
            let fresh = kept.is_none();
            let buffers = ForwardBuffers::new(ctx, batch, frame, core, read, room, Residency::LayerByLayer, kept)?;
            if one_tile && fresh {
                uploaded = Some(LayerUpload::of(&buffers));
            }
            self.record(batch, params, &buffers)?;
            buffers.output().readable_in(batch)
        };
        let collect = |core: Rect, result: ReadBack| store_core(ctx, &mut image, core, &result);
        let (mut stats, cores) = run_batches(ctx, tiling, plan, options, record, collect)?;
        if let Some(upload) = uploaded {
            resident.keep(upload);
        }
        stats.taps = cores.iter().map(|&core| taps(params, frame.windows, core)).sum();
        Ok((image, stats))
    }

    /// The pipelines [`Self::record`] dispatches for a render through `lens` under `model`.
    fn passes(&self, lens: &LensView, model: Model) -> Result<Passes> {
        // The layer pipeline, whether it sums row spans (from the block sums), and how many of
        // the bindings it declares.
        let path = lens.path(model);
        let (layer, spans, layer_bindings) =
            match (path, &self.layer_disk, &self.layer_gauge, &self.layer_ring, &self.layer_kernel) {
                (AperturePath::Disk, Some(disk), _, _, _) => (disk.clone(), true, LAYER_SLOTS.len()),
                (AperturePath::Ring, _, _, Some(ring), _) => (ring.clone(), true, LAYER_SLOTS.len()),
                (AperturePath::Kernel, _, _, _, Some(kernel)) => (kernel.clone(), true, LAYER_GAUGE_SLOTS.len()),
                (AperturePath::Gauge, _, Some(variants), _, _) => {
                    (variants.get(&lens.gauge_specialization())?, true, LAYER_GAUGE_SLOTS.len())
                }
                _ if self.kernel == LayerKernel::Baseline => (self.layer.clone(), false, 7),
                _ => (self.layer.clone(), false, LAYER_SLOTS.len()),
            };
        let sources = match self.kernel {
            LayerKernel::Baseline => None,
            _ => Some(self.sources.get(&[lens.is_vignetted() as u32])?),
        };
        Ok(Passes { sources, blocks: self.kernel == LayerKernel::Optimised && spans, layer, layer_bindings })
    }

    /// Whether a tile's record through `lens` under `model` fills the block sums
    /// (`ForwardBuffers::block_prefix`, `block_suffix`, `block_alpha`).
    pub(crate) fn sums_blocks(&self, lens: &LensView, model: Model) -> Result<bool> {
        Ok(self.passes(lens, model)?.blocks)
    }

    /// Compiles the pipelines a render through `lens` under `model` dispatches, side by side
    /// (its CoC does not matter: the aperture and the model choose them). A render calls it
    /// before its first tile records, and a caller may call it earlier, while the input is
    /// still read ([`crate::render::Renderer::warm_up`]). A driver that compiles at creation
    /// (lavapipe: 5-40 ms each, four for a disk) would otherwise compile them one after another
    /// at their first dispatch, on one core, while the others wait.
    pub fn compile_for(&self, lens: &Lens, model: Model) -> Result<()> {
        self.compile_passes(&LensView::new(&lens.coc, &lens.aperture), model)
    }

    /// Whether every pipeline a render through `lens` under `model` dispatches is compiled.
    pub fn compiled_for(&self, lens: &Lens, model: Model) -> Result<bool> {
        let pipelines = self.pipelines(&LensView::new(&lens.coc, &lens.aperture), model, Residency::LayerByLayer)?;
        Ok(pipelines.iter().all(|pipeline| pipeline.is_compiled()))
    }

    fn compile_passes(&self, lens: &LensView, model: Model) -> Result<()> {
        compile_side_by_side(&self.pipelines(lens, model, Residency::LayerByLayer)?)
    }

    /// Every pipeline [`Self::record`] dispatches for a tile of `residency` through `lens` under
    /// `model` (the composite pass only where the layers are stacked: layer by layer, the layer
    /// pass composites).
    pub(crate) fn pipelines(&self, lens: &LensView, model: Model, residency: Residency) -> Result<Vec<ComputePipeline>> {
        let passes = self.passes(lens, model)?;
        let mut pipelines = vec![passes.layer];
        if residency == Residency::Stacked {
            pipelines.push(self.composite.clone());
        }
        pipelines.extend(passes.sources);
        if passes.blocks {
            pipelines.push(self.blocks.clone());
        }
        Ok(pipelines)
    }

    /// Records the layer passes and the composite of one frame tile (the backward pass records
    /// them over its receivers, [`Residency::Stacked`], and reads every intermediate).
    pub(crate) fn record(&self, batch: &mut CommandBatch, params: &Params, b: &ForwardBuffers) -> Result<()> {
        if self.kernel == LayerKernel::Baseline && params.lens.is_vignetted() {
            // The first kernel's per-tap lens knows one shape per render.
            return Err(Error::unsupported("the baseline layer kernel cannot render a vignetted aperture"));
        }
        let groups = self.composite.groups_for([b.core.width() as u32, b.core.height() as u32, 1]);
        // A layer workgroup covers one 16x16 search tile: the optimised kernels write a run of
        // TILE / local_size_x adjacent pixels per invocation.
        let per_invocation = TILE as u32 / self.layer.shader().local_size[0];
        let layer_groups =
            self.layer.groups_for([(b.core.width() as u32).div_ceil(per_invocation), b.core.height() as u32, 1]);
        let passes = self.passes(&params.lens, params.model)?;
        let (layer_pipeline, binding_count) = (&passes.layer, passes.layer_bindings);
        // The prepasses over `layers` layers at once (the extent's third axis) from `inputs`.
        let prepasses = |batch: &mut CommandBatch, inputs: [Binding; 2], push: &DrBokehPush, layers: usize| {
            if let Some(sources) = &passes.sources {
                let extent = [b.read.width() as u32, b.read.height() as u32, layers as u32];
                let bindings = [inputs[0], inputs[1], b.area_lut.all(), b.source_pa.all(), b.source_sa.all()];
                batch.dispatch(sources, &bindings, push, sources.groups_for(extent))?;
            }
            if passes.blocks {
                let extent = [block_columns(b.read), b.read.height() as u32, layers as u32];
                let bindings =
                    [b.source_pa.all(), b.source_sa.all(), b.block_prefix.all(), b.block_suffix.all(), b.block_alpha.all()];
                batch.dispatch(&self.blocks, &bindings, push, self.blocks.groups_for(extent))?;
            }
            Ok::<_, Error>(())
        };
        let layer_pass = |batch: &mut CommandBatch, inputs: [Binding; 2], push: &DrBokehPush| {
            let bindings = [
                inputs[0],
                inputs[1],
                b.tile_window.all(),
                b.area_lut.all(),
                b.kernel.all(),
                b.layer_cw.all(),
                b.layer_vis.all(),
                b.source_pa.all(),
                b.source_sa.all(),
                b.tile_radii.all(),
                b.block_prefix.all(),
                b.block_suffix.all(),
                b.block_alpha.all(),
                b.aperture_rows.all(),
            ];
            batch.dispatch(layer_pipeline, &bindings[..binding_count], push, layer_groups)
        };
        match &b.result {
            // Stacked: every layer's prepasses at once, the layer passes, then the composite.
            Some(result) => {
                let inputs = [b.rgba[0].all(), b.disparity[0].all()];
                let push = params.push_tile(0, b.core, b.read);
                prepasses(batch, inputs, &push, params.layer_count)?;
                for layer in 0..params.layer_count {
                    layer_pass(batch, inputs, &params.push_tile(layer, b.core, b.read))?;
                }
                batch.dispatch(&self.composite, &[b.layer_cw.all(), b.layer_vis.all(), result.all()], &push, groups)
            }
            // Layer by layer.
            None => {
                for layer in 0..params.layer_count {
                    // The tables are the frame's (every layer's); the tile's buffers hold this
                    // one, and its pass folds it into the composite in layer_cw and layer_vis.
                    let push = DrBokehPush { slot: 0, fold: 1, ..params.push_tile(layer, b.core, b.read) };
                    let inputs = [b.rgba[layer].all(), b.disparity[layer].all()];
                    prepasses(batch, inputs, &push, 1)?;
                    layer_pass(batch, inputs, &push)?;
                }
                Ok(())
            }
        }
    }
}

/// The block-sum passes' invocations per row of `read` (`drbokeh_blocks.glsl`): one per global
/// 16-px block the rect touches.
pub(crate) fn block_columns(read: Rect) -> u32 {
    ((read.x1 - 1) / TILE - read.x0 / TILE + 1) as u32
}

/// Compiles `pipelines` on every core at once (see [`DrBokehGpu::compile_for`]).
pub(crate) fn compile_side_by_side(pipelines: &[ComputePipeline]) -> Result<()> {
    pipelines.par_iter().try_for_each(|pipeline| pipeline.compile())
}

/// The pipelines of one render's passes besides the composite ([`DrBokehGpu::passes`]).
struct Passes {
    /// The per-source prepass (the optimised kernels).
    sources: Option<ComputePipeline>,
    /// Whether the block sums of the disk path's interior spans run.
    blocks: bool,
    /// The layer pass, and how many of the bindings it declares.
    layer: ComputePipeline,
    layer_bindings: usize,
}

/// The device buffers of one frame tile: the uploaded `read` rect of every layer, the search
/// windows and lens tables, and every pass's output over the `core`.
pub(crate) struct ForwardBuffers {
    pub core: Rect,
    pub read: Rect,
    /// The uploaded rect: one buffer of every layer ([`Residency::Stacked`]) or one per layer.
    pub rgba: Vec<Buffer>,
    pub disparity: Vec<Buffer>,
    pub tile_window: Buffer,
    pub area_lut: Buffer,
    pub kernel: Buffer,
    pub aperture_rows: Buffer,
    /// Every layer's (C, W) and V over the core ([`Residency::Stacked`]); layer by layer, the
    /// running composite (the tile's image once the last layer has run) and its transmittance.
    pub layer_cw: Buffer,
    pub layer_vis: Buffer,
    /// The composite of every layer where the layers are stacked; `None` layer by layer
    /// ([`Residency`]: the tile's image is then `layer_cw`).
    pub result: Option<Buffer>,
    /// Prepass outputs over the read rect: P / A(r) per source, and (s, alpha).
    pub source_pa: Buffer,
    pub source_sa: Buffer,
    /// Per layer and search tile, the span paths' (interior, outer, orientation) bounds
    /// ([`span_radii`]): where they sum whole row spans from block sums, past which their taps
    /// add exact zeros, and which side of focus the window's sources lie.
    pub tile_radii: Buffer,
    /// Over the read rect: per source, the sums of (P / A, alpha) from its global 16-px row
    /// block's first column to it (prefix) and from it to the block's last (suffix, with
    /// both alphas in `block_alpha`): the disk path's interior spans.
    pub block_prefix: Buffer,
    pub block_suffix: Buffer,
    pub block_alpha: Buffer,
}

impl ForwardBuffers {
    /// The buffer holding the tile's image once its passes have run.
    pub fn output(&self) -> &Buffer {
        self.result.as_ref().unwrap_or(&self.layer_cw)
    }

    /// Allocates a tile's buffers (intermediates left unfilled: every pass writes its output
    /// whole) and records the upload of its `read` rect into `batch`, unless `kept` holds it
    /// already (layer by layer: [`ResidentStack::upload_of`] checked it); the frame's tables
    /// are shared, not copied.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        ctx: &Context,
        batch: &mut CommandBatch,
        frame: &ForwardFrame,
        core: Rect,
        read: Rect,
        room: TileRoom,
        residency: Residency,
        kept: Option<LayerUpload>,
    ) -> Result<Self> {
        let (stack, params) = (frame.stack, frame.params);
        let tables = frame.tables(ctx, batch)?;
        let tile_radii = match &frame.source_ranges {
            Some(ranges) => span_radii(params, ranges, frame.windows, core),
            None => vec![NO_SPAN_RADII; frame.windows.len()],
        };
        // Layers the intermediates hold at once.
        let layers = match residency {
            Residency::Stacked => params.layer_count as u64,
            Residency::LayerByLayer => 1,
        };
        let (core_pixels, read_pixels) = (core.area() as u64, read.area() as u64);
        let (mut rgba, mut disparity) = (Vec::new(), Vec::new());
        match (residency, kept) {
            (Residency::Stacked, _) => {
                let (read_n, read_room) = (params.layer_count * read.area(), params.layer_count * room.read);
                let colours = stack.layers.iter().flat_map(|l| crop_rows(&l.rgba.pixels, params.width, read));
                let depths = stack.layers.iter().flat_map(|l| crop_rows(&l.disparity, params.width, read));
                rgba.push(Buffer::from_slices_with_room_in(ctx, batch, "drbokeh rgba", read_n, read_room, colours)?);
                disparity.push(Buffer::from_slices_with_room_in(ctx, batch, "drbokeh disparity", read_n, read_room, depths)?);
            }
            (Residency::LayerByLayer, Some(kept)) => {
                debug_assert!(kept.read == read && kept.rgba.len() == stack.layers.len(), "a kept upload of another rect");
                (rgba, disparity) = (kept.rgba, kept.disparity);
            }
            (Residency::LayerByLayer, None) => {
                for l in &stack.layers {
                    let colours = crop_rows(&l.rgba.pixels, params.width, read);
                    let depths = crop_rows(&l.disparity, params.width, read);
                    rgba.push(Buffer::from_slices_with_room_in(ctx, batch, "drbokeh rgba", read.area(), room.read, colours)?);
                    disparity.push(Buffer::from_slices_with_room_in(ctx, batch, "drbokeh disparity", read.area(), room.read, depths)?);
                }
            }
        }
        // Every pass writes its whole output before a later one reads it (the layer pass every
        // core pixel of every layer, sources and blocks every read pixel, composite every core
        // pixel; layer by layer, the front layer's pass starts the running composite without
        // reading it; kernels that skip sources or blocks never read them): no fills.
        // Per pixel of the core or of the read rect: each buffer's size and its room.
        let over_core = |name: &str, per_pixel: u64| {
            Buffer::uninitialised_with_room(ctx, name, core_pixels * per_pixel, room.core as u64 * per_pixel)
        };
        let over_read = |name: &str, per_pixel: u64| {
            let (size, room) = (layers * read_pixels * per_pixel, layers * room.read as u64 * per_pixel);
            Buffer::uninitialised_with_room(ctx, name, size, room)
        };
        Ok(Self {
            core,
            read,
            layer_cw: over_core("drbokeh layer_cw", layers * VEC4)?,
            layer_vis: over_core("drbokeh layer_vis", layers * 4)?,
            result: match residency {
                Residency::Stacked => Some(over_core("drbokeh result", VEC4)?),
                Residency::LayerByLayer => None,
            },
            source_pa: over_read("drbokeh source_pa", VEC4)?,
            source_sa: over_read("drbokeh source_sa", 8)?,
            block_prefix: over_read("drbokeh block_prefix", VEC4)?,
            block_suffix: over_read("drbokeh block_suffix", VEC4)?,
            block_alpha: over_read("drbokeh block_alpha", 8)?,
            rgba,
            disparity,
            tile_radii: Buffer::from_iter_in(ctx, batch, "drbokeh tile_radii", tile_radii.len(), tile_radii)?,
            tile_window: tables.tile_window,
            area_lut: tables.area_lut,
            kernel: tables.kernel,
            aperture_rows: tables.aperture_rows,
        })
    }
}

/// What every tile of a frame shares: the inputs, the search windows, and the tables every
/// tile binds (uploaded once per attempt at the frame, by its first tile's batch).
pub(crate) struct ForwardFrame<'a> {
    pub stack: &'a LayerStack,
    pub params: &'a Params,
    pub windows: &'a [i32],
    area_lut: Vec<f32>,
    kernel: Vec<f32>,
    /// The gauge path's closed-form gauge constants and row table ([`aperture_rows`]).
    aperture_rows: Vec<[f32; 4]>,
    /// The tables on the device, once a tile has recorded their upload ([`Self::tables`]).
    tables: Mutex<Option<FrameTables>>,
    /// What the tiles' [`span_radii`] combine; `None`: tiles upload radii [0, f32::MAX]
    /// ([`LayerKernel::OptimisedNoInterior`]).
    source_ranges: Option<SourceRanges>,
}

/// The device copies of a frame's shared tables.
#[derive(Clone)]
pub(crate) struct FrameTables {
    tile_window: Buffer,
    area_lut: Buffer,
    kernel: Buffer,
    aperture_rows: Buffer,
}

impl<'a> ForwardFrame<'a> {
    pub fn new(
        stack: &'a LayerStack,
        params: &'a Params,
        aperture: &Aperture,
        windows: &'a [i32],
        source_ranges: Option<SourceRanges>,
    ) -> Self {
        let rows = match (params.lens.path(params.model), aperture) {
            // A vignetted polygon or ellipse: its base's table, then each tile's centroid.
            (AperturePath::Gauge, Aperture::Vignetted { base, .. }) if params.lens.is_vignetted_base() => {
                let eyes = params.eyes.iter().map(|&[x, y]| [x as f32, y as f32, 0.0, 0.0]);
                aperture_rows(base).iter().copied().chain(eyes).collect()
            }
            (AperturePath::Gauge, _) => aperture_rows(aperture).to_vec(),
            (AperturePath::Kernel, Aperture::Kernel(kernel)) => kernel_run_table(kernel),
            _ => vec![EMPTY_APERTURE_ROW],
        };
        Self {
            stack,
            params,
            windows,
            area_lut: params.area_lut_f32(),
            kernel: params.kernel_f32(),
            aperture_rows: rows,
            tables: Mutex::new(None),
            source_ranges,
        }
    }

    /// Starts an attempt at the frame: tables uploaded by an earlier attempt's batch (which an
    /// out-of-memory error may have stopped before it ran) are uploaded again.
    pub fn begin_attempt(&self) {
        *self.tables.lock().unwrap_or_else(|e| e.into_inner()) = None;
    }

    /// The shared tables on the device: the first tile of an attempt records their upload into
    /// its `batch` (ahead of its own passes, which the copy's barrier orders), later tiles bind
    /// the same buffers. Separate uploads, each a submission and a wait of its own, cost a few
    /// milliseconds per frame on a discrete GPU: as much as rendering a 1024^2 frame.
    fn tables(&self, ctx: &Context, batch: &mut CommandBatch) -> Result<FrameTables> {
        let mut tables = self.tables.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(tables) = &*tables {
            return Ok(tables.clone());
        }
        let uploaded = FrameTables {
            tile_window: Buffer::from_slice_in(ctx, batch, "drbokeh tile_window", self.windows)?,
            area_lut: Buffer::from_slice_in(ctx, batch, "drbokeh area_lut", &self.area_lut)?,
            kernel: Buffer::from_slice_in(ctx, batch, "drbokeh kernel", &self.kernel)?,
            aperture_rows: Buffer::from_slice_in(ctx, batch, "drbokeh aperture_rows", &self.aperture_rows)?,
        };
        *tables = Some(uploaded.clone());
        Ok(uploaded)
    }
}

/// The `aperture_rows` buffer of `drbokeh_layer_gauge.comp`: the constants of the gauge's
/// closed form ([`closed_form_gauge`]) followed by the row table ([`aperture_row_table`]), for
/// polygons and ellipses (a vignetted one's base's, then its tiles' centroids). One empty row
/// otherwise (Vulkan buffers cannot be empty). Building a polygon's table takes ~50-90 ms, as
/// long as the GPU's whole render of a 1024^2 five-layer frame, so the last few apertures'
/// tables are kept for the process: every frame of a shot, and every render of a benchmark,
/// shares its aperture's.
fn aperture_rows(aperture: &Aperture) -> Arc<Vec<[f32; 4]>> {
    static TABLES: KeptTables<Aperture, Vec<[f32; 4]>> = KeptTables::new();
    TABLES.get_or_make(aperture.clone(), || {
        Arc::new(match (closed_form_gauge(aperture), aperture_row_table(aperture)) {
            (Some(gauge), Some(rows)) => std::iter::once(gauge).chain(rows).collect(),
            _ => vec![EMPTY_APERTURE_ROW],
        })
    })
}

/// Pixels around `core` its gathers read: the largest window over its search tiles and layers.
pub(crate) fn halo(params: &Params, windows: &[i32], core: Rect) -> usize {
    let per_layer = params.tiles_x * params.tiles_y;
    let mut halo = 0;
    for layer in 0..params.layer_count {
        for t in search_tiles(params, core) {
            halo = halo.max(windows[layer * per_layer + t].max(0) as usize);
        }
    }
    halo
}

/// Source pixels the core's gathers visit (upper bound: windows are not clipped at borders).
pub(crate) fn taps(params: &Params, windows: &[i32], core: Rect) -> u64 {
    let per_layer = params.tiles_x * params.tiles_y;
    let mut taps = 0u64;
    for layer in 0..params.layer_count {
        for t in search_tiles(params, core) {
            let (tx, ty) = (t % params.tiles_x, t / params.tiles_x);
            let tile = Rect {
                x0: tx * TILE,
                y0: ty * TILE,
                x1: ((tx + 1) * TILE).min(params.width),
                y1: ((ty + 1) * TILE).min(params.height),
            };
            // An empty window (-1) gathers nothing.
            let side = (2 * windows[layer * per_layer + t] + 1).max(0) as u64;
            taps += tile.area() as u64 * side * side;
        }
    }
    taps
}
