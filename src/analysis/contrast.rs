//! Which MR contrast the histogram shows (T1 or T2), so `assign` labels the modes as the right
//! tissues, and a one-line reason for the report.
//!
//! This is the last resort: the metadata (`modality`: DICOM tags, BIDS names and sidecars, the
//! NIfTI `descrip`) and `--contrast` decide first, and can also name PD, FLAIR and CT, which
//! the histogram cannot tell from T2 and T1. The bases are *metadata*, *values* (Hounsfield
//! units), *histogram* (this rule; "detected" below), *assumed* (nothing told: T1) and *given*.
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
//!   shape (small dark mode, two large bright ones), so the histogram reads FLAIR as T1 (GM and
//!   WM swapped). FLAIR is known from its metadata (name, TI) or `--contrast flair`.
//!
//! The rule (`B` = brightest major candidate, height at least `major_fraction` of the tallest
//! candidate, the same "major" as in `assign`; tissue modes = candidates at least
//! `TISSUE_MIN_RATIO` (0.15) of `B`'s intensity, darker ones are shells such as the skull of an
//! unmasked head; `T` = tallest tissue mode; `r = (T - zero) / (B - zero)`):
//! 1. Fewer than two candidates: no evidence. T1 is *assumed* (and said so).
//! 2. `r < 0.5`: the bulk of the tissue is less than half as bright as a large bright mode.
//!    That is T2 (WM/GM dark, CSF bright), or a T1 with very much CSF (tiny or atrophic heads:
//!    the phantom at 20^3 and 24^3 voxels has its CSF mode tallest, from partial volume). The
//!    widths tell them apart: CSF is the broad mode in both contrasts (partial volume with every
//!    tissue, pulsation) and WM the sharp one, so the half-widths at half maximum on the outer
//!    sides (`T`'s dark side, `B`'s bright side) are compared:
//!    - `T` at least as broad as `B`: T1 (CSF dark) *detected*;
//!    - `T` sharper: T2 *detected* when the picture is clean: at most three major tissue modes
//!      (a head has at most three large tissue classes) and every major mode between `T` and
//!      `B` nearer `T` (T2's GM sits next to WM; T1's GM next to WM at the bright end);
//!    - otherwise the evidence conflicts and T1 is *assumed*: more major modes, widths not
//!      measurable, `T` closer to the zero than two of its half-widths (the noise floor of a
//!      tiny volume such as the 16^3 phantom, not WM), or a middle mode placed as in T1.
//!      Histograms of random counts have many major modes, so they never pass as T2
//!      (tests/contrast.rs sweeps them; tests/peaks.rs's arbitrary-histogram property relies on
//!      the T1 order).
//! 3. `r >= 0.5`: the T1 shape. T1 is *detected*, unless a separate candidate brighter than
//!    every major mode, at least `BRIGHT_MODE_RATIO` (1.8) times `B` and at least
//!    `BRIGHT_MODE_HEIGHT` (5 %) of the tallest candidate's height, exists: that is T2 whose CSF
//!    mode is small (GM then is `B`, CSF is 2-3 times GM) or a T1 with a bright tail (fat,
//!    vessels, a lesion), and the histogram cannot say which, so T1 is *assumed* and the reason
//!    names the mode. 1.8 lies below T2's CSF/GM (1.96 at TE 80 ms, more at longer TE) and above
//!    the phantom's bright tail (lesion 1350 and vessels 1450 over WM 850: 1.6-1.7).
//!
//! `--contrast t1|t2|pd|flair` skips the rule (*given*). Whatever the outcome, the reason is one line
//! with the numbers it used, so a reader can check it.

use super::params::AnalysisParams;
use super::peaks::{Mode, right_half_maximum};
use crate::reference::BINS;

/// A bright mode above every major one must be this many times the brightest major mode's
/// intensity (from zero) to be possibly T2's CSF (module doc, rule 3).
pub const BRIGHT_MODE_RATIO: f64 = 1.8;

/// ... and at least this fraction of the tallest candidate's height (T2's CSF mode is typically
/// 10-30 % of WM's height; the phantom's lesion and vessel voxels are far fewer).
pub const BRIGHT_MODE_HEIGHT: f64 = 0.05;

/// Most major tissue modes a clean T2 histogram has (WM, GM, CSF).
const MAX_T2_MAJORS: usize = 3;

/// A dark mode closer to the zero than this many of its half-widths is not resolved from it:
/// the noise floor (air of a tiny volume), not WM (rule 2). 2 half-widths = 2.4 sd.
const UNRESOLVED_HALF_WIDTHS: f64 = 2.0;

/// Modes darker than this fraction of the brightest major mode's intensity (from zero) are not
/// tissue in either contrast: dark shells (bone, muscle, the skull of an unmasked head). T1 CSF
/// is at least 0.2 of WM, T2 WM at least 0.21 of CSF (TE 120 ms, module doc); 0.15 leaves room.
pub const TISSUE_MIN_RATIO: f64 = 0.15;

/// The contrast tissues are labelled for: which tissue is brighter than which.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Contrast {
    /// T1-weighted: CSF < GM < WM (what the paper's windows describe).
    #[default]
    T1,
    /// T2-weighted: WM < GM < CSF.
    T2,
    /// Proton-density weighted: WM < GM < CSF, with much less contrast than T2 (CSF at 1.3-1.6
    /// times WM, `assign::PD_CSF_MIN_RATIO`).
    Pd,
    /// Fluid-attenuated inversion recovery: CSF suppressed (darkest), WM < GM.
    Flair,
    /// X-ray CT (density): CSF < WM < GM, as in FLAIR; bone far above every tissue.
    Ct,
}

impl Contrast {
    /// Name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Contrast::T1 => "T1",
            Contrast::T2 => "T2",
            Contrast::Pd => "PD",
            Contrast::Flair => "FLAIR",
            Contrast::Ct => "CT",
        }
    }

    /// The order of the tissues, darkest first, for reasons and help texts.
    pub fn order(self) -> &'static str {
        match self {
            Contrast::T1 => "CSF < GM < WM",
            Contrast::T2 | Contrast::Pd => "WM < GM < CSF",
            Contrast::Flair | Contrast::Ct => "CSF < WM < GM",
        }
    }

    /// Whether WM and GM are brighter than CSF with WM the brightest (T1's order, the one the
    /// faint-CSF search and the paper's windows assume).
    pub fn is_t1_order(self) -> bool {
        self == Contrast::T1
    }
}

/// What the user asked for (`--contrast`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ContrastChoice {
    /// From the metadata, then the histogram; T1 when neither can tell.
    #[default]
    Auto,
    /// Always T1.
    T1,
    /// Always T2.
    T2,
    /// Always proton density.
    Pd,
    /// Always FLAIR.
    Flair,
}

impl ContrastChoice {
    /// The contrast given, None for `Auto`.
    pub fn given(self) -> Option<Contrast> {
        match self {
            ContrastChoice::Auto => None,
            ContrastChoice::T1 => Some(Contrast::T1),
            ContrastChoice::T2 => Some(Contrast::T2),
            ContrastChoice::Pd => Some(Contrast::Pd),
            ContrastChoice::Flair => Some(Contrast::Flair),
        }
    }
}

/// What a decision (the modality or the contrast) rests on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Basis {
    /// What the file says: DICOM tags, a BIDS name or sidecar, the NIfTI `descrip`, the name.
    Metadata,
    /// The voxel values (Hounsfield units).
    Values,
    /// The shape of the histogram (module doc).
    Histogram,
    /// Nothing told: the default (MR, T1), said so.
    Assumed,
    /// `--modality` / `--contrast`.
    Given,
}

/// The basis of a contrast decision (the same scale as the modality's).
pub type ContrastBasis = Basis;

impl Basis {
    /// Lowercase name, as in the JSON.
    pub fn name(self) -> &'static str {
        match self {
            Basis::Metadata => "metadata",
            Basis::Values => "values",
            Basis::Histogram => "histogram",
            Basis::Assumed => "assumed",
            Basis::Given => "given",
        }
    }
}

/// A sequence family that says more than the contrast (the tissue order follows the contrast).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SequenceKind {
    /// Angiography (TOF or phase-contrast MRA, CT angiography): vessels bright.
    Angio,
    /// BOLD fMRI (T2*-weighted EPI).
    Bold,
    /// Arterial spin labelling.
    Asl,
    /// Diffusion-weighted imaging.
    Dwi,
    /// Susceptibility-weighted imaging (T2*).
    Swi,
}

impl SequenceKind {
    /// Lowercase name, as in the JSON.
    pub fn name(self) -> &'static str {
        match self {
            SequenceKind::Angio => "angio",
            SequenceKind::Bold => "bold",
            SequenceKind::Asl => "asl",
            SequenceKind::Dwi => "dwi",
            SequenceKind::Swi => "swi",
        }
    }
}

/// The contrast used, how it was decided, and why (one line).
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct ContrastReport {
    /// Contrast the tissues are labelled for.
    pub contrast: Contrast,
    /// What the decision rests on.
    pub basis: ContrastBasis,
    /// One line with the facts or numbers behind the decision.
    pub reason: String,
    /// The sequence family, when the metadata names one (angio, bold, asl, dwi, swi).
    pub kind: Option<SequenceKind>,
    /// A contrast agent was given (DICOM ContrastBolusAgent, BIDS `ce-`, words such as Gd).
    pub post_contrast: bool,
    /// Why the kind is what it is, when a rule beyond the contrast's own reason decided it (a
    /// CT angiogram: the word, suffix or agent that says so).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub kind_reason: Option<String>,
}

impl ContrastReport {
    /// A report without a sequence kind or contrast agent.
    pub fn new(contrast: Contrast, basis: ContrastBasis, reason: String) -> Self {
        ContrastReport {
            contrast,
            basis,
            reason,
            kind: None,
            post_contrast: false,
            kind_reason: None,
        }
    }

    /// The contrast's name with its kind and agent: `T1 angio`, `T1 post-contrast`.
    pub fn label(&self) -> String {
        let mut label = self.contrast.name().to_string();
        if let Some(kind) = self.kind {
            label = format!("{label} {}", kind.name());
        }
        if self.post_contrast {
            label.push_str(" post-contrast");
        }
        label
    }

    /// One line for people: `T2 (histogram): ...`.
    pub fn summary(&self) -> String {
        let line = format!("{} ({}): {}", self.label(), self.basis.name(), self.reason);
        match &self.kind_reason {
            Some(why) => format!("{line}; {why}"),
            None => line,
        }
    }
}

/// The contrast to label `candidates` (ascending significant modes above the background) for.
pub fn decide(
    choice: ContrastChoice,
    s: &[f64; BINS],
    candidates: &[Mode],
    zero: f64,
    params: &AnalysisParams,
) -> ContrastReport {
    match choice {
        ContrastChoice::Auto => detect(s, candidates, zero, params),
        given => {
            let contrast = given.given().unwrap_or_default();
            ContrastReport::new(contrast, ContrastBasis::Given, given_reason(contrast))
        }
    }
}

/// The reason of a contrast given with `--contrast`.
pub fn given_reason(contrast: Contrast) -> String {
    format!(
        "--contrast {} (tissues labelled {})",
        contrast.name().to_ascii_lowercase(),
        contrast.order()
    )
}

/// `I_norm` of a mode, for the reason line.
fn at(m: &Mode) -> String {
    format!("{:.3}", m.position / BINS as f64)
}

/// The rule of the module doc.
fn detect(
    s: &[f64; BINS],
    candidates: &[Mode],
    zero: f64,
    params: &AnalysisParams,
) -> ContrastReport {
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
        return dark_bulk(s, t, b, &majors, zero, r);
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
        ContrastBasis::Histogram,
        format!(
            "the largest mode (I_norm {}) is {r:.2} of the brightest large mode ({}): GM/WM at \
             the bright end, CSF darker (T1 shape; FLAIR looks the same)",
            at(t),
            at(b)
        ),
    )
}

/// Half-width at half maximum of `m` on its dark side, in bins (linear interpolation between
/// bin centres); `None` when `s` never falls below half the height on that side.
fn left_half_width(s: &[f64; BINS], m: &Mode) -> Option<f64> {
    let half = 0.5 * m.height;
    let b = (0..m.first).rev().find(|&b| s[b] < half)?;
    // s[b] < half <= s[b + 1]: the crossing lies between centres b + 0.5 and b + 1.5.
    let (lo, hi) = (s[b], s[b + 1]);
    let t = if hi > lo {
        (half - lo) / (hi - lo)
    } else {
        1.0
    };
    Some(m.position - (b as f64 + 0.5 + t))
}

/// Half-width at half maximum of `m` on its bright side, in bins.
fn right_half_width(s: &[f64; BINS], m: &Mode) -> Option<f64> {
    right_half_maximum(s, m).map(|x| x - m.position)
}

/// Rule 2 of the module doc: the tallest tissue mode `t` is dark next to a large bright mode
/// `b`, at `r` of its intensity.
fn dark_bulk(
    s: &[f64; BINS],
    t: &Mode,
    b: &Mode,
    majors: &[&Mode],
    zero: f64,
    r: f64,
) -> ContrastReport {
    let report = |contrast, basis, why: String| {
        let hint = if basis == ContrastBasis::Assumed {
            "; T1 assumed (use --contrast t2 if the scan is T2-weighted)"
        } else {
            ""
        };
        ContrastReport::new(
            contrast,
            basis,
            format!(
                "the largest mode (I_norm {}) is only {r:.2} of the brightest large mode ({}); \
                 {why}{hint}",
                at(t),
                at(b)
            ),
        )
    };
    if majors.len() > MAX_T2_MAJORS {
        let why = format!("{} large tissue modes, more than a head has", majors.len());
        return report(Contrast::T1, ContrastBasis::Assumed, why);
    }
    let (Some(dark), Some(bright)) = (left_half_width(s, t), right_half_width(s, b)) else {
        let why = "their widths cannot be measured".to_string();
        return report(Contrast::T1, ContrastBasis::Assumed, why);
    };
    if t.position - zero < UNRESOLVED_HALF_WIDTHS * dark {
        let why = format!(
            "it lies within {UNRESOLVED_HALF_WIDTHS} of its half-widths ({dark:.1} bins) of the \
             zero: the noise floor, not a tissue"
        );
        return report(Contrast::T1, ContrastBasis::Assumed, why);
    }
    let widths = format!("outer half-widths {dark:.1} and {bright:.1} bins");
    if dark >= bright {
        let why = format!(
            "the dark mode is the broad one ({widths}): CSF dark, WM bright (T1 with much CSF)"
        );
        return report(Contrast::T1, ContrastBasis::Histogram, why);
    }
    let far_middle = majors.iter().find(|m| {
        m.position > t.position
            && m.position < b.position
            && m.position - t.position >= 0.5 * (b.position - t.position)
    });
    if let Some(m) = far_middle {
        let why = format!(
            "the bright mode is the broad one ({widths}), as in T2, but a large mode at I_norm {} \
             sits nearer the bright one, as in T1",
            at(m)
        );
        return report(Contrast::T1, ContrastBasis::Assumed, why);
    }
    let why = format!(
        "the dark mode is sharp, the bright one broad ({widths}): WM/GM dark, CSF brightest (T2 \
         shape)"
    );
    report(Contrast::T2, ContrastBasis::Histogram, why)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::peaks::find_modes;

    /// A smoothed histogram made of Gaussians `(centre bin, height, sd in bins)`, and its modes.
    fn histogram(parts: &[(f64, f64, f64)]) -> ([f64; BINS], Vec<Mode>) {
        let mut s = [0.0; BINS];
        for (b, v) in s.iter_mut().enumerate() {
            let x = b as f64 + 0.5;
            *v = parts
                .iter()
                .map(|&(c, h, sd)| h * (-0.5 * ((x - c) / sd).powi(2)).exp())
                .sum();
        }
        let modes = find_modes(&s);
        assert_eq!(modes.len(), parts.len(), "{parts:?}: {modes:?}");
        (s, modes)
    }

    fn decide_on(choice: ContrastChoice, parts: &[(f64, f64, f64)]) -> ContrastReport {
        let (s, modes) = histogram(parts);
        decide(choice, &s, &modes, 0.0, &AnalysisParams::default())
    }

    fn auto(parts: &[(f64, f64, f64)]) -> ContrastReport {
        decide_on(ContrastChoice::Auto, parts)
    }

    fn outcome(r: &ContrastReport) -> (Contrast, ContrastBasis) {
        (r.contrast, r.basis)
    }

    const DETECTED_T1: (Contrast, ContrastBasis) = (Contrast::T1, ContrastBasis::Histogram);
    const DETECTED_T2: (Contrast, ContrastBasis) = (Contrast::T2, ContrastBasis::Histogram);
    const ASSUMED_T1: (Contrast, ContrastBasis) = (Contrast::T1, ContrastBasis::Assumed);

    #[test]
    fn t1_shape_is_detected_as_t1() {
        // MNI152-like: small broad CSF far below, GM and WM large at the bright end.
        let r = auto(&[
            (66.0, 1000.0, 8.0),
            (171.0, 25000.0, 10.0),
            (220.0, 25800.0, 6.0),
        ]);
        assert_eq!(outcome(&r), DETECTED_T1, "{}", r.reason);
        // GM the tallest, at 0.5 of WM or more: still T1.
        let r = auto(&[
            (60.0, 300.0, 8.0),
            (120.0, 1000.0, 8.0),
            (200.0, 600.0, 6.0),
        ]);
        assert_eq!(outcome(&r), DETECTED_T1, "{}", r.reason);
        // CSF the tallest mode (tiny phantoms: much partial volume), but broad, WM sharp.
        let r = auto(&[(40.0, 1000.0, 10.0), (100.0, 500.0, 4.0)]);
        assert_eq!(outcome(&r), DETECTED_T1, "{}", r.reason);
        assert!(r.reason.contains("much CSF"), "{}", r.reason);
    }

    #[test]
    fn t2_shape_is_detected_as_t2() {
        // WM 0.17, GM 0.25, CSF 0.60 (module doc): WM sharp, CSF broad and a third as tall.
        let r = auto(&[
            (43.0, 1000.0, 3.0),
            (64.0, 900.0, 4.0),
            (154.0, 300.0, 12.0),
        ]);
        assert_eq!(outcome(&r), DETECTED_T2, "{}", r.reason);
        assert!(r.reason.contains("T2 shape"), "{}", r.reason);
        // An unmasked head: a dark skull shell (0.13 of CSF) is the tallest mode, but no tissue
        // (the 64^3 T2 phantom of tests/contrast.rs looks like this).
        let r = auto(&[
            (20.0, 1400.0, 3.0),
            (43.0, 1100.0, 3.0),
            (64.0, 1250.0, 4.0),
            (154.0, 900.0, 12.0),
        ]);
        assert_eq!(outcome(&r), DETECTED_T2, "{}", r.reason);
        // GM merged into WM: one large sharp dark mode and a broad bright one.
        let r = auto(&[(50.0, 1000.0, 5.0), (150.0, 400.0, 12.0)]);
        assert_eq!(outcome(&r), DETECTED_T2, "{}", r.reason);
    }

    #[test]
    fn conflicting_or_missing_evidence_assumes_t1_and_says_so() {
        // One mode: no evidence.
        let r = auto(&[(100.0, 1000.0, 5.0)]);
        assert_eq!(outcome(&r), ASSUMED_T1);
        assert!(r.reason.contains("too few"), "{}", r.reason);
        let none = decide(
            ContrastChoice::Auto,
            &[0.0; BINS],
            &[],
            0.0,
            &AnalysisParams::default(),
        );
        assert_eq!(outcome(&none), ASSUMED_T1);
        // Widths say T2, but the middle large mode sits next to the bright one, as in T1.
        let r = auto(&[
            (50.0, 1000.0, 3.0),
            (150.0, 500.0, 4.0),
            (180.0, 400.0, 10.0),
        ]);
        assert_eq!(outcome(&r), ASSUMED_T1, "{}", r.reason);
        assert!(r.reason.contains("nearer the bright"), "{}", r.reason);
        // The tallest mode sits on the zero (the 16^3 phantom's air noise): not tissue.
        let r = auto(&[(4.0, 1000.0, 3.0), (14.0, 400.0, 5.0)]);
        assert_eq!(outcome(&r), ASSUMED_T1, "{}", r.reason);
        assert!(r.reason.contains("noise floor"), "{}", r.reason);
        // Four large tissue modes: not a head's histogram.
        let r = auto(&[
            (40.0, 1000.0, 3.0),
            (60.0, 900.0, 3.0),
            (90.0, 800.0, 3.0),
            (200.0, 700.0, 10.0),
        ]);
        assert_eq!(outcome(&r), ASSUMED_T1, "{}", r.reason);
        // T2 whose CSF mode is small (below the major fraction): ambiguous with a T1 bright tail.
        let r = auto(&[
            (43.0, 1000.0, 3.0),
            (64.0, 900.0, 4.0),
            (154.0, 100.0, 12.0),
        ]);
        assert_eq!(outcome(&r), ASSUMED_T1, "{}", r.reason);
        assert!(r.reason.contains("bright tail"), "{}", r.reason);
        assert!(r.reason.contains("--contrast t2"), "{}", r.reason);
    }

    #[test]
    fn small_or_near_bright_tails_keep_t1_detected() {
        let t1 = [(30.0, 300.0, 6.0), (75.0, 900.0, 5.0), (100.0, 1000.0, 4.0)];
        let with = |tail: (f64, f64, f64)| {
            let mut all = t1.to_vec();
            all.push(tail);
            auto(&all)
        };
        // 2x WM but under 5 % of the tallest mode: a tail.
        assert_eq!(outcome(&with((200.0, 40.0, 5.0))), DETECTED_T1);
        // 1.7x WM (the phantom's lesion and vessels): a tail, however tall.
        assert_eq!(outcome(&with((170.0, 150.0, 5.0))), DETECTED_T1);
        // 2x WM and 15 % of the tallest: could be T2's CSF.
        assert_eq!(outcome(&with((200.0, 150.0, 5.0))), ASSUMED_T1);
    }

    #[test]
    fn forced_choices_are_obeyed_and_reported() {
        let t2 = [
            (43.0, 1000.0, 3.0),
            (64.0, 900.0, 4.0),
            (154.0, 300.0, 12.0),
        ];
        let r = decide_on(ContrastChoice::T1, &t2);
        assert_eq!(outcome(&r), (Contrast::T1, ContrastBasis::Given));
        let r = decide_on(ContrastChoice::T2, &[(100.0, 1000.0, 5.0)]);
        assert_eq!(outcome(&r), (Contrast::T2, ContrastBasis::Given));
        assert!(r.summary().starts_with("T2 (given): --contrast t2"));
    }

    #[test]
    fn half_widths_are_interpolated_at_half_maximum() {
        // A Gaussian of sd 4: HWHM = 4 sqrt(2 ln 2) = 4.71 bins on either side.
        let (s, modes) = histogram(&[(100.0, 1000.0, 4.0)]);
        let want = 4.0 * (2.0 * 2f64.ln()).sqrt();
        let left = left_half_width(&s, &modes[0]).unwrap();
        let right = right_half_width(&s, &modes[0]).unwrap();
        assert!(
            (left - want).abs() < 0.1 && (right - want).abs() < 0.1,
            "{left} {right}"
        );
        // A mode touching bin 0 has no measurable dark side.
        let (s, modes) = histogram(&[(0.5, 1000.0, 4.0)]);
        assert_eq!(left_half_width(&s, &modes[0]), None);
    }
}
