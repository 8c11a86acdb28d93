//! GPU host code of the Dr.Bokeh forward renderer: uploads a stack, runs the four passes of
//! `glsl/drbokeh_*.comp` in one command batch, reads the composite back. The CPU reference of
//! the same passes is [`super::cpu`]; `Params` (validation, lens, area table, push constants)
//! is shared with it, so the two differ only in f32 vs f64 arithmetic.
use super::{Model, Params};
use crate::image::Image;
use crate::render::Lens;
use crate::shaders;
use crate::stack::LayerStack;
use crate::vk::{Buffer, CommandBatch, ComputePipeline, Context};
use crate::Result;

/// Bytes of one `vec2` / `vec4` in std430.
const VEC2: u64 = 8;
pub(crate) const VEC4: u64 = 16;

/// The Dr.Bokeh pipelines on one device; build once, render many stacks.
pub struct DrBokehGpu {
    ctx: Context,
    tile_bounds: ComputePipeline,
    tile_window: ComputePipeline,
    layer: ComputePipeline,
    composite: ComputePipeline,
}

/// What one render measured on the device.
#[derive(Clone, Copy, Debug, Default)]
pub struct RenderStats {
    /// Device time of the passes (timestamp queries), if the queue supports them.
    pub device_ns: Option<f64>,
}

impl DrBokehGpu {
    pub fn new(ctx: &Context) -> Result<Self> {
        let push = std::mem::size_of::<super::DrBokehPush>();
        Ok(Self {
            ctx: ctx.clone(),
            tile_bounds: ComputePipeline::new(ctx, &shaders::DRBOKEH_TILE_BOUNDS, 3, push)?,
            tile_window: ComputePipeline::new(ctx, &shaders::DRBOKEH_TILE_WINDOW, 2, push)?,
            layer: ComputePipeline::new(ctx, &shaders::DRBOKEH_LAYER, 7, push)?,
            composite: ComputePipeline::new(ctx, &shaders::DRBOKEH_COMPOSITE, 3, push)?,
        })
    }

    pub fn context(&self) -> &Context {
        &self.ctx
    }

    /// Renders `stack` through `lens`: premultiplied linear RGBA, HDR unclamped.
    pub fn render(&self, stack: &LayerStack, lens: &Lens, model: Model) -> Result<Image> {
        Ok(self.render_with_stats(stack, lens, model)?.0)
    }

    pub fn render_with_stats(&self, stack: &LayerStack, lens: &Lens, model: Model) -> Result<(Image, RenderStats)> {
        let params = Params::new(stack, lens, model)?;
        let buffers = ForwardBuffers::new(&self.ctx, stack, &params)?;
        let mut batch = CommandBatch::new(&self.ctx)?;
        self.record(&mut batch, &params, &buffers)?;
        batch.submit_and_wait()?;
        let stats = RenderStats { device_ns: batch.last_device_time_ns() };
        let pixels: Vec<[f32; 4]> = buffers.result.read(&self.ctx)?;
        Ok((Image { width: params.width, height: params.height, pixels }, stats))
    }

    /// Records the four forward passes over `buffers` (the backward reuses the intermediates).
    pub(crate) fn record(&self, batch: &mut CommandBatch, params: &Params, b: &ForwardBuffers) -> Result<()> {
        let tiles = (params.tiles_x * params.tiles_y) as u32;
        let image_groups = self.layer.groups_for([params.width as u32, params.height as u32, 1]);
        let tile_groups = self.tile_bounds.groups_for([tiles, 1, 1]);
        for layer in 0..params.layer_count {
            let push = params.push(layer);
            batch.dispatch(&self.tile_bounds, &[b.rgba.all(), b.disparity.all(), b.tile_bounds.all()], &push, tile_groups)?;
            batch.dispatch(&self.tile_window, &[b.tile_bounds.all(), b.tile_window.all()], &push, tile_groups)?;
            batch.dispatch(
                &self.layer,
                &[b.rgba.all(), b.disparity.all(), b.tile_window.all(), b.area_lut.all(), b.kernel.all(), b.layer_cw.all(), b.layer_vis.all()],
                &push,
                image_groups,
            )?;
        }
        batch.dispatch(&self.composite, &[b.layer_cw.all(), b.layer_vis.all(), b.result.all()], &params.push(0), image_groups)?;
        Ok(())
    }
}

/// The device buffers of one forward render: the uploaded stack and lens tables, and every
/// pass's output.
pub(crate) struct ForwardBuffers {
    pub rgba: Buffer,
    pub disparity: Buffer,
    pub area_lut: Buffer,
    pub kernel: Buffer,
    pub tile_bounds: Buffer,
    pub tile_window: Buffer,
    pub layer_cw: Buffer,
    pub layer_vis: Buffer,
    pub result: Buffer,
}

impl ForwardBuffers {
    pub fn new(ctx: &Context, stack: &LayerStack, params: &Params) -> Result<Self> {
        let layers = params.layer_count as u64;
        let pixels = (params.width * params.height) as u64;
        let tiles = (params.tiles_x * params.tiles_y) as u64;
        let rgba: Vec<[f32; 4]> = stack.layers.iter().flat_map(|l| l.rgba.pixels.iter().copied()).collect();
        let disparity: Vec<f32> = stack.layers.iter().flat_map(|l| l.disparity.iter().copied()).collect();
        Ok(Self {
            rgba: Buffer::from_slice(ctx, "drbokeh rgba", &rgba)?,
            disparity: Buffer::from_slice(ctx, "drbokeh disparity", &disparity)?,
            area_lut: Buffer::from_slice(ctx, "drbokeh area_lut", &params.area_lut_f32())?,
            kernel: Buffer::from_slice(ctx, "drbokeh kernel", &params.kernel_f32())?,
            tile_bounds: Buffer::zeroed(ctx, "drbokeh tile_bounds", layers * tiles * VEC2)?,
            tile_window: Buffer::zeroed(ctx, "drbokeh tile_window", layers * tiles * 4)?,
            layer_cw: Buffer::zeroed(ctx, "drbokeh layer_cw", layers * pixels * VEC4)?,
            layer_vis: Buffer::zeroed(ctx, "drbokeh layer_vis", layers * pixels * 4)?,
            result: Buffer::zeroed(ctx, "drbokeh result", pixels * VEC4)?,
        })
    }
}
