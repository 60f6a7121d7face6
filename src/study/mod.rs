//! Studies built on the engine: the accuracy-vs-time sweep's metrics, frontier and plot.
//!
//! Decisions: this layer sits beside the CLI (it uses the engine, the scene and the f64
//! reference, and knows nothing of Vulkan); each concern is its own file so the metrics and the
//! frontier are unit-tested without a GPU.

pub mod batch;
pub mod batch_group;
pub mod batch_guard;
pub mod batch_outputs;
pub mod batch_prefetch;
pub mod batch_qc;
pub mod batch_summary;
pub mod bids;
pub mod kernel_sweep;
pub mod metrics;
pub mod pareto;
pub mod perturb;
pub mod perturb_geometry;
pub mod perturb_run;
pub mod perturb_score;
pub mod plot;
pub mod ssim;
pub mod stability;
pub mod vessels;
