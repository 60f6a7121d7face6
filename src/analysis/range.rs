//! Which intensity range is mapped to `I_norm` 0..1: the paper's min/max (eq. 1), or a robust
//! range from percentiles that a handful of hot voxels cannot move.
//!
//! The robust rule (the f64 definition is `reference::robust::exact_robust_range`):
//! - `lo` = the 0.5th percentile of all finite voxels. The background (air, masked zeros) is
//!   the dark end of an MRI and stays inside the range, so the histogram analysis still sees the
//!   background mode it places its threshold after; a few cold outliers (negative spikes) are
//!   clamped to 0.
//! - `hi` = the 99.5th percentile of the foreground, the voxels at or above the background
//!   threshold `t = P2 + 0.1 (P98 - P2)` over all finite voxels (FSL BET's brain/background
//!   threshold, Smith 2002). Taking it over the foreground makes it independent of how much air
//!   the field of view holds; 0.5 % of the head is far more than "a handful" of hot voxels
//!   (fat, vessels, spikes) and far less than any tissue.
//! - The range ends `HEADROOM` (10 %) of its width above that percentile, even past the data's
//!   maximum: clamped voxels pile up in the top `I_norm` bin, and right at the percentile that
//!   pile sits against the brightest tissue and reads as a mode (on the MNI152 template, P99.5
//!   is 234 of 255, inside the WM mode's upper flank, and the pile was taken for WM). The
//!   headroom also keeps room for the pathology band above WM. Not capping it at the maximum
//!   keeps the range of a clean scan and of the same scan with hot voxels the same (MNI152:
//!   0..257.4 both; eq. 1 gives 0..255 and 0..8925).
//! - Where the rule gives no range (`hi <= lo`: a volume whose foreground is one value, e.g.
//!   two-valued masks), the finite min/max are used, as in eq. 1.
//!
//! Percentiles are read from fine histograms (`FINE_BINS` bins over a physical interval, plus
//! counts under and over it), refined: the first pass spans the finite min/max; when the robust
//! range covers fewer than `MIN_SPAN_BINS` of its bins (hot voxels far above the tissue squeeze
//! it), the next pass spans only the bins between the two percentiles, narrowed to the smallest
//! and largest value found inside the interval, up to `MAX_PASSES`. Inside
//! the final bin a percentile is interpolated as if the bin's voxels were spread evenly, so the
//! estimate is within one bin width of the exact value: at most 1/512 of the robust range.
//! The GPU (`passes::fine_histogram`) and the host (`reference::robust::fine_histogram`) feed
//! the same estimator ([`robust_step`]).

use crate::model::{LinearMap, Samples};
use crate::reference::fine_histogram::{FINE_BINS, RangeHistogram};
use crate::reference::normalize::half_difference;

/// How the physical intensity range mapped to `I_norm = 0..1` is chosen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum NormalizeMode {
    /// Percentiles of the finite voxels (see the module doc); values outside are clamped. The
    /// default: a handful of hot voxels leaves the rendering as it is on the clean scan.
    #[default]
    Robust,
    /// The paper's eq. 1: the finite minimum and maximum (the paper-literal preset).
    MinMax,
    /// The robust rule with the foreground's 99.99th percentile as the high end
    /// ([`PROJECTION_HIGH_PERCENTILE`]): what MIP and MinIP get in place of `Robust`
    /// ([`NormalizeMode::for_projection`]). A projection shows each ray's brightest voxel, so
    /// the brightest 0.5 % (a TOF angiogram's vessels) must stay graded instead of clipping
    /// to white (issue 32 item 5: 42 % of a TOF MIP's foreground pixels were saturated).
    RobustProjection,
}

impl NormalizeMode {
    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            NormalizeMode::Robust => "robust",
            NormalizeMode::MinMax => "minmax",
            NormalizeMode::RobustProjection => "robust (projection: P99.99)",
        }
    }

    /// The mode a scene of `projection` (MIP or MinIP) uses: `Robust` becomes
    /// `RobustProjection`; `MinMax` stays.
    pub fn for_projection(self, projection: bool) -> NormalizeMode {
        match self {
            NormalizeMode::Robust if projection => NormalizeMode::RobustProjection,
            other => other,
        }
    }

    /// The foreground percentile the high end is read at (robust modes).
    pub fn high_percentile(self) -> f64 {
        match self {
            NormalizeMode::RobustProjection => PROJECTION_HIGH_PERCENTILE,
            _ => HIGH_PERCENTILE,
        }
    }
}

/// Low end: this percentile of all finite voxels.
pub const LOW_PERCENTILE: f64 = 0.5;
/// High end: this percentile of the foreground voxels.
pub const HIGH_PERCENTILE: f64 = 99.5;
/// High end for MIP and MinIP ([`NormalizeMode::RobustProjection`]): still above a handful of
/// hot voxels (0.01 % of a 256^3 head's foreground is ~800 voxels), far above the bright 0.5 %.
pub const PROJECTION_HIGH_PERCENTILE: f64 = 99.99;
/// The range ends this fraction of its width above the high percentile (see the module doc).
pub const HEADROOM: f64 = 0.1;
/// Background threshold: `P_BACKGROUND_LOW + BACKGROUND_FRACTION (P_BACKGROUND_HIGH - ..)`.
pub const P_BACKGROUND_LOW: f64 = 2.0;
/// See [`P_BACKGROUND_LOW`].
pub const P_BACKGROUND_HIGH: f64 = 98.0;
/// See [`P_BACKGROUND_LOW`].
pub const BACKGROUND_FRACTION: f64 = 0.1;
/// A pass is final when the robust range covers at least this many of its bins.
pub const MIN_SPAN_BINS: usize = 512;
/// Most fine-histogram passes. Each pass narrows the interval to the bins between the two
/// percentiles and to the values actually inside them, so hot voxels far above the tissue (even
/// 1e30 over data at 1) resolve in three passes; the limit only bounds pathological data.
pub const MAX_PASSES: usize = 6;

/// The robust range and how it was found.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct RobustRange {
    /// Physical value mapped to `I_norm = 0`.
    pub lo: f64,
    /// Physical value mapped to `I_norm = 1`.
    pub hi: f64,
    /// Background threshold the foreground was taken above (physical).
    pub background: f64,
    /// The rule gave no range and the finite min/max were used.
    pub fell_back: bool,
    /// Fine-histogram passes it took.
    pub passes: usize,
}

/// The range a volume was normalized with, for reports: the mode, the data's finite min/max
/// (the paper's Imin/Imax) and, in robust mode, the robust range.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct RangeChoice {
    /// The mode asked for.
    pub mode: NormalizeMode,
    /// Smallest finite physical intensity (eq. 1's Imin); None without finite voxels.
    pub data_min: Option<f64>,
    /// Largest finite physical intensity (eq. 1's Imax).
    pub data_max: Option<f64>,
    /// The robust range (robust mode with finite voxels).
    pub robust: Option<RobustRange>,
}

/// What to do after a fine-histogram pass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RobustStep {
    /// The range is resolved.
    Done(RobustRange),
    /// Histogram `[lo, hi]` next.
    Refine {
        /// Low edge of the next pass.
        lo: f64,
        /// High edge of the next pass.
        hi: f64,
    },
}

/// Where the voxel of 1-based `rank` (in ascending order) lies: its bin (None when under or
/// over the range) and its value, interpolated inside the bin as if its voxels were evenly
/// spread.
fn at_rank(h: &RangeHistogram, rank: u64) -> (Option<usize>, f64) {
    if rank <= h.under {
        return (None, h.lo);
    }
    let mut below = h.under;
    for (i, &count) in h.bins.iter().enumerate() {
        if count > 0 && rank <= below + count {
            let within = ((rank - below) as f64 - 0.5) / count as f64;
            let (a, b) = (h.edge(i), h.edge(i + 1));
            return (Some(i), a + (b - a) * within);
        }
        below += count;
    }
    (None, h.hi)
}

/// Voxels at or above `t`, counting the part of `t`'s bin above it as evenly spread.
fn count_at_least(h: &RangeHistogram, t: f64) -> u64 {
    let mut count = h.over as f64;
    for (i, &c) in h.bins.iter().enumerate() {
        let (a, b) = (h.edge(i), h.edge(i + 1));
        if a >= t {
            count += c as f64;
        } else if b > t {
            count += c as f64 * (b - t) / (b - a);
        }
    }
    if t <= h.lo {
        count += h.under as f64;
    }
    count.round() as u64
}

/// 1-based rank of the `percent` percentile among `n` sorted values (the smallest value with at
/// least `percent` % of the values at or below it).
pub fn percentile_rank(n: u64, percent: f64) -> u64 {
    ((n as f64 * percent / 100.0).ceil() as u64).clamp(1, n.max(1))
}

/// The background threshold from the 2nd and 98th percentiles.
pub fn background_threshold(p_low: f64, p_high: f64) -> f64 {
    p_low + 2.0 * BACKGROUND_FRACTION * half_difference(p_high, p_low)
}

/// 1-based rank (among all `n` voxels) of the high percentile of the `foreground` top voxels.
pub fn high_rank(n: u64, foreground: u64) -> u64 {
    high_rank_at(n, foreground, HIGH_PERCENTILE)
}

/// [`high_rank`] at the `percent` percentile.
pub fn high_rank_at(n: u64, foreground: u64, percent: f64) -> u64 {
    let foreground = foreground.clamp(1, n.max(1));
    (n - foreground) + percentile_rank(foreground, percent)
}

/// One step of the estimator: the percentiles from pass `pass` (1-based) over `h`, either
/// final or the interval the next pass should cover. `data` is the finite min/max (the
/// fallback). `None` when `h` counts no voxel.
pub fn robust_step(h: &RangeHistogram, pass: usize, data: (f64, f64)) -> Option<RobustStep> {
    robust_step_at(h, pass, data, HIGH_PERCENTILE)
}

/// [`robust_step`] with the high end at the foreground's `high_percent` percentile.
pub fn robust_step_at(
    h: &RangeHistogram,
    pass: usize,
    data: (f64, f64),
    high_percent: f64,
) -> Option<RobustStep> {
    let n = h.total();
    if n == 0 {
        return None;
    }
    let value = |percent: f64| at_rank(h, percentile_rank(n, percent));
    let (lo_bin, lo) = value(LOW_PERCENTILE);
    let t = background_threshold(value(P_BACKGROUND_LOW).1, value(P_BACKGROUND_HIGH).1);
    let (hi_bin, hi) = at_rank(h, high_rank_at(n, count_at_least(h, t), high_percent));
    let resolved = match (lo_bin, hi_bin) {
        (Some(a), Some(b)) => b + 1 - a.min(b) >= MIN_SPAN_BINS,
        _ => true,
    };
    if resolved {
        return Some(RobustStep::Done(finish(lo, hi, t, data, pass)));
    }
    if pass >= MAX_PASSES {
        // Both ends still in one bin after every refinement: the foreground is (nearly) one
        // value, and interpolating inside that bin would invent a range.
        let hi = if lo_bin == hi_bin { lo } else { hi };
        return Some(RobustStep::Done(finish(lo, hi, t, data, pass)));
    }
    let (a, b) = (lo_bin.unwrap_or(0), hi_bin.unwrap_or(FINE_BINS - 1));
    let (mut next_lo, mut next_hi) = (h.edge(a), h.edge(b + 1));
    if let Some((least, most)) = h.inside {
        (next_lo, next_hi) = (next_lo.max(least), next_hi.min(most));
    }
    if next_hi.partial_cmp(&next_lo) != Some(std::cmp::Ordering::Greater) {
        // Every voxel between the two percentiles has one value: that value is both ends.
        return Some(RobustStep::Done(finish(next_lo, next_lo, t, data, pass)));
    }
    if next_lo == h.lo && next_hi == h.hi {
        return Some(RobustStep::Done(finish(lo, hi, t, data, pass)));
    }
    Some(RobustStep::Refine {
        lo: next_lo,
        hi: next_hi,
    })
}

/// The final range, or the min/max fallback when the percentiles give none.
pub fn finish(lo: f64, hi: f64, background: f64, data: (f64, f64), passes: usize) -> RobustRange {
    if hi > lo && lo.is_finite() && hi.is_finite() {
        let with_headroom = hi + 2.0 * HEADROOM * half_difference(hi, lo);
        RobustRange {
            lo,
            hi: if with_headroom.is_finite() {
                with_headroom
            } else {
                hi
            },
            background,
            fell_back: false,
            passes,
        }
    } else {
        RobustRange {
            lo: data.0,
            hi: data.1,
            background,
            fell_back: true,
            passes,
        }
    }
}

/// The robust range by its definition, from the sorted finite physical values (the f64 twin the
/// GPU's fine-histogram estimate is tested against; `passes` is 0). None without finite voxels.
pub fn exact_robust_range(samples: &Samples, to_physical: LinearMap) -> Option<RobustRange> {
    let mut values: Vec<f64> = (0..samples.len())
        .map(|i| samples.get(i))
        .filter(|s| s.is_finite())
        .map(|s| to_physical.apply(s))
        .filter(|p| !p.is_nan())
        .collect();
    values.sort_by(f64::total_cmp);
    let n = values.len() as u64;
    let at = |rank: u64| values[(rank - 1) as usize];
    let (first, last) = (*values.first()?, *values.last()?);
    let lo = at(percentile_rank(n, LOW_PERCENTILE));
    let t = background_threshold(
        at(percentile_rank(n, P_BACKGROUND_LOW)),
        at(percentile_rank(n, P_BACKGROUND_HIGH)),
    );
    let foreground = values.len() - values.partition_point(|&v| v < t);
    let hi = at(high_rank(n, foreground as u64));
    Some(finish(lo, hi, t, (first, last), 0))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn histogram(lo: f64, hi: f64, values: &[f64]) -> RangeHistogram {
        let mut h = RangeHistogram::empty(lo, hi);
        for &v in values {
            h.add(v);
        }
        h
    }

    #[test]
    fn ranks_follow_the_inverse_cdf() {
        assert_eq!(percentile_rank(1000, 0.5), 5);
        assert_eq!(percentile_rank(1000, 99.5), 995);
        assert_eq!(percentile_rank(3, 0.5), 1);
        assert_eq!(percentile_rank(3, 100.0), 3);
        assert_eq!(percentile_rank(0, 50.0), 1);
        assert_eq!(high_rank(1000, 200), 800 + 199);
    }

    #[test]
    fn hot_voxels_do_not_move_the_high_end_and_a_refinement_is_asked_for() {
        // 10 000 voxels 0..1000 and three at 40 000: the range squeezes into 51 of 2048 bins.
        let mut values: Vec<f64> = (0..10_000).map(|i| i as f64 / 10.0).collect();
        values.extend([40_000.0; 3]);
        let h = histogram(0.0, 40_000.0, &values);
        let Some(RobustStep::Refine { lo, hi }) = robust_step(&h, 1, (0.0, 40_000.0)) else {
            panic!("expected a refinement");
        };
        assert!(lo <= 5.0 && (995.0..1100.0).contains(&hi), "{lo}..{hi}");
        let h = histogram(lo, hi, &values);
        let Some(RobustStep::Done(r)) = robust_step(&h, 2, (0.0, 40_000.0)) else {
            panic!("expected a result");
        };
        // t = P2 + 0.1 (P98 - P2) = 20 + 0.1 * 960 = 116; 8840 foreground voxels up to 999.9.
        assert!((r.background - 115.9).abs() < 1.0, "{r:?}");
        assert!(
            // P99.5 of the foreground is 995.8; the range ends 10 % of 995.8 - 5 higher.
            (r.lo - 4.9).abs() < 0.6 && (r.hi - 1094.9).abs() < 0.7,
            "{r:?}"
        );
        assert!(!r.fell_back);
    }

    #[test]
    fn a_two_valued_volume_falls_back_to_its_min_and_max() {
        let mut values = vec![0.0; 9_990];
        values.extend([1000.0; 10]);
        let h = histogram(0.0, 1000.0, &values);
        let mut step = robust_step(&h, 1, (0.0, 1000.0));
        for pass in 2..=MAX_PASSES {
            match step {
                Some(RobustStep::Refine { lo, hi }) => {
                    step = robust_step(&histogram(lo, hi, &values), pass, (0.0, 1000.0))
                }
                _ => break,
            }
        }
        let Some(RobustStep::Done(r)) = step else {
            panic!("{step:?}");
        };
        assert!(r.fell_back && r.lo == 0.0 && r.hi == 1000.0, "{r:?}");
    }

    #[test]
    fn empty_histograms_give_nothing() {
        assert_eq!(robust_step(&histogram(0.0, 1.0, &[]), 1, (0.0, 1.0)), None);
    }

    #[test]
    fn the_exact_definition_agrees_with_the_worked_example() {
        let mut values: Vec<f32> = (0..10_000).map(|i| i as f32 / 10.0).collect();
        values.extend([40_000.0; 3]);
        values.push(f32::NAN);
        let r = exact_robust_range(&Samples::from_f32(&values), LinearMap::IDENTITY).unwrap();
        assert_eq!((r.lo as f32, r.hi as f32), (5.0, 1094.88));
        let two = Samples::from_f32(&[0.0, 0.0, 0.0, 7.0]);
        let r = exact_robust_range(&two, LinearMap::IDENTITY).unwrap();
        assert!(
            !r.fell_back && r.lo == 0.0 && (r.hi - 7.7).abs() < 1e-12,
            "{r:?}"
        );
        let constant = Samples::from_f32(&[3.0; 5]);
        let r = exact_robust_range(&constant, LinearMap::IDENTITY).unwrap();
        assert!(r.fell_back && (r.lo, r.hi) == (3.0, 3.0), "{r:?}");
        assert_eq!(
            exact_robust_range(&Samples::from_f32(&[f32::NAN]), LinearMap::IDENTITY),
            None
        );
    }
}
