//! `morphray derive FILE -o DIR` as a user runs it (issue 15 item 5): one NIfTI per map with the
//! input's affine, maps in their units and ranges, and nothing ever overwritten without --force
//! (the input never). Uses the built binary with the validation layer required.

mod common;

use common::volumes::{Rng, smooth_field, volume_with_affine};
use morphray::volume::Samples;
use morphray::volume::nifti::write_nifti1;
use morphray::volume::source::{ReadOptions, VolumeSource, read};
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
    let dir = std::env::temp_dir().join(format!("morphray-derive-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn load(path: &Path) -> morphray::volume::Volume {
    read(
        &VolumeSource::File(path.to_path_buf()),
        &ReadOptions::default(),
    )
    .unwrap()
    .volume
}

/// An oblique, anisotropic 19 x 15 x 11 input with a bright tube.
fn input(dir: &Path) -> PathBuf {
    let dims = [19usize, 15, 11];
    let mut rng = Rng(3);
    let field = smooth_field(dims, &mut rng, 0.0, 200.0);
    let values: Vec<i16> = field
        .iter()
        .enumerate()
        .map(|(i, f)| {
            let (y, z) = ((i / 19) % 15, i / (19 * 15));
            let tube = if (y as i64 - 7).abs() <= 1 && (z as i64 - 5).abs() <= 1 {
                800.0
            } else {
                0.0
            };
            (f + tube) as i16
        })
        .collect();
    let (c, s) = (20f64.to_radians().cos(), 20f64.to_radians().sin());
    let affine = [
        [0.9 * c, -1.1 * s, 0.0, -8.0],
        [0.9 * s, 1.1 * c, 0.0, 4.0],
        [0.0, 0.0, 1.7, -2.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let v = volume_with_affine(dims, affine, Samples::from_i16(&values));
    let path = dir.join("scan.nii.gz");
    write_nifti1(&v, &path, true).unwrap();
    path
}

#[test]
fn derive_writes_every_map_with_the_input_affine_and_never_overwrites() {
    let dir = folder("maps");
    let scan = input(&dir);
    let dir_s = dir.to_str().unwrap();
    let out = morphray(&[
        "derive",
        scan.to_str().unwrap(),
        "-o",
        dir_s,
        "--denoise",
        "median",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let source = load(&scan);
    for map in [
        "normalized",
        "gradient",
        "curvature",
        "vesselness",
        "denoised",
    ] {
        let path = dir.join(format!("scan_{map}.nii.gz"));
        let v = load(&path);
        assert_eq!(v.dims, source.dims, "{map}");
        for r in 0..3 {
            for c in 0..4 {
                let (a, b) = (v.orientation.affine[r][c], source.orientation.affine[r][c]);
                assert!((a - b).abs() < 1e-5, "{map}: affine[{r}][{c}] {a} vs {b}");
            }
        }
        let values = v.samples.to_f64_vec();
        assert!(values.iter().all(|x| x.is_finite()), "{map}");
        let (lo, hi) = values
            .iter()
            .fold((f64::MAX, f64::MIN), |(l, h), x| (l.min(*x), h.max(*x)));
        match map {
            "normalized" | "denoised" | "vesselness" => {
                assert!(lo >= 0.0 && hi <= 1.0, "{map}: {lo} .. {hi}")
            }
            "gradient" => assert!(lo >= 0.0 && hi > 0.0, "{map}: {lo} .. {hi}"),
            _ => assert!(lo < 0.0 && hi > 0.0, "{map}: {lo} .. {hi}"),
        }
        if map == "vesselness" {
            // The tube's centre responds more than the corner of the field.
            let centre = values[9 + 19 * (7 + 15 * 5)];
            assert!(centre > 0.2 && centre > values[0], "tube centre {centre}");
        }
    }
    // A second run refuses before doing anything and leaves the files as they were.
    let before = std::fs::read(dir.join("scan_gradient.nii.gz")).unwrap();
    let again = morphray(&[
        "derive",
        scan.to_str().unwrap(),
        "-o",
        dir_s,
        "--maps",
        "gradient",
    ]);
    assert_eq!(again.status.code(), Some(1));
    let err = String::from_utf8_lossy(&again.stderr);
    assert!(
        err.starts_with("morphray: ") && err.contains("scan_gradient.nii.gz"),
        "{err}"
    );
    assert_eq!(
        std::fs::read(dir.join("scan_gradient.nii.gz")).unwrap(),
        before
    );
    // --force replaces the maps, never the input.
    let forced = morphray(&[
        "derive",
        scan.to_str().unwrap(),
        "-o",
        dir_s,
        "--maps",
        "gradient",
        "--force",
    ]);
    assert!(
        forced.status.success(),
        "{}",
        String::from_utf8_lossy(&forced.stderr)
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn derive_refuses_bad_requests_in_one_line() {
    let dir = folder("bad");
    let scan = input(&dir);
    let dir_s = dir.to_str().unwrap();
    let scan_s = scan.to_str().unwrap();
    // A folder inside a file: no user can create it (a path at / can be made by root).
    let under_a_file = scan.join("out");
    let under_a_file = under_a_file.to_str().unwrap();
    for (args, needle) in [
        (
            vec!["derive", scan_s, "-o", dir_s, "--maps", "foo"],
            "unknown map",
        ),
        (
            vec!["derive", scan_s, "-o", dir_s, "--denoise", "gaussian:-1"],
            "positive",
        ),
        (vec!["derive", scan_s, "-o", under_a_file], "morphray:"),
        (
            vec!["derive", scan_s, "-o", dir_s, "--vessel-scales", "0"],
            "positive",
        ),
    ] {
        let out = morphray(&args);
        assert!(!out.status.success(), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
