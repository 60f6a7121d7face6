//! Twin of the normalization kernel: the paper's eq. 1, `I_norm = (I - Imin) / (Imax - Imin)`.
//!
//! Decisions (NUMERICS.md):
//! - Everything is f64: `phys = stored * slope + intercept`, then `(phys - imin) / (imax - imin)`.
//!   The GPU gets a scale and bias computed the same way on the CPU, so ranges such as ±3e38 or
//!   `1e30 + tiny` never overflow or flush.
//! - The result is clamped to `[0, 1]` with a NaN-safe clamp (NaN and `-0.0` map to
//!   `+0.0`), so every output is a finite number in `[0, 1]`.
//! - Non-finite samples normalize to `0.0`; they are excluded from the histogram by the caller's
//!   finite mask and render transparent.
//! - Constant-volume policy: when `imax - imin` is not a number greater than zero (constant
//!   volume, swapped or non-finite bounds), every voxel normalizes to `0.0` (a black image and the
//!   histogram `[N, 0, ..]`) instead of `0/0 = NaN`.
//! - Ranges near the f64 limit (float64 data at +-1.7e308) would overflow `imax - imin` to
//!   infinity, so the ratio is taken between halves: `(phys/2 - imin/2) / (imax/2 - imin/2)`.
//!   Halving is exact for normal numbers, and the difference of two halves of finite numbers is
//!   finite.

use crate::model::{LinearMap, Samples};

/// Physical `(imin, imax)` from the stored finite range and the stored-to-physical map.
///
/// A negative slope reverses the order, so the two ends are swapped; the result always has
/// `imin <= imax` when the inputs are finite.
pub fn physical_range(stored_min: f64, stored_max: f64, to_physical: LinearMap) -> (f64, f64) {
    let a = to_physical.apply(stored_min);
    let b = to_physical.apply(stored_max);
    if a <= b { (a, b) } else { (b, a) }
}

/// Normalized intensity of one physical value (the per-voxel body of [`normalize`]).
///
/// Returns `0.0` for a NaN `phys` or an unusable range (see the module doc); a `phys` of ±inf
/// (a finite sample whose `stored * slope` overflowed) clamps like any other value.
pub fn normalize_value(phys: f64, imin: f64, imax: f64) -> f64 {
    let half_range = half_difference(imax, imin);
    if phys.is_nan() || !half_range.is_finite() || half_range <= 0.0 {
        return 0.0;
    }
    let x = half_difference(phys, imin) / half_range;
    // NaN and -0.0 both become +0.0 here.
    if x.is_nan() || x <= 0.0 {
        0.0
    } else if x >= 1.0 {
        1.0
    } else {
        x
    }
}

/// `(a - b) / 2` without overflow for any finite `a`, `b` (infinite when either is).
pub fn half_difference(a: f64, b: f64) -> f64 {
    a / 2.0 - b / 2.0
}

/// Normalizes every sample: `clamp((stored * slope + intercept - imin) / (imax - imin), 0, 1)`,
/// with non-finite samples and unusable ranges mapped to `0.0`.
pub fn normalize(samples: &Samples, to_physical: LinearMap, imin: f64, imax: f64) -> Vec<f64> {
    (0..samples.len())
        .map(|i| {
            let stored = samples.get(i);
            if stored.is_finite() {
                normalize_value(to_physical.apply(stored), imin, imax)
            } else {
                0.0
            }
        })
        .collect()
}
