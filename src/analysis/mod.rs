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
//! 4. `background`: the darkest modes below 12 % of the WM candidate's intensity (air noise,
//!    dark shells) and the spikes below the tissue are background; the threshold is the valley
//!    after them.
//! 5. `contrast` decides T1 or T2 (or takes `--contrast`); `assign`: for T1, WM = brightest
//!    major mode, for T2 the darkest; GM and CSF by their intensity ratio to WM. A tissue that
//!    is not there is `None`, never invented.
//! 6. `windows`: adaptive windows around the modes (boundaries at valleys) and the paper preset.
//! 7. `table1`: the report and its flat Table-1 row.
//!
//! Every step is a total function of the histogram: empty, constant, uniform and single-voxel
//! histograms give a report with no peaks, never a panic.

pub mod assign;
pub mod background;
pub mod contrast;
pub mod params;
pub mod peaks;
pub mod range;
pub mod smoothing;
pub mod spikes;
pub mod table1;
pub mod windows;

pub use contrast::{Contrast, ContrastBasis, ContrastChoice, ContrastReport};
pub use params::AnalysisParams;
pub use range::{NormalizeMode, RangeChoice, RobustRange};
pub use table1::{
    InPaperWindow, ModeInfo, ModeRole, Peak, Peaks, SpikeInfo, Table1Row, TissueReport,
};
pub use windows::{PAPER_EDGE, TissueWindows, Window};

use crate::reference::BINS;

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

    let modes: Vec<peaks::Mode> = peaks::find_modes(&s)
        .into_iter()
        .filter(|m| peaks::is_significant(m, noise, params))
        .collect();
    let bg = background::find_background(&s, &modes, &spike_bins, params);
    let candidates = &modes[bg.modes..];
    let decided = contrast::decide(params.contrast, &s, candidates, bg.zero, params);
    let assignment = assign::assign_for(decided.contrast, candidates, bg.zero, params);

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
        contrast: decided,
    }
}
