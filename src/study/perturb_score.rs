//! Truth ranges and scoring of the perturbation study (issue 11, item 2): is each detected
//! tissue peak inside the bulk of that tissue's intensities?
//!
//! Decisions:
//! - Truth per tissue = the 10th to 90th percentile of the PHYSICAL intensity (after
//!   scl_slope/intercept) of the finite voxels labelled with it, percentiles linearly
//!   interpolated between order statistics (numpy's default), so the numbers can be checked with
//!   one line of numpy.
//! - A missing peak (`None`) or a missing truth (no voxel of that class) is a miss, never a hit.
//! - Targets (the issue's): GM and WM inside on every volume, CSF on all but at most one.

use super::perturb::{Label, Perturbed, physical};

/// The three tissues, in table order.
pub const TISSUES: [Label; 3] = [Label::Csf, Label::Gm, Label::Wm];

/// A tissue's truth: the 10th-90th percentile of its physical intensities.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Truth {
    /// 10th percentile.
    pub p10: f64,
    /// 90th percentile.
    pub p90: f64,
    /// Voxels of the class that were counted.
    pub voxels: usize,
}

impl Truth {
    /// Whether `value` lies in `[p10, p90]`.
    pub fn contains(&self, value: f64) -> bool {
        (self.p10..=self.p90).contains(&value)
    }
}

/// Truths of CSF, GM and WM (`None` where a class has no finite voxel).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Truths {
    /// Cerebrospinal fluid.
    pub csf: Option<Truth>,
    /// Grey matter.
    pub gm: Option<Truth>,
    /// White matter.
    pub wm: Option<Truth>,
}

/// Percentile `q` (0..=1) of sorted `values`, linear between order statistics.
pub fn percentile(sorted: &[f64], q: f64) -> Option<f64> {
    let last = sorted.len().checked_sub(1)?;
    let at = last as f64 * q.clamp(0.0, 1.0);
    let (lo, hi) = (at.floor() as usize, (at.ceil() as usize).min(last));
    let t = at - lo as f64;
    Some(sorted[lo] + t * (sorted[hi] - sorted[lo]))
}

/// The truth of one class from physical `values` and `labels` (same length; extra entries of
/// the longer one are ignored).
pub fn truth_of(values: &[f64], labels: &[Label], class: Label) -> Option<Truth> {
    let mut inside: Vec<f64> = values
        .iter()
        .zip(labels)
        .filter(|(v, l)| **l == class && v.is_finite())
        .map(|(v, _)| *v)
        .collect();
    inside.sort_unstable_by(f64::total_cmp);
    Some(Truth {
        p10: percentile(&inside, 0.1)?,
        p90: percentile(&inside, 0.9)?,
        voxels: inside.len(),
    })
}

/// The truths of a perturbed volume, from what it stores.
pub fn truths(perturbed: &Perturbed) -> Truths {
    let values = physical(&perturbed.volume);
    let of = |class| truth_of(&values, &perturbed.labels, class);
    Truths {
        csf: of(Label::Csf),
        gm: of(Label::Gm),
        wm: of(Label::Wm),
    }
}

/// One tissue's result.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct TissueScore {
    /// Detected peak in physical units (`None`: not found).
    pub peak: Option<f64>,
    /// Its truth.
    pub truth: Option<Truth>,
    /// Peak found and inside the truth.
    pub inside: bool,
}

/// The three tissues' results for one volume.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Score {
    /// Cerebrospinal fluid.
    pub csf: TissueScore,
    /// Grey matter.
    pub gm: TissueScore,
    /// White matter.
    pub wm: TissueScore,
}

/// Scores detected peaks (physical units; CSF, GM, WM) against the truths.
pub fn score(peaks: [Option<f64>; 3], truths: &Truths) -> Score {
    let one = |peak: Option<f64>, truth: Option<Truth>| TissueScore {
        peak,
        truth,
        inside: peak.zip(truth).is_some_and(|(p, t)| t.contains(p)),
    };
    Score {
        csf: one(peaks[0], truths.csf),
        gm: one(peaks[1], truths.gm),
        wm: one(peaks[2], truths.wm),
    }
}

/// How many volumes had each tissue inside, and whether the issue's target holds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Totals {
    /// Volumes scored.
    pub volumes: usize,
    /// Volumes with CSF inside.
    pub csf: usize,
    /// Volumes with GM inside.
    pub gm: usize,
    /// Volumes with WM inside.
    pub wm: usize,
}

impl Totals {
    /// Totals over `scores`.
    pub fn of(scores: &[Score]) -> Totals {
        let count = |f: fn(&Score) -> bool| scores.iter().filter(|s| f(s)).count();
        Totals {
            volumes: scores.len(),
            csf: count(|s| s.csf.inside),
            gm: count(|s| s.gm.inside),
            wm: count(|s| s.wm.inside),
        }
    }

    /// The issue's target: GM and WM inside on every volume, CSF on all but at most one.
    pub fn target_met(&self) -> bool {
        self.gm == self.volumes && self.wm == self.volumes && self.csf + 1 >= self.volumes
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_interpolate_like_numpy() {
        let v: Vec<f64> = (1..=11).map(f64::from).collect();
        assert_eq!(percentile(&v, 0.1), Some(2.0));
        assert_eq!(percentile(&v, 0.9), Some(10.0));
        // numpy.percentile([1, 2, 3, 4], 10) = 1.3
        assert!((percentile(&[1.0, 2.0, 3.0, 4.0], 0.1).unwrap() - 1.3).abs() < 1e-12);
        assert_eq!(percentile(&[], 0.5), None);
        assert_eq!(percentile(&[7.0], 0.9), Some(7.0));
    }

    #[test]
    fn truths_use_only_the_class_and_finite_voxels() {
        let values = [1.0, 2.0, f64::NAN, 100.0, 5.0];
        let labels = [Label::Gm, Label::Gm, Label::Gm, Label::Wm, Label::Gm];
        let t = truth_of(&values, &labels, Label::Gm).unwrap();
        assert_eq!(t.voxels, 3);
        assert!(
            (t.p10 - 1.2).abs() < 1e-12 && (t.p90 - 4.4).abs() < 1e-12,
            "{t:?}"
        );
        assert!(truth_of(&values, &labels, Label::Csf).is_none());
    }

    #[test]
    fn missing_peaks_and_truths_are_misses_and_the_target_allows_one_csf_miss() {
        let t = Truth {
            p10: 10.0,
            p90: 20.0,
            voxels: 5,
        };
        let truths = Truths {
            csf: Some(t),
            gm: Some(t),
            wm: None,
        };
        let s = score([Some(10.0), None, Some(15.0)], &truths);
        assert!(s.csf.inside && !s.gm.inside && !s.wm.inside);
        let all = Truths {
            csf: Some(t),
            gm: Some(t),
            wm: Some(t),
        };
        let good = score([Some(15.0); 3], &all);
        let csf_miss = score([Some(25.0), Some(15.0), Some(15.0)], &all);
        assert!(Totals::of(&[good, good, csf_miss]).target_met());
        assert!(!Totals::of(&[good, csf_miss, csf_miss]).target_met());
        assert!(!Totals::of(&[good, s]).target_met());
    }
}
