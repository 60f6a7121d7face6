//! What a volume is (the modality: MR, CT, PET, other) and which contrast it has, decided from
//! what the file says before the histogram is asked.
//!
//! The readers (`volume::source`) gather [`ScanFacts`]: DICOM tags (Modality, ScanningSequence,
//! SequenceVariant, RepetitionTime, EchoTime, InversionTime, ContrastBolusAgent,
//! SeriesDescription, ProtocolName), a NIfTI's BIDS name (suffix and `ce-` entity), its JSON
//! sidecar and its `descrip`. [`identify`] turns them, and a summary of the voxel values
//! ([`ValueSummary`], for Hounsfield units), into an [`Identity`]; the histogram rule
//! (`contrast`) decides the contrast only when nothing here did.
//!
//! Decisions (each outcome carries its basis and a one-line reason naming the fact):
//! - Modality, first that speaks: `--modality`; the Modality tag (DICOM or sidecar); the BIDS
//!   suffix (`_ct`, `_pet`, or an MR suffix such as `_T2w`); words of SeriesDescription,
//!   ProtocolName, `descrip` (CT, CTA, PET, FDG; MR sequence words); TR/TE/TI present (only MR
//!   has them); words of the file name; the values (Hounsfield units, [`ValueSummary::looks_ct`]);
//!   otherwise MR is *assumed*. A CT whose values are not Hounsfield units (rescaled to 0..255,
//!   say) keeps its metadata's CT and the reason says the values disagree.
//! - Contrast, first that speaks: `--contrast`; a CT (density order, `Contrast::Ct`); the BIDS
//!   suffix; contrast words of SeriesDescription, ProtocolName, `descrip` (T1, T2, PD, FLAIR
//!   and sequence names, `rules::words`); the timing (TR, TE, TI: `rules::timing`); the words of
//!   the file name; then the histogram. Explicit names come before the timing because a
//!   sequence named by its operator is what the site meant, and timing rules have exceptions
//!   (MPRAGE's TR is the inversion period); when both speak and disagree the reason says so.
//! - Sequence families (angio, BOLD, ASL, DWI, SWI) come from the same words and suffixes and
//!   set the tissue order when no contrast word does: angio (TOF) T1, BOLD/DWI/SWI T2 (T2*),
//!   ASL PD. A contrast agent (DICOM ContrastBolusAgent, sidecar ContrastBolusAgent, BIDS `ce-`,
//!   words Gd, gado, C+, post) flags a post-contrast scan.
//! - Nothing here reads files or panics: the facts are plain strings and numbers, and bad ones
//!   (non-finite or negative times) are ignored.

use super::contrast::{Basis, Contrast, ContrastChoice, ContrastReport, SequenceKind};

use super::modality_rules as rules;

pub use rules::{Named, is_known_suffix, timing, words};

/// What the file says about the scan (every field optional; the readers fill what they find).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct ScanFacts {
    /// DICOM Modality (MR, CT, PT, ...) or the sidecar's `Modality`.
    pub modality: Option<String>,
    /// DICOM ScanningSequence (SE, GR, IR, EP, ...).
    pub scanning_sequence: Option<String>,
    /// DICOM SequenceVariant (SK, SP, MP, ...).
    pub sequence_variant: Option<String>,
    /// RepetitionTime, ms.
    pub repetition_time_ms: Option<f64>,
    /// EchoTime, ms.
    pub echo_time_ms: Option<f64>,
    /// InversionTime, ms.
    pub inversion_time_ms: Option<f64>,
    /// ContrastBolusAgent as written.
    pub contrast_agent: Option<String>,
    /// SeriesDescription.
    pub series_description: Option<String>,
    /// ProtocolName.
    pub protocol_name: Option<String>,
    /// The BIDS suffix of the file name (`T1w`, `T2w`, `FLAIR`, `angio`, `ct`, ...), as written.
    pub bids_suffix: Option<String>,
    /// The value of the BIDS `ce-` entity (contrast agent), as written.
    pub bids_ce: Option<String>,
    /// The NIfTI header's `descrip`.
    pub descrip: Option<String>,
    /// The file's name without its extension.
    pub file_name: Option<String>,
    /// Where the facts came from (`DICOM header`, `BIDS sidecar NAME.json`, ...).
    pub sources: Vec<String>,
}

impl ScanFacts {
    /// A time in ms if it is one (finite, > 0).
    fn time(v: Option<f64>) -> Option<f64> {
        v.filter(|t| t.is_finite() && *t > 0.0)
    }

    /// TR, TE, TI in ms (None where absent or unusable).
    pub fn times(&self) -> (Option<f64>, Option<f64>, Option<f64>) {
        (
            Self::time(self.repetition_time_ms),
            Self::time(self.echo_time_ms),
            Self::time(self.inversion_time_ms),
        )
    }

    /// The texts whose words are read, with their names, most trusted first.
    pub fn texts(&self) -> Vec<(&'static str, &str)> {
        [
            ("SeriesDescription", &self.series_description),
            ("ProtocolName", &self.protocol_name),
            ("descrip", &self.descrip),
        ]
        .into_iter()
        .filter_map(|(name, t)| t.as_deref().map(|t| (name, t)))
        .filter(|(_, t)| !t.trim().is_empty())
        .collect()
    }
}

/// The imaging modality.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Modality {
    /// Magnetic resonance.
    #[default]
    Mr,
    /// X-ray computed tomography.
    Ct,
    /// Positron emission tomography (DICOM `PT`).
    Pt,
    /// Anything else (ultrasound, nuclear medicine, an unknown tag).
    Other,
}

impl Modality {
    /// Name in reports (DICOM's spelling).
    pub fn name(self) -> &'static str {
        match self {
            Modality::Mr => "MR",
            Modality::Ct => "CT",
            Modality::Pt => "PT",
            Modality::Other => "other",
        }
    }

    /// DICOM's Modality value read as one of these.
    pub fn from_tag(tag: &str) -> Modality {
        match tag.trim().to_ascii_uppercase().as_str() {
            "MR" | "MRI" => Modality::Mr,
            "CT" => Modality::Ct,
            "PT" | "PET" => Modality::Pt,
            _ => Modality::Other,
        }
    }
}

/// What the user asked for (`--modality`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ModalityChoice {
    /// From the metadata, then the values; MR when neither tells.
    #[default]
    Auto,
    /// This modality, whatever the file says.
    Given(Modality),
}

/// The modality, what the decision rests on, and why.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct ModalityReport {
    /// The modality.
    pub modality: Modality,
    /// Metadata, values, assumed or given.
    pub basis: Basis,
    /// One line naming the fact or the numbers.
    pub reason: String,
}

impl ModalityReport {
    /// One line for people: `CT (metadata): ...`.
    pub fn summary(&self) -> String {
        format!(
            "{} ({}): {}",
            self.modality.name(),
            self.basis.name(),
            self.reason
        )
    }
}

impl Default for ModalityReport {
    fn default() -> Self {
        ModalityReport {
            modality: Modality::Mr,
            basis: Basis::Assumed,
            reason: "nothing tells what the scan is; MR assumed (use --modality)".into(),
        }
    }
}

/// Counts of the physical values in Hounsfield-unit bands (a sample of the voxels suffices).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct ValueSummary {
    /// Finite values counted.
    pub counted: u64,
    /// Values in [-1100, -900]: air in HU.
    pub air: u64,
    /// Values in [-3100, -1100): padding outside a CT's field of view (-2048, -3024).
    pub padding: u64,
    /// Values in [-150, 150]: water, fat's edge, brain, blood.
    pub soft: u64,
    /// Values of at least 300: bone, calcium, iodinated contrast.
    pub dense: u64,
    /// Smallest value counted.
    pub min: f64,
    /// Largest value counted.
    pub max: f64,
}

/// CT needs at least this fraction of the values at air (-1000 HU): a head CT's field of
/// view holds 20-60 % air; a skull-stripped or tightly cropped one may have less, and falls to
/// the metadata.
pub const CT_AIR_FRACTION: f64 = 0.02;
/// ... and at least this fraction of soft tissue or water (-150..150 HU) ...
pub const CT_SOFT_FRACTION: f64 = 0.02;
/// ... and a maximum of at least this many HU (bone, 700-3000).
pub const CT_MIN_MAX_HU: f64 = 300.0;

impl ValueSummary {
    /// Counts one physical value (non-finite ones are skipped).
    pub fn add(&mut self, v: f64) {
        if !v.is_finite() {
            return;
        }
        if self.counted == 0 {
            (self.min, self.max) = (v, v);
        }
        self.counted += 1;
        self.min = self.min.min(v);
        self.max = self.max.max(v);
        if (-1100.0..=-900.0).contains(&v) {
            self.air += 1;
        } else if (-3100.0..-1100.0).contains(&v) {
            self.padding += 1;
        } else if (-150.0..=150.0).contains(&v) {
            self.soft += 1;
        } else if v >= 300.0 {
            self.dense += 1;
        }
    }

    /// The summary of `values`.
    pub fn of(values: impl IntoIterator<Item = f64>) -> ValueSummary {
        let mut s = ValueSummary::default();
        values.into_iter().for_each(|v| s.add(v));
        s
    }

    fn fraction(&self, n: u64) -> f64 {
        n as f64 / self.counted.max(1) as f64
    }

    /// Whether the values look like Hounsfield units: air near -1000 HU (plus padding), soft
    /// tissue near 0 and something dense; MR magnitudes are never negative there.
    pub fn looks_ct(&self) -> bool {
        self.counted > 0
            && self.fraction(self.air + self.padding) >= CT_AIR_FRACTION
            && self.fraction(self.air) > 0.0
            && self.fraction(self.soft) >= CT_SOFT_FRACTION
            && self.max >= CT_MIN_MAX_HU
            && self.min >= -3100.0
    }

    /// One line with the numbers behind [`ValueSummary::looks_ct`].
    pub fn describe(&self) -> String {
        format!(
            "values {:.0}..{:.0}, {:.1} % at air (-1000 HU), {:.1} % at -150..150",
            self.min,
            self.max,
            100.0 * self.fraction(self.air + self.padding),
            100.0 * self.fraction(self.soft)
        )
    }
}

/// What the scan is, as far as the metadata, the values and the user tell before the histogram.
#[derive(Clone, Debug, PartialEq)]
pub struct Identity {
    /// The modality (always decided: MR is the assumption).
    pub modality: ModalityReport,
    /// The contrast, when something other than the histogram decided it.
    pub contrast: Option<ContrastReport>,
    /// The sequence family the metadata names (also when the histogram decides the contrast).
    pub kind: Option<SequenceKind>,
    /// Why a CT is an angiogram (`kind` is then `Angio`): the fact that says so.
    pub ct_angiography: Option<String>,
    /// Whether the metadata names a contrast agent.
    pub post_contrast: bool,
}

impl Identity {
    /// Only the user's choices (no facts): an in-memory volume or a histogram alone.
    pub fn from_choices(modality: ModalityChoice, contrast: ContrastChoice) -> Identity {
        identify(&ScanFacts::default(), None, modality, contrast)
    }

    /// The contrast report, asking the histogram (`detect`) only when nothing else decided.
    pub fn contrast_or_else(&self, detect: impl FnOnce() -> ContrastReport) -> ContrastReport {
        let mut report = self.contrast.clone().unwrap_or_else(detect);
        report.kind = report.kind.or(self.kind);
        report.post_contrast |= self.post_contrast;
        report
    }
}

/// The decision of the module doc.
pub fn identify(
    facts: &ScanFacts,
    values: Option<&ValueSummary>,
    modality: ModalityChoice,
    contrast: ContrastChoice,
) -> Identity {
    let modality = decide_modality(facts, values, modality);
    let named = rules::named_contrast(facts);
    let ct_angiography = (modality.modality == Modality::Ct)
        .then(|| rules::ct_angiography(facts))
        .flatten();
    let kind = if ct_angiography.is_some() {
        Some(SequenceKind::Angio)
    } else {
        named.as_ref().and_then(|n| n.kind)
    };
    let post_contrast = rules::post_contrast(facts);
    let contrast = if let Some(given) = contrast.given() {
        Some(ContrastReport::new(
            given,
            Basis::Given,
            super::contrast::given_reason(given),
        ))
    } else if modality.modality == Modality::Ct {
        let basis = modality.basis;
        let mut report = ContrastReport::new(
            Contrast::Ct,
            basis,
            format!(
                "a CT (modality from {}): density order {}, bone brightest",
                basis.name(),
                Contrast::Ct.order()
            ),
        );
        report.kind_reason = ct_angiography
            .as_ref()
            .map(|why| format!("a CT angiogram: {why}"));
        Some(report)
    } else if modality.modality == Modality::Mr {
        named.and_then(|n| {
            n.contrast
                .map(|c| ContrastReport::new(c, Basis::Metadata, n.reason))
        })
    } else {
        None
    };
    Identity {
        modality,
        contrast,
        kind,
        ct_angiography,
        post_contrast,
    }
}

/// The modality rule of the module doc.
fn decide_modality(
    facts: &ScanFacts,
    values: Option<&ValueSummary>,
    choice: ModalityChoice,
) -> ModalityReport {
    let report = |modality, basis, reason: String| ModalityReport {
        modality,
        basis,
        reason,
    };
    if let ModalityChoice::Given(m) = choice {
        return report(
            m,
            Basis::Given,
            format!("--modality {}", m.name().to_lowercase()),
        );
    }
    let not_hu = |m: Modality, reason: String| match values {
        Some(v) if m == Modality::Ct && v.counted > 0 && !v.looks_ct() => format!(
            "{reason}; the {} are not Hounsfield units (rescaled?), so CT windows in HU do not \
             apply",
            v.describe()
        ),
        _ => reason,
    };
    let hu = values.filter(|v| v.looks_ct());
    if let Some(v) = hu.filter(|_| rules::mr_only_by_angiography(facts)) {
        return report(
            Modality::Ct,
            Basis::Values,
            format!(
                "Hounsfield units ({}), and the name says angiography: a CT angiogram",
                v.describe()
            ),
        );
    }
    if let Some(m) = rules::metadata_modality(facts) {
        let reason = not_hu(m.0, m.1);
        return report(m.0, Basis::Metadata, reason);
    }
    if let Some(v) = hu {
        return report(
            Modality::Ct,
            Basis::Values,
            format!("Hounsfield units: {}", v.describe()),
        );
    }
    ModalityReport::default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hounsfield_values_are_recognised_and_mr_magnitudes_are_not() {
        // A head CT: 40 % air, 45 % brain and water, 10 % bone, a little fat.
        let ct = ValueSummary::of(
            (0..1000)
                .map(|i| match i % 20 {
                    0..=7 => -1000.0,
                    8..=16 => 35.0,
                    17 | 18 => 1200.0,
                    _ => -90.0,
                })
                .chain([-1024.0, 2500.0]),
        );
        assert!(ct.looks_ct(), "{ct:?}");
        let mr = ValueSummary::of((0..1000).map(|i| f64::from(i % 700)));
        assert!(!mr.looks_ct(), "{mr:?}");
        assert!(!ValueSummary::default().looks_ct());
        // The same CT shifted to 0..4095 (a stored value without its rescale): not HU.
        let shifted = ValueSummary::of((0..1000).map(|i| if i % 2 == 0 { 24.0 } else { 1060.0 }));
        assert!(!shifted.looks_ct());
    }

    #[test]
    fn a_ct_named_or_given_contrast_as_an_angiogram_is_angio_and_a_plain_ct_is_not() {
        let hu = ValueSummary::of((0..1000).map(|i| match i % 10 {
            0..=3 => -1000.0,
            4..=8 => 40.0,
            _ => 1200.0,
        }));
        let id = |facts: ScanFacts| {
            identify(
                &facts,
                Some(&hu),
                ModalityChoice::Auto,
                ContrastChoice::Auto,
            )
        };
        let named = |file: &str| ScanFacts {
            file_name: Some(file.into()),
            ..Default::default()
        };
        let plain = id(named("head_ct"));
        assert_eq!(plain.modality.modality, Modality::Ct);
        assert_eq!((plain.kind, plain.ct_angiography), (None, None));
        for (facts, why) in [
            (named("head_CTA"), "names CTA"),
            (named("CT_AVM"), "names AVM (a vascular lesion"),
            (
                ScanFacts {
                    modality: Some("CT".into()),
                    contrast_agent: Some("Omnipaque".into()),
                    ..Default::default()
                },
                "ContrastBolusAgent 'Omnipaque' on a CT",
            ),
            (
                ScanFacts {
                    bids_suffix: Some("angio".into()),
                    ..Default::default()
                },
                "BIDS suffix _angio",
            ),
        ] {
            let got = id(facts);
            assert_eq!(got.modality.modality, Modality::Ct, "{got:?}");
            assert_eq!(got.kind, Some(SequenceKind::Angio), "{got:?}");
            let reason = got.contrast.and_then(|c| c.kind_reason).unwrap_or_default();
            assert!(reason.contains(why), "{reason}");
        }
        // An MR angiogram stays MR: magnitudes are not Hounsfield units.
        let mr = ValueSummary::of((0..1000).map(|i| f64::from(i % 700)));
        let facts = ScanFacts {
            bids_suffix: Some("angio".into()),
            ..Default::default()
        };
        let tof = identify(
            &facts,
            Some(&mr),
            ModalityChoice::Auto,
            ContrastChoice::Auto,
        );
        assert_eq!(tof.modality.modality, Modality::Mr);
        assert_eq!(tof.ct_angiography, None);
        // "no" as the agent is no agent.
        let none = id(ScanFacts {
            modality: Some("CT".into()),
            contrast_agent: Some("None".into()),
            ..Default::default()
        });
        assert_eq!(none.kind, None);
    }

    #[test]
    fn nothing_known_is_mr_t1_assumed_by_the_histogram() {
        let id = Identity::from_choices(ModalityChoice::Auto, ContrastChoice::Auto);
        assert_eq!(id.modality.modality, Modality::Mr);
        assert_eq!(id.modality.basis, Basis::Assumed);
        assert_eq!(id.contrast, None);
        let given =
            Identity::from_choices(ModalityChoice::Given(Modality::Ct), ContrastChoice::Flair);
        assert_eq!(given.modality.basis, Basis::Given);
        let c = given.contrast.expect("given");
        assert_eq!((c.contrast, c.basis), (Contrast::Flair, Basis::Given));
    }
}
