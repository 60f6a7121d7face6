//! What one scan's analysis says, as one serializable record: the paper's Table-1 row, the
//! tissue peaks, the windows, the contrast and the loader's warnings. The Python package's
//! `Volume.peaks()` and the batch command's JSON line per scan are this record, so a notebook
//! and a cohort run report the same fields under the same names.
//!
//! Decisions: plain data only (no engine, no timings), so it can be written before the
//! thumbnails and read back by the group level without a device; `table1` is the flat row
//! (one column per field) that the group TSV is made of.

use crate::analysis::{
    ContrastReport, InPaperWindow, Peaks, Table1Row, TissueReport, TissueWindows,
};

/// One scan's analysis (see the module doc).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ScanSummary {
    /// The input as the user named it (path or a label such as "phantom").
    pub file: String,
    /// Voxels along i, j, k.
    pub dims: [u32; 3],
    /// The paper's Table-1 row.
    pub table1: Table1Row,
    /// The three tissue peaks (I_norm and physical), null where no mode was found.
    pub peaks: Peaks,
    /// I_norm below which voxels count as background.
    pub background_threshold: f64,
    /// The windows the renderer uses (placed on this volume's peaks).
    pub windows: TissueWindows,
    /// The paper's fixed T1 windows.
    pub paper_windows: TissueWindows,
    /// Whether each peak lies inside the paper's window.
    pub in_paper_window: InPaperWindow,
    /// The contrast the tissues were labelled for, how it was decided and why.
    pub contrast: ContrastReport,
    /// The loader's repairs and warnings about the input.
    pub warnings: Vec<String>,
}

impl ScanSummary {
    /// The record of `report`, the analysis of a `dims` volume read from `file`.
    pub fn new(file: &str, dims: [u32; 3], report: &TissueReport, warnings: &[String]) -> Self {
        ScanSummary {
            file: file.to_string(),
            dims,
            table1: report.table1(),
            peaks: report.peaks,
            background_threshold: report.background_threshold,
            windows: report.adaptive_windows,
            paper_windows: report.paper_windows,
            in_paper_window: report.in_paper_window,
            contrast: report.contrast.clone(),
            warnings: warnings.to_vec(),
        }
    }
}
