//! The stored-to-physical intensity map of a scan (NIfTI's scl_slope / scl_inter, DICOM's
//! RescaleSlope / RescaleIntercept).

/// Maps stored sample values to physical intensities: `physical = stored * slope + intercept`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct LinearMap {
    /// Multiplier applied to a stored sample (never 0, never non-finite).
    pub slope: f64,
    /// Added after the multiplication.
    pub intercept: f64,
}

impl LinearMap {
    /// The identity map: stored samples are physical intensities.
    pub const IDENTITY: LinearMap = LinearMap {
        slope: 1.0,
        intercept: 0.0,
    };

    /// Physical intensity of one stored sample value.
    pub fn apply(&self, stored: f64) -> f64 {
        stored * self.slope + self.intercept
    }
}
