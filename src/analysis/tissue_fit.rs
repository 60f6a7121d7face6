//! Tissue classes by fitting (issue 28, item 2): the mixture of `reference::tissue_fit` (three
//! pure classes, two partial-volume mixtures, a uniform tail) fitted by EM in f32 to the
//! histogram inside the brain (the brain-extraction mask) or, without a mask, to the
//! foreground (the bins above the background threshold).
//!
//! Decisions:
//! - f32 arithmetic here (the E-step's exponentials are most of the cost); the f64 twin in
//!   `reference::tissue_fit` is the specification, and tests hold the two together.
//! - Which fitted class is which tissue follows the contrast: T1 CSF < GM < WM; T2 and PD
//!   WM < GM < CSF; FLAIR and CT CSF < WM < GM (CSF darkest, GM above WM).
//! - EM starts from the histogram's quantiles at the middles of typical brain fractions
//!   (CSF 15 %, GM 45 %, WM 40 %) taken in the contrast's intensity order, so the start already
//!   knows which class is small; it does not depend on the mode hunter. When that fit is not
//!   sound, a second start at the quantiles 1/6, 1/2, 5/6 runs, and the higher likelihood wins
//!   (EM finds local optima).
//! - A fit is used for the windows only when it is sound ([`Fit::sound`]): finite, the pure
//!   means ascending at least [`MIN_SEPARATION_BINS`] and [`MIN_SEPARATION_SDS`] SDs apart
//!   ([`BRAIN_MIN_SEPARATION_SDS`] inside a brain mask when the fit is close), each pure class holding at least
//!   [`MIN_WEIGHT`], and goodness at least [`MIN_GOODNESS`]. Otherwise the mode hunter's
//!   windows stay, and the report says which path decided.

use super::contrast::Contrast;
use crate::reference::BINS;
use crate::reference::tissue_fit::{
    CLASSES, FitStart, MAX_ITERATIONS, MAX_TAIL_WEIGHT, MIN_SD_BINS, Mixture, PURE, TOLERANCE,
};

/// Least distance between two fitted pure means for a sound fit, in bins.
pub const MIN_SEPARATION_BINS: f64 = 3.0;
/// Least distance between two neighbouring fitted means, in units of the larger of their SDs:
/// two equal Gaussians closer than 2 SDs make one mode, so three classes fitted to one broad
/// mode (a histogram with no tissue contrast) are no classes.
pub const MIN_SEPARATION_SDS: f64 = 2.0;
/// The same inside a brain mask with a close fit ([`BRAIN_MIN_GOODNESS`]): there the histogram
/// holds only brain, so classes that overlap (T2's GM and WM: T2w's fit inside its mask had GM
/// and WM 1.2 SDs apart, goodness 0.952, weights 0.30 / 0.44; `morphray peaks T2w.nii.gz`, this
/// machine) are tissues, not one mode split.
pub const BRAIN_MIN_SEPARATION_SDS: f64 = 1.0;
/// Least goodness for [`BRAIN_MIN_SEPARATION_SDS`] to apply.
pub const BRAIN_MIN_GOODNESS: f64 = 0.9;
/// Least weight of a pure class for a sound fit.
pub const MIN_WEIGHT: f64 = 0.03;
/// Least goodness of fit (`1 - TV`) for a sound fit.
pub const MIN_GOODNESS: f64 = 0.6;

/// Which voxels the fitted histogram counted.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FitDomain {
    /// Inside the brain-extraction mask.
    BrainMask,
    /// Above the background threshold (no mask).
    Foreground,
}

impl FitDomain {
    /// Words for reports.
    pub fn words(self) -> &'static str {
        match self {
            FitDomain::BrainMask => "inside the brain mask",
            FitDomain::Foreground => "over the foreground (no brain mask)",
        }
    }
}

/// One fitted tissue class.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct FittedClass {
    /// Mean (I_norm).
    pub mean: f64,
    /// Standard deviation (I_norm).
    pub sd: f64,
    /// Share of the fitted voxels.
    pub weight: f64,
    /// Mean in the volume's physical units.
    pub mean_raw: f64,
    /// Standard deviation in physical units.
    pub sd_raw: f64,
}

/// The fit as reported.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Fit {
    /// Where the histogram came from.
    pub domain: FitDomain,
    /// Contrast the classes were labelled for.
    pub contrast: Contrast,
    /// Cerebrospinal fluid.
    pub csf: FittedClass,
    /// Grey matter.
    pub gm: FittedClass,
    /// White matter.
    pub wm: FittedClass,
    /// Weights of the two partial-volume classes (darker pair, brighter pair).
    pub partial_volume_weights: [f64; 2],
    /// Weight of the uniform tail class.
    pub tail_weight: f64,
    /// `1 - TV` between histogram and model.
    pub goodness: f64,
    /// Log-likelihood per voxel.
    pub log_likelihood: f64,
    /// EM iterations.
    pub iterations: usize,
    /// Voxels fitted.
    pub voxels: f64,
    /// Fitted bin range `[first, last)`.
    pub bins: [usize; 2],
    /// Whether the windows come from this fit ([`Fit::sound`]).
    pub sound: bool,
    /// Host time of the fit, ms.
    pub fit_ms: f64,
}

/// Tissue index (0 CSF, 1 GM, 2 WM) of each ascending pure class under `contrast`.
pub fn tissue_order(contrast: Contrast) -> [usize; PURE] {
    match contrast {
        Contrast::T1 => [0, 1, 2],
        Contrast::T2 | Contrast::Pd => [2, 1, 0],
        Contrast::Flair | Contrast::Ct => [0, 2, 1],
    }
}

/// Typical share of each tissue (CSF, GM, WM) inside a brain mask.
const TYPICAL_SHARE: [f64; 3] = [0.15, 0.45, 0.40];

/// EM's start for `hist` on `[first, last)` under `contrast` (module doc); None when the range
/// holds no voxel.
pub fn start_for(
    hist: &[f64; BINS],
    first: usize,
    last: usize,
    contrast: Contrast,
) -> Option<FitStart> {
    let order = tissue_order(contrast);
    let mut targets = [0.0; PURE];
    let mut below = 0.0;
    for (k, &tissue) in order.iter().enumerate() {
        targets[k] = below + 0.5 * TYPICAL_SHARE[tissue];
        below += TYPICAL_SHARE[tissue];
    }
    start_at(hist, first, last, targets)
}

/// EM's start at the histogram's quantiles `targets` (ascending) on `[first, last)`.
pub fn start_at(
    hist: &[f64; BINS],
    first: usize,
    last: usize,
    targets: [f64; PURE],
) -> Option<FitStart> {
    let (first, last) = (first.min(BINS), last.min(BINS));
    let total: f64 = hist.get(first..last)?.iter().sum();
    if total <= 0.0 {
        return None;
    }
    let n = BINS as f64;
    let quantile = |q: f64| {
        let mut acc = 0.0;
        for (b, &c) in hist.iter().enumerate().take(last).skip(first) {
            acc += c;
            if acc >= q * total {
                return (b as f64 + 0.5) / n;
            }
        }
        (last as f64 - 0.5) / n
    };
    let mut means = targets.map(quantile);
    // Distinct starts: a histogram with few occupied bins would give equal quantiles.
    for k in 1..PURE {
        means[k] = means[k].max(means[k - 1] + 1.0 / n);
    }
    let spread = ((last - first) as f64 / n / 12.0).max(MIN_SD_BINS / n);
    Some(FitStart {
        first,
        last,
        means,
        sds: [spread; PURE],
    })
}

/// EM in f32 (the algorithm of `reference::tissue_fit::fit`). None when the range is empty.
pub fn fit_f32(hist: &[f64; BINS], start: &FitStart) -> Option<Mixture> {
    let (first, last) = (start.first.min(BINS), start.last.min(BINS));
    if last <= first {
        return None;
    }
    let counts: Vec<(f32, f32)> = (first..last)
        .filter(|&b| hist[b] > 0.0)
        .map(|b| (hist[b] as f32, (b as f32 + 0.5) / BINS as f32))
        .collect();
    let voxels: f32 = counts.iter().map(|c| c.0).sum();
    if voxels <= 0.0 {
        return None;
    }
    let n = BINS as f32;
    let uniform = n / (last - first) as f32;
    let min_sd = MIN_SD_BINS as f32 / n;
    let mut means = start.means.map(|m| m as f32);
    let mut sds = start.sds.map(|s| (s as f32).max(min_sd));
    let mut weights = [0.3f32, 0.3, 0.3, 0.04, 0.04, 0.02];
    let (mut previous, mut ll_per_voxel, mut iterations) = (f32::NEG_INFINITY, 0.0f32, 0);
    let inv_sqrt_2pi = 1.0 / (2.0 * std::f32::consts::PI).sqrt();
    while iterations < MAX_ITERATIONS {
        iterations += 1;
        // Per class: mean, -1/(2 sd^2), weight / (sd sqrt(2 pi)).
        let mut coef = [(0.0f32, 0.0f32, 0.0f32); CLASSES - 1];
        for (c, slot) in coef.iter_mut().enumerate() {
            let (m, s) = moments32(&means, &sds, c);
            *slot = (m, -0.5 / (s * s), weights[c] * inv_sqrt_2pi / s);
        }
        let tail = weights[CLASSES - 1] * uniform;
        let mut resp = [0.0f32; CLASSES];
        let (mut xs, mut xxs) = ([0.0f32; PURE], [0.0f32; PURE]);
        let mut ll = 0.0f64;
        for &(count, x) in &counts {
            let mut p = [0.0f32; CLASSES];
            for (c, &(m, k, a)) in coef.iter().enumerate() {
                let d = x - m;
                let e = k * d * d;
                // e^-30 = 1e-13 of the class's peak (7.7 SDs away): nothing to add.
                p[c] = if e > -30.0 { a * e.exp() } else { 0.0 };
            }
            p[CLASSES - 1] = tail;
            let total: f32 = p.iter().sum();
            if total <= 0.0 || !total.is_finite() {
                continue;
            }
            ll += f64::from(count) * f64::from((total / n).ln());
            let scale = count / total;
            for c in 0..CLASSES {
                resp[c] += p[c] * scale;
            }
            for k in 0..PURE {
                let r = p[k] * scale;
                xs[k] += r * x;
                xxs[k] += r * x * x;
            }
        }
        ll_per_voxel = (ll / f64::from(voxels)) as f32;
        let resp_total: f32 = resp.iter().sum();
        if resp_total <= 0.0 {
            return None;
        }
        for c in 0..CLASSES {
            weights[c] = resp[c] / resp_total;
        }
        let tail = weights[CLASSES - 1];
        let cap = MAX_TAIL_WEIGHT as f32;
        if tail > cap && tail < 1.0 {
            let scale = (1.0 - cap) / (1.0 - tail);
            for w in &mut weights[..CLASSES - 1] {
                *w *= scale;
            }
            weights[CLASSES - 1] = cap;
        }
        for k in 0..PURE {
            if resp[k] > 0.0 {
                let m = xs[k] / resp[k];
                means[k] = m;
                sds[k] = (xxs[k] / resp[k] - m * m).max(0.0).sqrt().max(min_sd);
            }
        }
        if (ll_per_voxel - previous).abs() < TOLERANCE as f32 {
            break;
        }
        previous = ll_per_voxel;
    }
    let means = means.map(f64::from);
    let sds = sds.map(f64::from);
    let weights = weights.map(f64::from);
    let goodness =
        crate::reference::tissue_fit::goodness(hist, first, last, &means, &sds, &weights);
    Some(Mixture {
        means,
        sds,
        weights,
        goodness,
        log_likelihood: f64::from(ll_per_voxel),
        iterations,
        voxels: f64::from(voxels),
    })
}

fn moments32(means: &[f32; PURE], sds: &[f32; PURE], c: usize) -> (f32, f32) {
    if c < PURE {
        return (means[c], sds[c]);
    }
    let (a, b) = (c - PURE, c - PURE + 1);
    let d = means[b] - means[a];
    let var = 0.5 * (sds[a] * sds[a] + sds[b] * sds[b]) + d * d / 12.0;
    (0.5 * (means[a] + means[b]), var.sqrt())
}

/// Whether a mixture fitted over `domain` is sound enough for windows (module doc).
pub fn is_sound(m: &Mixture, domain: FitDomain) -> bool {
    let sep = MIN_SEPARATION_BINS / BINS as f64;
    let sds = if domain == FitDomain::BrainMask && m.goodness >= BRAIN_MIN_GOODNESS {
        BRAIN_MIN_SEPARATION_SDS
    } else {
        MIN_SEPARATION_SDS
    };
    let finite = m.means.iter().chain(&m.sds).all(|v| v.is_finite());
    finite
        && (1..PURE).all(|k| {
            let gap = m.means[k] - m.means[k - 1];
            gap >= sep && gap >= sds * m.sds[k].max(m.sds[k - 1])
        })
        && m.weights[..PURE].iter().all(|&w| w >= MIN_WEIGHT)
        && m.goodness >= MIN_GOODNESS
}

/// Fits `hist` on `[first, last)` for `contrast` and labels the classes; `imin`/`imax` map
/// I_norm to physical units. None when there is nothing to fit.
pub fn fit_tissues(
    hist: &[f64; BINS],
    (first, last): (usize, usize),
    contrast: Contrast,
    domain: FitDomain,
    (imin, imax): (f64, f64),
) -> Option<(Fit, Mixture)> {
    let started = std::time::Instant::now();
    // Two starts, the better likelihood wins: the contrast's typical shares, and equal thirds
    // (a brain whose shares are far from typical: atrophy, a partial field of view).
    let start = start_for(hist, first, last, contrast)?;
    let mut m = fit_f32(hist, &start)?;
    if !is_sound(&m, domain) {
        let thirds = start_at(hist, first, last, [1.0 / 6.0, 0.5, 5.0 / 6.0])?;
        if let Some(other) = fit_f32(hist, &thirds)
            && other.log_likelihood > m.log_likelihood + 1e-6
        {
            m = other;
        }
    }
    // EM keeps the order of its start almost always; sort so labels follow intensity.
    let mut idx = [0usize, 1, 2];
    idx.sort_by(|&a, &b| m.means[a].total_cmp(&m.means[b]));
    m.means = idx.map(|i| m.means[i]);
    m.sds = idx.map(|i| m.sds[i]);
    let pure_w = idx.map(|i| m.weights[i]);
    m.weights[..PURE].copy_from_slice(&pure_w);
    let span = imax - imin;
    let order = tissue_order(contrast);
    let class = |tissue: usize| {
        let k = order.iter().position(|&t| t == tissue).unwrap_or(tissue);
        FittedClass {
            mean: m.means[k],
            sd: m.sds[k],
            weight: m.weights[k],
            mean_raw: imin + m.means[k] * span,
            sd_raw: m.sds[k] * span,
        }
    };
    let fit = Fit {
        domain,
        contrast,
        csf: class(0),
        gm: class(1),
        wm: class(2),
        partial_volume_weights: [m.weights[PURE], m.weights[PURE + 1]],
        tail_weight: m.weights[CLASSES - 1],
        goodness: m.goodness,
        log_likelihood: m.log_likelihood,
        iterations: m.iterations,
        voxels: m.voxels,
        bins: [start.first, start.last],
        sound: is_sound(&m, domain),
        fit_ms: started.elapsed().as_secs_f64() * 1e3,
    };
    Some((fit, m))
}

/// The occupied bin range `[first, last)` of `hist` from `from` on.
pub fn occupied_range(hist: &[f64; BINS], from: usize) -> (usize, usize) {
    let first = (from..BINS).find(|&b| hist[b] > 0.0).unwrap_or(BINS);
    let last = (first..BINS)
        .rev()
        .find(|&b| hist[b] > 0.0)
        .map_or(first, |b| b + 1);
    (first, last)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::tissue_fit::fit;

    fn three_classes(means: [f64; 3], sds: [f64; 3], w: [f64; 3]) -> [f64; BINS] {
        let n = BINS as f64;
        std::array::from_fn(|b| {
            let x = (b as f64 + 0.5) / n;
            (0..3)
                .map(|k| {
                    let z = (x - means[k]) / sds[k];
                    w[k] * (-0.5 * z * z).exp() / sds[k]
                })
                .sum::<f64>()
                * 1e4
        })
    }

    #[test]
    fn the_f32_fit_matches_its_f64_twin() {
        let h = three_classes([0.21, 0.47, 0.66], [0.05, 0.04, 0.03], [0.2, 0.45, 0.35]);
        // Awkward range: not starting at 0, not ending at 256.
        let start = start_for(&h, 7, 249, Contrast::T1).expect("a start");
        let a = fit_f32(&h, &start).expect("f32");
        let b = fit(&h, &start).expect("f64");
        for k in 0..PURE {
            assert!((a.means[k] - b.means[k]).abs() < 2e-4, "{a:?} {b:?}");
            assert!((a.sds[k] - b.sds[k]).abs() < 2e-4, "{a:?} {b:?}");
        }
        for c in 0..CLASSES {
            assert!((a.weights[c] - b.weights[c]).abs() < 2e-3, "{a:?} {b:?}");
        }
        assert!((a.goodness - b.goodness).abs() < 1e-3);
    }

    #[test]
    fn labels_follow_the_contrast() {
        let h = three_classes([0.2, 0.5, 0.7], [0.03, 0.03, 0.03], [0.15, 0.4, 0.45]);
        let (range, raw) = ((5, 250), (0.0, 1.0));
        let t1 = fit_tissues(&h, range, Contrast::T1, FitDomain::Foreground, raw)
            .expect("fit")
            .0;
        assert!(
            t1.csf.mean < t1.gm.mean && t1.gm.mean < t1.wm.mean,
            "{t1:?}"
        );
        let t2 = fit_tissues(&h, range, Contrast::T2, FitDomain::Foreground, raw)
            .expect("fit")
            .0;
        assert!(
            t2.wm.mean < t2.gm.mean && t2.gm.mean < t2.csf.mean,
            "{t2:?}"
        );
        let flair = fit_tissues(&h, range, Contrast::Flair, FitDomain::Foreground, raw)
            .expect("fit")
            .0;
        assert!(
            flair.csf.mean < flair.wm.mean && flair.wm.mean < flair.gm.mean,
            "{flair:?}"
        );
        assert!(
            t1.sound && t2.sound && flair.sound,
            "{t1:?}\n{t2:?}\n{flair:?}"
        );
    }

    #[test]
    fn empty_or_single_bin_histograms_are_total() {
        let mut h = [0.0; BINS];
        assert!(
            fit_tissues(
                &h,
                (0, BINS),
                Contrast::T1,
                FitDomain::Foreground,
                (0.0, 1.0)
            )
            .is_none()
        );
        h[40] = 1.0;
        let (fit, _) = fit_tissues(
            &h,
            (0, BINS),
            Contrast::T1,
            FitDomain::Foreground,
            (0.0, 1.0),
        )
        .expect("a fit of one voxel");
        assert!(!fit.sound, "{fit:?}");
        assert_eq!(occupied_range(&h, 0), (40, 41));
        assert_eq!(occupied_range(&[0.0; BINS], 3), (BINS, BINS));
    }
}
