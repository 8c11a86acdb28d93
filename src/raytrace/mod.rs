//! Thin-lens distributed ray tracing of billboard scenes: the ground truth every quality claim
//! is measured against (Dr.Bokeh paper, Sec. 5.2.1 and Appendix 7.2).
//!
//! - [`scene`]: textured planes (billboards, tilted planes) and the camera frame;
//! - [`texture`], [`shape`], [`strokes`], [`noise`]: procedural content, nothing downloaded;
//! - `trace`: the thin-lens ray model and per-ray compositing; `render`: the passes;
//! - `scenes`: the built-in scene set; [`output`]: files written by `lensblur raytrace`.
mod grid;
pub mod noise;
pub mod output;
mod render;
pub mod sampling;
pub mod scene;
mod scenes;
pub mod shape;
pub mod strokes;
pub mod texture;
mod trace;

pub use render::{render_ground_truth, EMPTY_DEPTH};
pub use scene::{Scene, Surface, ZPass};
pub use scenes::{builtin_scene, builtin_scenes, single_image_scenes};
pub use trace::{RowProgress, TraceOptions};

use crate::camera::{CocModel, PhysicalCamera};
use crate::image::Image;
use crate::stack::LayerStack;

/// Everything the ray tracer produces for one scene; the benchmark consumes it in memory and
/// `lensblur raytrace` writes it to files.
#[derive(Clone, Debug)]
pub struct GroundTruth {
    pub name: String,
    pub camera: PhysicalCamera,
    /// The camera in pixels of this image (`CocModel::from_physical(camera, width)`).
    pub coc: CocModel,
    /// Pinhole (all-in-focus) render: linear, premultiplied RGBA.
    pub pinhole: Image,
    /// Planar depth (scene units) of the pinhole render's visible surface per pixel;
    /// `camera::FAR_DEPTH_SENTINEL`-or-larger (1e10) where nothing is hit.
    pub pinhole_depth: Vec<f32>,
    /// The true layer stack: each billboard alone (pinhole), front to back, premultiplied,
    /// disparity `1/z` defined everywhere.
    pub layers: LayerStack,
    /// The thin-lens defocused render: linear, premultiplied RGBA.
    pub defocused: Image,
}
