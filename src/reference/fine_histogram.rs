//! Twin of the fine-histogram kernel (shaders/fine_histogram.comp): counts of the finite
//! voxels' physical values in `FINE_BINS` equal bins over `[lo, hi]`, and outside it.
//!
//! Decisions:
//! - f64: the bin of `x = (phys - lo) / (hi - lo)` is `min(floor(x * FINE_BINS), FINE_BINS - 1)`
//!   (so `hi` itself lands in the last bin, like the 256-bin histogram), `x < 0` counts as
//!   under and `x > 1` as over. The kernel computes `x` in f32 through the normalization's
//!   pre-scale and offset, so a value within an f32 rounding of a bin edge may land in the
//!   neighbouring bin there; consumers of the counts (the robust-range estimator) are exact to
//!   one bin width either way.
//! - The smallest and largest value inside the interval are kept too: the robust-range
//!   estimator shrinks its next interval to them.
//! - Non-finite samples are not counted; a sample whose `stored * slope` overflows to +-inf is
//!   (it is over or under the range).
//! - Ranges near the f64 limit are handled through half differences (no `hi - lo` overflow).

use super::normalize::half_difference;
use crate::model::{LinearMap, Samples};

/// Bins of one fine-histogram pass (2048 u32 + 2 fit 8 KiB of shared memory on the GPU).
pub const FINE_BINS: usize = 2048;

/// Counts of finite voxels' physical values in `FINE_BINS` equal bins over `[lo, hi]` (the
/// last bin includes `hi`), and outside it.
#[derive(Clone, Debug, PartialEq)]
pub struct RangeHistogram {
    /// Physical value at the low edge of bin 0.
    pub lo: f64,
    /// Physical value at the high edge of the last bin.
    pub hi: f64,
    /// Voxels per bin (`FINE_BINS` of them).
    pub bins: Vec<u64>,
    /// Voxels below `lo`.
    pub under: u64,
    /// Voxels above `hi`.
    pub over: u64,
    /// The smallest and largest value inside `[lo, hi]` (None when no voxel is inside).
    pub inside: Option<(f64, f64)>,
}

impl RangeHistogram {
    /// An empty histogram over `[lo, hi]`.
    pub fn empty(lo: f64, hi: f64) -> Self {
        RangeHistogram {
            lo,
            hi,
            bins: vec![0; FINE_BINS],
            under: 0,
            over: 0,
            inside: None,
        }
    }

    /// Every voxel counted, inside the range or not.
    pub fn total(&self) -> u64 {
        self.under + self.over + self.bins.iter().sum::<u64>()
    }

    /// Low edge of bin `i` (`bins.len()` = the high edge of the range); no overflow for ranges
    /// near the f64 limit.
    pub fn edge(&self, i: usize) -> f64 {
        if i >= self.bins.len() {
            return self.hi;
        }
        self.lo + half_difference(self.hi, self.lo) * (i as f64 / (self.bins.len() as f64 / 2.0))
    }

    /// Counts one physical value.
    pub fn add(&mut self, phys: f64) {
        let half = half_difference(self.hi, self.lo);
        let x = half_difference(phys, self.lo) / half;
        if x.is_nan() {
            return;
        }
        if x < 0.0 {
            self.under += 1;
        } else if x > 1.0 {
            self.over += 1;
        } else {
            let n = self.bins.len();
            let bin = ((x * n as f64) as usize).min(n - 1);
            self.bins[bin] += 1;
            self.inside = Some(match self.inside {
                Some((a, b)) => (a.min(phys), b.max(phys)),
                None => (phys, phys),
            });
        }
    }
}

/// The histogram of the finite samples' physical values over `[lo, hi]` (`lo < hi`).
pub fn fine_histogram(
    samples: &Samples,
    to_physical: LinearMap,
    lo: f64,
    hi: f64,
) -> RangeHistogram {
    let mut h = RangeHistogram::empty(lo, hi);
    for i in 0..samples.len() {
        let stored = samples.get(i);
        if stored.is_finite() {
            h.add(to_physical.apply(stored));
        }
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_land_in_their_bins_and_the_ends_are_inclusive() {
        let samples = Samples::from_f32(&[0.0, 1.0, 0.5, -0.1, 1.1, f32::NAN, f32::INFINITY]);
        let h = fine_histogram(&samples, LinearMap::IDENTITY, 0.0, 1.0);
        assert_eq!(h.bins[0], 1);
        assert_eq!(h.bins[FINE_BINS - 1], 1);
        assert_eq!(h.bins[FINE_BINS / 2], 1);
        assert_eq!((h.under, h.over, h.total()), (1, 1, 5));
    }

    #[test]
    fn ranges_near_the_f64_limit_do_not_overflow() {
        let mut h = RangeHistogram::empty(-1.7e308, 1.7e308);
        h.add(0.0);
        h.add(1.7e308);
        assert_eq!(h.bins[FINE_BINS / 2], 1);
        assert_eq!(h.bins[FINE_BINS - 1], 1);
        assert!(h.edge(FINE_BINS / 2).abs() < 1e300);
    }
}
