//! The analysis report and the paper's Table-1 row.
//!
//! Decisions:
//! - "Used voxels" = finite voxels whose histogram bin is at or above the background threshold
//!   bin, i.e. the voxels not classed as background (air, masked zeros, dark shells). It is
//!   exact with respect to the histogram it was computed from.
//! - Every peak is given in `I_norm` and in raw (physical) units, `raw = imin + norm (imax -
//!   imin)`, computed as given (a report with non-finite bounds carries non-finite raw values,
//!   which serde_json writes as null).
//! - Missing tissues are `None` (JSON `null`), never a placeholder number.
//! - The report also lists every significant mode with its role and every spike, so a reader can
//!   see why a tissue is missing.

use super::contrast::ContrastReport;
use super::params::AnalysisParams;
use super::range::RangeChoice;
use super::windows::TissueWindows;

/// A tissue mode's location.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Peak {
    /// In `I_norm` (`[0, 1]`).
    pub norm: f64,
    /// In physical units: `imin + norm * (imax - imin)`, or `(1 - norm) * imin + norm * imax`
    /// when the range overflows f64 (float64 data near +-1.7e308).
    pub raw: f64,
}

impl Peak {
    /// A peak at `norm`, converted with the volume's physical range.
    pub fn new(norm: f64, imin: f64, imax: f64) -> Self {
        Peak {
            norm,
            raw: if (imax - imin).is_finite() {
                imin + norm * (imax - imin)
            } else {
                (1.0 - norm) * imin + norm * imax
            },
        }
    }
}

/// The three tissue modes; `None` = not present in the histogram.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Peaks {
    /// Cerebrospinal fluid.
    pub csf: Option<Peak>,
    /// Grey matter.
    pub gm: Option<Peak>,
    /// White matter.
    pub wm: Option<Peak>,
}

/// Whether each detected peak lies inside the paper's fixed window; `None` when missing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct InPaperWindow {
    /// CSF peak in 0.05-0.12.
    pub csf: Option<bool>,
    /// GM peak in 0.12-0.18.
    pub gm: Option<bool>,
    /// WM peak above 0.18.
    pub wm: Option<bool>,
}

/// What a significant mode of the smoothed histogram was taken for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ModeRole {
    /// Below the background threshold.
    Background,
    /// Cerebrospinal fluid.
    Csf,
    /// Grey matter.
    Gm,
    /// White matter.
    Wm,
    /// Above the background but not a tissue (dark shell, bright tail, extra mode).
    Other,
}

/// One significant mode of the smoothed histogram.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ModeInfo {
    /// Location.
    pub peak: Peak,
    /// Smoothed count at the top.
    pub height: f64,
    /// Topographic prominence in smoothed counts.
    pub prominence: f64,
    /// Role assigned.
    pub role: ModeRole,
}

/// A single-bin spike (masked zeros, padding, saturation).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct SpikeInfo {
    /// Histogram bin.
    pub bin: usize,
    /// Voxels in it.
    pub count: u32,
    /// Whether it counts as background (it lies below the tissue).
    pub background: bool,
}

/// The full result of [`super::analyze`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TissueReport {
    /// All voxels of frame 0, as given.
    pub total_voxels: usize,
    /// Finite voxels at or above the background threshold (see the module doc).
    pub used_voxels: u64,
    /// NaN or infinite voxels, as given.
    pub nonfinite_voxels: usize,
    /// Finite voxels: the histogram's sum.
    pub finite_voxels: u64,
    /// Physical intensity mapped to `I_norm = 0`.
    pub imin: f64,
    /// Physical intensity mapped to `I_norm = 1`.
    pub imax: f64,
    /// CSF, GM and WM modes.
    pub peaks: Peaks,
    /// Background threshold in `I_norm`: a bin edge, `bin / 256`.
    pub background_threshold: f64,
    /// Whether each peak falls in the paper's window.
    pub in_paper_window: InPaperWindow,
    /// Windows placed around the detected peaks.
    pub adaptive_windows: TissueWindows,
    /// The paper's fixed windows.
    pub paper_windows: TissueWindows,
    /// Every significant mode, ascending, with its role.
    pub modes: Vec<ModeInfo>,
    /// Every spike, ascending.
    pub spikes: Vec<SpikeInfo>,
    /// Gaussian smoothing width actually used, in bins.
    pub smoothing_sigma_bins: f64,
    /// Parameters used.
    pub params: AnalysisParams,
    /// How `imin..imax` was chosen: the mode, eq. 1's data min/max, the robust range (filled in
    /// by the engine, which knows the data; until then the default mode with no data).
    pub range: RangeChoice,
    /// Contrast the tissues were labelled for, what the decision rests on, and why.
    pub contrast: ContrastReport,
    /// What the volume is (MR, CT, ...), what the decision rests on, and why.
    pub modality: super::ModalityReport,
    /// The foreground window shown when no tissue class was found (in the WM slot of
    /// `adaptive_windows`), and why; None when tissue classes were found.
    pub fallback: Option<super::Fallback>,
    /// The tissue mixture fitted to the histogram (`tissue_fit`), when one was fitted.
    pub fit: Option<super::Fit>,
    /// A fit inside the brain mask that was not sound (the windows stayed with `fit` or the
    /// modes).
    pub rejected_fit: Option<super::Fit>,
    /// Which path placed `adaptive_windows`.
    pub windows_from: super::WindowsFrom,
}

/// One row of the paper's Table 1, flat (one column per field, for CSV or JSON lines).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Table1Row {
    /// All voxels.
    pub total_voxels: usize,
    /// Finite voxels above the background threshold.
    pub used_voxels: u64,
    /// NaN or infinite voxels.
    pub nonfinite_voxels: usize,
    /// Eq. 1's Imin: the smallest finite physical intensity (the paper's column).
    pub imin: Option<f64>,
    /// Eq. 1's Imax: the largest finite physical intensity (the paper's column).
    pub imax: Option<f64>,
    /// `robust` or `minmax`: how the range mapped to `I_norm` 0..1 was chosen.
    pub normalize: &'static str,
    /// Physical intensity mapped to `I_norm = 0` (the robust range's low end, or Imin).
    pub range_lo: f64,
    /// Physical intensity mapped to `I_norm = 1` (the robust range's high end, or Imax).
    pub range_hi: f64,
    /// CSF peak in eq. 1's `I_norm` (the paper's column).
    pub csf_norm_eq1: Option<f64>,
    /// GM peak in eq. 1's `I_norm`.
    pub gm_norm_eq1: Option<f64>,
    /// WM peak in eq. 1's `I_norm`.
    pub wm_norm_eq1: Option<f64>,
    /// CSF peak in the rendered `I_norm` (`range_lo..range_hi`, what the windows are in).
    pub csf_norm: Option<f64>,
    /// GM peak in `I_norm`.
    pub gm_norm: Option<f64>,
    /// WM peak in `I_norm`.
    pub wm_norm: Option<f64>,
    /// CSF peak in physical units.
    pub csf_raw: Option<f64>,
    /// GM peak in physical units.
    pub gm_raw: Option<f64>,
    /// WM peak in physical units.
    pub wm_raw: Option<f64>,
    /// Background threshold in `I_norm`.
    pub background_threshold: f64,
}

impl TissueReport {
    /// A peak in eq. 1's `I_norm` (`(raw - Imin) / (Imax - Imin)` over the data's finite range),
    /// what the paper's Table 1 and fixed windows are in. None without the peak or the range.
    pub fn eq1_norm(&self, peak: Option<Peak>) -> Option<f64> {
        let (lo, hi) = (self.range.data_min?, self.range.data_max?);
        let half = crate::reference::normalize::half_difference(hi, lo);
        let x = crate::reference::normalize::half_difference(peak?.raw, lo) / half;
        x.is_finite().then_some(x)
    }

    /// The flat Table-1 row.
    pub fn table1(&self) -> Table1Row {
        let p = &self.peaks;
        Table1Row {
            total_voxels: self.total_voxels,
            used_voxels: self.used_voxels,
            nonfinite_voxels: self.nonfinite_voxels,
            imin: self.range.data_min,
            imax: self.range.data_max,
            normalize: self.range.mode.name(),
            range_lo: self.imin,
            range_hi: self.imax,
            csf_norm_eq1: self.eq1_norm(p.csf),
            gm_norm_eq1: self.eq1_norm(p.gm),
            wm_norm_eq1: self.eq1_norm(p.wm),
            csf_norm: p.csf.map(|x| x.norm),
            gm_norm: p.gm.map(|x| x.norm),
            wm_norm: p.wm.map(|x| x.norm),
            csf_raw: p.csf.map(|x| x.raw),
            gm_raw: p.gm.map(|x| x.raw),
            wm_raw: p.wm.map(|x| x.raw),
            background_threshold: self.background_threshold,
        }
    }
}
