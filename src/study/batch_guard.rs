//! What a cohort batch checks before it writes and before it skips: the output folder is not a
//! raw dataset (nor the input itself), and a scan counts as finished only when its outputs are
//! whole and were made from the input as it is now.
//!
//! Decisions:
//! - OUT_DIR is refused when it is the input dataset (same device and inode, so `./bids/.` and
//!   a symbolic link are caught) or when it holds a `dataset_description.json` that morphray did
//!   not write: one that is not valid JSON, one without `DatasetType: derivative` (BIDS reads a
//!   missing DatasetType as raw) or a derivative of another pipeline. Writing there would
//!   replace that description and mix morphray's records into someone else's dataset. A folder
//!   inside the input (`BIDS/derivatives/morphray`, the BIDS convention) is fine.
//! - A scan's summary records its input's size and modification time ([`SourceStamp`]); a rerun
//!   redoes a scan whose input changed (replaced, touched, a different size), whose summary is
//!   not a whole JSON object (a truncated or hand-edited file) or records no stamp (written by
//!   an older morphray), and whose thumbnails are not whole PNG files (no `IEND` at the end).
//!   Size and time, not a hash: hashing every finished scan on each rerun would read the whole
//!   cohort again, which is what resuming avoids; a replacement of the same size written within
//!   the same nanosecond is the one change this misses.

use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

/// Why OUT_DIR is refused (one sentence with the fix).
pub fn refuse_output_dir(bids: &Path, out: &Path) -> Result<(), String> {
    if same_file(bids, out) {
        return Err(format!(
            "the output folder {} is the input dataset itself: name a new folder, for example \
             {}/derivatives/morphray",
            out.display(),
            bids.display()
        ));
    }
    let description = out.join("dataset_description.json");
    let text = match std::fs::read_to_string(&description) {
        Ok(text) => text,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => {
            return Err(format!(
                "cannot read {} ({e}), so the output folder may be another dataset: name a new \
                 folder",
                description.display()
            ));
        }
    };
    match foreign_dataset(&text) {
        None => Ok(()),
        Some(what) => Err(format!(
            "the output folder {} holds {what} (its dataset_description.json), which the batch \
             would overwrite: name a new folder, for example {}/derivatives/morphray",
            out.display(),
            bids.display()
        )),
    }
}

/// What the dataset described by `text` is, when morphray did not write it.
fn foreign_dataset(text: &str) -> Option<String> {
    let Ok(value) = serde_json::from_str::<serde_json::Value>(text) else {
        return Some("a dataset description that is not valid JSON".into());
    };
    let kind = value.get("DatasetType").and_then(|v| v.as_str());
    if kind != Some("derivative") {
        return Some(format!(
            "a {} dataset",
            kind.map_or("raw (no DatasetType)".to_string(), |k| format!("\"{k}\""))
        ));
    }
    let by: Vec<&str> = value
        .get("GeneratedBy")
        .and_then(|v| v.as_array())
        .map(|a| a.iter().filter_map(|g| g.get("Name")?.as_str()).collect())
        .unwrap_or_default();
    if by.contains(&"morphray") {
        None
    } else if by.is_empty() {
        Some("a derivative dataset of an unnamed pipeline".into())
    } else {
        Some(format!("a derivative dataset of {}", by.join(", ")))
    }
}

#[cfg(unix)]
fn same_file(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(x), Ok(y)) => x.dev() == y.dev() && x.ino() == y.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_file(a: &Path, b: &Path) -> bool {
    match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}

/// An input file's size and modification time, recorded in its summary.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct SourceStamp {
    /// Bytes.
    pub size: u64,
    /// Modification time, nanoseconds since the Unix epoch (0 when the file system has none).
    pub mtime_ns: u64,
}

impl SourceStamp {
    /// The stamp of `path` now; `None` when it cannot be read.
    pub fn of(path: &Path) -> Option<SourceStamp> {
        let meta = std::fs::metadata(path).ok()?;
        let mtime_ns = meta
            .modified()
            .ok()
            .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
            .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX));
        Some(SourceStamp {
            size: meta.len(),
            mtime_ns,
        })
    }
}

/// The key of the stamp in a summary.
pub const STAMP_KEY: &str = "source";

/// Whether `summary` is a whole JSON object whose stamp matches `input` as it is now.
pub fn summary_current(summary: &Path, input: &Path) -> bool {
    let Ok(bytes) = std::fs::read(summary) else {
        return false;
    };
    let Ok(value) = serde_json::from_slice::<serde_json::Value>(&bytes) else {
        return false;
    };
    let recorded = value
        .get(STAMP_KEY)
        .and_then(|s| serde_json::from_value::<SourceStamp>(s.clone()).ok());
    recorded.is_some() && recorded == SourceStamp::of(input)
}

/// Whether `path` is a PNG file that ends with its `IEND` chunk (a whole file, not a cut one).
pub fn png_whole(path: &Path) -> bool {
    const IEND: [u8; 12] = [0, 0, 0, 0, b'I', b'E', b'N', b'D', 0xae, 0x42, 0x60, 0x82];
    let mut head = [0u8; 8];
    let mut tail = [0u8; 12];
    let Ok(mut file) = std::fs::File::open(path) else {
        return false;
    };
    file.read_exact(&mut head).is_ok()
        && head == *b"\x89PNG\r\n\x1a\n"
        && file.seek(SeekFrom::End(-12)).is_ok()
        && file.read_exact(&mut tail).is_ok()
        && tail == IEND
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp(name: &str) -> std::path::PathBuf {
        let dir =
            std::env::temp_dir().join(format!("morphray-guard-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn raw_and_foreign_datasets_are_refused_and_morphray_ones_accepted() {
        assert!(
            foreign_dataset(r#"{"Name": "x", "BIDSVersion": "1.10.0"}"#)
                .unwrap()
                .contains("raw (no DatasetType)")
        );
        assert!(
            foreign_dataset(r#"{"DatasetType": "raw"}"#)
                .unwrap()
                .contains("\"raw\"")
        );
        assert!(
            foreign_dataset("{\"DatasetType\": \"deriv")
                .unwrap()
                .contains("not valid JSON")
        );
        let fmriprep = r#"{"DatasetType": "derivative", "GeneratedBy": [{"Name": "fMRIPrep"}]}"#;
        assert!(foreign_dataset(fmriprep).unwrap().contains("fMRIPrep"));
        let ours = r#"{"DatasetType": "derivative", "GeneratedBy": [{"Name": "morphray"}]}"#;
        assert_eq!(foreign_dataset(ours), None);
    }

    #[test]
    fn the_input_itself_is_refused_through_another_spelling() {
        let bids = temp("self");
        let other = bids.join(".");
        let e = refuse_output_dir(&bids, &other).unwrap_err();
        assert!(e.contains("is the input dataset itself"), "{e}");
        let inside = bids.join("derivatives/morphray");
        std::fs::create_dir_all(&inside).unwrap();
        assert_eq!(refuse_output_dir(&bids, &inside), Ok(()));
    }

    #[test]
    fn a_summary_is_current_only_while_its_input_is_unchanged_and_it_is_whole() {
        let dir = temp("stamp");
        let input = dir.join("in.nii");
        std::fs::write(&input, b"0123456789").unwrap();
        let stamp = SourceStamp::of(&input).unwrap();
        let summary = dir.join("s.json");
        let text = serde_json::json!({ "dims": [1, 1, 1], STAMP_KEY: stamp }).to_string();
        std::fs::write(&summary, &text).unwrap();
        assert!(summary_current(&summary, &input));
        // Truncated: not whole JSON.
        std::fs::write(&summary, &text[..text.len() - 3]).unwrap();
        assert!(!summary_current(&summary, &input));
        // No stamp (an older summary).
        std::fs::write(&summary, r#"{"dims": [1, 1, 1]}"#).unwrap();
        assert!(!summary_current(&summary, &input));
        // The input replaced by one of another size.
        std::fs::write(&summary, &text).unwrap();
        std::fs::write(&input, b"01234567890").unwrap();
        assert!(!summary_current(&summary, &input));
    }

    #[test]
    fn a_cut_png_is_not_whole() {
        let dir = temp("png");
        let path = dir.join("a.png");
        let mut bytes = b"\x89PNG\r\n\x1a\n".to_vec();
        bytes.extend_from_slice(&[0, 0, 0, 0, b'I', b'E', b'N', b'D', 0xae, 0x42, 0x60, 0x82]);
        std::fs::write(&path, &bytes).unwrap();
        assert!(png_whole(&path));
        std::fs::write(&path, &bytes[..bytes.len() - 1]).unwrap();
        assert!(!png_whole(&path));
    }
}
