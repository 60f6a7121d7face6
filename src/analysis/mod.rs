//! Histogram analysis: CSF / GM / WM modes of a T1-weighted volume, the background threshold,
//! tissue windows, and the paper's Table-1 row. CPU only; the input is the 256-bin histogram of
//! `I_norm` over the finite voxels (the histogram kernel's output, or
//! [`crate::reference::histogram_of_samples`]).
//!
//! Pipeline ([`analyze_with`]), one file per step:
//! 1. `spikes`: single bins holding many voxels with empty surroundings (masked zeros, padding)
//!    are set aside, so smoothing does not smear them over the tissue next to them.
//! 2. `smoothing`: Gaussian, sigma = 1 bin or the quantization gap of a comb histogram.
//! 3. `peaks`: local maxima (plateaus report their centre, single tops a parabola-refined
//!    vertex clamped to the bin), topographic prominence, and a significance test against both
//!    Poisson noise and the mode's own height. Insignificant modes are dropped.
//!    When fewer than two modes stand above the background, shoulders (flattened flanks of
//!    merged modes) are added as modes (`peaks::find_shoulders`).
//! 4. `background`: the darkest modes below 12 % of the WM candidate's intensity (air noise,
//!    dark shells) and the spikes below the tissue are background; the threshold is the valley
//!    after them.
//! 5. `assign`: WM = brightest major mode; GM and CSF by their intensity ratio to WM. A tissue
//!    that is not there is `None`, never invented.
//! 6. `windows`: adaptive windows around the modes (boundaries at valleys) and the paper preset.
//! 7. `table1`: the report and its flat Table-1 row.
//!
//! Every step is a total function of the histogram: empty, constant, uniform and single-voxel
//! histograms give a report with no peaks, never a panic.

pub mod assign;
pub mod background;
pub mod params;
pub mod peaks;
pub mod range;
pub mod smoothing;
pub mod spikes;
pub mod table1;
pub mod windows;

pub use params::AnalysisParams;
pub use range::{NormalizeMode, RangeChoice, RobustRange};
pub use table1::{
    InPaperWindow, ModeInfo, ModeRole, Peak, Peaks, SpikeInfo, Table1Row, TissueReport,
};
pub use windows::{PAPER_EDGE, TissueWindows, Window};

use crate::reference::BINS;

/// `modes` plus the shoulders (`peaks::find_shoulders`) above the background, at least two
/// bins from every mode, in ascending order.
fn with_shoulders(
    cleaned: &[f64; BINS],
    s: &[f64; BINS],
    sigma: f64,
    modes: &[peaks::Mode],
    bg: &background::Background,
    params: &AnalysisParams,
) -> Vec<peaks::Mode> {
    let wide_sigma = sigma.max(params.shoulder_sigma_bins);
    let wide = smoothing::gaussian(cleaned, wide_sigma);
    let from = modes[..bg.modes]
        .last()
        .map_or(bg.threshold_bin, |m| m.last.max(bg.threshold_bin));
    let slope_noise = smoothing::slope_noise_factor(wide_sigma);
    let mut out = modes.to_vec();
    for shoulder in peaks::find_shoulders(&wide, s, from, slope_noise, params) {
        if modes
            .iter()
            .all(|m| (m.position - shoulder.position).abs() >= 2.0)
        {
            out.push(shoulder);
        }
    }
    out.sort_by(|a, b| a.position.total_cmp(&b.position));
    out
}

/// [`analyze_with`] with the default parameters.
pub fn analyze(
    hist: &[u32; BINS],
    imin: f64,
    imax: f64,
    total_voxels: usize,
    nonfinite_voxels: usize,
) -> TissueReport {
    analyze_with(
        hist,
        imin,
        imax,
        total_voxels,
        nonfinite_voxels,
        &AnalysisParams::default(),
    )
}

/// Analyzes a 256-bin histogram of `I_norm` (finite voxels only) of a volume whose physical
/// range is `[imin, imax]`. `total_voxels` and `nonfinite_voxels` are reported as given.
pub fn analyze_with(
    hist: &[u32; BINS],
    imin: f64,
    imax: f64,
    total_voxels: usize,
    nonfinite_voxels: usize,
    params: &AnalysisParams,
) -> TissueReport {
    let h: [f64; BINS] = hist.map(f64::from);
    let finite_voxels: u64 = hist.iter().map(|&c| u64::from(c)).sum();

    let gap = smoothing::quantization_gap(&h);
    let spike_bins = spikes::find_spikes(&h, gap, params.spike_min_fraction, params.spike_ratio);
    let cleaned = spikes::remove_spikes(&h, &spike_bins);
    let sigma = smoothing::effective_sigma(&cleaned, params.sigma_bins);
    let s = smoothing::gaussian(&cleaned, sigma);
    let noise = smoothing::noise_factor(sigma);

    let mut modes: Vec<peaks::Mode> = peaks::find_modes(&s)
        .into_iter()
        .filter(|m| peaks::is_significant(m, noise, params))
        .collect();
    let mut bg = background::find_background(&s, &modes, &spike_bins, params);
    if modes.len() - bg.modes < 2 {
        // Fewer than two tissue modes cannot be assigned: look for shoulders (merged modes).
        let shoulders = with_shoulders(&cleaned, &s, sigma, &modes, &bg, params);
        if shoulders.len() > modes.len() {
            modes = shoulders;
            bg = background::find_background(&s, &modes, &spike_bins, params);
        }
    }
    let candidates = &modes[bg.modes..];
    let assignment = assign::assign(candidates, bg.zero, params);

    let peak_of = |i: Option<usize>| i.map(|i| Peak::new(candidates[i].norm(), imin, imax));
    let peaks = Peaks {
        csf: peak_of(assignment.csf),
        gm: peak_of(assignment.gm),
        wm: peak_of(assignment.wm),
    };
    let paper_windows = TissueWindows::paper();
    let inside = |p: Option<Peak>, w: Option<Window>| p.zip(w).map(|(p, w)| w.contains(p.norm));
    let in_paper_window = InPaperWindow {
        csf: inside(peaks.csf, paper_windows.csf),
        gm: inside(peaks.gm, paper_windows.gm),
        wm: inside(peaks.wm, paper_windows.wm),
    };
    let adaptive_windows =
        windows::adaptive(&s, &modes, bg.modes, &assignment, bg.threshold_bin, params);

    let role = |i: usize| -> ModeRole {
        let Some(c) = i.checked_sub(bg.modes) else {
            return ModeRole::Background;
        };
        if assignment.csf == Some(c) {
            ModeRole::Csf
        } else if assignment.gm == Some(c) {
            ModeRole::Gm
        } else if assignment.wm == Some(c) {
            ModeRole::Wm
        } else {
            ModeRole::Other
        }
    };
    let mode_info = modes
        .iter()
        .enumerate()
        .map(|(i, m)| ModeInfo {
            peak: Peak::new(m.norm(), imin, imax),
            height: m.height,
            prominence: m.prominence,
            role: role(i),
        })
        .collect();
    let spike_info = spike_bins
        .iter()
        .map(|&bin| SpikeInfo {
            bin,
            count: hist[bin],
            background: bg.spikes.contains(&bin),
        })
        .collect();

    let used_voxels = hist[bg.threshold_bin.min(BINS)..]
        .iter()
        .map(|&c| u64::from(c))
        .sum();
    TissueReport {
        total_voxels,
        used_voxels,
        nonfinite_voxels,
        finite_voxels,
        imin,
        imax,
        peaks,
        background_threshold: bg.threshold_bin as f64 / BINS as f64,
        in_paper_window,
        adaptive_windows,
        paper_windows,
        modes: mode_info,
        spikes: spike_info,
        smoothing_sigma_bins: sigma,
        params: *params,
        range: RangeChoice::default(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The histogram of the MNI152 template under a +-15 % bias field and Rician noise (the
    /// perturbation study's `bias_rician` volume, I_norm over [0.003851923393085599, 279.337646484375]): GM
    /// and WM merge into one local maximum and CSF is only a flattening of GM's rising flank.
    const BIAS_RICIAN_HIST: [u32; BINS] = [
        83091, 243131, 385099, 501768, 584005, 632627, 643972, 625716, 583106, 522046, 450080,
        378234, 306348, 240232, 182294, 134754, 97517, 68147, 45976, 30723, 19879, 12489, 7387,
        4507, 2682, 1478, 896, 526, 326, 216, 177, 120, 150, 151, 168, 182, 185, 175, 184, 226,
        213, 243, 255, 259, 305, 302, 319, 338, 382, 403, 484, 536, 572, 633, 697, 816, 830, 877,
        943, 1004, 1066, 1167, 1201, 1307, 1316, 1312, 1368, 1395, 1461, 1525, 1567, 1598, 1604,
        1674, 1776, 1845, 1830, 1994, 1998, 1964, 2199, 2291, 2323, 2400, 2502, 2660, 2719, 2787,
        2905, 3095, 3269, 3386, 3391, 3588, 3591, 3845, 3818, 4021, 4252, 4136, 4348, 4396, 4410,
        4720, 4718, 4846, 4876, 5061, 5317, 5309, 5458, 5570, 5773, 5764, 6017, 6126, 6390, 6603,
        6643, 6788, 7067, 7235, 7619, 7858, 7965, 8534, 8696, 9098, 9377, 9971, 10375, 11019,
        11276, 11878, 12438, 13126, 13833, 14455, 14845, 15693, 16365, 17052, 17497, 17885, 18733,
        19405, 19830, 20357, 20695, 21109, 21566, 21893, 22171, 22113, 22604, 22712, 22886, 23191,
        22964, 23058, 23237, 22786, 22686, 22811, 22453, 22699, 22466, 22409, 21884, 21644, 21647,
        21124, 20968, 20610, 20210, 20146, 20119, 20117, 19780, 19681, 19686, 19498, 19384, 19142,
        19227, 19146, 18864, 19108, 18477, 18333, 18059, 17913, 17594, 16940, 16639, 16315, 15689,
        15516, 14985, 14395, 14115, 13792, 13519, 13178, 12992, 12531, 12159, 12057, 11630, 11173,
        10689, 10496, 10026, 9571, 9061, 8644, 8011, 7285, 6720, 6344, 5718, 5057, 4645, 4102,
        3666, 3298, 2902, 2499, 2377, 1973, 1708, 1431, 1215, 1060, 871, 751, 565, 464, 374, 292,
        231, 181, 134, 91, 60, 39, 33, 28, 17, 7, 6, 6, 1, 2, 0, 1,
    ];

    #[test]
    fn merged_tissues_of_a_biased_scan_are_found_as_shoulders() {
        let (imin, imax) = (0.003851923393085599, 279.337646484375);
        let total = BIAS_RICIAN_HIST.iter().map(|&c| c as usize).sum();
        let r = analyze(&BIAS_RICIAN_HIST, imin, imax, total, 0);
        // The truths: 10th-90th percentiles of each tissue's intensities in that volume.
        let inside =
            |p: Option<Peak>, lo: f64, hi: f64| p.is_some_and(|p| (lo..=hi).contains(&p.raw));
        assert!(inside(r.peaks.csf, 56.3, 104.1), "{:?}", r.peaks);
        assert!(inside(r.peaks.gm, 138.1, 193.0), "{:?}", r.peaks);
        assert!(inside(r.peaks.wm, 192.4, 237.2), "{:?}", r.peaks);
        // Without the shoulder fallback only one tissue mode stands: nothing could be assigned.
        let maxima = r.modes.iter().filter(|m| m.prominence > 0.0).count();
        assert_eq!(
            maxima, 2,
            "background and the merged GM/WM mode: {:?}",
            r.modes
        );
    }
}
