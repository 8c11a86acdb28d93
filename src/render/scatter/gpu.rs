//! GPU host code of the scatter baseline: uploads the image and its disparity, dispatches
//! `glsl/scatter.comp` (the scatter written as a gather, no atomics) once, reads back.
use super::{AREA_EPSILON, EDGE_SHARPNESS, WINDOW_MARGIN};
use crate::image::Image;
use crate::render::gather::gpu::{check_input, dispatch_image_pass};
use crate::render::Lens;
use crate::shaders;
use crate::vk::{ComputePipeline, Context, Slot, TexelFormat};
use crate::Result;

/// Push constants of `glsl/scatter.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct ScatterPush {
    width: i32,
    height: i32,
    /// Window half-size: the largest CoC of the image plus the rim margin.
    reach: i32,
    /// Side of the kernel image (0: none).
    kernel_size: i32,
    k: f32,
    focus: f32,
    edge_sharpness: f32,
    area_epsilon: f32,
    aperture: [f32; 4],
}
const _: () = assert!(std::mem::size_of::<ScatterPush>() == 48);

/// The scatter baseline on the GPU.
pub struct Scatter {
    ctx: Context,
    pipeline: ComputePipeline,
}

impl Scatter {
    pub fn new(ctx: &Context) -> Result<Self> {
        let pipeline = ComputePipeline::with_slots(ctx, &shaders::SCATTER, &[Slot::Texels(TexelFormat::Vec4), Slot::Texels(TexelFormat::Float), Slot::Storage, Slot::Texels(TexelFormat::Float)], std::mem::size_of::<ScatterPush>())?;
        Ok(Self { ctx: ctx.clone(), pipeline })
    }

    /// Renders `image` (linear, premultiplied) with per-pixel `disparity` through `lens`.
    pub fn run(&self, image: &Image, disparity: &[f32], lens: &Lens) -> Result<Image> {
        check_input(image, disparity)?;
        let (kernel_size, kernel) = lens.aperture.kernel_texels();
        let largest = disparity.iter().map(|&d| lens.coc.radius(d)).fold(0.0f32, f32::max);
        let push = ScatterPush {
            width: image.width as i32,
            height: image.height as i32,
            reach: largest.ceil() as i32 + WINDOW_MARGIN as i32,
            kernel_size: kernel_size as i32,
            k: lens.coc.k_px,
            focus: lens.coc.focus_disparity,
            edge_sharpness: EDGE_SHARPNESS,
            area_epsilon: AREA_EPSILON,
            aperture: lens.aperture.gpu_params(),
        };
        dispatch_image_pass(&self.ctx, &self.pipeline, "scatter", image, disparity, &kernel, &push)
    }
}
