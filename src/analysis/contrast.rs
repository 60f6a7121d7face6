//! Which MR contrast the histogram shows (T1 or T2), so `assign` labels the modes as the right
//! tissues, and a one-line reason for the report.
//!
//! What tells the contrasts apart in the histogram of a head (only the significant modes above
//! the background, `candidates`, are used; ratios are intensities measured from the background
//! zero, as in `assign`):
//! - T1 (adult): CSF < GM < WM. The two large tissue classes, GM and WM, sit at the bright end;
//!   WM is the brightest large mode; CSF is a small, broad mode far below (0.2-0.45 of WM). So
//!   the tallest mode is GM or WM, at least `gm_min_ratio` (0.5) of the brightest major mode.
//! - T2: WM < GM < CSF. WM and GM are the two large modes at the dark end and lie close together
//!   (GM about 1.2-1.6 times WM); CSF is the brightest mode, 2.5-4 times WM, and usually smaller.
//!   Worked example (spin echo, TR 4000 ms, TE 100 ms, 3 T relaxation times, proton densities WM
//!   0.7, GM 0.8, CSF 1.0): WM 0.17, GM 0.25, CSF 0.60, so WM/CSF = 0.28, GM/CSF = 0.42; at TE
//!   80 ms GM/CSF = 0.51, at TE 120 ms 0.33.
//! - FLAIR: CSF suppressed (dark, small), GM brighter than WM. In a histogram this is the T1
//!   shape (small dark mode, two large bright ones), so FLAIR is read as T1 and its GM and WM are
//!   swapped. This is a documented limit; `--contrast` cannot express FLAIR either.
//!
//! The rule (`B` = brightest major candidate, height at least `major_fraction` of the tallest
//! candidate, the same "major" as in `assign`; tissue modes = candidates at least
//! `TISSUE_MIN_RATIO` (0.15) of `B`'s intensity, darker ones are shells such as the skull of an
//! unmasked head; `T` = tallest tissue mode; `r = (T - zero) / (B - zero)`):
//! 1. Fewer than two candidates: no evidence. T1 is *assumed* (and said so).
//! 2. `r < 0.5`: the bulk of the tissue is less than half as bright as a large bright mode, which
//!    is T2 (T1 would need CSF to be the largest class). T2 is *detected* when the picture is
//!    clean: at most three major tissue modes (a head has at most three large tissue classes), and
//!    every major mode between `T` and `B` lies nearer `T` than `B` (T2's GM sits next to WM; in
//!    a T1 with a huge CSF mode, GM sits next to WM at the bright end). Otherwise the evidence
//!    conflicts and T1 is *assumed*. Histograms of random counts have many major modes, so they
//!    never pass as T2 (tests/peaks.rs's arbitrary-histogram property keeps the T1 order).
//! 3. `r >= 0.5`: the T1 shape. T1 is *detected*, unless a separate candidate brighter than
//!    every major mode, at least `BRIGHT_MODE_RATIO` (1.8) times `B` and at least
//!    `BRIGHT_MODE_HEIGHT` (5 %) of the tallest candidate's height, exists: that is T2 whose CSF mode is small (GM
//!    then is `B`, CSF is 2-3 times GM) or a T1 with a bright tail (fat, vessels, a lesion), and
//!    the histogram cannot say which, so T1 is *assumed* and the reason names the mode. 1.8 lies
//!    below T2's CSF/GM (1.96 at TE 80 ms, more at longer TE) and above the phantom's bright tail
//!    (lesion 1350 and vessels 1450 over WM 850: 1.6-1.7).
//!
//! `--contrast t1|t2` skips the rule (*forced*). Whatever the outcome, the reason is one line
//! with the numbers it used, so a reader can check it.

use super::params::AnalysisParams;
use super::peaks::Mode;
use crate::reference::BINS;

/// A bright mode above every major one must be this many times the brightest major mode's
/// intensity (from zero) to be possibly T2's CSF (module doc, rule 3).
pub const BRIGHT_MODE_RATIO: f64 = 1.8;

/// ... and at least this fraction of the tallest candidate's height (T2's CSF mode is typically
/// 10-30 % of WM's height; the phantom's lesion and vessel voxels are far fewer).
pub const BRIGHT_MODE_HEIGHT: f64 = 0.05;

/// Most major tissue modes a clean T2 histogram has (WM, GM, CSF).
const MAX_T2_MAJORS: usize = 3;

/// Modes darker than this fraction of the brightest major mode's intensity (from zero) are not
/// tissue in either contrast: dark shells (bone, muscle, the skull of an unmasked head). T1 CSF
/// is at least 0.2 of WM, T2 WM at least 0.21 of CSF (TE 120 ms, module doc); 0.15 leaves room.
pub const TISSUE_MIN_RATIO: f64 = 0.15;

/// The contrast tissues are labelled for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Contrast {
    /// T1-weighted: CSF < GM < WM (what the paper's windows describe).
    #[default]
    T1,
    /// T2-weighted: WM < GM < CSF.
    T2,
}

impl Contrast {
    /// Name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Contrast::T1 => "T1",
            Contrast::T2 => "T2",
        }
    }
}

/// What the user asked for (`--contrast`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ContrastChoice {
    /// Detect from the histogram; T1 when the evidence is missing or conflicts.
    #[default]
    Auto,
    /// Always T1.
    T1,
    /// Always T2.
    T2,
}

/// How the contrast was decided.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ContrastBasis {
    /// The histogram showed it (module doc).
    Detected,
    /// The histogram did not show it (too few modes, or conflicting evidence): T1 by default.
    Assumed,
    /// `--contrast t1|t2`.
    Forced,
}

impl ContrastBasis {
    /// Lowercase name, as in the JSON.
    pub fn name(self) -> &'static str {
        match self {
            ContrastBasis::Detected => "detected",
            ContrastBasis::Assumed => "assumed",
            ContrastBasis::Forced => "forced",
        }
    }
}

/// The contrast used, how it was decided, and why (one line).
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct ContrastReport {
    /// Contrast the tissues are labelled for.
    pub contrast: Contrast,
    /// Detected, assumed or forced.
    pub basis: ContrastBasis,
    /// One line with the numbers behind the decision.
    pub reason: String,
}

impl ContrastReport {
    fn new(contrast: Contrast, basis: ContrastBasis, reason: String) -> Self {
        ContrastReport {
            contrast,
            basis,
            reason,
        }
    }

    /// One line for people: `T2 (detected): ...`.
    pub fn summary(&self) -> String {
        format!(
            "{} ({}): {}",
            self.contrast.name(),
            self.basis.name(),
            self.reason
        )
    }
}

/// The contrast to label `candidates` (ascending significant modes above the background) for.
pub fn decide(
    choice: ContrastChoice,
    candidates: &[Mode],
    zero: f64,
    params: &AnalysisParams,
) -> ContrastReport {
    match choice {
        ContrastChoice::T1 => ContrastReport::new(
            Contrast::T1,
            ContrastBasis::Forced,
            "--contrast t1 (tissues labelled CSF < GM < WM)".into(),
        ),
        ContrastChoice::T2 => ContrastReport::new(
            Contrast::T2,
            ContrastBasis::Forced,
            "--contrast t2 (tissues labelled WM < GM < CSF)".into(),
        ),
        ContrastChoice::Auto => detect(candidates, zero, params),
    }
}

/// `I_norm` of a mode, for the reason line.
fn at(m: &Mode) -> String {
    format!("{:.3}", m.position / BINS as f64)
}

/// The rule of the module doc.
fn detect(candidates: &[Mode], zero: f64, params: &AnalysisParams) -> ContrastReport {
    let assumed =
        |reason: String| ContrastReport::new(Contrast::T1, ContrastBasis::Assumed, reason);
    if candidates.len() < 2 {
        return assumed(format!(
            "{} tissue mode(s) above the background, too few to tell T1 from T2; T1 assumed \
             (use --contrast t2 for a T2-weighted scan)",
            candidates.len()
        ));
    }
    let tallest = candidates.iter().map(|m| m.height).fold(0.0, f64::max);
    let is_major = |m: &&Mode| m.height >= params.major_fraction * tallest;
    let Some(b) = candidates
        .iter()
        .filter(is_major)
        .max_by(|a, b| a.position.total_cmp(&b.position))
    else {
        return assumed("no tissue mode with a height; T1 assumed".into());
    };
    let span = b.position - zero;
    if !(span > 0.0 && span.is_finite()) {
        return assumed("the tissue modes sit at the background level; T1 assumed".into());
    }
    // Tissue candidates: not darker than TISSUE_MIN_RATIO of `b` (dark shells are not tissue).
    let tissue: Vec<&Mode> = candidates
        .iter()
        .filter(|m| (m.position - zero) / span >= TISSUE_MIN_RATIO)
        .collect();
    let majors: Vec<&Mode> = tissue.iter().copied().filter(is_major).collect();
    let t = tissue
        .iter()
        .copied()
        .max_by(|a, b| a.height.total_cmp(&b.height))
        .unwrap_or(b);
    let r = (t.position - zero) / span;
    if r < params.gm_min_ratio {
        return t2_or_conflict(t, b, &majors, r);
    }
    // The T1 shape; a large bright mode above every major one could still be T2's small CSF.
    let bright = candidates
        .iter()
        .filter(|m| m.position > b.position && m.height >= BRIGHT_MODE_HEIGHT * tallest)
        .map(|m| (m, (m.position - zero) / span))
        .filter(|&(_, ratio)| ratio >= BRIGHT_MODE_RATIO)
        .max_by(|a, b| a.0.prominence.total_cmp(&b.0.prominence));
    if let Some((m, ratio)) = bright {
        return assumed(format!(
            "the tissue bulk is bright (T1 shape), but a separate bright mode at I_norm {} is \
             {ratio:.1}x the brightest large mode ({}): CSF of a T2 scan or a bright tail of a \
             T1 (fat, vessels, lesion); T1 assumed (use --contrast t2 if the scan is T2-weighted)",
            at(m),
            at(b)
        ));
    }
    ContrastReport::new(
        Contrast::T1,
        ContrastBasis::Detected,
        format!(
            "the largest mode (I_norm {}) is {r:.2} of the brightest large mode ({}): GM/WM at \
             the bright end, CSF darker (T1 shape; FLAIR looks the same)",
            at(t),
            at(b)
        ),
    )
}

/// Rule 2 of the module doc: the tallest mode `t` is dark next to a large bright mode `b`.
fn t2_or_conflict(t: &Mode, b: &Mode, majors: &[&Mode], r: f64) -> ContrastReport {
    let between = majors
        .iter()
        .filter(|m| m.position > t.position && m.position < b.position);
    let far_middle = between
        .clone()
        .find(|m| m.position - t.position >= 0.5 * (b.position - t.position));
    if majors.len() > MAX_T2_MAJORS || far_middle.is_some() {
        let why = match far_middle {
            Some(m) => format!(
                "a large mode at I_norm {} sits nearer the bright one",
                at(m)
            ),
            None => format!("{} large tissue modes, more than T2's three", majors.len()),
        };
        return ContrastReport::new(
            Contrast::T1,
            ContrastBasis::Assumed,
            format!(
                "the largest mode (I_norm {}) is only {r:.2} of a large bright mode ({}), as in \
                 T2, but {why}; T1 assumed (use --contrast t2 if the scan is T2-weighted)",
                at(t),
                at(b)
            ),
        );
    }
    ContrastReport::new(
        Contrast::T2,
        ContrastBasis::Detected,
        format!(
            "the largest mode (I_norm {}) is only {r:.2} of the brightest large mode ({}): \
             WM/GM at the dark end, CSF brightest (T2 shape)",
            at(t),
            at(b)
        ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mode(position: f64, height: f64) -> Mode {
        let b = position as usize;
        Mode {
            first: b,
            last: b,
            position,
            height,
            prominence: height,
        }
    }

    fn auto(candidates: &[Mode]) -> ContrastReport {
        decide(
            ContrastChoice::Auto,
            candidates,
            0.0,
            &AnalysisParams::default(),
        )
    }

    #[test]
    fn t1_shape_is_detected_as_t1() {
        // MNI152-like: small CSF far below, GM and WM large at the bright end.
        let r = auto(&[
            mode(66.0, 1000.0),
            mode(171.0, 25000.0),
            mode(220.0, 25800.0),
        ]);
        assert_eq!(
            (r.contrast, r.basis),
            (Contrast::T1, ContrastBasis::Detected)
        );
        // GM the tallest, at 0.5 of WM or more: still T1.
        let r = auto(&[mode(60.0, 300.0), mode(120.0, 1000.0), mode(200.0, 600.0)]);
        assert_eq!(
            (r.contrast, r.basis),
            (Contrast::T1, ContrastBasis::Detected)
        );
    }

    #[test]
    fn t2_shape_is_detected_as_t2() {
        // WM 0.17, GM 0.25, CSF 0.60 (module doc), CSF a third of WM's height but major.
        let r = auto(&[mode(43.0, 1000.0), mode(64.0, 900.0), mode(154.0, 300.0)]);
        assert_eq!(
            (r.contrast, r.basis),
            (Contrast::T2, ContrastBasis::Detected)
        );
        assert!(r.reason.contains("T2 shape"), "{}", r.reason);
        // An unmasked head: a dark skull shell (0.13 of CSF) is the tallest mode, but no tissue
        // (the 64^3 T2 phantom of tests/contrast.rs looks like this).
        let r = auto(&[
            mode(20.0, 1400.0),
            mode(43.0, 1100.0),
            mode(64.0, 1250.0),
            mode(154.0, 900.0),
        ]);
        assert_eq!(
            (r.contrast, r.basis),
            (Contrast::T2, ContrastBasis::Detected)
        );
        // GM merged into WM: one large dark mode and a bright major one.
        let r = auto(&[mode(50.0, 1000.0), mode(150.0, 400.0)]);
        assert_eq!(r.contrast, Contrast::T2);
    }

    #[test]
    fn conflicting_or_missing_evidence_assumes_t1_and_says_so() {
        // One mode: no evidence.
        let r = auto(&[mode(100.0, 1000.0)]);
        assert_eq!(
            (r.contrast, r.basis),
            (Contrast::T1, ContrastBasis::Assumed)
        );
        assert!(r.reason.contains("too few"), "{}", r.reason);
        assert_eq!(auto(&[]).basis, ContrastBasis::Assumed);
        // A tall dark mode, but the middle large mode sits next to the bright one (a T1 with a
        // huge CSF mode, hydrocephalus-like): conflicting, T1 assumed.
        let r = auto(&[mode(50.0, 1000.0), mode(150.0, 500.0), mode(180.0, 400.0)]);
        assert_eq!(
            (r.contrast, r.basis),
            (Contrast::T1, ContrastBasis::Assumed)
        );
        assert!(r.reason.contains("nearer the bright"), "{}", r.reason);
        // Four large modes: not a clean T2.
        let four = [
            mode(40.0, 1000.0),
            mode(60.0, 900.0),
            mode(90.0, 800.0),
            mode(200.0, 700.0),
        ];
        assert_eq!(auto(&four).basis, ContrastBasis::Assumed);
        // T2 whose CSF mode is small (below the major fraction): ambiguous with a T1 bright tail.
        let r = auto(&[mode(43.0, 1000.0), mode(64.0, 900.0), mode(154.0, 100.0)]);
        assert_eq!(
            (r.contrast, r.basis),
            (Contrast::T1, ContrastBasis::Assumed)
        );
        assert!(r.reason.contains("bright tail"), "{}", r.reason);
    }

    #[test]
    fn small_or_near_bright_tails_keep_t1_detected() {
        let t1 = [mode(30.0, 300.0), mode(75.0, 900.0), mode(100.0, 1000.0)];
        let with = |tail: Mode| {
            let mut all = t1.to_vec();
            all.push(tail);
            auto(&all)
        };
        // 2x WM but under 5 % of the tallest mode: a tail.
        assert_eq!(with(mode(200.0, 40.0)).basis, ContrastBasis::Detected);
        // 1.7x WM (the phantom's lesion and vessels): a tail, however tall.
        assert_eq!(with(mode(170.0, 150.0)).basis, ContrastBasis::Detected);
        // 2x WM and 15 % of the tallest: could be T2's CSF.
        let r = with(mode(200.0, 150.0));
        assert_eq!(
            (r.contrast, r.basis),
            (Contrast::T1, ContrastBasis::Assumed)
        );
    }

    #[test]
    fn forced_choices_are_obeyed_and_reported() {
        let t2 = [mode(43.0, 1000.0), mode(64.0, 900.0), mode(154.0, 300.0)];
        let p = AnalysisParams::default();
        let r = decide(ContrastChoice::T1, &t2, 0.0, &p);
        assert_eq!((r.contrast, r.basis), (Contrast::T1, ContrastBasis::Forced));
        let r = decide(ContrastChoice::T2, &[], 0.0, &p);
        assert_eq!((r.contrast, r.basis), (Contrast::T2, ContrastBasis::Forced));
        assert!(r.summary().starts_with("T2 (forced): --contrast t2"));
    }
}
