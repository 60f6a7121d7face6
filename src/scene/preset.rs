//! Presets by modality (issue 28 item 3): one table of named looks, chosen automatically from
//! what the analysis decided the volume is, or by hand (`--preset NAME`). The CLI, the viewer
//! and Python read this table; nothing here knows about the command line.
//!
//! Decisions:
//! - A preset rewrites the classification the analysis windows made (windows, colours,
//!   opacities, visibility) and may ask for the vessel channel; the user's `--tissues`,
//!   `--window`, `--opacity` and `--color` still apply after it, so a preset is a default,
//!   never a lock.
//! - Automatic choice, first that applies: an angiogram is `angio`: an MR angiogram (BIDS
//!   `_angio`, TOF words) and a CT angiogram (a CT whose metadata names CTA, angio or a
//!   vascular lesion such as an AVM, or a contrast agent: `analysis::modality`); any other CT
//!   is `ct`; BOLD and ASL series are `epi`; a contrast agent in an MR's metadata is
//!   `post-contrast`; everything else is `mr` (the T1/T2/PD/FLAIR default, unchanged). The
//!   reason for an automatic `angio` on a CT is printed with the preset ([`Preset::why`]).
//! - CT windows are in Hounsfield units, mapped to I_norm through the report's range
//!   (`raw = imin + norm (imax - imin)`): skin and fat -200..0 HU, soft tissue 0..80 HU (both
//!   hidden by default), contrast-filled vessels 150..300 HU (red), bone 300 HU and up (ivory),
//!   so bone and vessels show by default. A window whose top lies above the range is left open
//!   above (`hi = 1 + edge`), because values past `imax` are clamped to 1. The values count as
//!   Hounsfield units when the range reaches below -500 (air) and above 300; otherwise (a CT
//!   stored rescaled, such as 0..255) the same four bands are cut from the foreground range
//!   above the background threshold: vessels from 45 % to 75 % of it, bone above 75 %, a
//!   fallback from the histogram that the preset's name records (`ct (values not HU)`).
//! - Angiography shows the bright band above the brightest tissue (the pathology slot, or the
//!   top 40 % of the foreground when the analysis found none) and the vessel channel (the
//!   multi-scale vesselness), with the brain tissues hidden. On a CT in Hounsfield units the
//!   band is the contrast-filled lumen, 150..600 HU (iodinated arterial blood is 200-500 HU;
//!   600 keeps most cortical bone, 1000 HU and up, out of it; thin bone and the skull's
//!   partial-volume edge still fall inside, which the vesselness then outweighs).
//! - EPI / BOLD / ASL: one foreground window (the background threshold up, open above) in the
//!   white-matter slot, translucent, the other tissues hidden: low-resolution series rarely
//!   have fittable classes, and the foreground is what the scan shows. A 4-D series is read
//!   as the mean of its frames for it (`engine::session`, unless a frame is named).

use super::classification::{Classification, MANUAL_EDGE, TissueClass, Window};
use crate::analysis::{Identity, Modality, SequenceKind, TissueReport};

/// One look of the table.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Preset {
    /// MR tissues (T1, T2, PD, FLAIR): the fitted CSF, GM and WM classes.
    Mr,
    /// CT in Hounsfield units: bone and contrast-filled vessels.
    Ct,
    /// Angiography (TOF MRA, CTA): the bright band and the vesselness.
    Angio,
    /// Post-contrast T1: the tissues plus the enhancing band above WM.
    PostContrast,
    /// Low-resolution EPI, BOLD, ASL: a foreground window.
    Epi,
    /// The paper's look: MR tissues with the translucent opacities of eq. 4's renderer before
    /// issue 34 (CSF 0.20, GM 0.30, WM 0.90 per mm); stills then use the headlight without depth
    /// cues unless asked (`SceneArgs::as_still`).
    Paper,
}

/// The table: every preset with its one-line description, in `--preset list` order.
pub const PRESETS: [(Preset, &str); 6] = [
    (
        Preset::Mr,
        "MR tissues (T1, T2, PD, FLAIR): CSF, GM and WM from the fitted classes (alias: brain)",
    ),
    (
        Preset::Ct,
        "CT in Hounsfield units: bone (300 HU up) and contrast vessels (150-300 HU) shown",
    ),
    (
        Preset::Angio,
        "angiography (TOF MRA, CTA): the bright band and the vesselness channel",
    ),
    (
        Preset::PostContrast,
        "post-contrast T1: CSF, GM, WM plus the enhancing band above WM",
    ),
    (
        Preset::Epi,
        "EPI, BOLD, ASL: one translucent foreground window on the mean frame of a 4-D series",
    ),
    (
        Preset::Paper,
        "the paper's look: translucent tissues (CSF 0.2, GM 0.3, WM 0.9), headlight, no cues",
    ),
];

/// The paper preset's opacities per mm (CSF, GM, WM): morphray's defaults before issue 34.
pub const PAPER_OPACITIES: [(TissueClass, f32); 3] = [
    (TissueClass::Csf, 0.20),
    (TissueClass::Gm, 0.30),
    (TissueClass::Wm, 0.90),
];

/// Hounsfield bands of the CT preset: (slot, lo, hi, visible, colour, opacity).
const CT_BANDS: [(TissueClass, f64, f64, bool, [f32; 3], f32); 4] = [
    (
        TissueClass::Csf,
        -200.0,
        0.0,
        false,
        [0.95, 0.75, 0.60],
        0.05,
    ),
    (TissueClass::Gm, 0.0, 80.0, false, [0.85, 0.45, 0.40], 0.10),
    (
        TissueClass::Pathology,
        150.0,
        300.0,
        true,
        [0.90, 0.10, 0.15],
        0.8,
    ),
    (
        TissueClass::Wm,
        300.0,
        3000.0,
        true,
        [0.96, 0.94, 0.82],
        0.9,
    ),
];

/// The contrast-filled lumen of a CT angiogram in Hounsfield units (module doc).
pub const CTA_VESSELS_HU: (f64, f64) = (150.0, 600.0);

/// The same bands as fractions of the foreground range, for a CT not in Hounsfield units.
const CT_FRACTIONS: [(f64, f64); 4] = [(0.0, 0.15), (0.15, 0.45), (0.45, 0.75), (0.75, 2.0)];

impl Preset {
    /// Every preset, in table order.
    pub const ALL: [Preset; 6] = [
        Preset::Mr,
        Preset::Ct,
        Preset::Angio,
        Preset::PostContrast,
        Preset::Epi,
        Preset::Paper,
    ];

    /// Name as typed on the command line and written in the outputs.
    pub fn name(self) -> &'static str {
        match self {
            Preset::Mr => "mr",
            Preset::Ct => "ct",
            Preset::Angio => "angio",
            Preset::PostContrast => "post-contrast",
            Preset::Epi => "epi",
            Preset::Paper => "paper",
        }
    }

    /// The one-line description of the table.
    pub fn summary(self) -> &'static str {
        PRESETS
            .iter()
            .find(|(p, _)| *p == self)
            .map_or("", |(_, s)| s)
    }

    /// A name (case-insensitive; `brain` is `mr`, `bold` and `asl` are `epi`, `tof` and `cta`
    /// are `angio`, `gd` is `post-contrast`).
    pub fn parse(text: &str) -> Option<Preset> {
        match text.trim().to_ascii_lowercase().as_str() {
            "mr" | "brain" => Some(Preset::Mr),
            "ct" => Some(Preset::Ct),
            "angio" | "tof" | "cta" => Some(Preset::Angio),
            "post-contrast" | "postcontrast" | "gd" => Some(Preset::PostContrast),
            "epi" | "bold" | "asl" => Some(Preset::Epi),
            "paper" => Some(Preset::Paper),
            _ => None,
        }
    }

    /// The valid names, comma-separated (for errors).
    pub fn names() -> String {
        Preset::ALL.map(Preset::name).join(", ")
    }

    /// The preset for what the analysis decided the volume is (module doc).
    pub fn auto(report: &TissueReport) -> Preset {
        let contrast = &report.contrast;
        Preset::auto_for(
            report.modality.modality,
            contrast.kind,
            contrast.post_contrast,
        )
    }

    /// [`Preset::auto`] before the histogram analysis: the choice rests on the identity alone
    /// (modality, sequence kind, agent), which is what lets the memory plan count the vessel
    /// channel the preset turns on.
    pub fn auto_identified(identity: &Identity) -> Preset {
        Preset::auto_for(
            identity.modality.modality,
            identity.kind,
            identity.post_contrast,
        )
    }

    /// The rule of the module doc.
    fn auto_for(modality: Modality, kind: Option<SequenceKind>, post_contrast: bool) -> Preset {
        if kind == Some(SequenceKind::Angio) {
            Preset::Angio
        } else if modality == Modality::Ct {
            Preset::Ct
        } else if matches!(kind, Some(SequenceKind::Bold | SequenceKind::Asl)) {
            Preset::Epi
        } else if post_contrast {
            Preset::PostContrast
        } else {
            Preset::Mr
        }
    }

    /// Whether it draws the vessel channel (the vesselness), in DVR.
    pub fn wants_vessels(self) -> bool {
        self == Preset::Angio
    }

    /// How the preset is named in outputs: its name, and for a CT whose values are not
    /// Hounsfield units, that its windows came from the histogram.
    pub fn label(self, report: &TissueReport) -> String {
        let ct = report.modality.modality == Modality::Ct;
        match self {
            Preset::Ct if !values_are_hu(report) => format!(
                "{} (values not HU: bands from the foreground range)",
                self.name()
            ),
            Preset::Angio if ct && values_are_hu(report) => format!(
                "{} (CT: vessels {:.0}..{:.0} HU)",
                self.name(),
                CTA_VESSELS_HU.0,
                CTA_VESSELS_HU.1
            ),
            Preset::Angio if ct => format!(
                "{} (CT, values not HU: vessels from the bright band)",
                self.name()
            ),
            _ => self.name().to_string(),
        }
    }

    /// Why the automatic choice took this preset, when the modality and contrast lines do not
    /// say it already: a CT that is an angiogram names the fact (module doc).
    pub fn why(self, report: &TissueReport) -> Option<String> {
        (self == Preset::Angio && report.modality.modality == Modality::Ct)
            .then(|| report.contrast.kind_reason.clone())
            .flatten()
    }

    /// Rewrites the classification the analysis made (module doc).
    pub fn apply(self, classification: &mut Classification, report: &TissueReport) {
        match self {
            Preset::Mr => {}
            Preset::Paper => {
                for (tissue, opacity) in PAPER_OPACITIES {
                    classification.style_mut(tissue).opacity = opacity;
                }
            }
            Preset::PostContrast => {
                let band = classification.style(TissueClass::Pathology).window;
                let band = band.or_else(|| Some(top_band(report, 0.8)));
                let style = classification.style_mut(TissueClass::Pathology);
                style.window = band;
                style.visible = true;
            }
            Preset::Ct => apply_ct(classification, report),
            Preset::Angio => {
                let band = classification.style(TissueClass::Pathology).window;
                // A CT in Hounsfield units has a known lumen band; otherwise the bright band.
                let band = cta_band(report)
                    .filter(|_| report.modality.modality == Modality::Ct)
                    .or(band)
                    .unwrap_or_else(|| top_band(report, 0.6));
                classification.show_only(&[TissueClass::Pathology]);
                let style = classification.style_mut(TissueClass::Pathology);
                style.window = Some(band);
            }
            Preset::Epi => {
                classification.show_only(&[TissueClass::Wm]);
                let style = classification.style_mut(TissueClass::Wm);
                style.window = Some(open_window(report.background_threshold));
                style.opacity = 0.3;
            }
        }
    }
}

/// Whether the report's range looks like Hounsfield units (air below -500, bone above 300).
pub fn values_are_hu(report: &TissueReport) -> bool {
    report.imin < -500.0 && report.imax > 300.0
}

/// The contrast-filled lumen in I_norm, when the values are Hounsfield units (module doc).
fn cta_band(report: &TissueReport) -> Option<Window> {
    let span = report.imax - report.imin;
    if !(values_are_hu(report) && span.is_finite() && span > 0.0) {
        return None;
    }
    let lo = ((CTA_VESSELS_HU.0 - report.imin) / span).max(0.0);
    let hi = (CTA_VESSELS_HU.1 - report.imin) / span;
    let hi = if hi >= 1.0 { 1.0 + MANUAL_EDGE } else { hi };
    (lo < hi && lo < 1.0).then_some(Window {
        lo,
        hi,
        edge: MANUAL_EDGE,
    })
}

/// A window from `lo` (I_norm) open above.
fn open_window(lo: f64) -> Window {
    let lo = if lo.is_finite() {
        lo.clamp(0.0, 0.99)
    } else {
        0.0
    };
    Window {
        lo,
        hi: 1.0 + MANUAL_EDGE,
        edge: MANUAL_EDGE,
    }
}

/// The top `1 - from` of the foreground range (above the background threshold), open above.
fn top_band(report: &TissueReport, from: f64) -> Window {
    let bg = finite_or(report.background_threshold, 0.0).clamp(0.0, 0.99);
    open_window(bg + from * (1.0 - bg))
}

fn finite_or(v: f64, or: f64) -> f64 {
    if v.is_finite() { v } else { or }
}

/// CT bands in I_norm: Hounsfield units through the range, or fractions of the foreground.
fn apply_ct(classification: &mut Classification, report: &TissueReport) {
    let hu = values_are_hu(report);
    let span = report.imax - report.imin;
    let bg = finite_or(report.background_threshold, 0.0).clamp(0.0, 0.99);
    for ((tissue, lo_hu, hi_hu, visible, colour, opacity), (lo_f, hi_f)) in
        CT_BANDS.into_iter().zip(CT_FRACTIONS)
    {
        let (lo, hi) = if hu && span.is_finite() && span > 0.0 {
            ((lo_hu - report.imin) / span, (hi_hu - report.imin) / span)
        } else {
            (bg + lo_f * (1.0 - bg), bg + hi_f * (1.0 - bg))
        };
        let hi = if hi >= 1.0 { 1.0 + MANUAL_EDGE } else { hi };
        let style = classification.style_mut(tissue);
        style.window = (lo < hi && lo < 1.0).then_some(Window {
            lo: lo.max(0.0),
            hi,
            edge: MANUAL_EDGE,
        });
        style.visible = visible;
        style.colour = colour;
        style.opacity = opacity;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_back_and_the_table_lists_every_preset_once() {
        for p in Preset::ALL {
            assert_eq!(Preset::parse(p.name()), Some(p));
            assert!(!p.summary().is_empty());
        }
        assert_eq!(PRESETS.map(|(p, _)| p), Preset::ALL);
        assert_eq!(Preset::parse("Brain"), Some(Preset::Mr));
        assert_eq!(Preset::parse("bone"), None);
    }
}
