//! Which intensity range is mapped to `I_norm` 0..1: the paper's min/max (eq. 1), or a robust
//! range from percentiles that a handful of hot voxels cannot move.
//!
//! This file holds the mode only; the percentile rule is added with the robust normalization.

/// How the physical intensity range mapped to `I_norm = 0..1` is chosen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum NormalizeMode {
    /// Percentiles of the finite voxels (see the module doc); values outside are clamped.
    Robust,
    /// The paper's eq. 1: the finite minimum and maximum.
    #[default]
    MinMax,
}

impl NormalizeMode {
    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            NormalizeMode::Robust => "robust",
            NormalizeMode::MinMax => "minmax",
        }
    }
}
