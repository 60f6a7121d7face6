//! Histogram analysis (in progress): smoothing, spikes and mode detection.

pub mod params;
pub mod peaks;
pub mod smoothing;
pub mod spikes;

pub use params::AnalysisParams;
