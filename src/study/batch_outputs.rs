//! Where a cohort batch writes (BIDS Derivatives) and the records it writes there.
//!
//! Layout under OUT_DIR, for a scan `sub-01_ses-a_T1w.nii.gz`:
//! - `dataset_description.json` (`DatasetType: derivative`, `GeneratedBy: morphray`);
//! - `sub-01/ses-a/anat/sub-01_ses-a_desc-peaks_T1w.json`: the scan's summary (Table-1 row,
//!   peaks, windows, contrast, warnings) with its timings and its input's size and time; written
//!   last, so a whole summary whose input is unchanged means the scan is finished (a rerun skips
//!   it; `batch_guard`);
//! - `..._desc-{anterior,lateral,superior}_T1w.png`: the thumbnails;
//! - `..._desc-error_T1w.json`: why the scan failed (removed when a rerun succeeds);
//! - `logs/participant_shard-I-of-N.jsonl`: one JSON line per scan processed by that shard;
//! - `group/`: the group level's TSV and HTML report.
//!
//! Decisions: every file is written atomically (a killed job leaves no half-written record);
//! names follow BIDS derivatives (`desc-<label>` before the source suffix), so BIDS tools index
//! them with the source scans.

use super::batch_guard::{png_whole, summary_current};
use super::bids::{Scan, Shard};
use crate::files::write::{OutputError, write_file};
use std::path::{Path, PathBuf};

/// The three thumbnail views: (name, azimuth, elevation) in the camera's RAS convention
/// (azimuth 0 = anterior, 90 = from the right; elevation 90 = from above).
pub const VIEWS: [(&str, f64, f64); 3] = [
    ("anterior", 0.0, 0.0),
    ("lateral", 90.0, 0.0),
    ("superior", 0.0, 90.0),
];

/// The file names of one scan's outputs.
#[derive(Clone, Debug, PartialEq)]
pub struct ScanOutputs {
    /// `OUT_DIR/sub-X[/ses-Y]/anat`.
    pub dir: PathBuf,
    /// The summary (the scan's done marker).
    pub summary: PathBuf,
    /// The failure record.
    pub error: PathBuf,
    /// One PNG per entry of [`VIEWS`].
    pub thumbnails: [PathBuf; 3],
}

impl ScanOutputs {
    /// The outputs of `scan` under `out`.
    pub fn of(out: &Path, scan: &Scan) -> ScanOutputs {
        let dir = out.join(scan.output_dir());
        // `sub-01_ses-a_T1w` -> `sub-01_ses-a` + `T1w`: desc-<label> goes before the suffix.
        let base = scan
            .stem
            .strip_suffix(&scan.suffix)
            .map(|b| b.trim_end_matches('_'))
            .unwrap_or(&scan.stem);
        let name =
            |desc: &str, ext: &str| dir.join(format!("{base}_desc-{desc}_{}.{ext}", scan.suffix));
        ScanOutputs {
            summary: name("peaks", "json"),
            error: name("error", "json"),
            thumbnails: VIEWS.map(|(view, _, _)| name(view, "png")),
            dir,
        }
    }

    /// Whether the scan was finished by an earlier run from `input` as it is now: a whole
    /// summary whose stamp matches the input, and whole thumbnails when `thumbnails` (a
    /// peaks-only run does not stop a later run from adding them). See [`super::batch_guard`].
    pub fn finished(&self, input: &Path, thumbnails: bool) -> bool {
        summary_current(&self.summary, input)
            && (!thumbnails || self.thumbnails.iter().all(|t| png_whole(t)))
    }
}

/// The JSON-lines log of one shard.
pub fn log_path(out: &Path, shard: Shard) -> PathBuf {
    out.join("logs").join(format!(
        "participant_shard-{}-of-{}.jsonl",
        shard.index, shard.count
    ))
}

/// The group level's folder.
pub fn group_dir(out: &Path) -> PathBuf {
    out.join("group")
}

/// Writes `OUT_DIR/dataset_description.json` (BIDS Derivatives), replacing it atomically: all
/// shards write the same content, so concurrent writers cannot leave a mixed file.
pub fn write_dataset_description(out: &Path, bids: &Path) -> Result<(), OutputError> {
    let source = std::fs::canonicalize(bids).unwrap_or_else(|_| bids.to_path_buf());
    let description = serde_json::json!({
        "Name": "morphray tissue peaks and thumbnails",
        "BIDSVersion": "1.10.0",
        "DatasetType": "derivative",
        "GeneratedBy": [{
            "Name": "morphray",
            "Version": env!("CARGO_PKG_VERSION"),
            "Description": "Histogram tissue peaks (the paper's Table 1), adaptive windows and \
                            GPU-rendered thumbnails of each anatomical scan",
        }],
        "SourceDatasets": [{ "URL": format!("file://{}", source.display()) }],
    });
    let text = serde_json::to_string_pretty(&description).unwrap_or_default();
    write_file(&out.join("dataset_description.json"), text.as_bytes())
}

/// Writes `value` as pretty JSON to `path` atomically, creating its folder.
pub fn write_json(path: &Path, value: &serde_json::Value) -> Result<(), OutputError> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| OutputError::io(dir, e))?;
    }
    let text = serde_json::to_string_pretty(value).unwrap_or_default();
    write_file(path, text.as_bytes())
}

/// Appends one line to a JSON-lines log (one `write` call per line, so lines of a process do not
/// interleave).
pub fn append_line(path: &Path, value: &serde_json::Value) -> Result<(), OutputError> {
    use std::io::Write;
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| OutputError::io(dir, e))?;
    }
    let mut line = serde_json::to_string(value).unwrap_or_default();
    line.push('\n');
    std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(path)
        .and_then(|mut f| f.write_all(line.as_bytes()))
        .map_err(|e| OutputError::io(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outputs_follow_bids_derivative_names() {
        let scan = Scan {
            subject: "01".into(),
            session: Some("a".into()),
            stem: "sub-01_ses-a_run-2_T1w".into(),
            suffix: "T1w".into(),
            path: "in.nii.gz".into(),
            relative: "sub-01/ses-a/anat/sub-01_ses-a_run-2_T1w.nii.gz".into(),
        };
        let o = ScanOutputs::of(Path::new("/out"), &scan);
        assert_eq!(
            o.summary,
            Path::new("/out/sub-01/ses-a/anat/sub-01_ses-a_run-2_desc-peaks_T1w.json")
        );
        assert_eq!(
            o.thumbnails[2],
            Path::new("/out/sub-01/ses-a/anat/sub-01_ses-a_run-2_desc-superior_T1w.png")
        );
        assert_eq!(
            log_path(Path::new("/out"), Shard { index: 1, count: 3 }),
            Path::new("/out/logs/participant_shard-1-of-3.jsonl")
        );
    }
}
