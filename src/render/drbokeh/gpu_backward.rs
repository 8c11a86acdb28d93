//! GPU host code of the Dr.Bokeh backward pass: the four forward passes, then the three
//! gather passes of `glsl/drbokeh_backward_*.comp` (composite, own, source; pass 3, the tile
//! reach, is computed on the host, which needs it to cut the tiles anyway, and uploaded) over
//! the forward's intermediates, in one command batch per frame tile. The f64 reference of the
//! same passes is [`super::backward_cpu`].
//!
//! A tile is a core C of *source* pixels, whose gradients it writes. They gather over the
//! receivers O whose windows hold a source of C (C grown by the tile reach, pass 3); O's
//! adjoints need the forward's intermediates over O, which read O grown by its halo. So the
//! forward and passes 1-2 run with core O, pass 4 with core C, all over the same upload.
//! Every pixel sums the same terms in the same order as untiled. The scalar gradients are sums
//! of per-pixel shares (dL/dK: `rel g_s` per pixel; dL/d focus: minus every disparity
//! gradient) done on the host in f64 in image order after the last tile: deterministic and
//! independent of the tile size.
use super::backward::BackwardOptions;
use super::backward_cpu::tile_reach_cpu;
use super::bounds::{grow_windows, search_windows};
use super::gpu::{crop, frame_cores, halo, round_to_tile, run_tiled, taps, Footprint, ForwardBuffers, CORE_BYTES_PER_PIXEL, READ_BYTES_PER_PIXEL, VEC4};
use super::{DrBokehGpu, Model, Params, RenderOptions, RenderStats, TILE};
use crate::image::Image;
use crate::render::grad::{Differentiable, LayerGradients, StackGradients};
use crate::render::Lens;
use crate::shaders;
use crate::stack::LayerStack;
use crate::tiling::Rect;
use crate::vk::{Buffer, CommandBatch, ComputePipeline, Context};
use crate::{Error, Result};

/// The Dr.Bokeh forward and backward pipelines on one device, for one model and options.
pub struct DrBokehGpuGrad {
    forward: DrBokehGpu,
    composite: ComputePipeline,
    own: ComputePipeline,
    source: ComputePipeline,
    /// Passes 2 and 4 compiled for the default model with a disk aperture and no kernel image
    /// (see [`disk_path`]): lavapipe runs every branch, so the general code costs every tap.
    own_disk: ComputePipeline,
    source_disk: ComputePipeline,
    pub model: Model,
    pub options: BackwardOptions,
}

/// The backward's device buffers (all layer-major, one element per layer pixel).
struct BackwardBuffers {
    grad_output: Buffer,
    adj_cw: Buffer,
    adj_vis: Buffer,
    own: Buffer,
    /// Pass 2's per-receiver (rel, alpha, dL/dV / sum D, window) for pass 4: one load a tap.
    receiver: Buffer,
    tile_reach: Buffer,
    grad_rgba: Buffer,
    grad_disparity: Buffer,
    k_partial: Buffer,
}

impl DrBokehGpuGrad {
    pub fn new(ctx: &Context, model: Model, options: BackwardOptions) -> Result<Self> {
        let push = std::mem::size_of::<super::DrBokehPush>();
        Ok(Self {
            forward: DrBokehGpu::new(ctx)?,
            composite: ComputePipeline::new(ctx, &shaders::DRBOKEH_BACKWARD_COMPOSITE, 5, push)?,
            own: ComputePipeline::new(ctx, &shaders::DRBOKEH_BACKWARD_OWN, 9, push)?,
            source: ComputePipeline::new(ctx, &shaders::DRBOKEH_BACKWARD_SOURCE, 11, push)?,
            own_disk: ComputePipeline::new(ctx, &shaders::DRBOKEH_BACKWARD_OWN_DISK, 9, push)?,
            source_disk: ComputePipeline::new(ctx, &shaders::DRBOKEH_BACKWARD_SOURCE_DISK, 11, push)?,
            model,
            options,
        })
    }

    pub fn context(&self) -> &Context {
        self.forward.context()
    }

    /// [`Differentiable::backward`] plus what the passes measured, on automatically sized tiles.
    pub fn backward_with_stats(&self, stack: &LayerStack, lens: &Lens, grad_output: &Image) -> Result<(StackGradients, RenderStats)> {
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
        if (grad_output.width, grad_output.height) != (stack.width, stack.height) {
            return Err(Error::param(format!(
                "output gradient is {}x{}, the stack {}x{}",
                grad_output.width, grad_output.height, stack.width, stack.height
            )));
        }
        let params = Params::new(stack, lens, self.model)?;
        let windows = grow_windows(search_windows(&params, stack), self.options.window_margin());
        let per_layer = params.tiles_x * params.tiles_y;
        let reach: Vec<i32> = windows.chunks(per_layer.max(1)).flat_map(|w| tile_reach_cpu(&params, w)).collect();
        let frame = Frame { stack, params: &params, windows: &windows, reach: &reach, grad_output };
        let footprint = backward_footprint(&params, windows.iter().copied().max().unwrap_or(0), reach.iter().copied().max().unwrap_or(0));
        run_tiled(self.context(), &params, options, footprint, |tile| self.backward_tiles(&frame, tile, options))
    }

    fn backward_tiles(&self, frame: &Frame, tile: usize, options: &RenderOptions) -> Result<(StackGradients, RenderStats)> {
        let ctx = self.context();
        let params = frame.params;
        let baseline = ctx.allocated_bytes();
        let cores = frame_cores(params.width, params.height, tile);
        let mut grads = FrameGradients::new(params);
        let mut stats = RenderStats { tiles: cores.len(), tile_size: tile, ..RenderStats::default() };
        let mut device_ns = Some(0.0);
        for (done, &core) in cores.iter().enumerate() {
            let receivers = frame.receivers(core);
            let read = receivers.grown(halo(params, frame.windows, receivers), params.width, params.height);
            let fwd = ForwardBuffers::new(ctx, frame.stack, params, frame.windows, receivers, read)?;
            let bwd = self.buffers(params, frame.grad_output, frame.reach, core, receivers, read)?;
            stats.peak_device_bytes = stats.peak_device_bytes.max(ctx.allocated_bytes().saturating_sub(baseline));
            let mut batch = CommandBatch::new(ctx)?;
            self.forward.record(&mut batch, params, &fwd)?;
            self.record(&mut batch, params, &fwd, &bwd, core)?;
            batch.submit_and_wait()?;
            device_ns = device_ns.zip(batch.last_device_time_ns()).map(|(a, b)| a + b);
            stats.taps += taps(params, frame.windows, receivers);
            grads.store(ctx, params, &bwd, core)?;
            if let Some(progress) = options.progress {
                progress(done + 1, cores.len());
            }
        }
        stats.device_ns = device_ns;
        Ok((grads.finish(params), stats))
    }

    fn buffers(&self, params: &Params, grad_output: &Image, reach: &[i32], core: Rect, receivers: Rect, read: Rect) -> Result<BackwardBuffers> {
        let ctx = self.context();
        let layers = params.layer_count as u64;
        let (read_n, core_n) = (layers * read.area() as u64, layers * core.area() as u64);
        let gout: Vec<[f32; 4]> = crop(&grad_output.pixels, params.width, receivers).collect();
        Ok(BackwardBuffers {
            grad_output: Buffer::from_slice(ctx, "drbokeh grad_output", &gout)?,
            adj_cw: Buffer::zeroed(ctx, "drbokeh adj_cw", read_n * VEC4)?,
            adj_vis: Buffer::zeroed(ctx, "drbokeh adj_vis", read_n * 4)?,
            own: Buffer::zeroed(ctx, "drbokeh own", read_n * VEC4)?,
            receiver: Buffer::zeroed(ctx, "drbokeh receiver", read_n * VEC4)?,
            tile_reach: Buffer::from_slice(ctx, "drbokeh tile_reach", reach)?,
            grad_rgba: Buffer::zeroed(ctx, "drbokeh grad_rgba", core_n * VEC4)?,
            grad_disparity: Buffer::zeroed(ctx, "drbokeh grad_disparity", core_n * 4)?,
            k_partial: Buffer::zeroed(ctx, "drbokeh k_partial", core_n * 4)?,
        })
    }

    /// Passes 1 and 2 over the receivers (the forward's core), pass 4 over the tile's `sources`.
    fn record(&self, batch: &mut CommandBatch, params: &Params, f: &ForwardBuffers, b: &BackwardBuffers, sources: Rect) -> Result<()> {
        let groups = self.own.groups_for([f.core.width() as u32, f.core.height() as u32, 1]);
        let leaky_slope = self.options.leaky_slope as f32;
        let push = |layer| super::DrBokehPush { leaky_slope, ..params.push_tile(layer, f.core, f.read) };
        let push_sources = |layer| super::DrBokehPush { leaky_slope, ..params.push_tile(layer, sources, f.read) };
        let (own_pipeline, source_pipeline) = if disk_path(params) { (&self.own_disk, &self.source_disk) } else { (&self.own, &self.source) };
        // TILE / local_size_x adjacent sources per invocation (the disk path runs several).
        let per_invocation = TILE as u32 / source_pipeline.shader().local_size[0];
        let source_groups = source_pipeline.groups_for([(sources.width() as u32).div_ceil(per_invocation), sources.height() as u32, 1]);
        let composite = [f.layer_cw.all(), f.layer_vis.all(), b.grad_output.all(), b.adj_cw.all(), b.adj_vis.all()];
        batch.dispatch(&self.composite, &composite, &push(0), groups)?;
        for layer in 0..params.layer_count {
            let own = [
                f.rgba.all(),
                f.disparity.all(),
                f.tile_window.all(),
                f.area_lut.all(),
                f.kernel.all(),
                b.adj_cw.all(),
                b.adj_vis.all(),
                b.own.all(),
                b.receiver.all(),
            ];
            batch.dispatch(own_pipeline, &own, &push(layer), groups)?;
            let source = [
                f.rgba.all(),
                f.disparity.all(),
                b.receiver.all(),
                f.area_lut.all(),
                f.kernel.all(),
                b.adj_cw.all(),
                b.own.all(),
                b.grad_rgba.all(),
                b.grad_disparity.all(),
                b.k_partial.all(),
                b.tile_reach.all(),
            ];
            batch.dispatch(source_pipeline, &source, &push_sources(layer), source_groups)?;
        }
        Ok(())
    }
}

/// Whether passes 2 and 4 take their disk path: the default model with a disk aperture and no
/// kernel image (K = 1, Euclidean gauge; mirrors the forward's disk path and the headers of
/// `glsl/drbokeh_backward_{own,source}_disk.comp`).
fn disk_path(params: &Params) -> bool {
    let [blades, _, _, kernel] = params.lens.aperture;
    params.model == Model::DrBokeh && blades < 3.0 && (kernel < 0.5 || params.lens.kernel_size == 0)
}

/// The frame the tiles cut: inputs, search windows and their transpose (layer-major).
struct Frame<'a> {
    stack: &'a LayerStack,
    params: &'a Params,
    windows: &'a [i32],
    reach: &'a [i32],
    grad_output: &'a Image,
}

impl Frame<'_> {
    /// The receivers whose windows may hold a source of `core`: the core grown by the largest
    /// reach of its search tiles, widened to whole 16x16 search tiles (the forward's layer
    /// kernel runs one search window per workgroup), clipped to the image.
    fn receivers(&self, core: Rect) -> Rect {
        let p = self.params;
        let grown = core.grown(halo(p, self.reach, core), p.width, p.height);
        Rect { x0: grown.x0 / TILE * TILE, y0: grown.y0 / TILE * TILE, x1: round_to_tile(grown.x1).min(p.width), y1: round_to_tile(grown.y1).min(p.height) }
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
            total: layers * (read * (READ_BYTES_PER_PIXEL + adjoint_bytes) + receivers * CORE_BYTES_PER_PIXEL + core * gradient_bytes)
                + 2 * receivers * VEC4,
        }
    }
}

/// The full-frame per-pixel gradients, layer-major, filled tile by tile.
struct FrameGradients {
    rgba: Vec<[f32; 4]>,
    disparity: Vec<f32>,
    k_partial: Vec<f32>,
}

impl FrameGradients {
    fn new(params: &Params) -> Self {
        let n = params.layer_count * params.width * params.height;
        Self { rgba: vec![[0.0; 4]; n], disparity: vec![0.0; n], k_partial: vec![0.0; n] }
    }

    /// Copies a tile's core-local gradients into the frame.
    fn store(&mut self, ctx: &Context, params: &Params, b: &BackwardBuffers, core: Rect) -> Result<()> {
        let rgba: Vec<[f32; 4]> = b.grad_rgba.read(ctx)?;
        let disparity: Vec<f32> = b.grad_disparity.read(ctx)?;
        let k_partial: Vec<f32> = b.k_partial.read(ctx)?;
        let n = params.width * params.height;
        let w = core.width();
        for layer in 0..params.layer_count {
            for y in 0..core.height() {
                let from = (layer * core.height() + y) * w;
                let to = layer * n + (core.y0 + y) * params.width + core.x0;
                self.rgba[to..to + w].copy_from_slice(&rgba[from..from + w]);
                self.disparity[to..to + w].copy_from_slice(&disparity[from..from + w]);
                self.k_partial[to..to + w].copy_from_slice(&k_partial[from..from + w]);
            }
        }
        Ok(())
    }

    /// Splits the frame per layer and sums the scalar shares in f64 in image order (layer by
    /// layer, row by row), whatever order the tiles came in.
    fn finish(self, params: &Params) -> StackGradients {
        let n = params.width * params.height;
        let k_px = self.k_partial.iter().map(|&v| v as f64).sum();
        let focus_disparity = -self.disparity.iter().map(|&v| v as f64).sum::<f64>();
        let layers = (0..params.layer_count)
            .map(|l| LayerGradients { rgba: self.rgba[l * n..(l + 1) * n].to_vec(), disparity: self.disparity[l * n..(l + 1) * n].to_vec() })
            .collect();
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
}
