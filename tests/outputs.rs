//! What the program writes, as a user runs it (issue 12): outputs are atomic, checked before any
//! GPU work, never written over the input or over an existing scan without --force; the input's
//! warnings reach stderr, --json and the PNG provenance; NaN/inf numbers are usage errors.
//!
//! "Before any GPU work" is shown with `--device no-such-gpu`: a check that ran after opening
//! the device would fail with the device's message instead. Failing writes are real: a child
//! shell lowers the file-size limit (`ulimit -f`, with SIGXFSZ ignored) so the write fails
//! halfway with EFBIG, as a full disk fails it with ENOSPC.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_morphray");

fn morphray(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .env("MORPHRAY_VALIDATION", "required")
        .output()
        .expect("the morphray binary runs")
}

/// A fresh directory for one test.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("morphray-outputs-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn s(path: &Path) -> &str {
    path.to_str().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A 16^3 phantom written by the binary itself.
fn phantom(path: &Path) {
    let o = morphray(&["phantom", "--dims", "16x16x16", "-o", s(path)]);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// Exit status 1, one `morphray:` line that contains `needle`.
fn assert_refused(o: &Output, needle: &str) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert_eq!(
        err.trim_end().lines().count(),
        1,
        "one line expected: {err}"
    );
    assert!(err.starts_with("morphray: "), "{err}");
    assert!(err.contains(needle), "`{needle}` not in: {err}");
}

/// Names in `dir`, sorted (to see that no temporary file was left behind).
fn names(dir: &Path) -> Vec<String> {
    let mut all: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    all.sort();
    all
}

#[test]
fn render_onto_its_own_input_is_refused_and_the_input_is_untouched() {
    let dir = scratch("own-input");
    let scan = dir.join("scan.nii.gz");
    phantom(&scan);
    let before = std::fs::read(&scan).unwrap();
    std::fs::create_dir_all(dir.join("x")).unwrap();
    let dotted = dir.join("x").join("..").join("scan.nii.gz");
    // A hard link named like an image: the same file, whatever its name.
    let linked = dir.join("scan.png");
    std::fs::hard_link(&scan, &linked).unwrap();
    for output in [&scan, &dotted, &linked] {
        let o = morphray(&[
            "--device",
            "no-such-gpu",
            "render",
            s(&scan),
            "-o",
            s(output),
        ]);
        assert_refused(&o, "it is the input");
    }
    assert_eq!(std::fs::read(&scan).unwrap(), before);
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn phantom_replaces_an_existing_volume_only_with_force() {
    let dir = scratch("force");
    let scan = dir.join("scan.nii");
    phantom(&scan);
    let before = std::fs::read(&scan).unwrap();
    let o = morphray(&["phantom", "--dims", "20x20x20", "-o", s(&scan)]);
    assert_refused(&o, "--force");
    assert_eq!(std::fs::read(&scan).unwrap(), before);
    let o = morphray(&["phantom", "--dims", "20x20x20", "-o", s(&scan), "--force"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_ne!(std::fs::read(&scan).unwrap(), before);
    assert_eq!(names(&dir), ["scan.nii"]);
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn wrong_extensions_are_refused_before_any_gpu_work() {
    let dir = scratch("ext");
    let scan = dir.join("scan.nii");
    phantom(&scan);
    let out = |name: &str| dir.join(name).to_str().unwrap().to_string();
    let cases: [(Vec<String>, &str); 5] = [
        (
            vec!["render".into(), s(&scan).into(), "-o".into(), out("a.jpg")],
            "a.png",
        ),
        (
            vec!["phantom".into(), "-o".into(), out("p.img")],
            "p.nii.gz",
        ),
        (
            vec![
                "bench".into(),
                s(&scan).into(),
                "--json".into(),
                out("b.txt"),
            ],
            "b.json",
        ),
        (
            vec![
                "accuracy".into(),
                s(&scan).into(),
                "--plot".into(),
                out("c.png"),
            ],
            "c.svg",
        ),
        (
            vec![
                "view".into(),
                s(&scan).into(),
                "--offscreen".into(),
                "--frames".into(),
                "1".into(),
                "--screenshot".into(),
                out("v.jpg"),
            ],
            "v.png",
        ),
    ];
    for (args, suggestion) in cases {
        let mut all = vec!["--device", "no-such-gpu"];
        all.extend(args.iter().map(String::as_str));
        assert_refused(&morphray(&all), suggestion);
    }
    assert_eq!(names(&dir), ["scan.nii"]);
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn unusable_output_places_are_refused_before_any_gpu_work() {
    let dir = scratch("places");
    let scan = dir.join("scan.nii");
    phantom(&scan);
    std::fs::create_dir_all(dir.join("shot.png")).unwrap();
    // Turntable frames are all checked up front: the second frame's name is taken by a directory.
    std::fs::create_dir_all(dir.join("orbit-001.png")).unwrap();
    let missing = dir.join("missing").join("a.png");
    let directory = dir.join("shot.png");
    let orbit = dir.join("orbit.png");
    // Tests run as root, for whom read-only permission bits do not stop a write: /proc is a
    // directory where even root cannot create a file, so it stands in for a read-only one.
    for (output, needle, turntable) in [
        (s(&missing), "does not exist", false),
        (s(&directory), "it is a directory", false),
        ("/proc/a.png", "no file can be created in /proc", false),
        ("/dev/full", "not a regular file", false),
        (s(&orbit), "orbit-001.png: it is a directory", true),
    ] {
        let mut args = vec!["--device", "no-such-gpu", "render", s(&scan), "-o", output];
        if turntable {
            args.extend(["--turntable", "3"]);
        }
        assert_refused(&morphray(&args), needle);
    }
    let _ = std::fs::remove_dir_all(dir);
}

/// Runs morphray in a shell whose file-size limit is 2 blocks (1 or 2 KiB, by shell: less than
/// a 32x32 PNG with its provenance, or a 16^3 volume), with SIGXFSZ ignored, so writes past it
/// fail with EFBIG instead of killing the process.
fn morphray_with_small_file_limit(args: &[&str]) -> Output {
    let quoted: Vec<String> = args.iter().map(|a| format!("'{a}'")).collect();
    let script = format!(
        "trap '' XFSZ; ulimit -f 2 || exit 99; exec '{BIN}' {}",
        quoted.join(" ")
    );
    Command::new("sh")
        .args(["-c", &script])
        .output()
        .expect("sh runs")
}

#[test]
fn a_write_that_fails_halfway_leaves_the_previous_file_whole() {
    let dir = scratch("halfway");
    let scan = dir.join("scan.nii");
    phantom(&scan);
    // The previous image: any content must survive (a plain file, written without the limit).
    let image = dir.join("image.png");
    std::fs::write(&image, b"the previous, complete image").unwrap();
    let o = morphray_with_small_file_limit(&[
        "--pipeline-cache",
        "off",
        "render",
        s(&scan),
        "-o",
        s(&image),
        "--size",
        "32x32",
        "--mode",
        "mip",
    ]);
    assert_refused(&o, "image.png: the file is larger than");
    assert_eq!(
        std::fs::read(&image).unwrap(),
        b"the previous, complete image"
    );
    // The same for a NIfTI replaced with --force: 8 KiB of voxels do not fit under the limit.
    let before = std::fs::read(&scan).unwrap();
    let o = morphray_with_small_file_limit(&[
        "phantom",
        "--dims",
        "16x16x16",
        "-o",
        s(&scan),
        "--force",
    ]);
    assert_refused(&o, "any previous file of that name is unchanged");
    assert_eq!(std::fs::read(&scan).unwrap(), before);
    assert_eq!(
        names(&dir),
        ["image.png", "scan.nii"],
        "no temporary file left"
    );
    let _ = std::fs::remove_dir_all(dir);
}

/// A 16^3 phantom whose pixdim[1] is 0: the loader repairs it (1 mm) and says so.
fn repaired_file(dir: &Path) -> PathBuf {
    let path = dir.join("repaired.nii");
    phantom(&path);
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[80..84].copy_from_slice(&0.0f32.to_le_bytes());
    std::fs::write(&path, bytes).unwrap();
    path
}

const REPAIR: &str = "pixdim[1] (voxel size along i) is 0";

#[test]
fn loader_warnings_reach_stderr_json_and_the_png_provenance() {
    let dir = scratch("warnings");
    let input = repaired_file(&dir);
    let image = dir.join("r.png");
    let o = morphray(&["render", s(&input), "-o", s(&image), "--size", "8x8"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains(&format!("morphray: warning: {REPAIR}")),
        "{}",
        stderr(&o)
    );
    let chunks = morphray::files::png::read_text_chunks(&image).unwrap();
    let warnings = chunks
        .iter()
        .find(|(k, _)| k == "morphray:warnings")
        .map(|(_, v)| v.clone())
        .expect("a morphray:warnings chunk");
    let list: Vec<String> = serde_json::from_str(&warnings).unwrap();
    assert!(list.iter().any(|w| w.contains(REPAIR)), "{list:?}");
    for command in [vec!["peaks"], vec!["plan", "--size", "8x8"]] {
        let mut args = command.clone();
        args.extend([s(&input), "--json"]);
        let o = morphray(&args);
        assert!(o.status.success(), "{command:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(REPAIR), "{command:?}: {}", stderr(&o));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let listed = v["warnings"].as_array().expect("a warnings list");
        assert!(
            listed.iter().any(|w| w.as_str().unwrap().contains(REPAIR)),
            "{command:?}: {listed:?}"
        );
    }
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn derive_prints_the_loaders_warnings_too() {
    let dir = scratch("derive-warnings");
    let input = repaired_file(&dir);
    let out = dir.join("maps");
    let o = morphray(&["derive", s(&input), "-o", s(&out), "--maps", "normalized"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains(&format!("morphray: warning: {REPAIR}")),
        "{}",
        stderr(&o)
    );
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn render_without_o_writes_the_inputs_name_and_replaces_it_only_with_force() {
    let dir = scratch("default-output");
    let input = dir.join("sub-01_T1w.nii.gz");
    phantom(&input);
    let run = |extra: &[&str]| {
        let mut args = vec!["render", s(&input), "--size", "8x8", "--mode", "mip"];
        args.extend(extra);
        Command::new(BIN)
            .args(&args)
            .current_dir(&dir)
            .env("MORPHRAY_VALIDATION", "required")
            .output()
            .expect("the morphray binary runs")
    };
    let o = run(&[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let png = dir.join("sub-01_T1w.png");
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("wrote sub-01_T1w.png"),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    let first = std::fs::metadata(&png).unwrap().modified().unwrap();
    // Again: the default name exists, so it is refused in one line naming --force.
    let o = run(&[]);
    assert_refused(&o, "sub-01_T1w.png exists");
    assert!(stderr(&o).contains("--force"), "{}", stderr(&o));
    assert_eq!(std::fs::metadata(&png).unwrap().modified().unwrap(), first);
    std::thread::sleep(std::time::Duration::from_millis(20));
    let o = run(&["--force"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::metadata(&png).unwrap().modified().unwrap() > first);
    // Without an input the phantom's picture is phantom.png.
    let o = Command::new(BIN)
        .args(["render", "--size", "8x8", "--mode", "mip"])
        .current_dir(&dir)
        .env("MORPHRAY_VALIDATION", "required")
        .output()
        .expect("the morphray binary runs");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(dir.join("phantom.png").exists());
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_clean_file_has_an_empty_warnings_chunk_and_list() {
    let dir = scratch("clean");
    let input = dir.join("clean.nii");
    phantom(&input);
    let image = dir.join("c.png");
    let o = morphray(&[
        "render",
        s(&input),
        "-o",
        s(&image),
        "--size",
        "8x8",
        "--mode",
        "mip",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("warning"), "{}", stderr(&o));
    let chunks = morphray::files::png::read_text_chunks(&image).unwrap();
    assert!(chunks.contains(&("morphray:warnings".into(), "[]".into())));
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn tissue_notes_are_printed_for_dvr_only() {
    let dir = scratch("notes");
    let input = dir.join("small.nii");
    phantom(&input);
    let image = dir.join("n.png");
    let render = |mode: &str| {
        let o = morphray(&[
            "render",
            s(&input),
            "-o",
            s(&image),
            "--size",
            "8x8",
            "--mode",
            mode,
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        stderr(&o)
    };
    // The 16^3 phantom has no distinct GM peak: DVR cannot show GM and says so.
    assert!(render("dvr").contains("peak was found"), "premise");
    for mode in ["mip", "minip"] {
        let err = render(mode);
        assert!(!err.contains("peak was found"), "{mode}: {err}");
    }
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn nan_and_infinite_numbers_are_usage_errors_naming_the_flag() {
    let dir = scratch("numbers");
    let out = dir.join("x.png");
    for (flag, value) in [
        ("--azimuth", "NaN"),
        ("--elevation", "inf"),
        ("--zoom", "-inf"),
        ("--zoom", "infinity"),
        ("--step", "nan"),
    ] {
        let o = morphray(&["render", "-o", s(&out), &format!("{flag}={value}")]);
        assert_eq!(o.status.code(), Some(2), "{flag} {value}: {}", stderr(&o));
        assert!(stderr(&o).contains(flag), "{}", stderr(&o));
    }
    // Nor can a turntable ask for billions of file names to be made and checked.
    for frames in ["0", "10001", "4000000000"] {
        let o = morphray(&["render", "-o", s(&out), "--turntable", frames]);
        assert_eq!(o.status.code(), Some(2), "{frames}: {}", stderr(&o));
    }
    assert!(names(&dir).is_empty());
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn the_viewer_shows_warnings_and_keeps_them_in_its_screenshot() {
    let dir = scratch("viewer");
    let input = repaired_file(&dir);
    let shot = dir.join("shot.png");
    let o = morphray(&[
        "view",
        s(&input),
        "--offscreen",
        "--frames",
        "1",
        "--size",
        "64x48",
        "--screenshot",
        s(&shot),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("morphray: warning: repaired.nii: pixdim[1]"),
        "{}",
        stderr(&o)
    );
    let chunks = morphray::files::png::read_text_chunks(&shot).unwrap();
    assert!(
        chunks
            .iter()
            .any(|(k, v)| k == "morphray:warnings" && v.contains(REPAIR)),
        "{chunks:?}"
    );
    let _ = std::fs::remove_dir_all(dir);
}
