//! Single-bin spikes: many voxels with one value and almost none nearby.
//!
//! Decisions:
//! - A spike is a bin holding at least `spike_min_fraction` of the finite voxels and more than
//!   `spike_ratio` times every other bin within `reach = max(3, gap + 1)` bins (`gap` = the
//!   quantization gap, so the teeth of a comb histogram are not spikes of each other). Tissue
//!   never looks like that: it is spread by noise and partial volume over many bins. Spikes are
//!   masked zeros (the skull-stripped MNI152 template: 78 % of its voxels are exactly 0),
//!   padding values, or saturation.
//! - Spikes are taken out before smoothing (replaced by the mean of their immediate neighbours),
//!   because a Gaussian would smear a 6.8 M-voxel spike over the 2 k-voxel tissue bins next to
//!   it. Spikes below the darkest tissue mode are background; others are only listed.
//! - Quantization outliers ([`find_quantization_outliers`]): single bins far below (or above)
//!   BOTH neighbours, by more than `quantization_z` Poisson deviations of the nearer one. A
//!   tissue density is smooth over many bins, so such a bin is an artefact of binning integer
//!   (or few-valued) data whose value step does not divide the bin width: u8 data over a robust
//!   range of 234 values leaves every 11th bin empty, a mean of three u8 slices (values in thirds)
//!   puts 2 instead of 3 values in every 5th bin. Each such bin becomes a deep, "significant"
//!   dip that splits a tissue mode in two; it is replaced by the mean of its neighbours, like a
//!   spike. Dips only as a pattern (5 or more: a single one is a real sharp valley), bumps
//!   always (a single bin holding two values of a 258-value range made a fake GM mode on the
//!   MNI152); only for dense histograms (quantization gap 1): a comb of gap 2 or more is the
//!   smoothing's job (`smoothing`), and its empty bins are not outliers.
//! - The top bin holds every voxel at or above the range's top when the range is robust (the
//!   clamped bright tail: 0.5 % of the foreground, piled into one bin), so it is capped at its
//!   neighbour's count ([`cap_top_bin`]): a pile-up there is not a mode.

use crate::reference::BINS;

/// Bins that are spikes, ascending.
pub fn find_spikes(hist: &[f64; BINS], gap: usize, min_fraction: f64, ratio: f64) -> Vec<usize> {
    let total: f64 = hist.iter().sum();
    if total <= 0.0 {
        return Vec::new();
    }
    let reach = gap.saturating_add(1).max(3);
    (0..BINS)
        .filter(|&b| {
            let h = hist[b];
            if h <= 0.0 || h < min_fraction * total {
                return false;
            }
            let lo = b.saturating_sub(reach);
            let hi = (b + reach).min(BINS - 1);
            (lo..=hi).filter(|&n| n != b).all(|n| h > ratio * hist[n])
        })
        .collect()
}

/// A copy of `hist` with every spike replaced by the mean of its existing immediate neighbours.
pub fn remove_spikes(hist: &[f64; BINS], spikes: &[usize]) -> [f64; BINS] {
    let mut out = *hist;
    for &b in spikes {
        let neighbours: Vec<f64> = [b.checked_sub(1), (b + 1 < BINS).then_some(b + 1)]
            .into_iter()
            .flatten()
            .map(|n| hist[n])
            .collect();
        out[b] = if neighbours.is_empty() {
            0.0
        } else {
            neighbours.iter().sum::<f64>() / neighbours.len() as f64
        };
    }
    out
}

/// A quantization dip is also below this fraction of its lower neighbour: a bin holding n
/// instead of n + 1 stored values has at most 2/3 of its neighbours' counts (n = 2; 0 when an
/// empty bin falls between two values), while the top of a large real mode stands out by many
/// Poisson deviations but only a few percent.
const QUANTIZATION_DIP: f64 = 0.85;

/// ... and a quantization bump above this multiple of its higher neighbour (3 values among
/// bins of 2: 1.5); a real Gaussian mode's top reaches 1.3 only below a width of 1.4 bins.
const QUANTIZATION_BUMP: f64 = 1.3;

/// Fewer dips than this are not a binning pattern (see [`find_quantization_outliers`]).
const QUANTIZATION_PATTERN: usize = 5;

/// Interior bins (1..=254) that lie more than `z` Poisson deviations and 15 % below the lower,
/// or `z` deviations and 30 % above the higher of their two neighbours (see the module doc),
/// ascending; dips only when there are at least 5 of them.
pub fn find_quantization_outliers(hist: &[f64; BINS], z: f64) -> Vec<usize> {
    let neighbours = |b: usize| {
        let (l, r) = (hist[b - 1], hist[b + 1]);
        (l.min(r), l.max(r))
    };
    let dips: Vec<usize> = (1..BINS - 1)
        .filter(|&b| {
            let (low, _) = neighbours(b);
            hist[b] < low - z * low.sqrt() && hist[b] < QUANTIZATION_DIP * low
        })
        .collect();
    let bumps = (1..BINS - 1).filter(|&b| {
        let (_, high) = neighbours(b);
        hist[b] > high + z * high.max(1.0).sqrt() && hist[b] > QUANTIZATION_BUMP * high
    });
    // Dips count only as a pattern: one or a few are real sharp valleys (two steep modes
    // meeting, as between air noise and a dark shell). A bump 30 % above both neighbours is
    // never a tissue top (that would need a mode narrower than 1.4 bins), so one is enough: a
    // range of 258 integer values over 256 bins puts two values into a single bin.
    let mut found: Vec<usize> = if dips.len() >= QUANTIZATION_PATTERN {
        dips
    } else {
        Vec::new()
    };
    found.extend(bumps);
    found.sort_unstable();
    found
}

/// A copy of `hist` whose top bin holds at most its neighbour's count.
pub fn cap_top_bin(hist: &[f64; BINS]) -> [f64; BINS] {
    let mut out = *hist;
    out[BINS - 1] = out[BINS - 1].min(out[BINS - 2]);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn masked_zeros_are_a_spike_and_are_removed() {
        let mut h = [0.0; BINS];
        h[0] = 1e6;
        h[30..200].fill(1000.0);
        assert_eq!(find_spikes(&h, 1, 0.02, 5.0), vec![0]);
        let r = remove_spikes(&h, &[0]);
        assert_eq!(r[0], 0.0);
        assert_eq!(r[1..], h[1..]);
        // Replaced by the mean of both neighbours in the middle.
        let mut m = [10.0; BINS];
        m[50] = 1e6;
        assert_eq!(remove_spikes(&m, &find_spikes(&m, 1, 0.02, 5.0))[50], 10.0);
    }

    #[test]
    fn quantization_dips_are_outliers_but_poisson_wiggles_are_not() {
        // A u8 histogram over 234 values: every 11th bin empty.
        let mut h = [0.0; BINS];
        for (b, v) in h.iter_mut().enumerate().skip(30) {
            *v = if b % 11 == 0 {
                0.0
            } else {
                1000.0 + 10.0 * b as f64
            };
        }
        let found = find_quantization_outliers(&h, 6.0);
        assert_eq!(found, (33..255).step_by(11).collect::<Vec<_>>());
        let filled = remove_spikes(&h, &found);
        assert!((filled[44] - 1440.0).abs() < 1e-9, "{}", filled[44]);
        // Every 5th bin holding 2 instead of 3 values: 2/3 of its neighbours.
        let mut thirds = [6000.0; BINS];
        for b in (3..250).step_by(5) {
            thirds[b] = 4000.0;
        }
        assert_eq!(find_quantization_outliers(&thirds, 6.0).len(), 50);
        // The top of a narrow real mode (sigma 2 bins, 1e5 voxels) is many deviations but only
        // 13 % above its neighbours: not an outlier.
        let mut narrow = [0.0; BINS];
        for (b, v) in narrow.iter_mut().enumerate() {
            *v = 1e5 * (-0.5 * ((b as f64 - 100.0) / 2.0).powi(2)).exp();
        }
        assert!(find_quantization_outliers(&narrow, 6.0).is_empty());
        // A single sharp valley between two steep modes is real: not a pattern, left alone.
        let mut valley = [2500.0; BINS];
        valley[10..15].copy_from_slice(&[2000.0, 1217.0, 950.0, 1428.0, 3000.0]);
        assert!(find_quantization_outliers(&valley, 6.0).is_empty());
        // One bin holding two stored values among bins of one (a 258-value range) is filled.
        let mut double = [20_000.0; BINS];
        double[183] = 38_000.0;
        assert_eq!(find_quantization_outliers(&double, 6.0), vec![183]);
        // Poisson-sized wiggles (2 deviations) and the start of the support are left alone.
        let mut wiggle = [0.0; BINS];
        for (b, v) in wiggle.iter_mut().enumerate().skip(30) {
            *v = 10_000.0 + if b % 2 == 0 { 200.0 } else { -200.0 };
        }
        assert!(find_quantization_outliers(&wiggle, 6.0).is_empty());
        // A bright tail clamped into the top bin is capped at its neighbour.
        let mut top = [100.0; BINS];
        top[255] = 5000.0;
        assert_eq!(cap_top_bin(&top)[255], 100.0);
    }

    #[test]
    fn comb_teeth_and_small_or_broad_bins_are_not_spikes() {
        let mut comb = [0.0; BINS];
        for b in (0..BINS).step_by(6) {
            comb[b] = 100.0 + b as f64;
        }
        assert!(find_spikes(&comb, 6, 0.02, 5.0).is_empty());
        // A bin 5x its neighbours but under 2 % of the voxels is not a spike.
        let mut h = [1000.0; BINS];
        h[128] = 4000.0;
        assert!(find_spikes(&h, 1, 0.02, 5.0).is_empty());
        assert!(find_spikes(&[0.0; BINS], 1, 0.02, 5.0).is_empty());
    }
}
