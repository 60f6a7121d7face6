//! DICOM input through the command line (issue 14 item 4): `info --json` lists the series,
//! `convert` writes the assembled series as NIfTI, `--series` picks one, and `peaks` and
//! `render` work on a folder as a user would try them (GPU: lavapipe or the machine's device).

#[path = "common/dicom.rs"]
mod writer;

use morphray::volume::phantom::{PhantomSpec, generate};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use writer::Spec;

fn morphray(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_morphray"))
        .args(args)
        .output()
        .expect("the morphray binary runs")
}

fn folder(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("morphray-dcli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A one-line `morphray:` failure with exit status 1 containing `needle`.
fn assert_one_line_failure(o: &Output, needle: &str) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(
        err.starts_with("morphray: ") && !err.contains("panicked"),
        "{err}"
    );
    assert!(err.contains(needle), "`{needle}` not in {err}");
}

/// An exam as scanners write it: a localizer, a 3-D series, a smaller second series, a
/// corrupt file and a README.
fn exam(name: &str) -> (PathBuf, Spec, Spec) {
    let dir = folder(name);
    let main = Spec::oblique("1.2.826.0.1.3680043.2.1125.3.1");
    writer::write_series(&dir.join("S3"), &main);
    let second = Spec {
        slices: 5,
        number: 4,
        description: "second".into(),
        ..Spec::coronal("1.2.826.0.1.3680043.2.1125.3.2")
    };
    writer::write_series(&dir.join("S4"), &second);
    let localizer = Spec {
        slices: 3,
        number: 1,
        image_type: "ORIGINAL\\PRIMARY\\LOCALIZER".into(),
        description: "localizer".into(),
        ..Spec::sagittal("1.2.826.0.1.3680043.2.1125.3.3")
    };
    writer::write_series(&dir.join("S1"), &localizer);
    let mut garbage = vec![0u8; 128];
    garbage.extend_from_slice(b"DICM\x02\x00\x00\x00UL\x04\x00\xff\xff\xff\x7f");
    std::fs::write(dir.join("S3").join("broken.dcm"), &garbage).unwrap();
    std::fs::write(dir.join("README"), "exported by a PACS").unwrap();
    (dir, main, second)
}

#[test]
fn info_json_lists_every_series_with_the_default_and_the_skipped_files() {
    let (dir, main, second) = exam("info");
    let o = morphray(&["info", "--json", s(&dir)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let series = v["series"].as_array().unwrap();
    assert_eq!(series.len(), 3);
    for entry in series {
        for key in [
            "uid",
            "description",
            "number",
            "dims",
            "spacing",
            "affine",
            "count",
            "warnings",
        ] {
            assert!(entry.get(key).is_some(), "{key} missing in {entry}");
        }
    }
    assert_eq!(series[0]["role"], "localizer");
    assert_eq!(series[1]["uid"], main.uid.as_str());
    assert_eq!(series[1]["dims"], serde_json::json!([24, 20, 12]));
    assert_eq!(series[1]["count"], 12);
    assert_eq!(v["default"], 1);
    assert!(
        v["default_reason"]
            .as_str()
            .unwrap()
            .contains("largest 3-D")
    );
    // The affine maps voxel (0,0,0) to the first slice's first pixel in RAS.
    let a = &series[1]["affine"];
    let origin = main.ras(0.0, 0.0, 0.0);
    for r in 0..3 {
        assert!((a[r][3].as_f64().unwrap() - origin[r]).abs() < 1e-6);
    }
    let skipped = v["skipped"].as_array().unwrap();
    assert_eq!(skipped.len(), 1, "{skipped:?}");
    assert!(skipped[0]["path"].as_str().unwrap().ends_with("broken.dcm"));
    assert_eq!(v["not_dicom_files"], 1);

    // --series picks what info describes.
    let o = morphray(&["info", "--json", "--series", &second.uid, s(&dir)]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["chosen"], 2);
    assert_eq!(v["volume"]["dims"], serde_json::json!([24, 20, 5]));
    let o = morphray(&["info", "--series", "9", s(&dir)]);
    assert_one_line_failure(&o, "--series 9");
}

#[test]
fn convert_writes_the_series_as_nifti_and_never_replaces_a_file_unasked() {
    let (dir, main, _) = exam("convert");
    let out = dir.join("t1.nii.gz");
    let o = morphray(&["convert", s(&dir), "-o", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let nii = morphray::volume::Volume::open(&out).unwrap();
    assert_eq!(nii.dims, [24, 20, 12]);
    let a = &nii.orientation.affine;
    for (i, j, k) in [(0.0, 0.0, 0.0), (23.0, 19.0, 11.0)] {
        let want = main.ras(i, j, k);
        for r in 0..3 {
            let got = a[r][0] * i + a[r][1] * j + a[r][2] * k + a[r][3];
            assert!((got - want[r]).abs() < 1e-3, "{got} vs {want:?}");
        }
    }
    assert_eq!(
        nii.samples.get(3 + 24 * (5 + 20 * 7)),
        main.value(3, 5, 7) as f64
    );
    // Existing output: refused without --force; the input itself: refused even with it.
    let o = morphray(&["convert", s(&dir), "-o", s(&out)]);
    assert_one_line_failure(&o, "t1.nii.gz");
    let o = morphray(&["convert", s(&out), "-o", s(&out), "--force"]);
    assert_one_line_failure(&o, "input");
    let o = morphray(&["convert", s(&dir)]);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn peaks_of_a_dicom_series_equal_those_of_the_same_volume_as_nifti() {
    let phantom = generate(&PhantomSpec::cube(48)).unwrap().volume;
    let dir = folder("peaks");
    let spec = writer::from_volume("1.2.826.0.1.3680043.2.1125.3.4", &phantom);
    writer::write_series(&dir.join("dicom"), &spec);
    let nii = dir.join("same.nii");
    let o = morphray(&["convert", s(&dir.join("dicom")), "-o", s(&nii)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let peaks = |input: &Path| {
        let o = morphray(&["peaks", "--json", s(input)]);
        assert!(o.status.success(), "{}", stderr(&o));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        (
            v["peaks"].clone(),
            v["imin"].clone(),
            v["imax"].clone(),
            v["file"].clone(),
        )
    };
    let (dicom_peaks, dmin, dmax, label) = peaks(&dir.join("dicom"));
    let (nifti_peaks, nmin, nmax, _) = peaks(&nii);
    assert!(dicom_peaks["wm"]["raw"].is_number(), "{dicom_peaks}");
    assert_eq!(dicom_peaks, nifti_peaks);
    assert_eq!((dmin, dmax), (nmin, nmax));
    // The Table-1 row names the series.
    assert!(label.as_str().unwrap().contains("series 3"), "{label}");
}

#[test]
fn render_of_an_exam_folder_writes_a_png_naming_the_series() {
    let (dir, _, _) = exam("render");
    let png = dir.join("x.png");
    let o = morphray(&["render", s(&dir), "-o", s(&png), "--size", "48x40"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let chunks = morphray::files::png::read_text_chunks(&png).unwrap();
    let input = chunks
        .iter()
        .find(|(k, _)| k == "morphray:input")
        .map(|(_, v)| v.clone())
        .unwrap_or_default();
    assert!(input.contains("series 3 \"T1 test\""), "{input}");
    let o = morphray(&["render", s(&dir), "-o", s(&png), "--frame", "1"]);
    assert_one_line_failure(&o, "--series");
}

/// `cd exam/S3 && morphray render ..`: the default output is named after the folder `..`
/// resolves to, in the current directory (not `volume.png`, not `..png`).
#[test]
fn render_of_dot_dot_names_the_picture_after_the_folder() {
    let (dir, _, _) = exam("dotdot");
    let here = dir.join("S3");
    let o = Command::new(env!("CARGO_BIN_EXE_morphray"))
        .args(["render", "..", "--size", "40x32"])
        .current_dir(&here)
        .output()
        .expect("the morphray binary runs");
    assert!(o.status.success(), "{}", stderr(&o));
    let name = dir.file_name().unwrap().to_string_lossy().into_owned();
    let png = here.join(format!("{name}.png"));
    assert!(png.is_file(), "{} missing: {}", png.display(), stderr(&o));
    assert!(!here.join("volume.png").exists());
}

#[test]
fn several_files_are_one_input_and_a_nifti_among_them_is_refused() {
    let dir = folder("several");
    let spec = Spec::axial("1.2.826.0.1.3680043.2.1125.3.9");
    let mut files = writer::write_series(&dir, &spec);
    files.sort();
    let names: Vec<&str> = files.iter().map(|p| s(p)).collect();
    // `morphray info *.dcm`: one series of all the files given.
    let mut args = vec!["info", "--json"];
    args.extend(&names);
    let o = morphray(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["series"].as_array().unwrap().len(), 1);
    assert_eq!(v["series"][0]["count"], 12);
    assert_eq!(v["volume"]["dims"], serde_json::json!([24, 20, 12]));
    // Half the files are half the slices: exactly what was given is read, not the folder.
    let mut args = vec!["info", "--json"];
    args.extend(&names[..6]);
    let v: serde_json::Value = serde_json::from_slice(&morphray(&args).stdout).unwrap();
    assert_eq!(v["series"][0]["count"], 6);
    // render reads them as one volume, and will not write over any of them.
    let png = dir.join("several.png");
    let mut args = vec!["render", "-o", s(&png), "--size", "40x32"];
    args.extend(&names);
    let o = morphray(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(png.exists());
    let mut args = vec!["render", "-o", names[3], "--size", "40x32"];
    args.extend(&names);
    assert_one_line_failure(&morphray(&args), "input");
    // A NIfTI among them: one line naming it.
    let nii = dir.join("other.nii");
    let volume = generate(&PhantomSpec::cube(8)).unwrap().volume;
    morphray::volume::nifti::write_nifti1(&volume, &nii, false).unwrap();
    let o = morphray(&["peaks", names[0], s(&nii)]);
    assert_one_line_failure(&o, "other.nii");
    assert!(stderr(&o).contains("not DICOM"), "{}", stderr(&o));
}

/// `morphray view` offscreen and scripted, validation required.
fn view_offscreen(args: &[&str]) -> Output {
    let o = Command::new(env!("CARGO_BIN_EXE_morphray"))
        .arg("view")
        .args(args)
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .env("MORPHRAY_VALIDATION", "required")
        .output()
        .expect("the morphray binary runs");
    let log = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(
        !stderr(&o).contains("no Vulkan") && !stderr(&o).contains("found no device"),
        "this test needs a Vulkan device (Debian: apt-get install mesa-vulkan-drivers \
         libvulkan1 vulkan-validationlayers): {}",
        stderr(&o)
    );
    assert!(o.status.success(), "{log}\n{}", stderr(&o));
    assert!(log.contains("validation layer: 0 error(s)"), "{log}");
    o
}

#[test]
fn the_viewer_opens_the_series_asked_for_and_switches_from_its_series_menu() {
    let (dir, _, second) = exam("viewer");
    let script = dir.join("series.txt");
    std::fs::write(&script, "wait 2\nseries 1\nwait 2\nseries 9\nwait 1\n").unwrap();
    let o = view_offscreen(&[
        s(&dir),
        "--series",
        &second.uid,
        "--size",
        "200x160",
        "--frames",
        "2",
        "--script",
        s(&script),
        "--offscreen",
    ]);
    let log = String::from_utf8_lossy(&o.stdout).into_owned();
    let second_at = log
        .find("series 4 \"second\" (24x20x5)")
        .unwrap_or_else(|| panic!("--series must open the second series first:\n{log}"));
    let main_at = log
        .find("series 3 \"T1 test\" (24x20x12)")
        .unwrap_or_else(|| panic!("`series 1` must open the main series:\n{log}"));
    assert!(second_at < main_at, "{log}");
    // An index the exam does not have is an error in the status line; the volume stays.
    assert!(log.contains("has no series 9"), "{log}");
    assert_eq!(log.matches("loaded ").count(), 2, "{log}");
}
