//! The benchmark: every method renders every ray-traced scene from the inputs it is entitled
//! to (the true layers, or only the pinhole image and its depth), and is scored against the
//! thin-lens ground truth with the paper's metrics (see [`crate::metrics`]).
//!
//! Methods live in a registry ([`Method`]); [`cpu_methods`] holds the CPU references, [`gpu_methods`] the
//! Vulkan renderers, [`all_methods`] both. [`run`] produces a [`BenchReport`] (JSON via serde, a
//! text table via `Display`), [`contact_sheet`] a labelled PNG of all renders and errors.
pub(crate) mod font;
pub mod gt_cache;
pub mod large;
mod methods;
pub mod apertures;
pub mod blender;
pub mod end_to_end;
pub mod perf;
pub mod perf_backward;
mod runner;
mod sheet;
mod table;
pub mod scenes;

pub use methods::{all_methods, cpu_methods, gpu_methods, select_methods, BenchCase, InputKind, Method};
pub use runner::{run, run_with_progress, BenchReport, CaseResult, MethodSummary, Worst};
pub use sheet::{contact_sheet, write_png, HEAT_MAX};
