//! The Snakemake workflow (tools/workflow/Snakefile) as CI runs it: `snakemake --cores 2` from
//! the cached venv of tools/pyenv.sh on a generated 6-subject BIDS dataset, two participant
//! shards then the group report, with the built binary. Fails (never skips) without the venv.

mod common;

use std::path::PathBuf;
use std::process::Command;

fn pyenv() -> PathBuf {
    if let Some(dir) = std::env::var_os("MORPHRAY_PYENV") {
        return PathBuf::from(dir);
    }
    let cache = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))
        .expect("neither XDG_CACHE_HOME nor HOME is set");
    cache.join("morphray/pyenv")
}

/// The venv's snakemake; fails (never skips) when the venv is missing.
fn snakemake() -> PathBuf {
    let snakemake = pyenv().join("bin/snakemake");
    assert!(
        snakemake.is_file(),
        "{} is missing: run tools/setup.sh (or tools/pyenv.sh) first",
        snakemake.display()
    );
    snakemake
}

#[test]
fn snakemake_runs_the_shards_then_the_group_report_on_six_subjects() {
    let snakemake = snakemake();
    let root = std::env::temp_dir().join(format!("morphray-workflow-{}", std::process::id()));
    let bids = root.join("bids");
    let out = root.join("derivatives");
    common::bids::write_dataset(&bids, 6, 24, false);
    let snakefile = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tools/workflow/Snakefile");
    let output = Command::new(&snakemake)
        .arg("-s")
        .arg(&snakefile)
        .args(["--cores", "2", "--directory"])
        .arg(&root)
        .arg("--config")
        .arg(format!("bids={}", bids.display()))
        .arg(format!("out={}", out.display()))
        .arg(format!("morphray={}", env!("CARGO_BIN_EXE_morphray")))
        .args(["shards=2", "thumbnail_size=32"])
        .output()
        .expect("snakemake runs");
    let said = format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(output.status.success(), "snakemake failed:\n{said}");
    // Two participant jobs, the group job and `all` ran (Snakemake's own summary line).
    assert!(said.contains("4 of 4 steps (100%) done"), "{said}");
    for shard in 0..2 {
        assert!(
            out.join(format!("logs/participant_shard-{shard}-of-2.jsonl"))
                .is_file()
        );
    }
    let tsv = std::fs::read_to_string(out.join("group/morphray_table1.tsv")).unwrap();
    assert_eq!(tsv.lines().count(), 7, "a header and six scans:\n{tsv}");
    for s in 1..=6 {
        assert!(
            tsv.contains(&format!("sub-{s:02}/anat/sub-{s:02}_T1w.nii.gz\t")),
            "{tsv}"
        );
    }
    let html = std::fs::read_to_string(out.join("group/morphray_report.html")).unwrap();
    assert!(html.contains("6 scans, 0 failed"));
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn the_slurm_executor_plugin_plans_the_same_workflow_without_edits() {
    // No cluster here: a dry run through Snakemake's Slurm executor plugin checks that the
    // Snakefile's rules and resources are accepted by it as they are (the submission itself
    // needs sbatch; README.md of tools/workflow says how to run it).
    let snakemake = snakemake();
    let root = std::env::temp_dir().join(format!("morphray-slurm-{}", std::process::id()));
    let bids = root.join("bids");
    common::bids::write_dataset(&bids, 2, 12, false);
    let snakefile = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tools/workflow/Snakefile");
    let output = Command::new(&snakemake)
        .arg("-s")
        .arg(&snakefile)
        .args([
            "--executor",
            "slurm",
            "--jobs",
            "4",
            "--dry-run",
            "--directory",
        ])
        .arg(&root)
        .arg("--config")
        .arg(format!("bids={}", bids.display()))
        .arg(format!("out={}", root.join("derivatives").display()))
        .args(["shards=3"])
        .output()
        .expect("snakemake runs");
    let said = format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    std::fs::remove_dir_all(&root).ok();
    assert!(output.status.success(), "the Slurm dry run failed:\n{said}");
    assert!(said.contains("This was a dry-run"), "{said}");
    // Three participant jobs, then the group job.
    let participant_jobs = said
        .lines()
        .find(|l| l.trim_start().starts_with("participant"))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|n| n.parse::<u32>().ok());
    assert_eq!(participant_jobs, Some(3), "{said}");
}
