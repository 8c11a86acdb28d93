//! Rendering methods. One module per method; each has GPU host code (driving its shaders in
//! `glsl/<method>_<pass>.comp`) and a CPU reference of the same math, used by tests.
use crate::camera::{Aperture, CocModel};

pub use method::{Highlight, InputKind, Method, MethodInput, MethodSettings, MethodSpec, Renderer, Setting, SingleImageGpu};

pub mod disk;
pub mod drbokeh;
pub mod gather;
pub mod gausspsf;
pub mod grad;
pub mod lens_samples;
pub mod method;
pub mod multiview;
pub mod oracle;
pub mod placement;
mod registry;
pub mod scatter;
#[cfg(test)]
mod test_inputs;
pub mod tiler;
pub mod vdslr;

/// Everything about the lens a renderer needs, in pixels.
#[derive(Clone, Debug, PartialEq)]
pub struct Lens {
    pub coc: CocModel,
    pub aperture: Aperture,
}
