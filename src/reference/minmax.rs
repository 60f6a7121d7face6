//! Twin of the min/max reduction kernel: range of the stored values over finite samples.
//!
//! Decisions:
//! - The range is taken over STORED values (before `scl_slope`/`scl_inter`); the physical range is
//!   derived from it in f64 afterwards ([`super::normalize::physical_range`]), so the GPU never
//!   needs f64.
//! - Order is IEEE-754 totalOrder restricted to finite values (`f64::total_cmp`), so `-0.0 < +0.0`:
//!   a volume holding both zeros has min `-0.0` and max `+0.0`, bit for bit. This is exactly the
//!   order of the order-preserving integer keys a GPU reduction uses instead of float atomics
//!   (NUMERICS.md), so the twin and the kernel can be compared by bit pattern, subnormals included
//!   (integer keys never flush them).
//! - Every value a [`Samples`] can hold is exact in f64 (u8/i8/u16/i16/f32), so f64 loses nothing.
//! - Non-finite values exist only in [`SampleKind::F32`]; they are skipped and counted separately.

use crate::model::{SampleKind, Samples};
use std::cmp::Ordering;

/// Minimum and maximum stored value over the finite samples, or `None` when there is none
/// (empty volume, or every sample NaN/±inf). `-0.0` orders below `+0.0` (see the module doc).
pub fn finite_min_max(samples: &Samples) -> Option<(f64, f64)> {
    let mut range: Option<(f64, f64)> = None;
    for i in 0..samples.len() {
        let v = samples.get(i);
        if !v.is_finite() {
            continue;
        }
        range = Some(match range {
            None => (v, v),
            Some((lo, hi)) => (
                if v.total_cmp(&lo) == Ordering::Less {
                    v
                } else {
                    lo
                },
                if v.total_cmp(&hi) == Ordering::Greater {
                    v
                } else {
                    hi
                },
            ),
        });
    }
    range
}

/// Number of NaN or ±infinite samples (always 0 for integer kinds).
pub fn nonfinite_count(samples: &Samples) -> usize {
    match samples.kind() {
        SampleKind::F32 => (0..samples.len())
            .filter(|&i| !samples.get(i).is_finite())
            .count(),
        SampleKind::U8 | SampleKind::I8 | SampleKind::U16 | SampleKind::I16 => 0,
    }
}
