//! The benchmark: every method renders every ray-traced scene from the inputs it is entitled
//! to (the true layers, or only the pinhole image and its depth), and is scored against the
//! thin-lens ground truth with the paper's metrics (see [`crate::metrics`]).
//!
//! Methods live in a registry ([`Method`]); [`cpu_methods`] holds the CPU references and GPU
//! methods are appended the same way. [`run`] produces a [`BenchReport`] (JSON via serde, a
//! text table via `Display`), [`contact_sheet`] a labelled PNG of all renders and errors.
mod font;
mod methods;
mod runner;
mod sheet;
mod table;
// `scenes.rs` obtains the ground truths from the ray tracer
// (`crate::raytrace::{builtin_scenes, render_ground_truth, TraceOptions}`), which is written
// on another branch; it joins the module tree when that branch is merged, together with the
// `lensblur bench` subcommand (src/cli/bench.rs, three commented lines in src/cli/mod.rs).
// Both were compiled and run here against a stand-in with that API before being commented out.
// pub mod scenes;

pub use methods::{all_methods, cpu_methods, gpu_methods, select_methods, BenchCase, InputKind, Method};
pub use runner::{run, run_with_progress, BenchReport, CaseResult, MethodSummary, Worst};
pub use sheet::{contact_sheet, write_png, HEAT_MAX};
