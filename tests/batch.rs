//! `morphray batch` as a cohort user runs it, on a generated 3-subject BIDS dataset whose last
//! scan is broken: BIDS Derivatives written per scan, the broken scan logged and skipped, a
//! rerun that skips finished scans, shards (by flag and by Slurm variables) that split the list,
//! and the group level's TSV and HTML report.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn morphray(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_morphray"));
    command.args(args);
    for key in [
        "SLURM_ARRAY_TASK_ID",
        "SLURM_ARRAY_TASK_COUNT",
        "SLURM_ARRAY_TASK_MIN",
    ] {
        command.env_remove(key);
    }
    command.envs(env.iter().copied());
    command.output().expect("the morphray binary runs")
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

fn temp(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("morphray-batch-{}-{name}", std::process::id()))
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn summaries(out: &Path) -> Vec<String> {
    let mut found = Vec::new();
    for sub in ["sub-01", "sub-02", "sub-03"] {
        let path = out.join(format!("{sub}/anat/{sub}_desc-peaks_T1w.json"));
        if path.is_file() {
            found.push(sub.to_string());
        }
    }
    found
}

#[test]
fn participant_and_group_levels_write_derivatives_skip_the_broken_scan_and_resume() {
    let bids = temp("bids");
    let out = temp("out");
    let _ = std::fs::remove_dir_all(&out);
    common::bids::write_dataset(&bids, 3, 32, true);
    let args = [
        "batch",
        s(&bids),
        s(&out),
        "participant",
        "--thumbnail-size",
        "48",
    ];
    let first = morphray(&args, &[]);
    // A run with a failed scan exits 3 (documented in --help), after doing the others.
    assert_eq!(first.status.code(), Some(3), "{}", text(&first));
    let said = text(&first);
    assert!(
        said.contains("1 of 3 scans failed") && said.contains("--allow-failures"),
        "{said}"
    );
    assert!(
        said.contains("3 scans: 2 done, 0 skipped (finished earlier), 1 failed"),
        "{said}"
    );
    assert!(
        said.contains("warning: sub-03/anat/sub-03_T1w.nii.gz skipped"),
        "{said}"
    );

    let description: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("dataset_description.json")).unwrap())
            .unwrap();
    assert_eq!(description["DatasetType"], "derivative");
    assert_eq!(description["GeneratedBy"][0]["Name"], "morphray");

    let anat = out.join("sub-01/anat");
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(anat.join("sub-01_desc-peaks_T1w.json")).unwrap())
            .unwrap();
    assert_eq!(summary["dims"], serde_json::json!([32, 32, 32]));
    assert_eq!(summary["table1"]["total_voxels"], 32 * 32 * 32);
    assert_eq!(summary["subject"], "01");
    let mut views = Vec::new();
    for view in ["anterior", "lateral", "superior"] {
        let png = std::fs::read(anat.join(format!("sub-01_desc-{view}_T1w.png"))).unwrap();
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
        assert_eq!(&png[16..24], &[0, 0, 0, 48, 0, 0, 0, 48], "48x48 thumbnail");
        views.push(png);
    }
    assert!(
        views[0] != views[1] && views[1] != views[2],
        "three different views"
    );
    let error: serde_json::Value = serde_json::from_slice(
        &std::fs::read(out.join("sub-03/anat/sub-03_desc-error_T1w.json")).unwrap(),
    )
    .unwrap();
    assert!(
        error["error"]
            .as_str()
            .unwrap()
            .contains("sub-03_T1w.nii.gz"),
        "{error}"
    );
    let log = std::fs::read_to_string(out.join("logs/participant_shard-0-of-1.jsonl")).unwrap();
    assert_eq!(log.lines().count(), 3, "{log}");

    // A rerun skips the finished scans (their summaries are untouched) and retries the broken one.
    let written = std::fs::metadata(anat.join("sub-01_desc-peaks_T1w.json"))
        .unwrap()
        .modified()
        .unwrap();
    let mut allowed = args.to_vec();
    allowed.push("--allow-failures");
    let again = morphray(&allowed, &[]);
    assert!(again.status.success(), "{}", text(&again));
    assert!(
        text(&again).contains("3 scans: 0 done, 2 skipped (finished earlier), 1 failed"),
        "{}",
        text(&again)
    );
    let after = std::fs::metadata(anat.join("sub-01_desc-peaks_T1w.json"))
        .unwrap()
        .modified()
        .unwrap();
    assert_eq!(written, after);
    // A peaks-only run leaves thumbnails to a later run, which does not skip those scans.
    std::fs::remove_file(anat.join("sub-01_desc-lateral_T1w.png")).unwrap();
    let third = morphray(&allowed, &[]);
    assert!(
        text(&third).contains("3 scans: 1 done, 1 skipped"),
        "{}",
        text(&third)
    );
    assert!(anat.join("sub-01_desc-lateral_T1w.png").is_file());

    let group = morphray(&["batch", s(&bids), s(&out), "group"], &[]);
    assert!(group.status.success(), "{}", text(&group));
    let tsv = std::fs::read_to_string(out.join("group/morphray_table1.tsv")).unwrap();
    let lines: Vec<&str> = tsv.lines().collect();
    assert_eq!(lines.len(), 3, "{tsv}");
    assert!(
        lines[0].starts_with("scan\tsubject\tsession\tsuffix\t") && lines[0].contains("wm_norm")
    );
    assert!(
        lines[1].starts_with("sub-01/anat/sub-01_T1w.nii.gz\t01\tn/a\tT1w\t"),
        "{tsv}"
    );
    let html = std::fs::read_to_string(out.join("group/morphray_report.html")).unwrap();
    assert_eq!(html.matches("<svg").count(), 3);
    // The thumbnails are inside the report (data: URIs), named by their files.
    assert!(
        html.contains("alt=\"sub-02_desc-lateral_T1w.png\""),
        "{html}"
    );
    assert_eq!(html.matches("src=\"data:image/png;base64,").count(), 6);
    assert!(html.contains("2 scans, 1 failed"));
    assert!(html.contains("sub-03/anat/sub-03_T1w.nii.gz"));
    std::fs::remove_dir_all(&out).unwrap();
    std::fs::remove_dir_all(&bids).unwrap();
}

#[test]
fn shards_by_flag_or_slurm_variables_split_the_scans_and_labels_select_subjects() {
    let bids = temp("shards");
    common::bids::write_dataset(&bids, 3, 24, false);
    let run = |out: &Path, extra: &[&str], env: &[(&str, &str)]| {
        let _ = std::fs::remove_dir_all(out);
        let mut args = vec!["batch", s(&bids), s(out), "participant", "--no-thumbnails"];
        args.extend_from_slice(extra);
        let o = morphray(&args, env);
        assert!(o.status.success(), "{}", text(&o));
        summaries(out)
    };
    let a = temp("shard-a");
    let b = temp("shard-b");
    assert_eq!(run(&a, &["--shard", "0/2"], &[]), ["sub-01", "sub-03"]);
    // Slurm arrays may start at 1: task 2 of 1..2 is shard 1/2.
    let slurm = [
        ("SLURM_ARRAY_TASK_ID", "2"),
        ("SLURM_ARRAY_TASK_COUNT", "2"),
        ("SLURM_ARRAY_TASK_MIN", "1"),
    ];
    assert_eq!(run(&b, &[], &slurm), ["sub-02"]);
    assert!(b.join("logs/participant_shard-1-of-2.jsonl").is_file());
    assert_eq!(
        run(&a, &["--participant-label", "sub-02", "03"], &[]),
        ["sub-02", "sub-03"]
    );
    let unknown = morphray(
        &[
            "batch",
            s(&bids),
            s(&a),
            "participant",
            "--participant-label",
            "7",
        ],
        &[],
    );
    assert_eq!(unknown.status.code(), Some(1));
    assert!(
        text(&unknown).contains("no subject sub-7"),
        "{}",
        text(&unknown)
    );
    let bad = morphray(
        &["batch", s(&bids), s(&a), "participant", "--shard", "2/2"],
        &[],
    );
    assert_eq!(bad.status.code(), Some(1));
    for dir in [&a, &b, &bids] {
        std::fs::remove_dir_all(dir).unwrap();
    }
}

#[test]
fn the_output_folder_is_never_the_input_or_another_dataset() {
    let bids = temp("guard");
    common::bids::write_dataset(&bids, 1, 16, false);
    let description = std::fs::read(bids.join("dataset_description.json")).unwrap();
    let run = |out: &Path| {
        morphray(
            &["batch", s(&bids), s(out), "participant", "--no-thumbnails"],
            &[],
        )
    };
    // The input itself, also spelled another way.
    for out in [bids.clone(), bids.join("sub-01/..")] {
        let o = run(&out);
        assert_eq!(o.status.code(), Some(1), "{}", text(&o));
        assert!(
            text(&o).contains("is the input dataset itself"),
            "{}",
            text(&o)
        );
    }
    // Another raw dataset, and a derivative of another pipeline.
    let raw = temp("guard-raw");
    common::bids::write_dataset(&raw, 1, 8, false);
    let o = run(&raw);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(
        text(&o).contains("holds a raw (no DatasetType) dataset"),
        "{}",
        text(&o)
    );
    let other = temp("guard-fmriprep");
    std::fs::create_dir_all(&other).unwrap();
    let theirs = r#"{"DatasetType": "derivative", "GeneratedBy": [{"Name": "fMRIPrep"}]}"#;
    std::fs::write(other.join("dataset_description.json"), theirs).unwrap();
    let o = run(&other);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(
        text(&o).contains("derivative dataset of fMRIPrep"),
        "{}",
        text(&o)
    );
    assert_eq!(text(&o).lines().count(), 1, "one line: {}", text(&o));
    // Nothing was written into any of them.
    assert_eq!(
        std::fs::read(bids.join("dataset_description.json")).unwrap(),
        description
    );
    assert!(!bids.join("logs").exists() && !raw.join("logs").exists());
    assert_eq!(
        std::fs::read_to_string(other.join("dataset_description.json")).unwrap(),
        theirs
    );
    // The BIDS place for derivatives, inside the input, is fine.
    let inside = bids.join("derivatives/morphray");
    let o = run(&inside);
    assert!(o.status.success(), "{}", text(&o));
    for dir in [&bids, &raw, &other] {
        std::fs::remove_dir_all(dir).unwrap();
    }
}

#[test]
fn resume_redoes_a_replaced_input_and_a_truncated_summary() {
    let bids = temp("resume");
    let out = temp("resume-out");
    let _ = std::fs::remove_dir_all(&out);
    let scans = common::bids::write_dataset(&bids, 2, 16, false);
    let args = ["batch", s(&bids), s(&out), "participant", "--no-thumbnails"];
    let first = morphray(&args, &[]);
    assert!(first.status.success(), "{}", text(&first));
    let summary = out.join("sub-01/anat/sub-01_desc-peaks_T1w.json");
    let recorded: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&summary).unwrap()).unwrap();
    let size = std::fs::metadata(&scans[0]).unwrap().len();
    assert_eq!(recorded["source"]["size"], size);
    // Unchanged: both skipped.
    let again = morphray(&args, &[]);
    assert!(
        text(&again).contains("0 done, 2 skipped"),
        "{}",
        text(&again)
    );
    // sub-01's input replaced by sub-02's (another size or time), sub-02's summary cut short.
    std::fs::copy(&scans[1], &scans[0]).unwrap();
    let other = out.join("sub-02/anat/sub-02_desc-peaks_T1w.json");
    let text2 = std::fs::read(&other).unwrap();
    std::fs::write(&other, &text2[..text2.len() / 2]).unwrap();
    let third = morphray(&args, &[]);
    assert!(third.status.success(), "{}", text(&third));
    assert!(
        text(&third).contains("2 done, 0 skipped"),
        "{}",
        text(&third)
    );
    let redone: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&other).unwrap()).unwrap();
    assert_eq!(redone["subject"], "02");
    std::fs::remove_dir_all(&out).unwrap();
    std::fs::remove_dir_all(&bids).unwrap();
}

#[test]
fn help_documents_the_exit_status() {
    let o = morphray(&["batch", "--help"], &[]);
    let said = text(&o);
    assert!(
        said.contains("3 when it ran but some scans failed") && said.contains("--allow-failures"),
        "{said}"
    );
}

/// A dataset of three scans for the report's quality column: a T1w phantom, the same phantom
/// named T2w (the BIDS suffix decides the contrast) and a constant T1w volume (nothing to show).
fn quality_dataset(root: &Path) {
    use morphray::volume::nifti::write_nifti1;
    use morphray::volume::phantom::{PhantomSpec, generate};
    let _ = std::fs::remove_dir_all(root);
    std::fs::create_dir_all(root).unwrap();
    std::fs::write(
        root.join("dataset_description.json"),
        r#"{"Name": "quality", "BIDSVersion": "1.10.0"}"#,
    )
    .unwrap();
    let phantom = generate(&PhantomSpec::cube(24)).unwrap().volume;
    let mut constant = phantom.clone();
    constant.samples = morphray::volume::Samples::from_f32(&vec![100.0; 24 * 24 * 24]);
    for (sub, suffix, volume) in [
        ("01", "T1w", &phantom),
        ("02", "T2w", &phantom),
        ("03", "T1w", &constant),
    ] {
        let anat = root.join(format!("sub-{sub}/anat"));
        std::fs::create_dir_all(&anat).unwrap();
        let path = anat.join(format!("sub-{sub}_{suffix}.nii.gz"));
        write_nifti1(volume, &path, true).unwrap();
    }
}

#[test]
fn the_report_flags_quality_embeds_its_pictures_and_takes_the_contrast_from_the_bids_suffix() {
    let bids = temp("quality-bids");
    let out = temp("quality-out");
    let _ = std::fs::remove_dir_all(&out);
    quality_dataset(&bids);
    let run = morphray(
        &[
            "batch",
            s(&bids),
            s(&out),
            "participant",
            "--thumbnail-size",
            "32",
        ],
        &[],
    );
    assert!(run.status.success(), "{}", text(&run));
    let group = morphray(&["batch", s(&bids), s(&out), "group"], &[]);
    assert!(group.status.success(), "{}", text(&group));
    let tsv = std::fs::read_to_string(out.join("group/morphray_table1.tsv")).unwrap();
    let header: Vec<&str> = tsv.lines().next().unwrap().split('\t').collect();
    let column = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let row = |sub: &str| -> Vec<String> {
        let line = tsv
            .lines()
            .find(|l| l.contains(&format!("sub-{sub}_")))
            .unwrap();
        line.split('\t').map(str::to_string).collect()
    };
    let (contrast, basis, qc) = (column("contrast"), column("contrast_basis"), column("qc"));
    assert_eq!(row("02")[contrast], "t2", "{tsv}");
    assert_eq!(row("02")[basis], "metadata", "{tsv}");
    assert_eq!(row("01")[contrast], "t1", "{tsv}");
    assert!(row("03")[qc].contains("blank picture"), "{tsv}");
    // The cause is named too: a constant volume gets no window at all.
    assert!(row("03")[qc].contains("no windows"), "{tsv}");
    assert!(!row("01")[qc].contains("no windows"), "{tsv}");
    assert!(!row("01")[qc].contains("blank picture"), "{tsv}");
    // One self-contained file: every thumbnail inside it, no link to a file beside it.
    let html = std::fs::read_to_string(out.join("group/morphray_report.html")).unwrap();
    assert_eq!(
        html.matches("src=\"data:image/png;base64,iVBOR").count(),
        9,
        "3 scans x 3 views"
    );
    assert!(!html.contains("src=\"../"), "no relative links");
    assert!(
        html.contains("class=\"flagged\""),
        "the blank scan's row is marked"
    );
    // The default thumbnails ran brain extraction (its decision is recorded); `head` did not.
    let summary = |out: &Path| -> serde_json::Value {
        let p = out.join("sub-01/anat/sub-01_desc-peaks_T1w.json");
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    assert!(summary(&out)["brain"].is_string(), "{}", summary(&out));
    let heads = temp("quality-heads");
    let _ = std::fs::remove_dir_all(&heads);
    let run = morphray(
        &[
            "batch",
            s(&bids),
            s(&heads),
            "participant",
            "--thumbnail-size",
            "32",
            "--participant-label",
            "01",
            "--thumbnails",
            "head",
        ],
        &[],
    );
    assert!(run.status.success(), "{}", text(&run));
    assert!(summary(&heads)["brain"].is_null(), "{}", summary(&heads));
    for dir in [bids, out, heads] {
        let _ = std::fs::remove_dir_all(dir);
    }
}
