//! A tiny BIDS dataset for the batch and workflow tests: phantoms written as NIfTI (each subject
//! its own noise seed), optionally a broken scan, and `dataset_description.json`.

use morphray::volume::nifti::write_nifti1;
use morphray::volume::phantom::{PhantomSpec, generate};
use std::path::{Path, PathBuf};

/// Writes `subjects` subjects (`sub-01`, ...) with one `n`^3 T1w phantom each under `root`
/// (replacing it), the last of them broken when `broken` (a truncated gzip stream named like a
/// scan). Returns the scans' paths.
pub fn write_dataset(root: &Path, subjects: usize, n: usize, broken: bool) -> Vec<PathBuf> {
    let _ = std::fs::remove_dir_all(root);
    std::fs::create_dir_all(root).unwrap();
    std::fs::write(
        root.join("dataset_description.json"),
        r#"{"Name": "morphray test cohort", "BIDSVersion": "1.10.0"}"#,
    )
    .unwrap();
    let mut paths = Vec::new();
    for s in 1..=subjects {
        let anat = root.join(format!("sub-{s:02}/anat"));
        std::fs::create_dir_all(&anat).unwrap();
        let path = anat.join(format!("sub-{s:02}_T1w.nii.gz"));
        if broken && s == subjects {
            std::fs::write(&path, [0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 3, 1, 2, 3]).unwrap();
        } else {
            let spec = PhantomSpec {
                seed: PhantomSpec::DEFAULT_SEED + s as u64,
                ..PhantomSpec::cube(n)
            };
            write_nifti1(&generate(&spec).unwrap().volume, &path, true).unwrap();
        }
        // A sidecar, which is not a scan.
        std::fs::write(anat.join(format!("sub-{s:02}_T1w.json")), "{}").unwrap();
        paths.push(path);
    }
    paths
}
