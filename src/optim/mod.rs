//! Depth from defocus (Dr.Bokeh paper, Sec. 4.3): given an all-in-focus layer stack and a
//! defocused photograph, optimise the layers' disparity through any differentiable renderer.
//!
//! - [`loss`]: Eq. 13 (L1 + edge-aware smoothness + hierarchical SSIM) with analytic gradients;
//! - [`adam`]: the optimiser;
//! - [`fit`]: [`fit_depth`], the optimisation loop over a
//!   [`Differentiable`](crate::render::grad::Differentiable) renderer;
//! - [`depth_error`](mod@depth_error): disparity and CoC errors against a known truth;
//! - [`experiment`]: the benchmark of the paper's Tables 2-3 on our ray-traced scenes.
pub mod adam;
pub mod depth_error;
#[cfg(feature = "raytrace")]
pub mod experiment;
pub mod fit;
pub mod loss;

pub use adam::Adam;
pub use depth_error::{coc_error, depth_error, DepthError};
#[cfg(feature = "raytrace")]
pub use experiment::{experiment_truths, fit_scene, format_results, run_experiment, ExperimentOptions, SceneResult};
pub use fit::{fit_depth, FitOptions, FitResult};
