//! What a volume is, through the command line (issue 28, items 1 and 4): `info` and `peaks`
//! (text and JSON) report the modality and the contrast with basis and reason, from a BIDS name
//! and sidecar, a DICOM series' tags and Hounsfield values; a garbage or huge sidecar is a
//! warning; the PNG provenance records both; a scan with one tissue mode is not blank.
//! `peaks` and `render` need a Vulkan device (lavapipe here).

#[path = "common/volumes.rs"]
mod volumes;
#[path = "common/dicom.rs"]
mod writer;

use dicom_core::VR;
use dicom_dictionary_std::tags;
use morphray::volume::Samples;
use morphray::volume::nifti::write_nifti1;
use morphray::volume::phantom::{PhantomSpec, generate};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn morphray(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_morphray"))
        .args(args)
        .env("MORPHRAY_VALIDATION", "required")
        .output()
        .expect("the morphray binary runs")
}

fn folder(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("morphray-modality-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn json_of(args: &[&str]) -> Value {
    let o = morphray(args);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice(&o.stdout).unwrap()
}

/// The 20^3 T1 phantom written as `dir/name`.
fn phantom_file(dir: &Path, name: &str) -> PathBuf {
    let path = dir.join(name);
    let phantom = generate(&PhantomSpec::cube(20)).unwrap();
    write_nifti1(&phantom.volume, &path, false).unwrap();
    path
}

fn pair(v: &Value) -> (String, String) {
    let value = v
        .get("modality")
        .or_else(|| v.get("contrast"))
        .and_then(Value::as_str)
        .unwrap_or_default();
    (value.into(), v["basis"].as_str().unwrap_or_default().into())
}

fn p(a: &str, b: &str) -> (String, String) {
    (a.into(), b.into())
}

#[test]
fn bids_names_and_sidecars_decide_in_info() {
    let dir = folder("bids");
    let t2 = phantom_file(&dir, "sub-01_T2w.nii");
    let v = json_of(&["info", s(&t2), "--json"]);
    assert_eq!(pair(&v["identity"]["modality"]), p("mr", "metadata"));
    assert_eq!(pair(&v["identity"]["contrast"]), p("t2", "metadata"));
    assert_eq!(v["identity"]["contrast"]["reason"], "BIDS suffix _T2w");
    // A sidecar's times decide a name without a suffix (BIDS seconds -> ms).
    let plain = phantom_file(&dir, "scan.nii");
    std::fs::write(
        dir.join("scan.json"),
        r#"{"RepetitionTime": 9.0, "EchoTime": 0.12, "InversionTime": 2.5}"#,
    )
    .unwrap();
    let v = json_of(&["info", s(&plain), "--json"]);
    let c = &v["identity"]["contrast"];
    assert_eq!(pair(c), p("flair", "metadata"), "{c}");
    assert!(c["reason"].as_str().unwrap().contains("TI 2500 ms"), "{c}");
    assert_eq!(v["identity"]["facts"]["inversion_time_ms"], 2500.0);
    // The text form says the same in one line each.
    let o = morphray(&["info", s(&plain)]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("contrast      FLAIR (metadata): TR 9000 ms"),
        "{text}"
    );
    assert!(text.contains("BIDS sidecar scan.json"), "{text}");
    // Post-contrast from the ce- entity.
    let ce = phantom_file(&dir, "sub-01_ce-gadolinium_T1w.nii");
    let v = json_of(&["info", s(&ce), "--json"]);
    assert_eq!(v["identity"]["contrast"]["post_contrast"], true);
    // The overrides.
    let v = json_of(&[
        "--modality",
        "ct",
        "--contrast",
        "pd",
        "info",
        s(&t2),
        "--json",
    ]);
    assert_eq!(pair(&v["identity"]["modality"]), p("ct", "given"));
    assert_eq!(pair(&v["identity"]["contrast"]), p("pd", "given"));
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_garbage_or_huge_sidecar_is_a_warning_not_an_error() {
    let dir = folder("garbage");
    let bad = phantom_file(&dir, "bad_T1w.nii");
    std::fs::write(dir.join("bad_T1w.json"), b"{ not json \xff").unwrap();
    let huge = phantom_file(&dir, "huge.nii");
    let mut big = vec![b' '; 2 << 20];
    big.extend_from_slice(br#"{"EchoTime": 0.1}"#);
    std::fs::write(dir.join("huge.json"), big).unwrap();
    let list = phantom_file(&dir, "list.nii");
    std::fs::write(dir.join("list.json"), "[1, 2, 3]").unwrap();
    for (file, says) in [
        (&bad, "is not JSON"),
        (&huge, "ignored"),
        (&list, "not a JSON object"),
    ] {
        let v = json_of(&["info", s(file), "--json"]);
        let warnings: Vec<&str> = v["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(Value::as_str)
            .collect();
        assert!(
            warnings
                .iter()
                .any(|w| w.contains("sidecar") && w.contains(says)),
            "{file:?}: {warnings:?}"
        );
    }
    // The bad sidecar does not hide the name's suffix; the huge one's EchoTime is not read.
    let v = json_of(&["info", s(&bad), "--json"]);
    assert_eq!(pair(&v["identity"]["contrast"]), p("t1", "metadata"));
    let v = json_of(&["info", s(&huge), "--json"]);
    assert_eq!(v["identity"]["facts"]["echo_time_ms"], Value::Null);
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn dicom_tags_name_the_modality_and_the_contrast() {
    let dir = folder("dicom");
    let ct = writer::Spec {
        modality: "CT",
        description: "Head routine".into(),
        ..writer::Spec::axial("1.2.826.0.1.3680043.2.1125.28.1")
    };
    writer::write_series(&dir.join("ct"), &ct);
    let v = json_of(&["info", s(&dir.join("ct")), "--json"]);
    let id = &v["volume"]["identity"];
    assert_eq!(pair(&id["modality"]), p("ct", "metadata"), "{id}");
    let reason = id["modality"]["reason"].as_str().unwrap();
    // The writer's values (10..1529) are no HU: the reason says so.
    assert!(reason.starts_with("Modality 'CT'; the values"), "{reason}");
    assert_eq!(pair(&id["contrast"]), p("ct", "metadata"));
    let mr = writer::Spec {
        description: "localizer".into(),
        extra: vec![
            (tags::PROTOCOL_NAME, VR::LO, "t2_tse_tra".into()),
            (tags::REPETITION_TIME, VR::DS, "4000".into()),
            (tags::ECHO_TIME, VR::DS, "98".into()),
        ],
        ..writer::Spec::axial("1.2.826.0.1.3680043.2.1125.28.2")
    };
    writer::write_series(&dir.join("mr"), &mr);
    let v = json_of(&["info", s(&dir.join("mr")), "--json"]);
    let id = &v["volume"]["identity"];
    assert_eq!(pair(&id["contrast"]), p("t2", "metadata"), "{id}");
    assert!(
        id["contrast"]["reason"]
            .as_str()
            .unwrap()
            .contains("ProtocolName 't2_tse_tra'"),
        "{id}"
    );
    assert_eq!(id["facts"]["echo_time_ms"], 98.0);
    let _ = std::fs::remove_dir_all(dir);
}

/// A 24^3 head of Hounsfield units: air, a bone shell, brain.
fn ct_file(dir: &Path) -> PathBuf {
    let n = 24usize;
    let c = (n as f64 - 1.0) / 2.0;
    let values: Vec<i16> = (0..n * n * n)
        .map(|i| {
            let (x, y, z) = (i % n, (i / n) % n, i / (n * n));
            let r =
                ((x as f64 - c).powi(2) + (y as f64 - c).powi(2) + (z as f64 - c).powi(2)).sqrt();
            match r {
                r if r < 7.0 => 35 + (i % 7) as i16,
                r if r < 9.0 => 1200,
                _ => -1000 + (i % 5) as i16,
            }
        })
        .collect();
    let volume = volumes::volume([n; 3], [1.0; 3], Samples::from_i16(&values));
    let path = dir.join("head.nii");
    write_nifti1(&volume, &path, false).unwrap();
    path
}

#[test]
fn hounsfield_values_say_ct_and_peaks_reports_both_objects() {
    let dir = folder("hu");
    let ct = ct_file(&dir);
    let v = json_of(&["info", s(&ct), "--json"]);
    assert_eq!(pair(&v["identity"]["modality"]), p("ct", "values"));
    assert!(
        v["identity"]["modality"]["reason"]
            .as_str()
            .unwrap()
            .starts_with("Hounsfield units")
    );
    let v = json_of(&["peaks", s(&ct), "--json"]);
    assert_eq!(pair(&v["modality"]), p("ct", "values"), "{}", v["modality"]);
    assert_eq!(pair(&v["contrast"]), p("ct", "values"), "{}", v["contrast"]);
    for key in ["modality", "contrast"] {
        assert!(v[key]["reason"].as_str().is_some_and(|r| !r.is_empty()));
    }
    let o = morphray(&["peaks", s(&ct)]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("modality CT (values): Hounsfield units"),
        "{text}"
    );
    assert!(text.contains("contrast CT (values)"), "{text}");
    // The phantom by a BIDS name: MR and T2 from the metadata, in peaks too.
    let t2 = phantom_file(&dir, "sub-02_T2w.nii");
    let v = json_of(&["peaks", s(&t2), "--json"]);
    assert_eq!(pair(&v["modality"]), p("mr", "metadata"));
    assert_eq!(pair(&v["contrast"]), p("t2", "metadata"));
    let _ = std::fs::remove_dir_all(dir);
}

/// Lit pixels of an RGBA PNG (any channel above 1).
fn lit_pixels(png: &Path) -> usize {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(png).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut rgba = vec![0; reader.output_buffer_size().unwrap()];
    reader.next_frame(&mut rgba).unwrap();
    rgba.chunks_exact(4)
        .filter(|p| p[..3].iter().any(|&c| c > 1))
        .count()
}

#[test]
fn one_tissue_mode_renders_the_foreground_and_provenance_records_the_decisions() {
    let dir = folder("fallback");
    // Rician-like air noise around a ball of one tissue with a smooth bias: one broad mode.
    let n = 32usize;
    let c = (n as f64 - 1.0) / 2.0;
    let mut rng = volumes::Rng(28);
    let values: Vec<i16> = (0..n * n * n)
        .map(|i| {
            let (x, y, z) = (i % n, (i / n) % n, i / (n * n));
            let r =
                ((x as f64 - c).powi(2) + (y as f64 - c).powi(2) + (z as f64 - c).powi(2)).sqrt();
            let noise = (rng.unit() + rng.unit() + rng.unit()) * 10.0;
            let v = if r < 12.0 {
                600.0 + 8.0 * x as f64
            } else {
                0.0
            };
            (v + noise).round() as i16
        })
        .collect();
    let volume = volumes::volume([n; 3], [1.0; 3], Samples::from_i16(&values));
    let path = dir.join("sub-01_T2w.nii");
    write_nifti1(&volume, &path, false).unwrap();
    let v = json_of(&["peaks", s(&path), "--json"]);
    assert!(v["peaks"]["wm"].is_null(), "{}", v["peaks"]);
    assert!(
        v["fallback"]["reason"].as_str().is_some(),
        "{}",
        v["fallback"]
    );
    let png = dir.join("one.png");
    let o = morphray(&["render", s(&path), "-o", s(&png), "--size", "48x48"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    let said: Vec<&str> = err
        .lines()
        .filter(|l| l.contains("no tissue class could be found"))
        .collect();
    assert_eq!(said.len(), 1, "{err}");
    assert!(!err.contains("only the background"), "{err}");
    assert!(lit_pixels(&png) > 200, "the foreground is drawn");
    let chunks = morphray::files::png::read_text_chunks(&png).unwrap();
    let parameters = &chunks
        .iter()
        .find(|(k, _)| k.contains("parameters"))
        .unwrap()
        .1;
    let p: Value = serde_json::from_str(parameters).unwrap();
    assert_eq!(
        pair(&p["modality"]),
        (String::from("mr"), String::from("metadata"))
    );
    assert_eq!(
        pair(&p["contrast"]),
        (String::from("t2"), String::from("metadata"))
    );
    assert!(p["fallback"]["window"]["lo"].as_f64().is_some(), "{p}");
    let _ = std::fs::remove_dir_all(dir);
}
