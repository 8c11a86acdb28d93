//! GPU host code of the Dr.Bokeh backward pass: the four forward passes, then the three
//! gather passes of `glsl/drbokeh_backward_*.comp` over the forward's intermediates, in one
//! command batch. The f64 reference of the same passes is [`super::backward_cpu`]. The scalar
//! gradients are sums of per-pixel shares (dL/dK: `rel g_s` per pixel; dL/d focus: minus
//! every disparity gradient) done on the host in f64 in a fixed order: deterministic.
use super::backward::BackwardOptions;
use super::gpu::{ForwardBuffers, VEC4};
use super::{DrBokehGpu, Model, Params, RenderStats};
use crate::image::Image;
use crate::render::grad::{Differentiable, LayerGradients, StackGradients};
use crate::render::Lens;
use crate::shaders;
use crate::stack::LayerStack;
use crate::vk::{Buffer, CommandBatch, ComputePipeline, Context};
use crate::{Error, Result};

/// The Dr.Bokeh forward and backward pipelines on one device, for one model and options.
pub struct DrBokehGpuGrad {
    forward: DrBokehGpu,
    composite: ComputePipeline,
    own: ComputePipeline,
    tile_reach: ComputePipeline,
    source: ComputePipeline,
    pub model: Model,
    pub options: BackwardOptions,
}

/// The backward's device buffers (all layer-major, one element per layer pixel).
struct BackwardBuffers {
    grad_output: Buffer,
    adj_cw: Buffer,
    adj_vis: Buffer,
    own: Buffer,
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
            own: ComputePipeline::new(ctx, &shaders::DRBOKEH_BACKWARD_OWN, 8, push)?,
            tile_reach: ComputePipeline::new(ctx, &shaders::DRBOKEH_BACKWARD_TILE_REACH, 2, push)?,
            source: ComputePipeline::new(ctx, &shaders::DRBOKEH_BACKWARD_SOURCE, 11, push)?,
            model,
            options,
        })
    }

    pub fn context(&self) -> &Context {
        self.forward.context()
    }

    /// [`Differentiable::backward`] plus the device time of the whole batch (forward included).
    pub fn backward_with_stats(&self, stack: &LayerStack, lens: &Lens, grad_output: &Image) -> Result<(StackGradients, RenderStats)> {
        if (grad_output.width, grad_output.height) != (stack.width, stack.height) {
            return Err(Error::param(format!(
                "output gradient is {}x{}, the stack {}x{}",
                grad_output.width, grad_output.height, stack.width, stack.height
            )));
        }
        let ctx = self.context();
        let params = Params::new(stack, lens, self.model)?;
        let fwd = ForwardBuffers::whole_frame(ctx, stack, &params, self.options.window_margin())?;
        let bwd = self.buffers(&params, grad_output)?;
        let mut batch = CommandBatch::new(ctx)?;
        self.forward.record(&mut batch, &params, &fwd)?;
        self.record(&mut batch, &params, &fwd, &bwd)?;
        batch.submit_and_wait()?;
        let stats = RenderStats { device_ns: batch.last_device_time_ns(), ..RenderStats::default() };
        Ok((read_gradients(ctx, &params, &bwd)?, stats))
    }

    fn buffers(&self, params: &Params, grad_output: &Image) -> Result<BackwardBuffers> {
        let ctx = self.context();
        let n = (params.layer_count * params.width * params.height) as u64;
        Ok(BackwardBuffers {
            grad_output: Buffer::from_slice(ctx, "drbokeh grad_output", &grad_output.pixels)?,
            adj_cw: Buffer::zeroed(ctx, "drbokeh adj_cw", n * VEC4)?,
            adj_vis: Buffer::zeroed(ctx, "drbokeh adj_vis", n * 4)?,
            own: Buffer::zeroed(ctx, "drbokeh own", n * VEC4)?,
            tile_reach: Buffer::zeroed(ctx, "drbokeh tile_reach", (params.layer_count * params.tiles_x * params.tiles_y) as u64 * 4)?,
            grad_rgba: Buffer::zeroed(ctx, "drbokeh grad_rgba", n * VEC4)?,
            grad_disparity: Buffer::zeroed(ctx, "drbokeh grad_disparity", n * 4)?,
            k_partial: Buffer::zeroed(ctx, "drbokeh k_partial", n * 4)?,
        })
    }

    fn record(&self, batch: &mut CommandBatch, params: &Params, f: &ForwardBuffers, b: &BackwardBuffers) -> Result<()> {
        let groups = self.own.groups_for([params.width as u32, params.height as u32, 1]);
        let tile_groups = self.tile_reach.groups_for([(params.tiles_x * params.tiles_y) as u32, 1, 1]);
        let push = |layer| super::DrBokehPush { leaky_slope: self.options.leaky_slope as f32, ..params.push(layer) };
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
            ];
            batch.dispatch(&self.own, &own, &push(layer), groups)?;
            batch.dispatch(&self.tile_reach, &[f.tile_window.all(), b.tile_reach.all()], &push(layer), tile_groups)?;
            let source = [
                f.rgba.all(),
                f.disparity.all(),
                f.tile_window.all(),
                f.area_lut.all(),
                f.kernel.all(),
                b.adj_cw.all(),
                b.own.all(),
                b.grad_rgba.all(),
                b.grad_disparity.all(),
                b.k_partial.all(),
                b.tile_reach.all(),
            ];
            batch.dispatch(&self.source, &source, &push(layer), groups)?;
        }
        Ok(())
    }
}

/// Splits the gradient buffers per layer and sums the scalar shares in f64, in pixel order.
fn read_gradients(ctx: &Context, params: &Params, b: &BackwardBuffers) -> Result<StackGradients> {
    let rgba: Vec<[f32; 4]> = b.grad_rgba.read(ctx)?;
    let disparity: Vec<f32> = b.grad_disparity.read(ctx)?;
    let k_partial: Vec<f32> = b.k_partial.read(ctx)?;
    let n = params.width * params.height;
    let layers = (0..params.layer_count)
        .map(|l| LayerGradients { rgba: rgba[l * n..(l + 1) * n].to_vec(), disparity: disparity[l * n..(l + 1) * n].to_vec() })
        .collect();
    Ok(StackGradients {
        layers,
        k_px: k_partial.iter().map(|&v| v as f64).sum(),
        focus_disparity: -disparity.iter().map(|&v| v as f64).sum::<f64>(),
    })
}

impl Differentiable for DrBokehGpuGrad {
    fn forward(&self, stack: &LayerStack, lens: &Lens) -> Result<Image> {
        self.forward.render(stack, lens, self.model)
    }

    fn backward(&self, stack: &LayerStack, lens: &Lens, grad_output: &Image) -> Result<StackGradients> {
        Ok(self.backward_with_stats(stack, lens, grad_output)?.0)
    }
}
