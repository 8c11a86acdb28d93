//! GPU host code of the scatter baseline: on frame tiles ([`crate::render::tiler`]), uploads
//! each tile's read rect of the image and its disparity, dispatches `glsl/scatter.comp` (the
//! scatter written as a gather, no atomics) over its core, reads back.
use super::{AREA_EPSILON, EDGE_SHARPNESS, WINDOW_MARGIN};
use crate::image::Image;
use crate::render::gather::gpu::{check_input, ImageBaseline};
use crate::render::tiler::{rect_push, RenderOptions, RenderStats};
use crate::render::{Lens, SingleImageGpu};
use crate::shaders;
use crate::vk::Context;
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
    /// The tile's core and read rects ([`rect_push`]).
    core: [i32; 4],
    read: [i32; 4],
}
const _: () = assert!(std::mem::size_of::<ScatterPush>() == 80);

/// The scatter baseline on the GPU.
pub struct Scatter(ImageBaseline);

impl Scatter {
    pub fn new(ctx: &Context) -> Result<Self> {
        Ok(Self(ImageBaseline::new::<ScatterPush>(ctx, &shaders::SCATTER, "scatter")?))
    }
}

impl SingleImageGpu for Scatter {
    fn run_with(&self, image: &Image, disparity: &[f32], lens: &Lens, options: &RenderOptions) -> Result<(Image, RenderStats)> {
        check_input(image, disparity)?;
        let largest = disparity.iter().map(|&d| lens.coc.radius(d)).fold(0.0f32, f32::max);
        // Every pixel sums the whole window of the largest CoC: that window is the halo.
        let reach = largest.ceil() as usize + WINDOW_MARGIN as usize;
        let push = |core, read, kernel_size| ScatterPush {
            width: image.width as i32,
            height: image.height as i32,
            reach: reach as i32,
            kernel_size,
            k: lens.coc.k_px,
            focus: lens.coc.focus_disparity,
            edge_sharpness: EDGE_SHARPNESS,
            area_epsilon: AREA_EPSILON,
            aperture: lens.aperture.gpu_params(),
            core: rect_push(core),
            read: rect_push(read),
        };
        self.0.run(image, disparity, lens, options, reach, |_| reach, push)
    }
}
