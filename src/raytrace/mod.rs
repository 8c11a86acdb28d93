//! Thin-lens distributed ray tracing of billboard scenes: the ground truth every quality claim
//! is measured against (Dr.Bokeh paper, Sec. 5.2.1 and Appendix 7.2).
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
