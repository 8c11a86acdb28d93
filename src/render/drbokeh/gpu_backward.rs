//! GPU host code of the Dr.Bokeh backward pass: the four forward passes, then the three
//! gather passes of `glsl/drbokeh_backward_*.comp` (composite, own, source; pass 3, the tile
//! reach, is computed on the host, which needs it to cut the tiles anyway, and uploaded) over
//! the forward's intermediates, recorded per frame tile, several tiles to a submission
//! ([`super::tiled`]). On the disk, passes 2 and 4 sum their interior rows from block sums
//! (pass 2 the forward's alphas; pass 4 the receivers' adjoints, summed per layer by pass 3',
//! `drbokeh_backward_blocks.comp`, over the forward's block buffers): the f64 reference of the
//! same passes, [`super::backward_cpu`], sums every tap.
//!
//! A tile is a core C of *source* pixels, whose gradients it writes. They gather over the
//! receivers O whose windows hold a source of C (C grown by the tile reach, pass 3); O's
//! adjoints need the forward's intermediates over O, which read O grown by its halo. So the
//! forward and passes 1-2 run with core O, pass 4 with core C, all over the same upload.
//! Every pixel sums the same terms in the same order as untiled. The scalar gradients are sums
//! of per-pixel shares (dL/dK: `rel g_s` per pixel; dL/d focus: minus every disparity
//! gradient) done on the host in f64 in image order after the last tile: deterministic and
//! independent of the tile size.
use super::backward::{check_inputs, BackwardOptions};
use super::backward_cpu::tile_reach_cpu;
use super::bounds::{grow_windows, receiver_radii, scanned_windows_and_ranges, StackScan};
use super::gpu::{block_columns, compile_side_by_side, halo, taps, ForwardBuffers, ForwardFrame, Residency, CORE_BYTES_PER_PIXEL, READ_BYTES_PER_PIXEL, VEC4};
use super::{AperturePath, DrBokehGpu, Model, Params, RenderOptions, RenderStats, TILE};
use crate::image::Image;
use crate::render::grad::{Differentiable, LayerGradients, StackGradients};
use crate::render::tiler::{crop_rows, place_core_rows, run_batches, run_tiled, Footprint, FrameTiling, TilePlan, TileRoom};
use crate::render::Lens;
use crate::shaders;
use crate::stack::LayerStack;
use crate::tile_grid::Rect;
use crate::vk::{Buffer, CommandBatch, ComputePipeline, Context, PipelineVariants, ReadBack, Slot, TexelFormat};
use crate::{Error, Result};

/// The Dr.Bokeh forward and backward pipelines on one device, for one model and options.
pub struct DrBokehGpuGrad {
    forward: DrBokehGpu,
    composite: ComputePipeline,
    own: ComputePipeline,
    source: ComputePipeline,
    /// Passes 2 and 4 compiled for the default model with a disk aperture and no kernel image
    /// (see [`AperturePath::Disk`]): lavapipe runs every branch, so the general code costs every tap.
    own_disk: ComputePipeline,
    source_disk: ComputePipeline,
    /// The same for a polygon or ellipse ([`AperturePath::Gauge`]): the disk path's code with
    /// the shape's closed-form gauge.
    own_gauge: PipelineVariants,
    source_gauge: PipelineVariants,
    /// The same for the ring ([`AperturePath::Ring`]): the disk path's code with the ring's
    /// weight and its d/dr in closed form.
    own_ring: ComputePipeline,
    source_ring: ComputePipeline,
    /// The same for a kernel image ([`AperturePath::Kernel`]): the disk path's code with the
    /// kernel's bilinear weight and its d/dr per tap, without the general shader's other
    /// shapes and models (lavapipe would run them under lane masks at every tap).
    own_kernel: ComputePipeline,
    source_kernel: ComputePipeline,
    /// Pass 3' of the disk path: block sums of the receivers' adjoints for pass 4's interior.
    blocks: ComputePipeline,
    pub model: Model,
    pub options: BackwardOptions,
}

/// The backward's device buffers of one tile (all layer-major, one element per layer pixel).
struct BackwardBuffers {
    grad_output: Buffer,
    adj_cw: Buffer,
    adj_vis: Buffer,
    own: Buffer,
    /// Pass 2's per-receiver (rel, alpha, dL/dV / sum D, window) for pass 4: one load a tap.
    receiver: Buffer,
    /// The frame's tile reach and smallest receiver radius within it (shared by every tile).
    tile_reach: Buffer,
    receiver_radius: Buffer,
    grad_rgba: Buffer,
    grad_disparity: Buffer,
    k_partial: Buffer,
}

/// A tile's per-source gradients over its core, host-readable once its batch has run.
struct TileGradients {
    rgba: ReadBack,
    disparity: ReadBack,
    k_partial: ReadBack,
}

/// Bindings of the backward passes 2 and 4 (`drbokeh_backward_own.comp`,
/// `drbokeh_backward_source.comp` and their disk paths): what their loops read at
/// lane-varying addresses are texel buffers ([`Slot::Texels`]).
const OWN_SLOTS: [Slot; 9] = {
    use Slot::{Storage, Texels};
    use TexelFormat::{Float, Vec4};
    [Texels(Vec4), Texels(Float), Storage, Texels(Float), Texels(Float), Texels(Vec4), Texels(Float), Storage, Storage]
};
/// [`OWN_SLOTS`] and the forward's alpha block sums (`drbokeh_backward_own_disk.comp`: the
/// disk's interior rows of V are span sums).
const OWN_SPAN_SLOTS: [Slot; 10] = Slot::concat(OWN_SLOTS, [Slot::Texels(TexelFormat::Vec2)]);
/// [`SOURCE_SLOTS`] and pass 3''s block sums and the tiles' smallest receiver radii
/// (`drbokeh_backward_source_disk.comp`: its interior rows are span sums).
const SOURCE_SPAN_SLOTS: [Slot; 15] = Slot::concat(
    SOURCE_SLOTS,
    [Slot::Texels(TexelFormat::Vec4), Slot::Texels(TexelFormat::Vec4), Slot::Texels(TexelFormat::Vec2), Slot::Storage],
);
/// Bindings of pass 3' (`drbokeh_backward_blocks.comp`).
const BLOCKS_SLOTS: [Slot; 5] =
    [Slot::Texels(TexelFormat::Vec4), Slot::Texels(TexelFormat::Vec4), Slot::Storage, Slot::Storage, Slot::Storage];
const SOURCE_SLOTS: [Slot; 11] = {
    use Slot::{Storage, Texels};
    use TexelFormat::{Float, Vec4};
    [
        Texels(Vec4),
        Texels(Float),
        Texels(Vec4),
        Texels(Float),
        Texels(Float),
        Texels(Vec4),
        Texels(Vec4),
        Storage,
        Storage,
        Storage,
        Storage,
    ]
};

impl DrBokehGpuGrad {
    pub fn new(ctx: &Context, model: Model, options: BackwardOptions) -> Result<Self> {
        let push = std::mem::size_of::<super::DrBokehPush>();
        Ok(Self {
            forward: DrBokehGpu::new(ctx)?,
            composite: ComputePipeline::new(ctx, &shaders::DRBOKEH_BACKWARD_COMPOSITE, 5, push)?,
            own: ComputePipeline::with_slots(ctx, &shaders::DRBOKEH_BACKWARD_OWN, &OWN_SLOTS, push)?,
            source: ComputePipeline::with_slots(ctx, &shaders::DRBOKEH_BACKWARD_SOURCE, &SOURCE_SLOTS, push)?,
            own_disk: ComputePipeline::with_slots(ctx, &shaders::DRBOKEH_BACKWARD_OWN_DISK, &OWN_SPAN_SLOTS, push)?,
            source_disk: ComputePipeline::with_slots(ctx, &shaders::DRBOKEH_BACKWARD_SOURCE_DISK, &SOURCE_SPAN_SLOTS, push)?,
            own_gauge: PipelineVariants::new(ctx, &shaders::DRBOKEH_BACKWARD_OWN_GAUGE, &OWN_SLOTS, push)?,
            source_gauge: PipelineVariants::new(ctx, &shaders::DRBOKEH_BACKWARD_SOURCE_GAUGE, &SOURCE_SLOTS, push)?,
            own_ring: ComputePipeline::with_slots(ctx, &shaders::DRBOKEH_BACKWARD_OWN_RING, &OWN_SLOTS, push)?,
            source_ring: ComputePipeline::with_slots(ctx, &shaders::DRBOKEH_BACKWARD_SOURCE_RING, &SOURCE_SLOTS, push)?,
            own_kernel: ComputePipeline::with_slots(ctx, &shaders::DRBOKEH_BACKWARD_OWN_KERNEL, &OWN_SLOTS, push)?,
            source_kernel: ComputePipeline::with_slots(
                ctx,
                &shaders::DRBOKEH_BACKWARD_SOURCE_KERNEL,
                &SOURCE_SLOTS,
                push,
            )?,
            blocks: ComputePipeline::with_slots(ctx, &shaders::DRBOKEH_BACKWARD_BLOCKS, &BLOCKS_SLOTS, push)?,
            model,
            options,
        })
    }

    pub fn context(&self) -> &Context {
        self.forward.context()
    }

    /// [`Differentiable::backward`] plus what the passes measured, on automatically sized tiles.
    pub fn backward_with_stats(
        &self,
        stack: &LayerStack,
        lens: &Lens,
        grad_output: &Image,
    ) -> Result<(StackGradients, RenderStats)> {
        self.backward_with(stack, lens, grad_output, &RenderOptions::default())
    }

    /// The backward on frame tiles of source pixels, cut (tile side, out-of-memory retries,
    /// progress) like the forward's [`DrBokehGpu::render_with`]. Every pixel sums the same
    /// terms in the same order whatever the tiling, and the scalar gradients are summed on the
    /// host in image order after the last tile, so the result is bit-identical for every tile
    /// size. `RenderStats::taps` counts the forward's gathers over the tiles' receivers.
    pub fn backward_with(
        &self,
        stack: &LayerStack,
        lens: &Lens,
        grad_output: &Image,
        options: &RenderOptions,
    ) -> Result<(StackGradients, RenderStats)> {
        check_inputs(stack, lens, grad_output)?;
        // One pass over the pixels gives both the disparity range and the search bounds.
        let scan = StackScan::new(stack, lens.coc.focus_disparity);
        let params = Params::with_range(stack, lens, self.model, scan.disparity_range())?;
        let (windows, ranges) = scanned_windows_and_ranges(&params, stack, &scan);
        let windows = grow_windows(windows, self.options.window_margin());
        let per_layer = params.tiles_x * params.tiles_y;
        let reach: Vec<i32> = windows.chunks(per_layer.max(1)).flat_map(|w| tile_reach_cpu(&params, w)).collect();
        let radii = receiver_radii(&params, &ranges, &reach);
        let ctx = self.context();
        let frame = Frame {
            forward: ForwardFrame::new(stack, &params, &lens.aperture, &windows, Some(ranges)),
            reach: &reach,
            tile_reach: Buffer::from_slice(ctx, "drbokeh tile_reach", &reach)?,
            receiver_radius: Buffer::from_slice(ctx, "drbokeh receiver_radius", &radii)?,
            grad_output,
        };
        let footprint = backward_footprint(
            &params,
            windows.iter().copied().max().unwrap_or(0),
            reach.iter().copied().max().unwrap_or(0),
        );
        // Work bound: the forward's windows over the receivers, and the adjoint's over the reach.
        let (max_window, max_reach) = (windows.iter().max(), reach.iter().max());
        let side = |r: Option<&i32>| 2 * r.copied().unwrap_or(0).max(0) as u64 + 1;
        let work = params.layer_count as u64 * (side(max_window).pow(2) + side(max_reach).pow(2));
        let tiling = params.tiling().with_work(work);
        self.compile_passes(&params)?;
        run_tiled(ctx, &tiling, options, footprint, |plan| self.backward_tiles(&frame, &tiling, plan, options))
    }

    /// One attempt at the frame: its tiles in batches of `plan.tiles_per_batch`, each tile's
    /// gradients stored into the frame's once its batch has run.
    fn backward_tiles(
        &self,
        frame: &Frame,
        tiling: &FrameTiling,
        plan: TilePlan,
        options: &RenderOptions,
    ) -> Result<(StackGradients, RenderStats)> {
        let ctx = self.context();
        let params = frame.forward.params;
        frame.forward.begin_attempt();
        let mut grads = FrameGradients::new(params);
        // The largest tile's rects, as its footprint counts them: receivers reach (widened to
        // whole search tiles) and the forward's windows around them.
        let largest = |bounds: &[i32]| bounds.iter().copied().max().unwrap_or(0).max(0) as usize;
        let receivers_margin = largest(frame.reach) + TILE;
        let read_margin = receivers_margin + largest(frame.forward.windows);
        let room = Room {
            sources: tiling.room(plan.tile, 0),
            forward: TileRoom {
                core: tiling.room(plan.tile, receivers_margin),
                read: tiling.room(plan.tile, read_margin),
            },
        };
        let record = |batch: &mut CommandBatch, core: Rect| {
            let receivers = frame.receivers(core);
            let read = receivers.grown(halo(params, frame.forward.windows, receivers), params.width, params.height);
            let fwd = ForwardBuffers::new(ctx, batch, &frame.forward, receivers, read, room.forward, Residency::Stacked, None)?;
            let bwd = self.buffers(batch, frame, core, receivers, read, room)?;
            self.forward.record(batch, params, &fwd)?;
            self.record(batch, params, &fwd, &bwd, core)?;
            Ok(TileGradients {
                rgba: bwd.grad_rgba.readable_in(batch)?,
                disparity: bwd.grad_disparity.readable_in(batch)?,
                k_partial: bwd.k_partial.readable_in(batch)?,
            })
        };
        let collect = |core: Rect, tile: TileGradients| grads.store(ctx, params, &tile, core);
        let (mut stats, cores) = run_batches(ctx, tiling, plan, options, record, collect)?;
        stats.taps = cores.iter().map(|&core| taps(params, frame.forward.windows, frame.receivers(core))).sum();
        Ok((grads.finish(), stats))
    }

    /// A tile's backward buffers, zero fills and uploads recorded into `batch`.
    fn buffers(
        &self,
        batch: &mut CommandBatch,
        frame: &Frame,
        core: Rect,
        receivers: Rect,
        read: Rect,
        room: Room,
    ) -> Result<BackwardBuffers> {
        let ctx = self.context();
        let params = frame.forward.params;
        let layers = params.layer_count as u64;
        let gout = crop_rows(&frame.grad_output.pixels, params.width, receivers);
        let (read_n, read_room) = (layers * read.area() as u64, layers * room.forward.read as u64);
        let (core_n, core_room) = (layers * core.area() as u64, layers * room.sources as u64);
        let mut over_read = |name: &str, per_pixel: u64| {
            Buffer::zeroed_with_room_in(ctx, batch, name, read_n * per_pixel, read_room * per_pixel)
        };
        let (adj_cw, adj_vis) = (over_read("drbokeh adj_cw", VEC4)?, over_read("drbokeh adj_vis", 4)?);
        let (own, receiver) = (over_read("drbokeh own", VEC4)?, over_read("drbokeh receiver", VEC4)?);
        let mut over_core = |name: &str, per_pixel: u64| {
            Buffer::zeroed_with_room_in(ctx, batch, name, core_n * per_pixel, core_room * per_pixel)
        };
        Ok(BackwardBuffers {
            adj_cw,
            adj_vis,
            own,
            receiver,
            grad_rgba: over_core("drbokeh grad_rgba", VEC4)?,
            grad_disparity: over_core("drbokeh grad_disparity", 4)?,
            k_partial: over_core("drbokeh k_partial", 4)?,
            grad_output: Buffer::from_slices_with_room_in(
                ctx,
                batch,
                "drbokeh grad_output",
                receivers.area(),
                room.forward.core,
                gout,
            )?,
            tile_reach: frame.tile_reach.clone(),
            receiver_radius: frame.receiver_radius.clone(),
        })
    }

    /// Passes 2 and 4 for the lens's path.
    fn adjoint_pipelines(&self, params: &Params) -> Result<[ComputePipeline; 2]> {
        Ok(match params.lens.path(params.model) {
            AperturePath::Disk => [self.own_disk.clone(), self.source_disk.clone()],
            AperturePath::Gauge => {
                let constants = params.lens.gauge_specialization();
                [self.own_gauge.get(&constants)?, self.source_gauge.get(&constants)?]
            }
            AperturePath::Ring => [self.own_ring.clone(), self.source_ring.clone()],
            AperturePath::Kernel => [self.own_kernel.clone(), self.source_kernel.clone()],
            AperturePath::PerTap => [self.own.clone(), self.source.clone()],
        })
    }

    /// Compiles every pipeline a tile of `params` dispatches, the forward's included, side by
    /// side before the first tile records (as [`DrBokehGpu::compile_for`] does for a render).
    fn compile_passes(&self, params: &Params) -> Result<()> {
        let mut pipelines = self.forward.pipelines(&params.lens, params.model, Residency::Stacked)?;
        pipelines.push(self.composite.clone());
        pipelines.extend(self.adjoint_pipelines(params)?);
        if params.lens.path(params.model) == AperturePath::Disk {
            pipelines.push(self.blocks.clone());
        }
        compile_side_by_side(&pipelines)
    }

    /// Passes 1 and 2 over the receivers (the forward's core), pass 4 over the tile's `sources`.
    fn record(
        &self,
        batch: &mut CommandBatch,
        params: &Params,
        f: &ForwardBuffers,
        b: &BackwardBuffers,
        sources: Rect,
    ) -> Result<()> {
        let groups = self.own.groups_for([f.core.width() as u32, f.core.height() as u32, 1]);
        let leaky_slope = self.options.leaky_slope as f32;
        let push = |layer| super::DrBokehPush { leaky_slope, ..params.push_tile(layer, f.core, f.read) };
        let push_sources = |layer| super::DrBokehPush { leaky_slope, ..params.push_tile(layer, sources, f.read) };
        let [own_pipeline, source_pipeline] = &self.adjoint_pipelines(params)?;
        // The disk path's pass 2 reads the forward's alpha block sums of this batch; pass 3'
        // then writes the receivers' adjoint sums over them, for pass 4.
        let spans = params.lens.path(params.model) == AperturePath::Disk;
        if spans && !self.forward.sums_blocks(&params.lens, params.model)? {
            return Err(Error::internal("the backward's disk path needs the forward's block sums"));
        }
        let (own_bindings, source_bindings) =
            if spans { (OWN_SPAN_SLOTS.len(), SOURCE_SPAN_SLOTS.len()) } else { (OWN_SLOTS.len(), SOURCE_SLOTS.len()) };
        let blocks_groups = self.blocks.groups_for([block_columns(f.read), f.read.height() as u32, 1]);
        // TILE / local_size_x adjacent sources per invocation (the disk path runs several).
        let per_invocation = TILE as u32 / source_pipeline.shader().local_size[0];
        let source_groups =
            source_pipeline.groups_for([(sources.width() as u32).div_ceil(per_invocation), sources.height() as u32, 1]);
        let composite = [f.layer_cw.all(), f.layer_vis.all(), b.grad_output.all(), b.adj_cw.all(), b.adj_vis.all()];
        batch.dispatch(&self.composite, &composite, &push(0), groups)?;
        for layer in 0..params.layer_count {
            let own = [
                f.rgba[0].all(),
                f.disparity[0].all(),
                f.tile_window.all(),
                f.area_lut.all(),
                f.kernel.all(),
                b.adj_cw.all(),
                b.adj_vis.all(),
                b.own.all(),
                b.receiver.all(),
                f.block_alpha.all(),
            ];
            batch.dispatch(own_pipeline, &own[..own_bindings], &push(layer), groups)?;
            if spans {
                let sums =
                    [b.adj_cw.all(), b.receiver.all(), f.block_prefix.all(), f.block_suffix.all(), f.block_alpha.all()];
                batch.dispatch(&self.blocks, &sums, &push(layer), blocks_groups)?;
            }
            let source = [
                f.rgba[0].all(),
                f.disparity[0].all(),
                b.receiver.all(),
                f.area_lut.all(),
                f.kernel.all(),
                b.adj_cw.all(),
                b.own.all(),
                b.grad_rgba.all(),
                b.grad_disparity.all(),
                b.k_partial.all(),
                b.tile_reach.all(),
                f.block_prefix.all(),
                f.block_suffix.all(),
                f.block_alpha.all(),
                b.receiver_radius.all(),
            ];
            batch.dispatch(source_pipeline, &source[..source_bindings], &push_sources(layer), source_groups)?;
        }
        Ok(())
    }
}

/// The frame the tiles cut: the forward's (inputs, grown search windows, device tables), the
/// windows' transpose (layer-major) on the host and the device, and the output gradient.
/// Pixels of the largest tile's rects, which every tile's buffers have room for: its sources
/// (the core), and the forward's over its receivers.
#[derive(Clone, Copy)]
struct Room {
    sources: usize,
    forward: TileRoom,
}

struct Frame<'a> {
    forward: ForwardFrame<'a>,
    reach: &'a [i32],
    tile_reach: Buffer,
    receiver_radius: Buffer,
    grad_output: &'a Image,
}

impl Frame<'_> {
    /// The receivers whose windows may hold a source of `core`: the core grown by the largest
    /// reach of its search tiles, widened to whole 16x16 search tiles (the forward's layer
    /// kernel runs one search window per workgroup), clipped to the image.
    fn receivers(&self, core: Rect) -> Rect {
        let p = self.forward.params;
        let grown = core.grown(halo(p, self.reach, core), p.width, p.height);
        Rect {
            x0: grown.x0 / TILE * TILE,
            y0: grown.y0 / TILE * TILE,
            x1: p.tiling().round(grown.x1).min(p.width),
            y1: p.tiling().round(grown.y1).min(p.height),
        }
    }
}

/// Device bytes of a backward tile of side `tile`: the forward's buffers over the receivers
/// (the core grown by `max_reach`, plus up to a search tile of alignment per side) and their
/// halo, the adjoints over the read rect, the gradients over the core.
fn backward_footprint(params: &Params, max_window: i32, max_reach: i32) -> impl Fn(usize) -> Footprint + '_ {
    move |tile: usize| {
        let side = tile.min(params.width.max(params.height)) as u64;
        let receivers_side = side + 2 * (max_reach.max(0) as u64 + TILE as u64);
        let (core, receivers) = (side * side, receivers_side * receivers_side);
        let read = (receivers_side + 2 * max_window.max(0) as u64).pow(2);
        let layers = params.layer_count as u64;
        // adj_cw, adj_vis, own, receiver per read pixel; grad_rgba, grad_disparity, k_partial
        // per core pixel.
        let (adjoint_bytes, gradient_bytes) = (VEC4 + 4 + VEC4 + VEC4, VEC4 + 4 + 4);
        Footprint {
            largest_binding: layers * read * VEC4,
            total: layers
                * (read * (READ_BYTES_PER_PIXEL + adjoint_bytes)
                    + receivers * CORE_BYTES_PER_PIXEL
                    + core * gradient_bytes)
                + 2 * receivers * VEC4,
        }
    }
}

/// The full-frame per-pixel gradients, one vector per layer (what [`StackGradients`] hands
/// out, so finishing moves them instead of copying a flat frame's slices: those copies were
/// most of a 1024^2 backward's host time outside the tiles), filled tile by tile.
struct FrameGradients {
    rgba: Vec<Vec<[f32; 4]>>,
    disparity: Vec<Vec<f32>>,
    k_partial: Vec<Vec<f32>>,
}

/// Pixels per partial sum of the scalar gradients ([`FrameGradients::finish`]): fixed, so the
/// sum is the same bits on any machine and for any tiling.
const SUM_RUN: usize = 1 << 14;

impl FrameGradients {
    fn new(params: &Params) -> Self {
        let n = params.width * params.height;
        let layers = params.layer_count;
        Self {
            rgba: (0..layers).map(|_| vec![[0.0; 4]; n]).collect(),
            disparity: (0..layers).map(|_| vec![0.0; n]).collect(),
            k_partial: (0..layers).map(|_| vec![0.0; n]).collect(),
        }
    }

    /// Copies a tile's core-local gradients (layer after layer, each the core's rows) into the
    /// frame, straight from the read-backs: a copy of each into a vector first, then one thread
    /// placing its rows, made reading back most of a 1024^2 backward's wall time on an H200.
    fn store(&mut self, ctx: &Context, params: &Params, tile: &TileGradients, core: Rect) -> Result<()> {
        fn place<T: Copy + Send + Sync>(frame: &mut [Vec<T>], tile: &[T], params: &Params, core: Rect) {
            for (layer, rows) in frame.iter_mut().zip(tile.chunks_exact(core.area())) {
                place_core_rows(layer, params.width, core, rows);
            }
        }
        tile.rgba.read_with(ctx, |rgba: &[[f32; 4]]| place(&mut self.rgba, rgba, params, core))?;
        tile.disparity.read_with(ctx, |disparity: &[f32]| place(&mut self.disparity, disparity, params, core))?;
        tile.k_partial.read_with(ctx, |k_partial: &[f32]| place(&mut self.k_partial, k_partial, params, core))
    }

    /// Hands out the layers' gradients and sums the scalar shares in f64 in a fixed order,
    /// whatever order the tiles came in: each run of [`SUM_RUN`] pixels of a layer on its own
    /// (on every core), then the runs' sums in image order. One thread's sum of every value
    /// (5M of each at 1024^2 five layers) held the device's result back for milliseconds.
    fn finish(self) -> StackGradients {
        fn sum(layers: &[Vec<f32>]) -> f64 {
            use rayon::prelude::*;
            let runs: Vec<f64> = layers
                .par_iter()
                .flat_map(|layer| layer.par_chunks(SUM_RUN).map(|run| run.iter().map(|&v| v as f64).sum::<f64>()))
                .collect();
            runs.iter().sum()
        }
        let k_px = sum(&self.k_partial);
        let focus_disparity = -sum(&self.disparity);
        let layers = self.rgba.into_iter().zip(self.disparity).map(|(rgba, disparity)| LayerGradients { rgba, disparity }).collect();
        StackGradients { layers, k_px, focus_disparity }
    }
}

impl Differentiable for DrBokehGpuGrad {
    fn forward(&self, stack: &LayerStack, lens: &Lens) -> Result<Image> {
        self.forward.render(stack, lens, self.model)
    }

    fn backward(&self, stack: &LayerStack, lens: &Lens, grad_output: &Image) -> Result<StackGradients> {
        Ok(self.backward_with_stats(stack, lens, grad_output)?.0)
    }

    fn backward_with(
        &self,
        stack: &LayerStack,
        lens: &Lens,
        grad_output: &Image,
        options: &RenderOptions,
    ) -> Result<(StackGradients, RenderStats)> {
        // The inherent method: the tiled backward.
        DrBokehGpuGrad::backward_with(self, stack, lens, grad_output, options)
    }
}
