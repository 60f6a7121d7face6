//! f64 CPU twins of the GPU kernels (in progress).
pub mod raymarch;
