//! Issue 30's non-DICOM cases, each through the command line as a user meets it: a float64
//! voxel at 1e300, an int32 minimum at -2^31 + 1, arguments out of range (`slice --mm`,
//! `--step`, `view --frames`, `wait`), outputs that would collide (`phantom --labels` onto
//! `-o`, a script's screenshot into a missing folder), and the messages of an image too large
//! for the budget, an unusable voxel spacing and a decimal `--memory-budget`. Volumes are the
//! built-in phantom at 32x32x24, re-encoded here.

mod common;

use morphray::volume::nifti::{LoadOptions, load_path};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

fn morphray(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_morphray"))
        .args(args)
        .output()
        .expect("the morphray binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn folder(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("morphray-hostile-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Writes the phantom as an uncompressed int16 NIfTI and returns (header bytes, int16 values).
fn phantom(dir: &Path) -> (PathBuf, Vec<u8>, Vec<i16>) {
    let path = dir.join("phantom.nii");
    let o = morphray(&["phantom", "-o", s(&path), "--dims", "32x32x24"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let bytes = std::fs::read(&path).unwrap();
    let offset = f32::from_le_bytes(bytes[108..112].try_into().unwrap()) as usize;
    let values = bytes[offset..]
        .chunks_exact(2)
        .map(|c| i16::from_le_bytes([c[0], c[1]]))
        .collect();
    (path, bytes[..offset].to_vec(), values)
}

/// The phantom's header with another datatype and these voxel bytes.
fn recoded(header: &[u8], datatype: i16, bitpix: i16, data: &[u8], path: &Path) {
    let mut bytes = header.to_vec();
    bytes[70..72].copy_from_slice(&datatype.to_le_bytes());
    bytes[72..74].copy_from_slice(&bitpix.to_le_bytes());
    // No scaling: the values are the physical ones.
    bytes[112..116].copy_from_slice(&0f32.to_le_bytes());
    bytes.extend_from_slice(data);
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn a_float64_voxel_at_1e300_converts_and_renders_the_phantom_with_what_changed_said() {
    let dir = folder("1e300");
    let (plain, header, values) = phantom(&dir);
    let mut data = Vec::new();
    for (i, &v) in values.iter().enumerate() {
        let x = if i == 0 { 1e300 } else { f64::from(v) };
        data.extend_from_slice(&x.to_le_bytes());
    }
    let hot = dir.join("hot.nii");
    recoded(&header, 64, 64, &data, &hot);

    // convert: every voxel but the hot one is written as it was; the warning says which changed.
    let out = dir.join("converted.nii.gz");
    let o = morphray(&["convert", s(&hot), "-o", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let said = stderr(&o);
    assert!(
        said.contains("1 of 24576 float64 voxels lie beyond"),
        "{said}"
    );
    assert!(said.contains("the largest 1e300"), "{said}");
    assert!(said.contains("convert writes them clamped"), "{said}");
    assert!(!said.contains("do not change"), "{said}");
    let v = load_path(&out, &LoadOptions::default()).unwrap().volume;
    let physical = |i: usize| v.to_physical.apply(v.samples.get(i));
    assert_eq!(physical(0), f64::from(1e36f32));
    let differing = (1..values.len())
        .filter(|&i| physical(i) != f64::from(values[i]))
        .count();
    assert_eq!(differing, 0, "voxels other than the hot one changed");
    assert!(values.iter().filter(|&&v| v > 0).count() > 1000);

    // render: the clamped voxel is a hot voxel for the robust range, as one at 30000 is (before:
    // a blank picture). One hot voxel moves the robust range a little (I_norm of the largest
    // mode 0.403 instead of 0.408 on a 48x48x40 phantom), so the picture is compared with that
    // of the same hot voxel at 30000, and with the clean phantom only for being drawn.
    let mut warm = Vec::new();
    for (i, &v) in values.iter().enumerate() {
        let x = if i == 0 { 30000.0 } else { f64::from(v) };
        warm.extend_from_slice(&x.to_le_bytes());
    }
    let warm_path = dir.join("warm.nii");
    recoded(&header, 64, 64, &warm, &warm_path);
    let render = |input: &Path, name: &str| {
        let png = dir.join(name);
        let o = morphray(&["render", s(input), "-o", s(&png), "--size", "64x64"]);
        assert!(o.status.success(), "{}", stderr(&o));
        common::pictures::Picture::read(&png)
    };
    let lit = |p: &common::pictures::Picture| p.find(None, |c| c.iter().any(|&x| x > 40)).len();
    let clean = lit(&render(&plain, "plain.png")) as f64;
    let warm = lit(&render(&warm_path, "warm.png")) as f64;
    let hot = lit(&render(&hot, "hot.png")) as f64;
    assert!(clean > 500.0, "the clean phantom is drawn: {clean}");
    assert!(
        hot > 0.25 * clean,
        "the phantom is drawn: {hot} lit pixels, {clean} clean"
    );
    assert!(
        (hot - warm).abs() <= 0.02 * warm,
        "lit pixels {hot} against {warm}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn info_reports_an_int32_minimum_that_is_in_the_data() {
    let dir = folder("int32");
    let (_, header, values) = phantom(&dir);
    let mut data = Vec::new();
    for (i, &v) in values.iter().enumerate() {
        let x = if i == 5 { -2147483647 } else { i32::from(v) };
        data.extend_from_slice(&x.to_le_bytes());
    }
    let path = dir.join("wide.nii");
    recoded(&header, 8, 32, &data, &path);
    let o = morphray(&["info", s(&path)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    let max = values.iter().max().unwrap();
    // Before: -2147483645 .. 1539, neither in the data.
    assert!(
        text.contains(&format!("intensity     -2147483647 .. {max} ")),
        "{text}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn phantom_labels_onto_the_output_are_refused_before_anything_is_written() {
    let dir = folder("labels");
    let out = dir.join("p.nii.gz");
    for extra in [&[][..], &["--force"][..]] {
        let same = format!("{}/./p.nii.gz", s(&dir));
        let mut args = vec![
            "phantom",
            "-o",
            s(&out),
            "--dims",
            "16x16x16",
            "--labels",
            &same,
        ];
        args.extend_from_slice(extra);
        let o = morphray(&args);
        assert!(!o.status.success());
        let said = stderr(&o);
        assert!(said.contains("names the same file as --output"), "{said}");
        assert!(said.contains("p_labels.nii.gz"), "{said}");
        assert!(!out.exists(), "nothing is written");
        assert!(!String::from_utf8_lossy(&o.stdout).contains("wrote"));
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn slice_mm_outside_the_volume_is_refused_with_its_extent() {
    let dir = folder("slice");
    let (plain, _, _) = phantom(&dir);
    let png = dir.join("s.png");
    let o = morphray(&[
        "slice",
        s(&plain),
        "--plane",
        "axial",
        "--mm",
        "500",
        "-o",
        s(&png),
    ]);
    assert!(!o.status.success());
    let said = stderr(&o);
    assert!(said.contains("--mm 500 is outside the volume"), "{said}");
    assert!(said.contains("(z) it spans -12.000 to 12.000 mm"), "{said}");
    assert!(!png.exists(), "no black picture");
    let o = morphray(&[
        "slice",
        s(&plain),
        "--plane",
        "axial",
        "--mm",
        "3",
        "-o",
        s(&png),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn steps_frames_and_waits_out_of_range_are_refused_at_once() {
    let dir = folder("bounds");
    let png = dir.join("r.png");
    let start = Instant::now();
    let o = morphray(&["render", "--step", "1e-9", "-o", s(&png), "--size", "32x32"]);
    assert!(!o.status.success());
    let said = stderr(&o);
    assert!(said.contains("is finer than 0.015625 voxel"), "{said}");
    assert!(
        start.elapsed() < Duration::from_secs(20),
        "refused before the work"
    );
    assert!(!png.exists());

    let o = morphray(&["view", "--offscreen", "--frames", "4000000000"]);
    let said = stderr(&o);
    assert!(
        !o.status.success() && said.contains("give 1 to 10000 frames"),
        "{said}"
    );
    let script = dir.join("s.txt");
    for (line, expected) in [
        (
            "wait 99999999",
            "expected a whole number of frames, 0..10000",
        ),
        ("idle 10001", "expected a whole number of frames, 0..10000"),
        ("step 1e-9", "step 0.000000001 is finer than 0.015625 voxel"),
    ] {
        std::fs::write(&script, line).unwrap();
        let o = morphray(&["view", "--offscreen", "--script", s(&script)]);
        let said = stderr(&o);
        assert!(
            !o.status.success() && said.contains(expected),
            "{line}: {said}"
        );
    }
    // A screenshot into a folder that does not exist fails before the window opens (before:
    // the run ended 0 and the failure was only in the status bar).
    let missing = dir.join("missing/shot.png");
    std::fs::write(&script, format!("screenshot {}\n", s(&missing))).unwrap();
    let o = morphray(&["view", "--offscreen", "--script", s(&script)]);
    let said = stderr(&o);
    assert!(!o.status.success(), "{said}");
    assert!(said.contains("s.txt:1: `screenshot"), "{said}");
    assert!(said.contains("does not exist"), "{said}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn messages_say_the_cause_and_the_fix() {
    let dir = folder("messages");
    let (plain, header, values) = phantom(&dir);
    let png = dir.join("r.png");

    // An image too large for the budget: the image is named, with the size that fits.
    let o = morphray(&[
        "render",
        s(&plain),
        "-o",
        s(&png),
        "--size",
        "4096x4096",
        "--memory-budget",
        "64M",
    ]);
    let said = stderr(&o);
    assert!(!o.status.success(), "{said}");
    assert!(
        said.contains("the 4096x4096 image is too large, not the volume"),
        "{said}"
    );
    assert!(
        said.contains("the largest image of that shape that fits is"),
        "{said}"
    );
    assert!(!said.contains("bricked"), "{said}");

    // pixdim 1e-30: the spacing is named unusable, with the fix; no "invalid GPU request".
    let mut tiny = header.clone();
    for axis in 1..4 {
        let at = 76 + 4 * axis;
        tiny[at..at + 4].copy_from_slice(&1e-30f32.to_le_bytes());
    }
    tiny[252..256].copy_from_slice(&[0; 4]); // qform_code, sform_code: pixdim alone
    let data: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    let tiny_path = dir.join("tiny.nii");
    recoded(&tiny, 4, 16, &data, &tiny_path);
    for mode in ["dvr", "mip"] {
        let o = morphray(&["render", s(&tiny_path), "-o", s(&png), "--mode", mode]);
        let said = stderr(&o);
        assert!(!o.status.success(), "{said}");
        assert!(said.contains("voxel spacing (1"), "{said}");
        assert!(said.contains("is unusable"), "{said}");
        assert!(said.contains("set the header's pixdim"), "{said}");
        assert!(!said.contains("invalid GPU request"), "{said}");
    }

    // Decimal budgets are sizes; a wrong unit says the accepted form.
    let o = morphray(&["info", s(&plain), "--memory-budget", "1.5G"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = morphray(&["info", s(&plain), "--memory-budget", "1.5T"]);
    let said = stderr(&o);
    assert!(!o.status.success() && said.contains("512M, 1.5G"), "{said}");

    // A pipeline cache path that is a file: one note, never "File exists (os error 17)".
    let file = dir.join("cache");
    std::fs::write(&file, b"x").unwrap();
    let o = morphray(&[
        "render",
        s(&plain),
        "-o",
        s(&png),
        "--size",
        "32x32",
        "--pipeline-cache",
        s(&file),
    ]);
    let said = stderr(&o);
    assert!(o.status.success(), "{said}");
    assert!(said.contains("is a file, not a folder"), "{said}");
    assert!(
        said.contains("pass --pipeline-cache with a writable folder"),
        "{said}"
    );
    assert!(!said.contains("os error 17"), "{said}");
    std::fs::remove_dir_all(&dir).unwrap();
}
