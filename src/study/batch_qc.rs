//! Quality flags of one batch scan (issue 32, item 4): what a person reviewing a cohort must
//! look at before trusting a row, written into the scan's summary and shown in the group TSV
//! and HTML.
//!
//! Decisions:
//! - Flags, not a score: each names what happened in words a reviewer can act on, and an empty
//!   list reads `ok`.
//! - `blank picture`: a thumbnail with no pixel off the background (the render's own test,
//!   `scene::visibility::pixels_off_background`); a scan that renders nothing is not a success.
//! - `fallback windows`: no tissue class was found, the foreground is shown instead.
//! - `no windows`: neither a tissue class nor the fallback was placed (nothing to show); the
//!   blank picture follows from it, this names the cause.
//! - `brain not found`: an MR head scan (structural, where extraction runs) in which no
//!   brain-like region was found, so its thumbnails show the whole head.
//! - `contrast guessed` / `contrast assumed`: the tissue order came from the histogram, or from
//!   nothing (T1 assumed), not from the file's metadata (DICOM tags, a BIDS suffix, a sidecar).

use crate::analysis::{Basis, TissueReport};
use crate::reference::brain_report::BrainDecision;

/// The flags of one scan (module doc); `lit` holds each thumbnail's pixels off the background
/// (empty when no thumbnails were rendered), `brain` the extraction's decision when it ran.
pub fn flags(report: &TissueReport, brain: Option<BrainDecision>, lit: &[usize]) -> Vec<String> {
    let mut flags = Vec::new();
    if lit.contains(&0) {
        flags.push("blank picture".to_string());
    }
    if report.fallback.is_some() {
        flags.push("fallback windows (no tissue class found)".to_string());
    } else if no_windows(report) {
        flags.push("no windows (no tissue class and no foreground found)".to_string());
    }
    if brain == Some(BrainDecision::NotFound) {
        flags.push("brain not found (the whole head is shown)".to_string());
    }
    match report.contrast.basis {
        Basis::Histogram => flags.push(format!(
            "contrast guessed from the histogram ({})",
            report.contrast.contrast.name()
        )),
        Basis::Assumed => flags.push("contrast assumed (T1: nothing told)".to_string()),
        _ => {}
    }
    flags
}

/// No window at all: neither a tissue class nor the foreground fallback was placed, so the
/// thumbnails can show nothing (seen on noise-free phantoms of a few discrete values).
fn no_windows(report: &TissueReport) -> bool {
    let w = &report.adaptive_windows;
    w.csf.is_none() && w.gm.is_none() && w.wm.is_none() && w.pathology.is_none()
}

/// The flags as one cell: `ok`, or the flags joined by `; `.
pub fn cell(flags: &[String]) -> String {
    if flags.is_empty() {
        "ok".to_string()
    } else {
        flags.join("; ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::{Basis, analyze};

    fn report() -> TissueReport {
        let mut hist = [0u32; crate::reference::BINS];
        hist[0] = 5000;
        for (b, count) in hist.iter_mut().enumerate().skip(1) {
            let g = |c: f64, n: f64| n * (-0.5 * ((b as f64 - c) / 6.0).powi(2)).exp();
            *count = (g(60.0, 800.0) + g(150.0, 3000.0) + g(210.0, 3500.0)) as u32;
        }
        analyze(&hist, 0.0, 1000.0, 100_000, 0)
    }

    #[test]
    fn each_problem_is_named_and_a_clean_scan_is_ok() {
        let mut r = report();
        r.contrast.basis = Basis::Metadata;
        assert_eq!(
            cell(&flags(&r, Some(BrainDecision::Head), &[10, 12, 9])),
            "ok"
        );
        let f = flags(&r, Some(BrainDecision::NotFound), &[10, 0, 9]);
        assert_eq!(f.len(), 2, "{f:?}");
        assert!(f[0].starts_with("blank picture") && f[1].starts_with("brain not found"));
        r.contrast.basis = Basis::Histogram;
        assert!(cell(&flags(&r, None, &[])).starts_with("contrast guessed from the histogram"));
        r.contrast.basis = Basis::Assumed;
        assert_eq!(
            cell(&flags(&r, None, &[])),
            "contrast assumed (T1: nothing told)"
        );
    }

    /// The fallback (foreground window, no tissue class) is named as such, not as `no windows`;
    /// a report with no window at all is `no windows`; a fitted scan carries neither.
    #[test]
    fn fallback_and_missing_windows_are_flagged() {
        let mut flat = report();
        flat.contrast.basis = Basis::Metadata;
        let window = crate::analysis::Window {
            lo: 0.2,
            hi: 1.0,
            edge: 0.002,
        };
        flat.fallback = Some(crate::analysis::Fallback {
            window,
            voxels: 1000,
            reason: "test".into(),
        });
        assert_eq!(
            cell(&flags(&flat, None, &[5, 5, 5])),
            "fallback windows (no tissue class found)"
        );
        flat.fallback = None;
        flat.adaptive_windows = crate::analysis::TissueWindows {
            csf: None,
            gm: None,
            wm: None,
            pathology: None,
        };
        assert!(
            cell(&flags(&flat, None, &[0]))
                .ends_with("no windows (no tissue class and no foreground found)")
        );
        let fitted = report();
        assert!(fitted.fallback.is_none());
        assert!(!cell(&flags(&fitted, None, &[5])).contains("fallback"));
    }
}
