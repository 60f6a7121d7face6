//! Gaussian smoothing of the 256-bin histogram.
//!
//! Decisions:
//! - A truncated Gaussian (radius `ceil(4 sigma)`) whose weights are renormalized over the bins
//!   that exist, so a flat histogram stays exactly flat up to its ends (no artificial slope, hence
//!   no artificial mode, at bin 0 or 255).
//! - Quantized data (an integer volume whose stored range spans fewer than 256 values) fills only
//!   every n-th bin: a comb. Smoothing with `sigma >= n` turns the comb back into the density it
//!   samples, so sigma is raised to the median gap between occupied bins. The median, not the
//!   mean, so that a few far outliers (one hot voxel setting `Imax`) do not widen the kernel.
//! - [`noise_factor`] is `sum(w²) / sum(w)²` of the full kernel: the variance of a smoothed
//!   Poisson count is about this times its mean, which the significance test uses.

use crate::reference::BINS;

/// Median distance between consecutive occupied bins (1 for a dense histogram, and when fewer
/// than two bins are occupied).
pub fn quantization_gap(hist: &[f64; BINS]) -> usize {
    let occupied: Vec<usize> = (0..BINS).filter(|&b| hist[b] > 0.0).collect();
    let mut gaps: Vec<usize> = occupied.windows(2).map(|w| w[1] - w[0]).collect();
    if gaps.is_empty() {
        return 1;
    }
    gaps.sort_unstable();
    gaps[gaps.len() / 2]
}

/// The smoothing width actually used: `max(sigma_min, quantization gap)`.
pub fn effective_sigma(hist: &[f64; BINS], sigma_min: f64) -> f64 {
    let sigma = if sigma_min.is_finite() && sigma_min > 0.0 {
        sigma_min
    } else {
        0.0
    };
    sigma.max(quantization_gap(hist) as f64)
}

fn kernel(sigma: f64) -> Vec<f64> {
    if !(sigma > 0.0 && sigma.is_finite()) {
        return vec![1.0];
    }
    let radius = (4.0 * sigma).ceil().min(BINS as f64) as usize;
    (0..=2 * radius)
        .map(|i| {
            let d = i as f64 - radius as f64;
            (-0.5 * d * d / (sigma * sigma)).exp()
        })
        .collect()
}

/// Gaussian smoothing with edge renormalization (see the module doc). `sigma <= 0` copies.
pub fn gaussian(hist: &[f64; BINS], sigma: f64) -> [f64; BINS] {
    let w = kernel(sigma);
    let radius = w.len() / 2;
    let mut out = [0.0; BINS];
    for (b, o) in out.iter_mut().enumerate() {
        let (mut sum, mut weight) = (0.0, 0.0);
        for (i, wi) in w.iter().enumerate() {
            let Some(src) = (b + i).checked_sub(radius) else {
                continue;
            };
            if src < BINS {
                sum += wi * hist[src];
                weight += wi;
            }
        }
        *o = if weight > 0.0 { sum / weight } else { 0.0 };
    }
    out
}

/// `sum(w²) / sum(w)²` of the full kernel of width `sigma` (about `1 / (2 sigma sqrt(pi))`).
pub fn noise_factor(sigma: f64) -> f64 {
    let w = kernel(sigma);
    let s: f64 = w.iter().sum();
    let s2: f64 = w.iter().map(|x| x * x).sum();
    s2 / (s * s)
}

/// Variance of the central-difference slope `(s[b+1] - s[b-1]) / 2` of a histogram smoothed
/// with width `sigma`, per Poisson count: `var(slope) ~ this * count` (the shoulder test's
/// noise level; about `1 / (4 sqrt(pi) sigma^3)` for wide kernels).
pub fn slope_noise_factor(sigma: f64) -> f64 {
    let w = kernel(sigma);
    let total: f64 = w.iter().sum();
    let at = |k: isize| {
        usize::try_from(k)
            .ok()
            .and_then(|k| w.get(k))
            .copied()
            .unwrap_or(0.0)
    };
    let squares: f64 = (-1..=w.len() as isize)
        .map(|k| (0.5 * (at(k + 1) - at(k - 1))).powi(2))
        .sum();
    squares / (total * total)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_stays_flat_to_the_ends() {
        let s = gaussian(&[7.0; BINS], 2.5);
        assert!(s.iter().all(|&v| (v - 7.0).abs() < 1e-12), "{s:?}");
    }

    #[test]
    fn smoothing_preserves_a_centred_symmetric_peak_and_its_mass() {
        let mut h = [0.0; BINS];
        h[100] = 1000.0;
        let s = gaussian(&h, 2.0);
        assert!((s.iter().sum::<f64>() - 1000.0).abs() < 1e-9);
        assert!((s[99] - s[101]).abs() < 1e-9 && s[100] > s[99]);
        // Peak value of a sampled unit Gaussian of sigma 2: 1 / sum(exp(-d²/8)) = 0.1995.
        assert!((s[100] / 1000.0 - 0.19947).abs() < 1e-4, "{}", s[100]);
    }

    #[test]
    fn noise_factor_matches_the_continuous_formula() {
        for sigma in [1.0, 2.0, 5.0] {
            let expected = 1.0 / (2.0 * sigma * std::f64::consts::PI.sqrt());
            assert!(
                (noise_factor(sigma) / expected - 1.0).abs() < 0.01,
                "sigma {sigma}"
            );
        }
        assert_eq!(noise_factor(0.0), 1.0);
    }

    #[test]
    fn slope_noise_factor_matches_the_continuous_formula() {
        let sigma: f64 = 3.0;
        let expected = 1.0 / (4.0 * std::f64::consts::PI.sqrt() * sigma.powi(3));
        // The central difference is 5 % below the continuous derivative at sigma 3.
        assert!((slope_noise_factor(sigma) / expected - 1.0).abs() < 0.1);
    }

    #[test]
    fn quantization_gap_is_the_median_spacing() {
        let mut h = [0.0; BINS];
        for b in (10..200).step_by(6) {
            h[b] = 1.0;
        }
        h[255] = 1.0; // a far outlier does not change the median
        assert_eq!(quantization_gap(&h), 6);
        assert_eq!(effective_sigma(&h, 1.0), 6.0);
        assert_eq!(quantization_gap(&[1.0; BINS]), 1);
        assert_eq!(quantization_gap(&[0.0; BINS]), 1);
        assert_eq!(effective_sigma(&[1.0; BINS], f64::NAN), 1.0);
    }
}
