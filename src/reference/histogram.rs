//! Twin of the histogram kernel: 256 bins of `I_norm` over the finite voxels.
//!
//! Decisions:
//! - This twin is deliberately **f32**, not f64: the bin of a value is computed exactly as the
//!   kernel does, `min(u32(clamp(v, 0, 1) * 256.0), 255)` in f32, so given the same f32 inputs
//!   the twin is bit-exact with the GPU. Multiplying by 256 is exact in binary floating point
//!   (barring overflow, impossible after the clamp), so the bin is exactly `floor(256 v)`.
//! - Clamp before the float-to-int conversion (NUMERICS.md: converting NaN, negative or too-large
//!   floats to uint is undefined on the GPU), and `min(.., 255)` puts exactly 1.0 in the last bin.
//! - Non-finite voxels are excluded through a caller-supplied predicate on the voxel index (they
//!   normalize to 0.0 and would otherwise inflate bin 0), so the bins sum to the finite count.
//! - Counts wrap on u32 overflow, like the kernel's `atomicAdd` (more than 2^32 voxels in one bin
//!   cannot occur for volumes that fit a 3D image).

use super::normalize::normalize_value;
use crate::model::{LinearMap, Samples};

/// Number of histogram bins.
pub const BINS: usize = 256;

/// Bin of one normalized value, computed in f32 exactly like the kernel. NaN lands in bin 0
/// (Rust's saturating cast), but NaN voxels are never binned: see [`histogram`].
pub fn bin_of(v: f32) -> usize {
    let scaled = v.clamp(0.0, 1.0) * BINS as f32;
    (scaled as u32).min(BINS as u32 - 1) as usize
}

/// Histogram of `norm[i]` over the indices for which `is_finite(i)` holds.
///
/// `is_finite` reports whether the ORIGINAL sample was finite (the normalized value of a
/// non-finite sample is 0.0 and must not be counted).
pub fn histogram(norm: &[f32], is_finite: impl Fn(usize) -> bool) -> [u32; BINS] {
    let mut bins = [0u32; BINS];
    for (i, &v) in norm.iter().enumerate() {
        if is_finite(i) {
            let b = bin_of(v);
            bins[b] = bins[b].wrapping_add(1);
        }
    }
    bins
}

/// The whole CPU path from stored samples to the histogram: eq. 1 in f64 ([`normalize_value`]),
/// rounded to f32 (what the GPU stores when the normalized volume is f32), then [`histogram`].
///
/// Used to build the analysis input on the CPU (for tests, fixtures and volumes the GPU never
/// sees); a GPU that stores `I_norm` at lower precision (R16_UNORM) can land a value on the other
/// side of a bin edge, so compare GPU histograms against [`histogram`] of the GPU's own values.
pub fn histogram_of_samples(
    samples: &Samples,
    to_physical: LinearMap,
    imin: f64,
    imax: f64,
) -> [u32; BINS] {
    let mut bins = [0u32; BINS];
    for i in 0..samples.len() {
        let stored = samples.get(i);
        if stored.is_finite() {
            let v = normalize_value(to_physical.apply(stored), imin, imax) as f32;
            let b = bin_of(v);
            bins[b] = bins[b].wrapping_add(1);
        }
    }
    bins
}
