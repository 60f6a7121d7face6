//! What a NIfTI file says about its scan besides its voxels ([`ScanFacts`]): the header's
//! `descrip`, the BIDS name and the JSON sidecar next to the file. (DICOM's tags are read with
//! its headers, `source::dicom::headers`.) The decision is `analysis::modality`'s.
//!
//! Decisions:
//! - `descrip`: kept as text (its words are read by the rules), and `TE=`, `TR=`, `TI=` keys
//!   (dcm2niix writes `TE=49;Time=...;phase=1`) are taken as times in ms.
//! - BIDS name: the stem (extensions `.nii`, `.nii.gz`, `.hdr`, `.img` removed) split at `_`;
//!   the last part is the suffix when it is one the rules know (`T1w`, `T2w`, `FLAIR`, `angio`,
//!   `ct`, ...), parts `key-value` are entities, of which `ce-` (contrast agent) is used. The
//!   stem is kept as the file name, whose words the rules read last.
//! - Sidecar: the same stem plus `.json` (BIDS). Read only up to [`MAX_SIDECAR_BYTES`]; a
//!   sidecar that is too large, not JSON, not an object or unreadable is a warning of the
//!   volume, never an error: the voxels are what the user asked for. Times are in seconds in
//!   BIDS; a value too large to be seconds (TE >= 1, TI >= 10, TR >= 100) is taken as ms and
//!   said so. Sidecar values replace those of `descrip`.

use crate::analysis::ScanFacts;
use crate::analysis::modality::is_known_suffix;
use std::path::{Path, PathBuf};

/// Largest sidecar read: BIDS sidecars are a few kB (slice timing of a multiband EPI included).
pub const MAX_SIDECAR_BYTES: u64 = 1 << 20;

/// The facts of a NIfTI header's `descrip` (module doc).
pub fn from_descrip(descrip: &str) -> ScanFacts {
    let text = descrip.trim_matches(|c: char| c.is_whitespace() || c == '\0');
    if text.is_empty() {
        return ScanFacts::default();
    }
    let mut facts = ScanFacts {
        descrip: Some(text.to_string()),
        sources: vec!["NIfTI descrip".into()],
        ..ScanFacts::default()
    };
    for part in text.split([';', ',', ' ']) {
        let Some((key, value)) = part.split_once('=') else {
            continue;
        };
        let Ok(v) = value.trim().parse::<f64>() else {
            continue;
        };
        let v = Some(v).filter(|v| v.is_finite() && *v > 0.0);
        match key.trim().to_ascii_uppercase().as_str() {
            "TE" => facts.echo_time_ms = v,
            "TR" => facts.repetition_time_ms = v,
            "TI" => facts.inversion_time_ms = v,
            _ => {}
        }
    }
    facts
}

/// The stem of a NIfTI/ANALYZE file name (extensions removed).
fn stem(name: &str) -> &str {
    let lower = name.to_ascii_lowercase();
    for ext in [
        ".nii.gz", ".nii", ".hdr.gz", ".img.gz", ".hdr", ".img", ".gz",
    ] {
        if lower.ends_with(ext) {
            return &name[..name.len() - ext.len()];
        }
    }
    name
}

/// Adds what the file's name and its sidecar say to `facts`; problems with the sidecar become
/// `warnings` (module doc).
pub fn add_path_facts(path: &Path, facts: &mut ScanFacts, warnings: &mut Vec<String>) {
    let Some(name) = path.file_name().map(|n| n.to_string_lossy().into_owned()) else {
        return;
    };
    let stem = stem(&name).to_string();
    let parts: Vec<&str> = stem.split('_').collect();
    if let Some(last) = parts
        .last()
        .filter(|p| !p.contains('-') && is_known_suffix(p))
    {
        facts.bids_suffix = Some(last.to_string());
    }
    facts.bids_ce = parts
        .iter()
        .find_map(|p| p.strip_prefix("ce-"))
        .map(str::to_string);
    facts.file_name = Some(stem.clone());
    let sidecar = path.with_file_name(format!("{stem}.json"));
    read_sidecar(&sidecar, facts, warnings);
}

/// Reads `sidecar` into `facts` when it exists (module doc).
fn read_sidecar(sidecar: &Path, facts: &mut ScanFacts, warnings: &mut Vec<String>) {
    let shown = sidecar
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let bytes = match crate::files::read::read_regular(sidecar, MAX_SIDECAR_BYTES) {
        Ok(bytes) => bytes,
        Err(e) if e.is_not_found() => return,
        Err(e) => {
            warnings.push(format!("the sidecar {shown} was ignored: {e}"));
            return;
        }
    };
    let json: serde_json::Value = match serde_json::from_slice(&bytes) {
        Ok(json) => json,
        Err(e) => {
            warnings.push(format!(
                "the sidecar {shown} was ignored: it is not JSON ({e})"
            ));
            return;
        }
    };
    let Some(object) = json.as_object() else {
        warnings.push(format!(
            "the sidecar {shown} was ignored: it is not a JSON object"
        ));
        return;
    };
    let text = |key: &str| -> Option<String> {
        match object.get(key)? {
            serde_json::Value::String(s) => Some(s.trim().to_string()),
            serde_json::Value::Array(a) => {
                let parts: Vec<&str> = a.iter().filter_map(|v| v.as_str()).collect();
                Some(parts.join("\\"))
            }
            _ => None,
        }
        .filter(|s| !s.is_empty())
    };
    let mut notes = Vec::new();
    let mut time = |key: &str, max_seconds: f64| -> Option<f64> {
        let value = object.get(key)?;
        let v = value
            .as_f64()
            .or_else(|| value.as_array()?.first()?.as_f64())?;
        if !(v.is_finite() && v > 0.0) {
            return None;
        }
        if v >= max_seconds {
            notes.push(format!("{key} {v} is taken as ms (BIDS uses seconds)"));
            Some(v)
        } else {
            Some(v * 1e3)
        }
    };
    let te = time("EchoTime", 1.0);
    let tr = time("RepetitionTime", 100.0);
    let ti = time("InversionTime", 10.0);
    facts.echo_time_ms = te.or(facts.echo_time_ms);
    facts.repetition_time_ms = tr.or(facts.repetition_time_ms);
    facts.inversion_time_ms = ti.or(facts.inversion_time_ms);
    facts.modality = text("Modality").or(facts.modality.take());
    facts.series_description = text("SeriesDescription").or(facts.series_description.take());
    facts.protocol_name = text("ProtocolName").or(facts.protocol_name.take());
    facts.contrast_agent = text("ContrastBolusAgent").or(facts.contrast_agent.take());
    facts.scanning_sequence = text("ScanningSequence").or(facts.scanning_sequence.take());
    facts.sequence_variant = text("SequenceVariant").or(facts.sequence_variant.take());
    facts.sources.push(format!("BIDS sidecar {shown}"));
    for note in notes {
        warnings.push(format!("the sidecar {shown}: {note}"));
    }
}

/// The sidecar a NIfTI file at `path` would have.
pub fn sidecar_path(path: &Path) -> Option<PathBuf> {
    let name = path.file_name()?.to_string_lossy().into_owned();
    Some(path.with_file_name(format!("{}.json", stem(&name))))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn descrip_times_and_names_are_read() {
        let f = from_descrip("TE=49;Time=133625.745;phase=1");
        assert_eq!(f.echo_time_ms, Some(49.0));
        assert_eq!(f.repetition_time_ms, None);
        assert_eq!(f.descrip.as_deref(), Some("TE=49;Time=133625.745;phase=1"));
        assert_eq!(from_descrip("\0\0"), ScanFacts::default());
        assert_eq!(from_descrip("TE=nan;TR=-3").echo_time_ms, None);
    }

    #[test]
    fn bids_names_give_suffix_entities_and_sidecar() {
        let mut f = ScanFacts::default();
        let mut w = Vec::new();
        add_path_facts(
            Path::new("/nonexistent/sub-01_ce-gadolinium_T1w.nii.gz"),
            &mut f,
            &mut w,
        );
        assert_eq!(f.bids_suffix.as_deref(), Some("T1w"));
        assert_eq!(f.bids_ce.as_deref(), Some("gadolinium"));
        assert_eq!(f.file_name.as_deref(), Some("sub-01_ce-gadolinium_T1w"));
        assert!(w.is_empty(), "{w:?}");
        let mut g = ScanFacts::default();
        add_path_facts(Path::new("CT_AVM.nii.gz"), &mut g, &mut w);
        assert_eq!(g.bids_suffix, None);
        assert_eq!(
            sidecar_path(Path::new("/d/a_T2w.nii.gz")),
            Some(PathBuf::from("/d/a_T2w.json"))
        );
    }
}
