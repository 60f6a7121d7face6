//! The `epi` preset on a 4-D series (issue 28): a BOLD series is shown as the mean of its
//! frames, with one line saying so; `--frame N` still shows one frame; a 4-D file whose preset
//! is not `epi` keeps frame 0. `peaks` and `render` need a Vulkan device (lavapipe here).
//!
//! The series is written here: 24x20x16 voxels, 5 frames, int16; a tissue box of 200 with a
//! bright blob of 1000 that moves one step a frame, so the mean's brightest voxel is
//! (1000 + 4 * 200) / 5 = 360 while each frame's is 1000.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const DIMS: [usize; 4] = [24, 20, 16, 5];

fn morphray(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_morphray"))
        .args(args)
        .env("MORPHRAY_VALIDATION", "required")
        .output()
        .expect("the morphray binary runs")
}

fn ok(args: &[&str]) -> String {
    let o = morphray(args);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Voxel value of frame `t` at (x, y, z) (module doc).
fn value(t: usize, [x, y, z]: [usize; 3]) -> i16 {
    let inside = (4..20).contains(&x) && (4..16).contains(&y) && (3..13).contains(&z);
    let blob = (6 + 2 * t..8 + 2 * t).contains(&x) && (8..10).contains(&y) && (7..9).contains(&z);
    match (inside, blob) {
        (true, true) => 1000,
        (true, false) => 200,
        _ => 0,
    }
}

/// A NIfTI-1 single file (348-byte header, 4 extension bytes, int16 voxels, 1 mm).
fn write_series(path: &Path) {
    let mut h = vec![0u8; 352];
    let put_i16 =
        |h: &mut Vec<u8>, at: usize, v: i16| h[at..at + 2].copy_from_slice(&v.to_le_bytes());
    let put_f32 =
        |h: &mut Vec<u8>, at: usize, v: f32| h[at..at + 4].copy_from_slice(&v.to_le_bytes());
    h[0..4].copy_from_slice(&348i32.to_le_bytes());
    let dim = [4, DIMS[0], DIMS[1], DIMS[2], DIMS[3], 1, 1, 1];
    for (i, d) in dim.iter().enumerate() {
        put_i16(&mut h, 40 + 2 * i, *d as i16);
    }
    put_i16(&mut h, 70, 4); // datatype int16
    put_i16(&mut h, 72, 16); // bitpix
    for i in 0..5 {
        put_f32(&mut h, 76 + 4 * i, 1.0); // pixdim[0..4]
    }
    put_f32(&mut h, 108, 352.0); // vox_offset
    put_f32(&mut h, 112, 1.0); // scl_slope
    h[123] = 2 | 8; // xyzt_units: mm, s
    h[344..348].copy_from_slice(b"n+1\0");
    let [nx, ny, nz, nt] = DIMS;
    for t in 0..nt {
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    h.extend_from_slice(&value(t, [x, y, z]).to_le_bytes());
                }
            }
        }
    }
    std::fs::write(path, h).unwrap();
}

fn series(name: &str) -> (PathBuf, PathBuf) {
    let dir = std::env::temp_dir().join(format!("morphray-epi-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let nii = dir.join(name);
    write_series(&nii);
    (dir, nii)
}

fn peaks(args: &[&str]) -> serde_json::Value {
    serde_json::from_str(&ok(args)).unwrap()
}

#[test]
fn a_bold_series_is_shown_as_its_mean_frame_and_says_so() {
    let (dir, nii) = series("sub-01_task-rest_bold.nii");
    let mean = peaks(&["peaks", s(&nii), "--json"]);
    assert_eq!(mean["preset"], "epi", "{mean}");
    // The mean of the frames, not frame 0: the blob's 1000 is averaged over five positions.
    let imax = mean["imax"].as_f64().unwrap();
    assert!((imax - 360.0).abs() < 1e-3, "mean's maximum {imax}");
    let frame0 = peaks(&["peaks", s(&nii), "--json", "--frame", "0"]);
    assert_eq!(frame0["imax"].as_f64(), Some(1000.0), "{frame0}");
    let text = ok(&["peaks", s(&nii)]);
    assert!(text.contains("epi: mean of 5 frames"), "{text}");
    let png = dir.join("epi.png");
    let out = ok(&["render", s(&nii), "-o", s(&png), "--size", "64x64"]);
    let lines: Vec<&str> = out.lines().filter(|l| l.contains("mean of 5")).collect();
    assert_eq!(
        lines,
        ["epi: mean of 5 frames (`--frame N` shows one frame)"],
        "{out}"
    );
    let provenance = String::from_utf8_lossy(&std::fs::read(&png).unwrap()).into_owned();
    assert!(
        provenance.contains("\"frame_of_4d_file\":\"mean of 5 frames\""),
        "no mean in the provenance"
    );
    // One frame by hand: no mean line.
    let out = ok(&[
        "render",
        s(&nii),
        "-o",
        s(&png),
        "--size",
        "64x64",
        "--frame",
        "2",
    ]);
    assert!(!out.contains("mean of"), "{out}");
}

#[test]
fn a_4d_file_whose_preset_is_not_epi_keeps_frame_0_unless_epi_is_named() {
    let (_dir, nii) = series("sub-01_T1w.nii");
    let plain = peaks(&["peaks", s(&nii), "--json"]);
    assert_eq!(plain["preset"], "mr", "{plain}");
    assert_eq!(plain["imax"].as_f64(), Some(1000.0), "{plain}");
    let named = peaks(&["peaks", s(&nii), "--json", "--preset", "epi"]);
    let imax = named["imax"].as_f64().unwrap();
    assert!((imax - 360.0).abs() < 1e-3, "mean's maximum {imax}");
}
