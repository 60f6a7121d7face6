//! Tunable constants of the histogram analysis, gathered in one value so accuracy studies can
//! vary them; [`AnalysisParams::default`] is what [`super::analyze`] uses.
//!
//! Every default is stated with its reason next to the field; the ratios are T1-specific (adult
//! contrast: CSF darker than GM darker than WM), which is what the paper's Table 1 describes.
//! T2 assignment uses its own ratios (see `assign`); `contrast` says which applies.

/// Parameters of [`super::analyze_with`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct AnalysisParams {
    /// Minimum Gaussian smoothing width, in bins. 1 bin: smoothing only steadies the
    /// bin-to-bin noise; telling noise from modes is the significance test's job, which knows
    /// the noise level. Wider kernels erase narrow real modes: the CSF mode of the MNI152
    /// template is about 5 bins wide and 17 % deep in the raw counts, and keeps 9 % of its
    /// height as prominence at sigma 1, 5 % at 1.5 and 1.6 % at 2. Raised automatically for
    /// quantized histograms (see `smoothing`).
    pub sigma_bins: f64,
    /// A mode is significant only if its prominence exceeds this many standard deviations of
    /// the Poisson noise of the smoothed histogram at its top and its base. 4 keeps random
    /// wiggles of flat and two-class histograms out (tests/peaks.rs runs many seeds); the
    /// MNI152 CSF mode passes at 4.3, its largest rejected wiggle (I_norm 0.17) reaches 3.4.
    pub noise_z: f64,
    /// ... and only if its prominence is at least this fraction of its own height: a mode must
    /// stand out from its surroundings, whatever the count scale (5 %).
    pub min_relative_prominence: f64,
    /// A single bin holding at least this fraction of the finite voxels ...
    pub spike_min_fraction: f64,
    /// ... and more than this many times every other bin within reach is a spike (masked
    /// zeros, padding, saturation), never a tissue.
    pub spike_ratio: f64,
    /// Modes at least this fraction of the tallest non-background mode's height are "major";
    /// WM is the brightest major mode. 20 % keeps small bright tails (vessels, fat, lesions)
    /// from being called WM while GM and WM, the two largest brain classes, always qualify.
    pub major_fraction: f64,
    /// Leading (darkest) modes whose intensity is below this fraction of the brightest major
    /// mode's intensity are background (air noise, dark shells); 0.12 = the lowest CSF ratio.
    pub background_max_ratio: f64,
    /// CSF intensity relative to WM, `(csf - zero) / (wm - zero)`, must be in
    /// `[csf_min_ratio, gm_min_ratio)`; T1 CSF is typically 0.2-0.45 of WM (MNI152: 0.30).
    pub csf_min_ratio: f64,
    /// GM intensity relative to WM must be at least this (T1 GM is typically 0.6-0.85 of WM;
    /// MNI152: 0.77); a lower second mode is CSF with GM missing.
    pub gm_min_ratio: f64,
    /// The WM window ends (and the pathology band starts) this many standard deviations above
    /// the WM mode, the standard deviation estimated from the right half-width at half maximum.
    pub wm_upper_sigmas: f64,
    /// Half-width of the adaptive windows' smooth transitions, in bins: 2 bins (0.8 % of the
    /// range), about how well a valley between two modes is located. Capped per report at a
    /// quarter of the narrowest window.
    pub edge_bins: f64,
    /// Smoothing width (bins) of the histogram whose slope is searched for shoulders, the
    /// fallback when fewer than two tissue modes are local maxima (see `peaks::find_shoulders`).
    /// 3 bins: the slope of a 1-bin-smoothed histogram is too noisy to locate a flattening.
    pub shoulder_sigma_bins: f64,
    /// A shoulder is a flattening of a flank whose slope falls to at most this fraction of the
    /// steeper stretches on both sides of it. 0.75: the WM shoulder of the MNI152 template under
    /// a +-15 % bias field and Rician noise flattens to 0.50, its CSF shoulder to 0.72 (ACCURACY.md,
    /// "Peaks under scanner perturbations"); a single Gaussian or Rayleigh mode has no flattening
    /// at all (its slope rises to the inflection point and falls once).
    pub shoulder_max_slope_ratio: f64,
    /// A single bin more than this many Poisson deviations below (above) both neighbours is a
    /// quantization artefact and is filled in (see `spikes::find_quantization_outliers`). 6: a
    /// dense Poisson histogram of 256 bins has such a bin about once in 10^5 histograms, while
    /// the artefacts it removes are 8-100 deviations deep on the MNI152 template.
    pub quantization_z: f64,
    /// When GM and WM are found but CSF is not a mode, CSF is the flattest flattening of the
    /// flank below GM within the CSF ratio band whose slope falls to at most this fraction of
    /// its steeper stretches (0.9) ...
    pub faint_csf_max_slope_ratio: f64,
    /// ... by at least this many Poisson deviations of the slope (2) ...
    pub faint_csf_noise_z: f64,
    /// ... at a height of at least this fraction of GM's (3 %). On the MNI152 template under a
    /// +-15 % bias field and Rician noise the CSF flattening has a slope ratio of 0.69-0.83 and
    /// 2.4-4.7 deviations over four noise seeds (ACCURACY.md), too faint for the general
    /// shoulder test; with GM and WM already placed, only this band is searched.
    pub faint_csf_min_height: f64,
    /// Which contrast the tissues are labelled for: detected from the histogram (`Auto`, see
    /// `contrast`), or forced to T1 or T2 (`--contrast`). Auto: T1 and T2 scans are both common,
    /// and a T2 read as T1 gets every tissue wrong.
    pub contrast: super::contrast::ContrastChoice,
    /// Which modality the volume is: from its metadata and values (`Auto`, see `modality`) or
    /// given (`--modality`).
    pub modality: super::modality::ModalityChoice,
}

impl Default for AnalysisParams {
    fn default() -> Self {
        AnalysisParams {
            sigma_bins: 1.0,
            noise_z: 4.0,
            min_relative_prominence: 0.05,
            spike_min_fraction: 0.02,
            spike_ratio: 5.0,
            major_fraction: 0.2,
            background_max_ratio: 0.12,
            csf_min_ratio: 0.12,
            gm_min_ratio: 0.5,
            wm_upper_sigmas: 3.0,
            edge_bins: 2.0,
            shoulder_sigma_bins: 3.0,
            shoulder_max_slope_ratio: 0.75,
            quantization_z: 6.0,
            faint_csf_max_slope_ratio: 0.9,
            faint_csf_noise_z: 2.0,
            faint_csf_min_height: 0.03,
            contrast: super::contrast::ContrastChoice::Auto,
            modality: super::modality::ModalityChoice::Auto,
        }
    }
}
