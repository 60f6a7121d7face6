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
