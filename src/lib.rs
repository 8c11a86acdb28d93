//! lensblur: physically based, occlusion-aware lens blur from layered RGBA + depth stacks,
//! rendered with Vulkan compute (raw `ash`), with a backward pass for gradients.
//!
//! A stack is a list of layers front to back, each premultiplied linear RGBA with a depth per
//! pixel stored as disparity (`1 / Z` with Z in metres for a physical camera). A [`render::Lens`]
//! is the circle-of-confusion model plus an aperture shape; a [`render::Method`] renders a stack
//! through it on a Vulkan device ([`vk::Context`]: a GPU, or Mesa's lavapipe on the CPU):
//!
//! ```
//! use lensblur::camera::{Aperture, CocModel, PhysicalCamera};
//! use lensblur::image::Image;
//! use lensblur::render::{Lens, Method};
//! use lensblur::stack::{Layer, LayerStack};
//! use lensblur::vk::Context;
//!
//! # fn main() -> lensblur::Result<()> {
//! let (w, h) = (32, 24);
//! // An orange card 1.5 m away in front of a grey wall at 8 m.
//! let card = Layer {
//!     name: "card".into(),
//!     rgba: Image::from_fn(w, h, |x, _| if x < 16 { [1.0, 0.5, 0.2, 1.0] } else { [0.0; 4] }),
//!     disparity: vec![1.0 / 1.5; w * h],
//! };
//! let wall = Layer { name: "wall".into(), rgba: Image::from_fn(w, h, |_, _| [0.5, 0.5, 0.5, 1.0]), disparity: vec![1.0 / 8.0; w * h] };
//! let stack = LayerStack::new(w, h, vec![card, wall])?;
//! // A 50 mm lens at f/2 on a full-frame sensor, focused on the card; six-bladed bokeh.
//! let camera = PhysicalCamera { focal_length_mm: 50.0, sensor_width_mm: 36.0, fstop: 2.0, focus_distance: 1.5 };
//! let lens = Lens { coc: CocModel::from_physical(&camera, w)?, aperture: Aperture::parse("polygon:6")? };
//! // Open the device once and reuse it for every render (LENSBLUR_DEVICE picks another).
//! let ctx = Context::from_env()?;
//! let image = Method::default().render(Some(&ctx), &stack, &lens)?;
//! assert_eq!((image.width, image.height), (w, h));
//! // The card is in focus: its pixels keep their colour.
//! assert!((image.get(4, 12)[0] - 1.0).abs() < 1e-3);
//! ctx.finish()?;
//! # Ok(())
//! # }
//! ```
//!
//! Files: [`stack::read_stack`] reads a layered EXR in any of the naming conventions Blender,
//! OpenImageIO and Nuke write, [`stack::write_image`] writes the result;
//! `examples/render_stack.rs` does the whole round trip with a camera from the file's header.
//!
//! Layout (see the book's architecture page, docs/book/src/architecture.md):
//! - [`vk`]: the only place with raw Vulkan calls and `unsafe`.
//! - [`camera`]: the circle-of-confusion model and aperture shapes, shared by CPU and GPU paths.
//! - [`image`]: the in-memory RGBA float image.
//! - [`stack`]: layer stacks and their file formats (EXR, PNG/JPEG) — I/O lives at the edges.
//! - [`input`]: a render's input as a caller hands it: read the file, resolve the camera
//!   (caller, header, shot camera file), auto-layer a flat image; map gradients back onto the
//!   file's channels.
//! - [`job`]: one render described once (input, camera, method and settings, lens character,
//!   options), checked once and run: what the CLI, shots, Python and sessions all build.
//! - [`session`]: a resident renderer (device, pipelines and input kept) for interactive refocus.
//! - [`cache_dir`]: the user cache folder every rebuildable file goes to.
//! - [`atomic_file`]: outputs appear whole (temporary file, rename) and interrupts remove parts.
//! - [`sequence`]: shots: frame ranges, frame file patterns, per-frame camera files.
//! - [`render`]: one module per rendering method, each with GPU host code and a CPU reference.
//! - [`character`]: lens character and artist controls layered on any method.
//! - [`raytrace`] (feature `raytrace`): the thin-lens ground-truth ray tracer and the built-in scenes.
//! - [`metrics`]: image quality metrics used by the benchmark.
//!
//! The command line (`cli/`), the benchmark and the device self-check (`dev/`) and the Python
//! module (`python/`) are crates of their own that build on this one; none of them is a
//! dependency of it.
// Raw pointers only where a foreign API needs them: the Vulkan module (`#[allow(unsafe_code)]`
// on its `mod` line below) and the deep reader's OpenEXR bindings (`src/stack/deep/ffi.rs`)
// opt in; anywhere else `unsafe` is a compile error (tests/architecture.rs checks both).
#![deny(unsafe_code)]

pub mod atomic_file;
pub mod cache_dir;
pub mod camera;
pub mod character;
pub mod error;
pub mod image;
pub mod input;
pub mod job;
pub mod metrics;
pub mod optim;
#[cfg(feature = "raytrace")]
pub mod raytrace;
pub mod render;
pub mod sequence;
pub mod session;
pub mod shaders;
pub mod stack;
pub mod tile_grid;
#[allow(unsafe_code)]
pub mod vk;

pub use error::{Error, InputMismatch, Result};

/// The build, for a front end's `--version`: the commit it was built from (`build.rs`) and
/// its profile (`debug` or `release`).
pub const BUILD_COMMIT: &str = env!("LENSBLUR_COMMIT");
pub const BUILD_PROFILE: &str = env!("LENSBLUR_PROFILE");
