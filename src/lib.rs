//! morphray: a GPU volume renderer for MRI built directly on Vulkan (`ash`).
//!
//! Layers, each knowing only the ones below it (ARCHITECTURE.md; `tests/layers.rs` checks it):
//!
//! ```text
//! cli                 commands, argument parsing, output formatting; no Vulkan calls
//! app                 the interactive viewer: window, egui interface, input, scripted runs
//! engine              one volume on one device: runs the passes in order, owns their outputs
//! passes              one file per GPU pass; each owns its pipeline and bindings
//! gpu                 the object layer on ash: instance, device, memory, resources, commands
//! volume              NIfTI reader, samples, statistics, the built-in phantom
//! analysis            histogram peaks, tissue windows, the paper's Table-1 row (CPU)
//! reference           f64 CPU twins of every GPU kernel, for tests and accuracy studies
//! files               reading user-named files safely (regular files only, with a cap),
//!                     writing outputs atomically, checking output paths before the work
//! ```
//!
//! Library code never panics on input data or Vulkan results: every failure is a typed error
//! whose `Display` is one sentence a person can act on.
#![warn(missing_docs)]
#![cfg_attr(
    not(test),
    deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)
)]

pub mod analysis;
#[cfg(feature = "viewer")]
pub mod app;
pub mod cli;
pub mod engine;
pub mod error;
pub mod files;
pub mod gpu;
pub mod model;
pub mod passes;
pub mod reference;
pub mod scene;
pub mod study;
pub mod volume;
