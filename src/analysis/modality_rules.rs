//! The rules of `modality`: what words, BIDS suffixes and sequence timings say.
//!
//! Decisions:
//! - Texts are read as words: upper-cased, split at everything that is not a letter or digit
//!   (`t1_mprage_sag` is T1, MPRAGE, SAG), and also squashed (separators removed) for the few
//!   names written with separators (`MP-RAGE`, `dark_fluid`). A word matches only whole: `T1`
//!   in `T1W`, never in `T10`.
//! - Explicit contrast words (T1, T2, PD, FLAIR and their weighted forms) outrank sequence
//!   families (MPRAGE, SPGR, BRAVO: T1; TSE, FSE, HASTE: T2), which several contrasts share
//!   (a T1 TSE exists); T1 FLAIR is T1.
//! - Timing, in ms (module doc of `modality`): TI 1500-3000 with a long TR (>= 4000) and a long
//!   TE (>= 40, when known) is FLAIR; TI <= 300 is STIR (T2-like); another TI with a short TE is
//!   inversion-prepared T1 (MPRAGE). Without TI: TE < 8 is a spoiled gradient echo (T1: SPGR,
//!   MPRAGE without its TI, TOF); TE >= 40 is T2 (spin echo) or T2* (gradient echo), the same
//!   tissue order; 8 <= TE < 40 is T1 with TR < 1000 and PD with TR >= 1500; otherwise silent.
//!   Known limits: a BOLD EPI (TE 30, TR 2000) reads as PD without its name.

use super::contrast::{Contrast, SequenceKind};
use super::modality::{Modality, ScanFacts};

/// What the words of one text say (the first word of each sort, with the word).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Said {
    /// An explicit contrast word.
    pub contrast: Option<(Contrast, String)>,
    /// A sequence-family word (weaker than a contrast word).
    pub family: Option<(Contrast, String)>,
    /// A sequence kind word.
    pub kind: Option<(SequenceKind, String)>,
    /// A modality word (CT, PET, or an MR word).
    pub modality: Option<(Modality, String)>,
    /// A contrast-agent word.
    pub agent: Option<String>,
}

/// A contrast, kind or both named by the metadata, and the reason.
#[derive(Clone, Debug, PartialEq)]
pub struct Named {
    /// The tissue order (None when only a kind is named and it sets none).
    pub contrast: Option<Contrast>,
    /// The sequence family.
    pub kind: Option<SequenceKind>,
    /// One line naming the fact.
    pub reason: String,
}

const T1: &[&str] = &[
    "T1",
    "T1W",
    "T1WI",
    "T1WEIGHTED",
    "T1FLAIR",
    "T1MPRAGE",
    "T1TSE",
    "T1SE",
    "T1FFE",
    "T1TFE",
    "3DT1",
    "T1C",
    "T1CE",
    "T1GD",
    "T1POST",
    "T1MAP",
];
const T2: &[&str] = &[
    "T2",
    "T2W",
    "T2WI",
    "T2WEIGHTED",
    "T2TSE",
    "T2FSE",
    "T2STAR",
    "T2STARW",
    "T2SPACE",
    "3DT2",
    "T2GRE",
    "STIR",
    "T2STIR",
];
const PD: &[&str] = &["PD", "PDW", "PDWI", "PDTSE", "PDFS", "PROTON"];
const FLAIR: &[&str] = &["FLAIR", "T2FLAIR", "DARKFLUID", "TIRM", "FLAIRW"];
const T1_FAMILY: &[&str] = &[
    "MPRAGE", "MP2RAGE", "SPGR", "FSPGR", "IRFSPGR", "BRAVO", "TFE", "FLASH", "VIBE", "UNIT1",
];
const T2_FAMILY: &[&str] = &["TSE", "FSE", "HASTE", "SSFSE", "RARE"];
const ANGIO: &[&str] = &[
    "TOF",
    "TOF3D",
    "3DTOF",
    "MRA",
    "ANGIO",
    "ANGIOGRAPHY",
    "CTA",
    "MRANGIO",
    "CEMRA",
];
/// Vascular lesions whose CT study is an angiogram (a CT named after an AVM is a CTA).
const VASCULAR: &[&str] = &["AVM", "ANEURYSM", "AVF"];
/// Angiography words that name no modality (a CT or an MR angiogram).
const NEUTRAL_ANGIO: &[&str] = &["ANGIO", "ANGIOGRAPHY"];
const BOLD: &[&str] = &["BOLD", "FMRI", "RESTING", "REST"];
const ASL: &[&str] = &["ASL", "PCASL", "PASL", "CASL", "M0SCAN"];
const DWI: &[&str] = &["DWI", "DTI", "DIFFUSION", "TRACEW", "ADC"];
const SWI: &[&str] = &["SWI", "SWAN", "SWIP"];
const CT: &[&str] = &["CT", "CTA", "CTP", "CTANGIO"];
const PET: &[&str] = &["PET", "FDG"];
const MR: &[&str] = &["MR", "MRI"];
const AGENT: &[&str] = &[
    "GD",
    "GAD",
    "GADO",
    "GADOLINIUM",
    "POSTGD",
    "POSTGAD",
    "POSTCONTRAST",
    "POSTCON",
    "T1C",
    "T1CE",
    "T1GD",
    "T1POST",
    "POST",
];
/// Names written with separators, found in the squashed text.
const SQUASHED: &[(&str, Contrast)] = &[("MPRAGE", Contrast::T1), ("DARKFLUID", Contrast::Flair)];

/// What the words of `text` say (module doc).
pub fn words(text: &str) -> Said {
    let upper = text.to_ascii_uppercase();
    let tokens: Vec<&str> = upper
        .split(|c: char| !c.is_ascii_alphanumeric())
        .filter(|t| !t.is_empty())
        .collect();
    let first = |list: &[&str]| {
        tokens
            .iter()
            .find(|t| list.contains(t))
            .map(|t| t.to_string())
    };
    let mut said = Said::default();
    // T1 FLAIR is a T1; otherwise FLAIR beats the T2 of "T2 FLAIR".
    let t1_flair = first(T1).is_some() && first(FLAIR).is_some() || tokens.contains(&"T1FLAIR");
    said.contrast = if t1_flair {
        first(T1).map(|w| (Contrast::T1, w))
    } else {
        first(FLAIR)
            .map(|w| (Contrast::Flair, w))
            .or_else(|| first(PD).map(|w| (Contrast::Pd, w)))
            .or_else(|| first(T2).map(|w| (Contrast::T2, w)))
            .or_else(|| first(T1).map(|w| (Contrast::T1, w)))
    };
    let squashed: String = upper.chars().filter(char::is_ascii_alphanumeric).collect();
    said.family = first(T1_FAMILY)
        .map(|w| (Contrast::T1, w))
        .or_else(|| first(T2_FAMILY).map(|w| (Contrast::T2, w)))
        .or_else(|| {
            SQUASHED
                .iter()
                .find(|(w, _)| squashed.contains(w))
                .map(|&(w, c)| (c, w.to_string()))
        });
    said.kind = [
        (ANGIO, SequenceKind::Angio),
        (BOLD, SequenceKind::Bold),
        (ASL, SequenceKind::Asl),
        (DWI, SequenceKind::Dwi),
        (SWI, SequenceKind::Swi),
    ]
    .into_iter()
    .find_map(|(list, kind)| first(list).map(|w| (kind, w)));
    let mr_word = said
        .contrast
        .as_ref()
        .or(said.family.as_ref())
        .map(|(_, w)| w.clone())
        .or_else(|| said.kind.as_ref().map(|(_, w)| w.clone()))
        .or_else(|| first(MR))
        .filter(|w| !CT.contains(&w.as_str()));
    said.modality = first(CT)
        .map(|w| (Modality::Ct, w))
        .or_else(|| first(PET).map(|w| (Modality::Pt, w)))
        .or_else(|| mr_word.map(|w| (Modality::Mr, w)));
    let pre = tokens
        .iter()
        .any(|t| ["PRE", "PRECONTRAST", "NATIVE"].contains(t));
    said.agent = first(AGENT)
        .filter(|w| !(pre && w == "POST"))
        .or_else(|| (upper.contains("C+") || upper.contains("+C")).then(|| "C+".to_string()));
    said
}

/// What a BIDS suffix says: (contrast, kind, modality).
fn suffix(suffix: &str) -> Option<(Option<Contrast>, Option<SequenceKind>, Modality)> {
    let mr = |c: Option<Contrast>, k| Some((c, k, Modality::Mr));
    match suffix.to_ascii_lowercase().as_str() {
        "t1w" | "inplanet1" | "unit1" | "t1map" => mr(Some(Contrast::T1), None),
        "t2w" | "inplanet2" | "t2starw" | "t2star" | "t2map" => mr(Some(Contrast::T2), None),
        "pdw" | "pd" | "pdmap" => mr(Some(Contrast::Pd), None),
        "flair" => mr(Some(Contrast::Flair), None),
        "angio" => mr(Some(Contrast::T1), Some(SequenceKind::Angio)),
        "bold" | "sbref" => mr(Some(Contrast::T2), Some(SequenceKind::Bold)),
        "asl" | "m0scan" => mr(Some(Contrast::Pd), Some(SequenceKind::Asl)),
        "dwi" => mr(Some(Contrast::T2), Some(SequenceKind::Dwi)),
        "swi" | "swimagandphase" => mr(Some(Contrast::T2), Some(SequenceKind::Swi)),
        "ct" => Some((None, None, Modality::Ct)),
        "pet" => Some((None, None, Modality::Pt)),
        _ => None,
    }
}

/// Whether `s` is a BIDS suffix these rules read (`T1w`, `FLAIR`, `angio`, `ct`, ...).
pub fn is_known_suffix(s: &str) -> bool {
    suffix(s).is_some()
}

/// The tissue order a kind has when no contrast is named (module doc of `modality`).
fn kind_contrast(kind: SequenceKind) -> Contrast {
    match kind {
        SequenceKind::Angio => Contrast::T1,
        SequenceKind::Bold | SequenceKind::Dwi | SequenceKind::Swi => Contrast::T2,
        SequenceKind::Asl => Contrast::Pd,
    }
}

/// The timing rule of the module doc: the contrast and a reason.
pub fn timing(tr: Option<f64>, te: Option<f64>, ti: Option<f64>) -> Option<(Contrast, String)> {
    let ms = |name: &str, v: Option<f64>| v.map(|v| format!("{name} {v:.0} ms"));
    let times: Vec<String> = [ms("TR", tr), ms("TE", te), ms("TI", ti)]
        .into_iter()
        .flatten()
        .collect();
    let said = |c: Contrast, why: &str| Some((c, format!("{}: {why}", times.join(", "))));
    if let Some(ti) = ti {
        let long_tr = tr.is_none_or(|tr| tr >= 4000.0);
        let long_te = te.is_none_or(|te| te >= 40.0);
        if (1500.0..=3000.0).contains(&ti) && long_tr && long_te {
            return said(Contrast::Flair, "inversion nulls the fluid (FLAIR)");
        }
        if ti <= 300.0 {
            return said(Contrast::T2, "short inversion nulls fat (STIR, T2-like)");
        }
        if ti < 1500.0 && te.is_none_or(|te| te < 20.0) {
            return said(
                Contrast::T1,
                "inversion-prepared short-TE sequence (T1, as MPRAGE)",
            );
        }
        return None;
    }
    let te = te?;
    if te < 8.0 {
        return said(Contrast::T1, "short-TE gradient echo (T1-weighted)");
    }
    if te >= 40.0 {
        return said(Contrast::T2, "long TE (T2- or T2*-weighted)");
    }
    match tr {
        Some(tr) if tr < 1000.0 => said(Contrast::T1, "short TR and short TE (T1-weighted)"),
        Some(tr) if tr >= 1500.0 => said(Contrast::Pd, "long TR and short TE (PD-weighted)"),
        _ => None,
    }
}

/// `text` quoted for a reason line (shortened).
fn quoted(text: &str) -> String {
    let one: String = text.split_whitespace().collect::<Vec<_>>().join(" ");
    let short: String = one.chars().take(60).collect();
    if short.len() < one.len() {
        format!("'{short}...'")
    } else {
        format!("'{short}'")
    }
}

/// The contrast (and kind) the metadata names, first that speaks (module doc of `modality`).
pub fn named_contrast(facts: &ScanFacts) -> Option<Named> {
    let (tr, te, ti) = facts.times();
    let timed = timing(tr, te, ti);
    let with_timing = |contrast: Contrast, kind, reason: String| {
        let reason = match &timed {
            Some((c, why)) if *c != contrast => {
                format!("{reason} ({why} would say {})", c.name())
            }
            _ => reason,
        };
        Some(Named {
            contrast: Some(contrast),
            kind,
            reason,
        })
    };
    if let Some(s) = facts.bids_suffix.as_deref()
        && let Some((Some(c), kind, _)) = suffix(s)
    {
        return with_timing(c, kind, format!("BIDS suffix _{s}"));
    }
    let texts = facts.texts();
    let said: Vec<(&str, &str, Said)> = texts.iter().map(|&(n, t)| (n, t, words(t))).collect();
    let kind = said.iter().find_map(|(_, _, s)| s.kind.clone());
    for (name, text, s) in &said {
        if let Some((c, w)) = &s.contrast {
            let reason = format!("{name} {} names {w}", quoted(text));
            return with_timing(*c, kind.as_ref().map(|k| k.0), reason);
        }
    }
    let kind = kind.map(|k| k.0);
    if let Some((c, why)) = &timed {
        return Some(Named {
            contrast: Some(*c),
            kind,
            reason: why.clone(),
        });
    }
    for (name, text, s) in &said {
        if let Some((c, w)) = &s.family {
            let reason = format!("{name} {} names the sequence {w}", quoted(text));
            return with_timing(*c, kind, reason);
        }
    }
    if let Some((name, text, s)) = said.iter().find(|(_, _, s)| s.kind.is_some())
        && let Some((k, w)) = &s.kind
    {
        let c = kind_contrast(*k);
        let reason = format!(
            "{name} {} names {w} ({}: tissues as in {})",
            quoted(text),
            k.name(),
            c.name()
        );
        return with_timing(c, Some(*k), reason);
    }
    let file = facts.file_name.as_deref()?;
    let s = words(file);
    let (c, w, k) = if let Some((c, w)) = s.contrast.or(s.family) {
        (c, w, s.kind.map(|k| k.0))
    } else {
        let (k, w) = s.kind?;
        (kind_contrast(k), w, Some(k))
    };
    with_timing(c, k, format!("the file name {} names {w}", quoted(file)))
}

/// The modality the metadata names, with the reason (module doc of `modality`).
pub fn metadata_modality(facts: &ScanFacts) -> Option<(Modality, String)> {
    if let Some(tag) = facts.modality.as_deref().filter(|t| !t.trim().is_empty()) {
        return Some((Modality::from_tag(tag), format!("Modality {}", quoted(tag))));
    }
    if let Some(s) = facts.bids_suffix.as_deref()
        && let Some((_, _, m)) = suffix(s)
    {
        return Some((m, format!("BIDS suffix _{s}")));
    }
    for (name, text) in facts.texts() {
        if let Some((m, w)) = words(text).modality {
            return Some((m, format!("{name} {} names {w}", quoted(text))));
        }
    }
    let (tr, te, ti) = facts.times();
    if tr.is_some() || te.is_some() || ti.is_some() {
        return Some((
            Modality::Mr,
            "repetition/echo times given: an MR sequence".into(),
        ));
    }
    let file = facts.file_name.as_deref()?;
    let (m, w) = words(file).modality?;
    Some((m, format!("the file name {} names {w}", quoted(file))))
}

/// Why a CT is an angiogram, when its metadata says so (module doc of `modality`): the BIDS
/// suffix `_angio`, angiography or vascular-lesion words (CTA, angio, AVM, aneurysm) in
/// SeriesDescription, ProtocolName, `descrip` or the file name, or a contrast agent
/// (ContrastBolusAgent, BIDS `ce-`): on a CT the agent is iodine, given to fill the vessels.
pub fn ct_angiography(facts: &ScanFacts) -> Option<String> {
    if let Some(s) = facts.bids_suffix.as_deref()
        && s.eq_ignore_ascii_case("angio")
    {
        return Some(format!("BIDS suffix _{s}"));
    }
    let texts = facts.texts();
    let named = texts
        .iter()
        .copied()
        .chain(facts.file_name.as_deref().map(|f| ("the file name", f)));
    for (name, text) in named {
        let upper = text.to_ascii_uppercase();
        let word = upper
            .split(|c: char| !c.is_ascii_alphanumeric())
            .find(|t| ANGIO.contains(t) || VASCULAR.contains(t) || *t == "CTANGIO");
        if let Some(w) = word {
            let what = if VASCULAR.contains(&w) {
                " (a vascular lesion: its CT is an angiogram)"
            } else {
                ""
            };
            return Some(format!("{name} {} names {w}{what}", quoted(text)));
        }
    }
    let agent = |v: &Option<String>| {
        v.as_deref()
            .map(str::trim)
            .filter(|a| {
                !a.is_empty()
                    && !["none", "no", "pre", "n/a", "0"].contains(&a.to_ascii_lowercase().as_str())
            })
            .map(str::to_string)
    };
    if let Some(a) = agent(&facts.contrast_agent) {
        return Some(format!("ContrastBolusAgent {} on a CT", quoted(&a)));
    }
    agent(&facts.bids_ce).map(|a| format!("BIDS ce-{a} (a contrast agent) on a CT"))
}

/// Whether the metadata's MR comes only from a word or suffix that names angiography without
/// a modality (`_angio`, `angio`): Hounsfield values then make the scan a CT angiogram.
pub fn mr_only_by_angiography(facts: &ScanFacts) -> bool {
    if facts
        .modality
        .as_deref()
        .is_some_and(|t| !t.trim().is_empty())
    {
        return false;
    }
    let (tr, te, ti) = facts.times();
    if tr.is_some() || te.is_some() || ti.is_some() {
        return false;
    }
    if let Some(s) = facts.bids_suffix.as_deref()
        && is_known_suffix(s)
    {
        return s.eq_ignore_ascii_case("angio");
    }
    let speaking = facts
        .texts()
        .into_iter()
        .map(|(_, t)| t)
        .chain(facts.file_name.as_deref())
        .find_map(|t| words(t).modality);
    matches!(speaking, Some((Modality::Mr, w)) if NEUTRAL_ANGIO.contains(&w.as_str()))
}

/// Whether the metadata names a contrast agent.
pub fn post_contrast(facts: &ScanFacts) -> bool {
    let given = |v: &Option<String>| {
        v.as_deref().is_some_and(|a| {
            let a = a.trim().to_ascii_lowercase();
            !a.is_empty() && !["none", "no", "pre", "n/a", "0"].contains(&a.as_str())
        })
    };
    given(&facts.contrast_agent)
        || given(&facts.bids_ce)
        || facts
            .texts()
            .iter()
            .map(|(_, t)| *t)
            .chain(facts.file_name.as_deref())
            .any(|t| words(t).agent.is_some())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words_are_matched_whole_and_explicit_contrast_wins() {
        let c = |t: &str| words(t).contrast.map(|c| c.0);
        assert_eq!(c("t1_mprage_sag"), Some(Contrast::T1));
        assert_eq!(c("AX T2 FLAIR"), Some(Contrast::Flair));
        assert_eq!(c("T1 FLAIR SAG"), Some(Contrast::T1));
        assert_eq!(c("PD_TSE"), Some(Contrast::Pd));
        assert_eq!(c("T10 LOCALIZER"), None);
        assert_eq!(words("MP-RAGE").family.map(|f| f.0), Some(Contrast::T1));
        assert_eq!(words("ax tse").family.map(|f| f.0), Some(Contrast::T2));
        assert_eq!(
            words("TOF_3D_multi-slab").kind.map(|k| k.0),
            Some(SequenceKind::Angio)
        );
        assert_eq!(words("Head CTA").modality.map(|m| m.0), Some(Modality::Ct));
        assert_eq!(words("T1 post Gd").agent.as_deref(), Some("POST"));
        assert_eq!(words("T1 pre").agent, None);
        assert_eq!(words("AX T1 C+").agent.as_deref(), Some("C+"));
        assert_eq!(words("TE=49;Time=133625.745;phase=1"), Said::default());
    }

    #[test]
    fn timings_follow_the_physics() {
        let t = |tr, te, ti| timing(tr, te, ti).map(|t| t.0);
        assert_eq!(
            t(Some(9000.0), Some(120.0), Some(2500.0)),
            Some(Contrast::Flair)
        );
        assert_eq!(t(Some(2300.0), Some(2.3), Some(900.0)), Some(Contrast::T1));
        assert_eq!(t(Some(4000.0), Some(60.0), Some(150.0)), Some(Contrast::T2));
        assert_eq!(t(Some(4000.0), Some(100.0), None), Some(Contrast::T2));
        assert_eq!(t(None, Some(49.0), None), Some(Contrast::T2));
        assert_eq!(t(Some(500.0), Some(15.0), None), Some(Contrast::T1));
        assert_eq!(t(Some(3000.0), Some(15.0), None), Some(Contrast::Pd));
        assert_eq!(t(Some(25.0), Some(3.4), None), Some(Contrast::T1));
        assert_eq!(t(Some(1200.0), Some(20.0), None), None);
        assert_eq!(t(Some(2000.0), None, None), None);
        // MP2RAGE's second inversion (TI 2500, TR 5000) with a short TE is no FLAIR.
        assert_eq!(t(Some(5000.0), Some(3.0), Some(2500.0)), None);
    }
}
