//! lensblur: physically based, occlusion-aware lens blur from layered RGBA + depth stacks,
//! rendered with Vulkan compute (raw `ash`), with a backward pass for gradients.
//!
//! Layout (see README "Architecture"):
//! - [`vk`]: the only place with raw Vulkan calls and `unsafe`.
//! - [`camera`]: the circle-of-confusion model and aperture shapes, shared by CPU and GPU paths.
//! - [`image`]: the in-memory RGBA float image.
//! - [`stack`]: layer stacks and their file formats (EXR, PNG/JPEG) — I/O lives at the edges.
//! - [`cache_dir`]: the user cache folder every rebuildable file goes to.
//! - [`atomic_file`]: outputs appear whole (temporary file, rename) and interrupts remove parts.
//! - [`sequence`]: shots: frame ranges, frame file patterns, per-frame camera files.
//! - [`render`]: one module per rendering method, each with GPU host code and a CPU reference.
//! - [`character`]: lens character and artist controls layered on any method.
//! - [`raytrace`]: the thin-lens ground-truth ray tracer and the built-in scenes.
//! - [`metrics`]: image quality metrics used by the benchmark.
//! - [`bench`]: the method registry, benchmark runner, report table and contact sheet.
pub mod atomic_file;
pub mod cache_dir;
pub mod camera;
pub mod character;
pub mod error;
pub mod image;
pub mod bench;
pub mod metrics;
pub mod optim;
pub mod raytrace;
pub mod render;
pub mod sequence;
pub mod shaders;
pub mod stack;
pub mod tiling;
pub mod vk;

pub use error::{Error, Result};
