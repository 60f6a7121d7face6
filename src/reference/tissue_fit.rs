//! f64 twin of the tissue fit (`analysis::tissue_fit`): a Gaussian mixture fitted by EM to a
//! 256-bin histogram of `I_norm`, with partial-volume classes as FSL FAST's histogram model has
//! them (Zhang, Brady and Smith 2001).
//!
//! The model over the bins `[first, last)` (bin centre `x_b = (b + 0.5) / 256`):
//! - three pure classes `k = 0, 1, 2` in ascending mean, each `N(mu_k, sd_k^2)` with weight
//!   `w_k`; which tissue each is depends on the contrast (`analysis::tissue_fit`);
//! - two partial-volume classes between the neighbours `(0, 1)` and `(1, 2)`: a voxel mixing
//!   `a` and `b` with a fraction uniform in `[0, 1]` plus the pure classes' noise. FAST
//!   integrates over the fraction; here its first two moments are matched by one Gaussian of
//!   mean `(mu_a + mu_b) / 2` and variance `(sd_a^2 + sd_b^2) / 2 + (mu_b - mu_a)^2 / 12`, which
//!   keeps the E-step to one exponential per class and bin. Their means and spreads follow the
//!   pure classes; only their weights are free;
//! - one uniform class over the fitted range: bright tails (gadolinium enhancement, vessels,
//!   fat) and stray voxels land there instead of pulling a tissue class towards them.
//!
//! Decisions:
//! - Binned EM: every bin is one observation weighted by its count, so a fit costs
//!   O(bins x classes x iterations) whatever the volume's size.
//! - The M-step updates the pure classes' means and spreads from their own responsibilities
//!   only (the partial-volume voxels inform the weights, as in FAST's histogram stage).
//! - A standard deviation never falls below [`MIN_SD_BINS`] bins (Sheppard's bin width
//!   `1/sqrt(12)` is the most a bin can hide), so a class cannot collapse onto one bin.
//! - It stops when the log-likelihood per voxel changes by less than [`TOLERANCE`] or after
//!   [`MAX_ITERATIONS`].
//! - Goodness of fit: `1 - TV`, the total-variation distance between the normalised histogram
//!   and the model's bin probabilities (1 = perfect; a histogram with one more class than the
//!   model sits near 0.8-0.9).

use super::BINS;
use crate::model::VoxelGrid;

/// Pure classes (CSF, GM, WM in some order).
pub const PURE: usize = 3;
/// All classes: the pure ones, two partial-volume mixtures, the uniform tail.
pub const CLASSES: usize = PURE + 2 + 1;
/// Floor of a standard deviation, in bins.
pub const MIN_SD_BINS: f64 = 0.5;
/// Largest weight of the uniform tail class: it is for small tails (enhancement, vessels),
/// never a tissue's worth of voxels, so it cannot swallow a class at a poor start.
pub const MAX_TAIL_WEIGHT: f64 = 0.1;
/// Convergence: change of the log-likelihood per voxel.
pub const TOLERANCE: f64 = 1e-6;
/// Most EM iterations.
pub const MAX_ITERATIONS: usize = 200;

/// Where EM starts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitStart {
    /// First bin of the fitted range.
    pub first: usize,
    /// One past the last bin.
    pub last: usize,
    /// Initial means of the pure classes, ascending (I_norm).
    pub means: [f64; PURE],
    /// Initial standard deviations (I_norm).
    pub sds: [f64; PURE],
}

/// A fitted mixture.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mixture {
    /// Pure classes' means (I_norm), ascending.
    pub means: [f64; PURE],
    /// Pure classes' standard deviations (I_norm).
    pub sds: [f64; PURE],
    /// Weights of the pure classes, the two partial-volume classes and the uniform tail
    /// (sum 1).
    pub weights: [f64; CLASSES],
    /// `1 - TV` between the histogram and the model (module doc).
    pub goodness: f64,
    /// Log-likelihood per voxel at the end.
    pub log_likelihood: f64,
    /// EM iterations run.
    pub iterations: usize,
    /// Voxels in the fitted range.
    pub voxels: f64,
}

/// Mean and standard deviation of class `c` of a mixture with pure `means` and `sds`.
pub fn class_moments(means: &[f64; PURE], sds: &[f64; PURE], c: usize) -> (f64, f64) {
    match c {
        0..=2 => (means[c], sds[c]),
        3 | 4 => {
            let (a, b) = (c - 3, c - 2);
            let d = means[b] - means[a];
            let var = 0.5 * (sds[a] * sds[a] + sds[b] * sds[b]) + d * d / 12.0;
            (0.5 * (means[a] + means[b]), var.sqrt())
        }
        _ => (f64::NAN, f64::NAN),
    }
}

fn gauss(x: f64, mean: f64, sd: f64) -> f64 {
    let z = (x - mean) / sd;
    (-0.5 * z * z).exp() / (sd * (2.0 * std::f64::consts::PI).sqrt())
}

/// Per-bin density of each class (density per unit I_norm) at bin centre `x`.
fn densities(means: &[f64; PURE], sds: &[f64; PURE], range: f64, x: f64) -> [f64; CLASSES] {
    std::array::from_fn(|c| {
        if c == CLASSES - 1 {
            1.0 / range
        } else {
            let (m, s) = class_moments(means, sds, c);
            gauss(x, m, s)
        }
    })
}

/// Fits the mixture to `hist` from `start`. None when the range holds no voxel or is empty.
pub fn fit(hist: &[f64; BINS], start: &FitStart) -> Option<Mixture> {
    let (first, last) = (start.first.min(BINS), start.last.min(BINS));
    let n = BINS as f64;
    let voxels: f64 = hist[first..last.max(first)].iter().sum();
    if last <= first || voxels <= 0.0 {
        return None;
    }
    let range = (last - first) as f64 / n;
    let min_sd = MIN_SD_BINS / n;
    let mut means = start.means;
    let mut sds = start.sds.map(|s| s.max(min_sd));
    let mut weights = [0.0; CLASSES];
    weights[..PURE].fill(0.3);
    weights[3..5].fill(0.04);
    weights[CLASSES - 1] = 0.02;
    let mut previous = f64::NEG_INFINITY;
    let mut iterations = 0;
    let mut log_likelihood = f64::NEG_INFINITY;
    while iterations < MAX_ITERATIONS {
        iterations += 1;
        let mut resp_sum = [0.0; CLASSES];
        let mut x_sum = [0.0; PURE];
        let mut xx_sum = [0.0; PURE];
        let mut ll = 0.0;
        for (b, &count) in hist.iter().enumerate().take(last).skip(first) {
            if count <= 0.0 {
                continue;
            }
            let x = (b as f64 + 0.5) / n;
            let d = densities(&means, &sds, range, x);
            let p: [f64; CLASSES] = std::array::from_fn(|c| weights[c] * d[c]);
            let total: f64 = p.iter().sum();
            if total <= 0.0 || !total.is_finite() {
                continue;
            }
            ll += count * (total / n).ln();
            for c in 0..CLASSES {
                let r = count * p[c] / total;
                resp_sum[c] += r;
                if c < PURE {
                    x_sum[c] += r * x;
                    xx_sum[c] += r * x * x;
                }
            }
        }
        log_likelihood = ll / voxels;
        let resp_total: f64 = resp_sum.iter().sum();
        if resp_total <= 0.0 {
            return None;
        }
        for c in 0..CLASSES {
            weights[c] = resp_sum[c] / resp_total;
        }
        cap_tail(&mut weights);
        for k in 0..PURE {
            if resp_sum[k] > 0.0 {
                let m = x_sum[k] / resp_sum[k];
                let var = (xx_sum[k] / resp_sum[k] - m * m).max(0.0);
                means[k] = m;
                sds[k] = var.sqrt().max(min_sd);
            }
        }
        if (log_likelihood - previous).abs() < TOLERANCE {
            break;
        }
        previous = log_likelihood;
    }
    let goodness = goodness(hist, first, last, &means, &sds, &weights);
    Some(Mixture {
        means,
        sds,
        weights,
        goodness,
        log_likelihood,
        iterations,
        voxels,
    })
}

/// Histogram of `I_norm` (eq. 1 in f64 with `imin`/`imax`, rounded to f32, the kernel's
/// binning) over the finite voxels of `volume` (a scan's first frame) where `inside` is nonzero:
/// the fit's input inside a brain mask.
pub fn histogram_inside(volume: VoxelGrid<'_>, inside: &[u8], imin: f64, imax: f64) -> [u32; BINS] {
    let mut bins = [0u32; BINS];
    let voxels = volume
        .dims
        .iter()
        .product::<usize>()
        .min(volume.samples.len());
    for (i, &m) in inside.iter().enumerate().take(voxels) {
        if m == 0 {
            continue;
        }
        let stored = volume.samples.get(i);
        if stored.is_finite() {
            let v = super::normalize::normalize_value(volume.to_physical.apply(stored), imin, imax);
            let b = super::histogram::bin_of(v as f32);
            bins[b] = bins[b].saturating_add(1);
        }
    }
    bins
}

/// [`histogram_inside`] over the voxels at every `stride`-th index along each axis whose block
/// of the working-grid `mask` is set (nearest lookup, `WorkingMask::export_nearest`), without
/// building a volume-sized mask.
pub fn histogram_inside_mask(
    volume: VoxelGrid<'_>,
    mask: &super::brain_mask::WorkingMask<'_>,
    stride: usize,
    (imin, imax): (f64, f64),
) -> [u32; BINS] {
    let mut bins = [0u32; BINS];
    let (d, w) = (volume.dims, mask.dims);
    let stride = stride.max(1);
    if w.contains(&0) || mask.values.len() < w[0] * w[1] * w[2] {
        return bins;
    }
    if volume.samples.len() < d[0] * d[1] * d[2] {
        return bins;
    }
    let block = |p: usize, a: usize| (p / mask.factors[a].max(1) as usize).min(w[a] - 1);
    for k in (0..d[2]).step_by(stride) {
        for j in (0..d[1]).step_by(stride) {
            let row = w[0] * (block(j, 1) + w[1] * block(k, 2));
            for i in (0..d[0]).step_by(stride) {
                if mask.values[row + block(i, 0)] < 0.5 {
                    continue;
                }
                let stored = volume.samples.get(i + d[0] * (j + d[1] * k));
                if stored.is_finite() {
                    let physical = volume.to_physical.apply(stored);
                    let v = super::normalize::normalize_value(physical, imin, imax);
                    let b = super::histogram::bin_of(v as f32);
                    bins[b] = bins[b].saturating_add(1);
                }
            }
        }
    }
    bins
}

/// Caps the tail class's weight at [`MAX_TAIL_WEIGHT`], the others scaled to keep the sum.
pub fn cap_tail(weights: &mut [f64; CLASSES]) {
    let tail = weights[CLASSES - 1];
    if tail > MAX_TAIL_WEIGHT && tail < 1.0 {
        let scale = (1.0 - MAX_TAIL_WEIGHT) / (1.0 - tail);
        for w in &mut weights[..CLASSES - 1] {
            *w *= scale;
        }
        weights[CLASSES - 1] = MAX_TAIL_WEIGHT;
    }
}

/// `1 - TV` between the histogram on `[first, last)` and the model's bin probabilities.
pub fn goodness(
    hist: &[f64; BINS],
    first: usize,
    last: usize,
    means: &[f64; PURE],
    sds: &[f64; PURE],
    weights: &[f64; CLASSES],
) -> f64 {
    let n = BINS as f64;
    let voxels: f64 = hist[first..last].iter().sum();
    if voxels <= 0.0 {
        return 0.0;
    }
    let range = (last - first) as f64 / n;
    let model: Vec<f64> = (first..last)
        .map(|b| {
            let d = densities(means, sds, range, (b as f64 + 0.5) / n);
            (0..CLASSES).map(|c| weights[c] * d[c]).sum::<f64>() / n
        })
        .collect();
    let mass: f64 = model.iter().sum();
    if mass <= 0.0 {
        return 0.0;
    }
    let tv: f64 = (first..last)
        .zip(&model)
        .map(|(b, q)| (hist[b] / voxels - q / mass).abs())
        .sum();
    1.0 - 0.5 * tv
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A histogram drawn from a known mixture (expected counts, no noise).
    fn synthetic(means: [f64; 3], sds: [f64; 3], w: [f64; 3], voxels: f64) -> [f64; BINS] {
        let n = BINS as f64;
        std::array::from_fn(|b| {
            let x = (b as f64 + 0.5) / n;
            (0..3)
                .map(|k| w[k] * gauss(x, means[k], sds[k]))
                .sum::<f64>()
                * voxels
                / n
        })
    }

    #[test]
    fn recovers_a_known_three_class_mixture() {
        let (means, sds, w) = ([0.2, 0.5, 0.7], [0.04, 0.035, 0.03], [0.15, 0.45, 0.4]);
        let h = synthetic(means, sds, w, 1e6);
        let start = FitStart {
            first: 10,
            last: 250,
            means: [0.25, 0.45, 0.75],
            sds: [0.05; 3],
        };
        let m = fit(&h, &start).expect("a fit");
        for k in 0..3 {
            assert!((m.means[k] - means[k]).abs() < 0.01, "{m:?}");
            assert!((m.sds[k] - sds[k]).abs() < 0.01, "{m:?}");
        }
        assert!(m.goodness > 0.97, "{m:?}");
        let sum: f64 = m.weights.iter().sum();
        assert!((sum - 1.0).abs() < 1e-9);
    }

    #[test]
    fn a_bright_tail_goes_to_the_uniform_class_not_to_the_brightest_tissue() {
        let (means, sds, w) = ([0.2, 0.5, 0.65], [0.03, 0.03, 0.03], [0.15, 0.45, 0.4]);
        let mut h = synthetic(means, sds, w, 1e6);
        // 3 % of the voxels spread evenly over 0.75-0.98: an enhancing tail.
        for c in h.iter_mut().take(251).skip(192) {
            *c += 3e4 / 59.0;
        }
        let start = FitStart {
            first: 10,
            last: 252,
            means: [0.25, 0.45, 0.7],
            sds: [0.05; 3],
        };
        let m = fit(&h, &start).expect("a fit");
        assert!((m.means[2] - 0.65).abs() < 0.01, "{m:?}");
        assert!(m.weights[CLASSES - 1] > 0.02, "{m:?}");
    }

    #[test]
    fn empty_or_inverted_ranges_give_none() {
        let h = [0.0; BINS];
        let start = FitStart {
            first: 0,
            last: BINS,
            means: [0.2, 0.5, 0.8],
            sds: [0.05; 3],
        };
        assert!(fit(&h, &start).is_none());
        let mut h = h;
        h[100] = 5.0;
        assert!(
            fit(
                &h,
                &FitStart {
                    first: 200,
                    last: 100,
                    ..start
                }
            )
            .is_none()
        );
        // One occupied bin: a fit that stays finite.
        let m = fit(&h, &start).expect("a fit");
        assert!(m.means.iter().all(|v| v.is_finite()), "{m:?}");
    }
}
