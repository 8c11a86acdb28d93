//! The benchmark: every method renders every ray-traced scene from the inputs it is entitled
//! to (the true layers, or only the pinhole image and its depth), and is scored against the
//! thin-lens ground truth with the paper's metrics (see [`lensblur::metrics`]).
//!
//! The methods are the registry's ([`lensblur::render::Method::ALL`], as [`BenchMethod`]s);
//! [`cpu_methods`] holds the CPU ones, [`gpu_methods`] the
//! Vulkan renderers, [`all_methods`] both. [`run`] produces a [`BenchReport`] (JSON via serde, a
//! text table via `Display`), [`contact_sheet`] a labelled PNG of all renders and errors.
pub mod gt_cache;
pub mod device_timings;
pub mod process_timings;
pub mod large;
mod methods;
pub mod apertures;
pub mod blender;
pub mod cycles;
pub mod end_to_end;
pub mod perf;
pub mod perf_backward;
mod peer;
mod runner;
mod single_image;
mod sheet;
mod table;
pub mod scenes;

pub use methods::{all_methods, cpu_methods, gpu_methods, select_methods, BenchCase, BenchMethod, InputKind};
pub use peer::{opendefocus_binary, run_opendefocus, PeerRun, OPENDEFOCUS_ENV};
pub use runner::{append_external, run, run_with_progress, BenchReport, CaseResult, MethodSummary, Worst};
pub use sheet::{contact_sheet, write_png, HEAT_MAX};
pub use single_image::{local_pick_gain, run_single_image, SingleImageTable, PEER, PICK_BLOCK, SINGLE_IMAGE_METHODS};
