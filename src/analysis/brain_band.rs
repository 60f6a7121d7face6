//! The tissue band of brain extraction (`reference::brain`, `band_for`): which smoothed intensities
//! count as brain tissue, from the 256-bin histogram of `I_norm` and the contrast.
//!
//! Decisions:
//! - Otsu's threshold over bins 1..=255 (bin 0 holds masked zeros and the clamped dark end; it
//!   would pull the split down to the air). Class 0 is bins `1..=k`, class 1 bins `k+1..=255`,
//!   `k` maximizes the between-class variance `w0 w1 (mu0 - mu1)^2`, and the threshold is the
//!   edge between the classes, `t = (k + 1) / 256` in `I_norm` (bin `b`
//!   holds `[b, b + 1) / 256`, `reference::histogram::bin_of`). Bin 255 is included: with the
//!   robust range's headroom it holds few voxels.
//! - **Masked background** (a skull-stripped volume: zeros outside the brain and nothing just
//!   above them, no air noise): then bin 0 is the background class and Otsu runs over bins
//!   0..=255. Without it the 8-bit MNI152 template (78 % zeros, bins 1..=26 empty) split GM from
//!   WM (raw 171), the band held WM only, the mask was a WM blob and the head test called the
//!   stripped template a head (outside fraction 0.33). A head has air noise above its zeros
//!   (chris_t1: 44 % zeros but 53 k voxels in bins 1..=2), so it keeps the 1..=255 rule. The
//!   test: bin 0 holds at least 10 % of the voxels and bins 1..=4 together less than 1 % of bin
//!   0 ([`masked_background`]).
//! - Ties: empty bins after `k` give the same classes, hence the same variance, so a gap in the
//!   histogram is a run of equal maxima; the split is the middle of the first such run (the
//!   middle of the gap), not its first bin. Quantized scans (8-bit data spread over 256 bins)
//!   and two-valued phantoms have such gaps; the first bin would put `lo` right on the dark
//!   class's upper edge, where smoothing lifts it into the band.
//! - T1 (CSF dark): `lo = t`; the WM peak `wm` is the centre `(b + 0.5) / 256` of the largest
//!   bin above the threshold (bins `k+1..=255`) of the histogram smoothed with sigma 1 bin
//!   (`analysis::smoothing::gaussian`, bin 0 zeroed first so masked zeros do not leak into
//!   bin 1..4); ties: the darkest. Before smoothing, the analysis's binning repairs
//!   (`analysis::spikes`) apply: the top bin (the robust range's clamped tail) is capped at its
//!   neighbour, single-bin quantization bumps and dip patterns of a dense histogram are replaced
//!   by their neighbours' mean, and sigma is raised to a comb's quantization gap
//!   (`smoothing::effective_sigma`, at most 8 bins). Without them the 8-bit MNI152 template (255 values over
//!   257.4 units: one bin holds two values, 39 k voxels against 20 k around it) put "WM" on
//!   that bin, at GM's upper flank. CPU only: the GPU never sees the histogram. `hi = wm + 0.45 (wm - lo)`: WM's upper flank is kept, fat
//!   (brighter than WM on T1) is cut.
//! - T2 and PD (CSF bright): `lo = 0.6 t` (GM and WM sit near Otsu's split between the dark air
//!   and skull and the tissue; 0.6 keeps the darker WM), `hi = 2.0`, i.e. no upper bound (CSF is
//!   the brightest tissue and belongs to the brain).
//! - `None` when the histogram has fewer than two occupied bins in 1..=255 (empty or constant:
//!   no split exists).
//!
//! Half a bin (0.002 of `I_norm`) separates the edge and centre conventions; the analysis reports
//! mode positions at `position / 256` (`peaks::Mode::norm`), which differs from the centre by the
//! same half bin.

use super::contrast::Contrast;
use super::params::AnalysisParams;
use super::{smoothing, spikes};
use crate::reference::BINS;

/// Fraction of `wm - lo` kept above the WM peak for T1.
pub const T1_HI_FRACTION: f64 = 0.45;
/// T2/PD lower end as a fraction of Otsu's threshold.
pub const T2_LO_FRACTION: f64 = 0.6;
/// T2/PD upper end (above every `I_norm`: no upper bound).
pub const T2_HI: f64 = 2.0;
/// A masked background: bin 0 holds at least this fraction of the voxels ...
pub const MASKED_MIN_FRACTION: f64 = 0.1;
/// ... and the bins 1..=this one ...
pub const MASKED_GAP_BINS: usize = 4;
/// ... hold together less than this fraction of bin 0's count.
pub const MASKED_GAP_RATIO: f64 = 0.01;
/// Smoothing of the histogram before the WM peak is taken, in bins.
pub const WM_SIGMA_BINS: f64 = 1.0;
/// A comb's quantization gap raises that sigma up to this many bins; larger gaps are not combs
/// but few-valued data (a two-valued phantom has one gap of 100+ bins), which keep sigma 1.
pub const MAX_COMB_SIGMA_BINS: f64 = 8.0;

/// Whether bin 0 is a masked background (module doc): at least `MASKED_MIN_FRACTION` of the
/// voxels, and bins 1..=`MASKED_GAP_BINS` together below `MASKED_GAP_RATIO` of it.
pub fn masked_background(hist: &[u32; BINS]) -> bool {
    let total: f64 = hist.iter().map(|&c| f64::from(c)).sum();
    let zeros = f64::from(hist[0]);
    let above: f64 = hist[1..=MASKED_GAP_BINS]
        .iter()
        .map(|&c| f64::from(c))
        .sum();
    total > 0.0 && zeros >= MASKED_MIN_FRACTION * total && above < MASKED_GAP_RATIO * zeros
}

/// Otsu's split over bins 1..=255, or 0..=255 for a masked background: the last bin `k` of the
/// dark class (ties: the middle of the first run of equal maxima, module doc). None without two
/// occupied bins.
pub fn otsu_bin(hist: &[u32; BINS]) -> Option<usize> {
    let first = usize::from(!masked_background(hist));
    let h: Vec<f64> = hist.iter().map(|&c| f64::from(c)).collect();
    let total: f64 = h[first..].iter().sum();
    let moment: f64 = (first..BINS).map(|b| b as f64 * h[b]).sum();
    let (mut w0, mut m0) = (0.0, 0.0);
    // (first k, last k of its run, value)
    let mut best: Option<(usize, usize, f64)> = None;
    for (k, &count) in h.iter().enumerate().take(BINS - 1).skip(first) {
        w0 += count;
        m0 += k as f64 * count;
        let w1 = total - w0;
        if w0 <= 0.0 || w1 <= 0.0 {
            continue;
        }
        let diff = m0 / w0 - (moment - m0) / w1;
        let between = w0 * w1 * diff * diff;
        match best {
            // Empty bins leave w0 and m0 unchanged, so a gap repeats the value exactly.
            Some((first, last, v)) if between == v && last + 1 == k => {
                best = Some((first, k, v));
            }
            Some((_, _, v)) if between <= v => {}
            _ => best = Some((k, k, between)),
        }
    }
    best.filter(|&(_, _, v)| v > 0.0)
        .map(|(first, last, _)| (first + last) / 2)
}

/// The tissue band `(lo, hi)` in `I_norm` for this histogram and contrast (module doc); None for
/// an empty or constant histogram.
pub fn band_for(hist: &[u32; BINS], contrast: Contrast) -> Option<(f64, f64)> {
    let k = otsu_bin(hist)?;
    let t = (k + 1) as f64 / BINS as f64;
    // FLAIR (CSF dark) takes the T1 arm, PD (CSF bright) the T2 arm; a CT has no brain band
    // (brain extraction is for MR heads).
    match contrast {
        Contrast::T1 | Contrast::Flair => {
            let wm = wm_peak(hist, k)?;
            Some((t, wm + T1_HI_FRACTION * (wm - t)))
        }
        Contrast::T2 | Contrast::Pd => Some((T2_LO_FRACTION * t, T2_HI)),
        Contrast::Ct => None,
    }
}

/// Centre of the largest smoothed bin above `k` (module doc).
fn wm_peak(hist: &[u32; BINS], k: usize) -> Option<f64> {
    let mut h = hist.map(f64::from);
    h[0] = 0.0;
    let h = clean(&h);
    let sigma = smoothing::effective_sigma(&h, WM_SIGMA_BINS).min(MAX_COMB_SIGMA_BINS);
    let s = smoothing::gaussian(&h, sigma);
    let mut best: Option<usize> = None;
    for b in k + 1..BINS {
        if best.is_none_or(|m| s[b] > s[m]) {
            best = Some(b);
        }
    }
    let best = best?;
    // The major modes above the split: local maxima of at least MAJOR_MODE_FRACTION of the
    // highest. On a T1 head whose scalp fat forms its own major mode (brighter than WM), three
    // stand above the split (GM with muscle, WM, fat): WM is the second brightest. Otherwise
    // (a stripped brain, or a head whose fat is spread thin) WM is the brightest of them.
    let major: Vec<usize> = (k + 1..BINS)
        .filter(|&b| {
            let left = if b > 0 { s[b - 1] } else { f64::MIN };
            let right = if b + 1 < BINS { s[b + 1] } else { f64::MIN };
            s[b] > left && s[b] >= right && s[b] >= MAJOR_MODE_FRACTION * s[best]
        })
        .collect();
    let wm = match major.len() {
        0 => best,
        1 | 2 => major[major.len() - 1],
        n => major[n - 2],
    };
    Some((wm as f64 + 0.5) / BINS as f64)
}

/// A local maximum of the smoothed histogram this fraction of the highest counts as a major
/// mode for finding WM (`wm_peak`).
pub const MAJOR_MODE_FRACTION: f64 = 0.2;

/// The analysis's binning repairs (module doc): the top bin capped at its neighbour, and for a
/// dense histogram the single-bin quantization outliers replaced by their neighbours' mean.
fn clean(h: &[f64; BINS]) -> [f64; BINS] {
    let capped = spikes::cap_top_bin(h);
    if smoothing::quantization_gap(&capped) != 1 {
        return capped;
    }
    let z = AnalysisParams::default().quantization_z;
    spikes::remove_spikes(&capped, &spikes::find_quantization_outliers(&capped, z))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Gaussian modes `(centre bin, sd bins, count)` added to bin 0's `zeros`.
    fn modes(zeros: u32, parts: &[(f64, f64, f64)]) -> [u32; BINS] {
        let mut h = [0u32; BINS];
        h[0] = zeros;
        for (b, v) in h.iter_mut().enumerate() {
            for &(c, sd, n) in parts {
                let x = (b as f64 - c) / sd;
                *v += (n * (-0.5 * x * x).exp()).round() as u32;
            }
        }
        h
    }

    #[test]
    fn empty_and_constant_histograms_have_no_band() {
        assert_eq!(band_for(&[0; BINS], Contrast::T1), None);
        let mut one = [0u32; BINS];
        one[100] = 5000;
        assert_eq!(band_for(&one, Contrast::T1), None);
        assert_eq!(band_for(&one, Contrast::T2), None);
        // Only a few zeros besides one bin: still constant over 1..=255.
        one[0] = 100;
        assert_eq!(band_for(&one, Contrast::T1), None);
        // Many zeros with an empty gap above them are a masked background, a class of its own:
        // a binary mask splits in the middle of its gap.
        one[0] = 1_000_000;
        assert_eq!(otsu_bin(&one), Some(49));
    }

    #[test]
    fn a_masked_background_joins_the_split() {
        // Stripped like the MNI152 template: zeros, nothing in bins 1..=4, a broad dark tail
        // (CSF and partial volume), GM 175, WM 222.
        let parts = [
            (110.0, 30.0, 8_000.0),
            (175.0, 10.0, 24_000.0),
            (222.0, 8.0, 25_800.0),
        ];
        let mut h = modes(2_000_000, &parts);
        h[1..=4].fill(0);
        assert!(masked_background(&h));
        let k = otsu_bin(&h).expect("split");
        // With bin 0 the split falls below GM; without it, into GM's flank.
        assert!(k < 140, "split {k} below GM");
        let mut unmasked = h;
        unmasked[0] = 0;
        let k_unmasked = otsu_bin(&unmasked).expect("split");
        assert!(k_unmasked > k + 20, "{k_unmasked} vs {k}");
        // The same with air noise above the zeros: a head, bin 0 excluded, split above CSF.
        let head = modes(2_000_000, &[&parts[..], &[(3.0, 3.0, 100_000.0)]].concat());
        assert!(!masked_background(&head));
        let k = otsu_bin(&head).expect("split");
        assert!(k > 100 && k < 175, "split {k} above the dark tail");
    }

    #[test]
    fn two_bins_split_between_them_and_bin_zero_is_ignored() {
        let mut h = [0u32; BINS];
        (h[0], h[40], h[200]) = (100, 100, 100);
        // Every k in 40..=199 splits the same classes: the middle of the gap.
        assert_eq!(otsu_bin(&h), Some(119));
        let (lo, hi) = band_for(&h, Contrast::T1).expect("two classes");
        assert!((lo - 120.0 / 256.0).abs() < 1e-15);
        let wm = 200.5 / 256.0;
        assert!((hi - (wm + 0.45 * (wm - lo))).abs() < 1e-15, "{hi}");
        let (lo2, hi2) = band_for(&h, Contrast::T2).expect("two classes");
        assert!((lo2 - 0.6 * 120.0 / 256.0).abs() < 1e-15 && hi2 == 2.0);
    }

    #[test]
    fn t1_head_band_spans_gm_and_wm_and_cuts_fat() {
        // Air/skull near 20, CSF 60, GM 140, WM 185, fat 240 (bins).
        let h = modes(
            200_000,
            &[
                (20.0, 8.0, 40_000.0),
                (60.0, 10.0, 3_000.0),
                (140.0, 8.0, 20_000.0),
                (185.0, 6.0, 25_000.0),
                (240.0, 4.0, 2_000.0),
            ],
        );
        let (lo, hi) = band_for(&h, Contrast::T1).expect("a head");
        let bin = |x: f64| x * 256.0;
        assert!(bin(lo) > 60.0 && bin(lo) < 125.0, "lo {}", bin(lo));
        // WM peak at 185.5 (centre of bin 185), hi = wm + 0.45 (wm - lo).
        let wm = 185.5 / 256.0;
        assert!((hi - (wm + 0.45 * (wm - lo))).abs() < 1e-12);
        assert!(bin(hi) > 200.0 && bin(hi) < 235.0, "hi {}", bin(hi));
    }

    #[test]
    fn t2_band_is_open_above() {
        // T2 with its air and skull in the low bins (most of a head's field of view): WM 60,
        // GM 80, CSF 180, air and skull 10.
        let h = modes(
            0,
            &[
                (10.0, 5.0, 200_000.0),
                (60.0, 6.0, 20_000.0),
                (80.0, 6.0, 18_000.0),
                (180.0, 10.0, 5_000.0),
            ],
        );
        let k = otsu_bin(&h).expect("split");
        let (lo, hi) = band_for(&h, Contrast::T2).expect("a head");
        assert!((lo - 0.6 * (k + 1) as f64 / 256.0).abs() < 1e-15);
        assert!(lo * 256.0 < 45.0 && lo * 256.0 > 10.0, "lo {}", lo * 256.0);
        assert_eq!(hi, 2.0);
    }

    #[test]
    fn a_quantization_bump_is_not_the_wm_peak() {
        // A skull-stripped T1 like the 8-bit MNI152 template: a broad dark tail, GM 175, WM
        // 222; Otsu splits below GM, and one bin on GM's upper flank holds two integer values
        // (twice its neighbours: its smoothed count beats WM's top without the repairs).
        let parts = [
            (110.0, 30.0, 8_000.0),
            (175.0, 10.0, 24_000.0),
            (222.0, 8.0, 25_800.0),
        ];
        let mut h = modes(0, &parts);
        let k = otsu_bin(&h).expect("split");
        let bump = 178;
        h[bump] *= 2;
        assert!(
            k < bump && h[bump] > h[222],
            "k {k}, bump {}, WM {}",
            h[bump],
            h[222]
        );
        assert_eq!(otsu_bin(&h).map(|k2| k2.abs_diff(k) <= 1), Some(true));
        let (lo, hi) = band_for(&h, Contrast::T1).expect("a band");
        let wm = (hi + T1_HI_FRACTION * lo) / (1.0 + T1_HI_FRACTION);
        assert!(
            (wm * 256.0 - 222.5).abs() < 1e-9,
            "wm at bin {}",
            wm * 256.0
        );
    }
}
