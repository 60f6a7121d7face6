//! BIDS discovery for cohort batches: the anatomical scans of a BIDS dataset, the participant
//! filter and the shard of a cluster array job (BIDS-App conventions).
//!
//! Decisions:
//! - A scan is a `.nii` or `.nii.gz` file in `sub-<label>/anat/` or `sub-<label>/ses-<label>/anat/`
//!   whose name starts with its subject's (and session's) entities; its suffix (`T1w`, `T2w`,
//!   `FLAIR`, ...) is the last `_` part of the name. Other files (JSON sidecars, `derivatives/`,
//!   `sourcedata/`, hidden folders) are not scans.
//! - The order is the sorted relative path, so every process of an array job sees the same list
//!   and shard `I/N` takes the scans whose index is `I` modulo `N`: disjoint, covering, and
//!   balanced within one scan whatever the subjects' scan counts.
//! - `--participant-label` takes labels with or without the `sub-` prefix (the BIDS-App
//!   specification allows both); a label that matches no subject is an error, not an empty run.
//! - Without `--shard`, `SLURM_ARRAY_TASK_ID` and `SLURM_ARRAY_TASK_COUNT` (and
//!   `SLURM_ARRAY_TASK_MIN`, as an array may start at 1) give the shard, so an `sbatch --array`
//!   script needs no arithmetic of its own.

use std::path::{Path, PathBuf};

/// One anatomical scan of a BIDS dataset.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Scan {
    /// Subject label (without `sub-`).
    pub subject: String,
    /// Session label (without `ses-`), if the dataset has sessions.
    pub session: Option<String>,
    /// The file name without `.nii`/`.nii.gz` (all its entities and the suffix).
    pub stem: String,
    /// The suffix: `T1w`, `T2w`, `FLAIR`, ...
    pub suffix: String,
    /// The file.
    pub path: PathBuf,
    /// Its path relative to the dataset root, `/`-separated (what the outputs mirror).
    pub relative: String,
}

impl Scan {
    /// The folder of this scan's outputs relative to the derivatives root (`sub-X[/ses-Y]/anat`).
    pub fn output_dir(&self) -> PathBuf {
        let mut dir = PathBuf::from(format!("sub-{}", self.subject));
        if let Some(session) = &self.session {
            dir.push(format!("ses-{session}"));
        }
        dir.join("anat")
    }
}

/// Which part of the scan list one process takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Shard {
    /// 0-based index, below `count`.
    pub index: usize,
    /// Number of shards, at least 1.
    pub count: usize,
}

impl Shard {
    /// All scans.
    pub const ALL: Shard = Shard { index: 0, count: 1 };

    /// Parses `I/N` (0 <= I < N).
    pub fn parse(text: &str) -> Result<Shard, String> {
        let bad = || format!("--shard `{text}` must be I/N with 0 <= I < N, e.g. 0/4");
        let (i, n) = text.split_once('/').ok_or_else(bad)?;
        let index: usize = i.trim().parse().map_err(|_| bad())?;
        let count: usize = n.trim().parse().map_err(|_| bad())?;
        if count == 0 || index >= count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }

    /// The shard of a Slurm array task, from `SLURM_ARRAY_TASK_ID`, `SLURM_ARRAY_TASK_COUNT`
    /// and `SLURM_ARRAY_TASK_MIN` as `var` returns them; None outside an array job.
    pub fn from_slurm(var: impl Fn(&str) -> Option<String>) -> Result<Option<Shard>, String> {
        let (Some(id), Some(count)) = (var("SLURM_ARRAY_TASK_ID"), var("SLURM_ARRAY_TASK_COUNT"))
        else {
            return Ok(None);
        };
        let number = |name: &str, text: &str| {
            text.trim()
                .parse::<usize>()
                .map_err(|_| format!("{name}={text} is not a number"))
        };
        let id = number("SLURM_ARRAY_TASK_ID", &id)?;
        let count = number("SLURM_ARRAY_TASK_COUNT", &count)?;
        let min = match var("SLURM_ARRAY_TASK_MIN") {
            Some(text) => number("SLURM_ARRAY_TASK_MIN", &text)?,
            None => 0,
        };
        let index = id.checked_sub(min).filter(|&i| i < count).ok_or_else(|| {
            format!(
                "SLURM_ARRAY_TASK_ID={id} is outside the array (SLURM_ARRAY_TASK_MIN={min}, \
                 SLURM_ARRAY_TASK_COUNT={count}); use --shard I/N"
            )
        })?;
        Ok(Some(Shard { index, count }))
    }

    /// Whether the scan at `position` of the sorted list is this shard's.
    pub fn takes(&self, position: usize) -> bool {
        position % self.count == self.index
    }
}

/// Why the dataset could not be listed.
#[derive(Debug, thiserror::Error)]
pub enum BidsError {
    /// A folder could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The folder.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
    /// Not a BIDS dataset (no `sub-*` folder).
    #[error(
        "{0} has no sub-* folder: give the root of a BIDS dataset (the folder with \
         dataset_description.json and the sub-<label> folders)"
    )]
    NotBids(String),
    /// A `--participant-label` with no subject.
    #[error("no subject sub-{label} in {root}; the dataset has {available}")]
    UnknownParticipant {
        /// The label.
        label: String,
        /// The dataset.
        root: String,
        /// The subjects found.
        available: String,
    },
}

fn read_dir(path: &Path) -> Result<Vec<PathBuf>, BidsError> {
    let io = |source| BidsError::Io {
        path: path.display().to_string(),
        source,
    };
    let mut entries = Vec::new();
    for entry in std::fs::read_dir(path).map_err(io)? {
        entries.push(entry.map_err(io)?.path());
    }
    entries.sort();
    Ok(entries)
}

fn name_of(path: &Path) -> &str {
    path.file_name().and_then(|n| n.to_str()).unwrap_or("")
}

/// The `.nii`/`.nii.gz` stem of a file name.
fn nifti_stem(name: &str) -> Option<&str> {
    name.strip_suffix(".nii.gz")
        .or_else(|| name.strip_suffix(".nii"))
        .filter(|s| !s.is_empty())
}

/// The scans of `anat` (entities checked against the folder's subject and session).
fn anat_scans(
    root: &Path,
    anat: &Path,
    subject: &str,
    session: Option<&str>,
) -> Result<Vec<Scan>, BidsError> {
    let prefix = match session {
        Some(s) => format!("sub-{subject}_ses-{s}_"),
        None => format!("sub-{subject}_"),
    };
    let mut scans = Vec::new();
    for path in read_dir(anat)? {
        let name = name_of(&path);
        let Some(stem) = nifti_stem(name) else {
            continue;
        };
        if !stem.starts_with(&prefix) || !path.is_file() {
            continue;
        }
        let suffix = stem.rsplit('_').next().unwrap_or("").to_string();
        let relative = path
            .strip_prefix(root)
            .map(|p| p.to_string_lossy().replace('\\', "/"))
            .unwrap_or_else(|_| name.to_string());
        scans.push(Scan {
            subject: subject.to_string(),
            session: session.map(str::to_string),
            stem: stem.to_string(),
            suffix,
            path,
            relative,
        });
    }
    Ok(scans)
}

/// The anatomical scans of the BIDS dataset at `root`, of the subjects in `participants` (all
/// when empty; labels with or without `sub-`), sorted (module doc).
pub fn discover(root: &Path, participants: &[String]) -> Result<Vec<Scan>, BidsError> {
    let subjects: Vec<(String, PathBuf)> = read_dir(root)?
        .into_iter()
        .filter(|p| p.is_dir())
        .filter_map(|p| {
            let label = name_of(&p).strip_prefix("sub-")?.to_string();
            (!label.is_empty()).then_some((label, p))
        })
        .collect();
    if subjects.is_empty() {
        return Err(BidsError::NotBids(root.display().to_string()));
    }
    let wanted: Vec<&str> = participants
        .iter()
        .map(|l| l.strip_prefix("sub-").unwrap_or(l))
        .collect();
    for label in &wanted {
        if !subjects.iter().any(|(s, _)| s == label) {
            let names: Vec<String> = subjects.iter().map(|(s, _)| format!("sub-{s}")).collect();
            return Err(BidsError::UnknownParticipant {
                label: label.to_string(),
                root: root.display().to_string(),
                available: names.join(", "),
            });
        }
    }
    let mut scans = Vec::new();
    for (subject, dir) in subjects {
        if !wanted.is_empty() && !wanted.contains(&subject.as_str()) {
            continue;
        }
        let anat = dir.join("anat");
        if anat.is_dir() {
            scans.extend(anat_scans(root, &anat, &subject, None)?);
        }
        for session_dir in read_dir(&dir)?.into_iter().filter(|p| p.is_dir()) {
            let Some(session) = name_of(&session_dir).strip_prefix("ses-") else {
                continue;
            };
            let anat = session_dir.join("anat");
            if !session.is_empty() && anat.is_dir() {
                scans.extend(anat_scans(root, &anat, &subject, Some(session))?);
            }
        }
    }
    scans.sort_by(|a, b| a.relative.cmp(&b.relative));
    Ok(scans)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_are_disjoint_and_cover_the_list() {
        let shards: Vec<Shard> = (0..3)
            .map(|i| Shard::parse(&format!("{i}/3")).unwrap())
            .collect();
        for position in 0..10 {
            assert_eq!(shards.iter().filter(|s| s.takes(position)).count(), 1);
        }
        for bad in ["3/3", "1", "a/2", "0/0", "-1/2"] {
            assert!(Shard::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn slurm_array_variables_give_the_shard_from_the_array_minimum() {
        let env = |pairs: &'static [(&'static str, &'static str)]| {
            move |name: &str| {
                pairs
                    .iter()
                    .find(|(k, _)| *k == name)
                    .map(|(_, v)| v.to_string())
            }
        };
        assert_eq!(Shard::from_slurm(env(&[])).unwrap(), None);
        let one_based = env(&[
            ("SLURM_ARRAY_TASK_ID", "3"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
            ("SLURM_ARRAY_TASK_MIN", "1"),
        ]);
        assert_eq!(
            Shard::from_slurm(one_based).unwrap(),
            Some(Shard { index: 2, count: 4 })
        );
        let outside = env(&[
            ("SLURM_ARRAY_TASK_ID", "4"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
        ]);
        assert!(Shard::from_slurm(outside).unwrap_err().contains("--shard"));
    }

    #[test]
    fn discovery_finds_anat_scans_with_and_without_sessions_in_order() {
        let root = std::env::temp_dir().join(format!("morphray-bids-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        for file in [
            "sub-02/anat/sub-02_T1w.nii.gz",
            "sub-02/anat/sub-02_T1w.json",
            "sub-01/ses-b/anat/sub-01_ses-b_T2w.nii",
            "sub-01/ses-a/anat/sub-01_ses-a_T1w.nii.gz",
            "sub-01/ses-a/func/sub-01_ses-a_task-rest_bold.nii.gz",
            "sub-03/anat/sub-04_T1w.nii.gz",
            "derivatives/sub-01/anat/sub-01_T1w.nii.gz",
        ] {
            let path = root.join(file);
            std::fs::create_dir_all(path.parent().unwrap()).unwrap();
            std::fs::write(&path, b"x").unwrap();
        }
        let scans = discover(&root, &[]).unwrap();
        let found: Vec<(&str, &str)> = scans
            .iter()
            .map(|s| (s.relative.as_str(), s.suffix.as_str()))
            .collect();
        assert_eq!(
            found,
            [
                ("sub-01/ses-a/anat/sub-01_ses-a_T1w.nii.gz", "T1w"),
                ("sub-01/ses-b/anat/sub-01_ses-b_T2w.nii", "T2w"),
                ("sub-02/anat/sub-02_T1w.nii.gz", "T1w"),
            ]
        );
        assert_eq!(scans[1].output_dir(), PathBuf::from("sub-01/ses-b/anat"));
        let only = discover(&root, &["sub-02".into()]).unwrap();
        assert_eq!(only.len(), 1);
        let err = discover(&root, &["9".into()]).unwrap_err().to_string();
        assert!(
            err.contains("sub-9") && err.contains("sub-01, sub-02, sub-03"),
            "{err}"
        );
        let err = discover(&root.join("sub-01"), &[]).unwrap_err().to_string();
        assert!(err.contains("no sub-* folder"), "{err}");
        std::fs::remove_dir_all(&root).unwrap();
    }
}
