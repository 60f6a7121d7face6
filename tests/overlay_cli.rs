//! `morphray render --overlay` (issue 16 item 3): the phantom's lesion label drawn in 3D on the
//! side where the lesion is, a bricked volume refused with a way out, a bad opacity refused.
//! Runs the binary on lavapipe (or any Vulkan device) with the validation layer required.

mod common;

use common::pictures::{Picture, dominant};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "morphray-overlay-cli-{}-{name}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn morphray(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_morphray"))
        .args(args)
        .env("MORPHRAY_VALIDATION", "required")
        .env("MORPHRAY_PROGRESS", "never")
        .output()
        .expect("morphray runs")
}

fn phantom(dir: &Path) -> (PathBuf, PathBuf, PathBuf) {
    let (volume, labels) = (dir.join("ph.nii.gz"), dir.join("labels.nii.gz"));
    let o = morphray(&[
        "phantom",
        "-o",
        volume.to_str().unwrap(),
        "--dims",
        "64x72x56",
        "--labels",
        labels.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The lesion (5) alone, green; every other label transparent.
    let lut = dir.join("lut.txt");
    std::fs::write(&lut, "1 a 0 0 0 255\n2 b 0 0 0 255\n3 c 0 0 0 255\n4 d 0 0 0 255\n5 Lesion 0 255 0 0\n6 v 0 0 0 255\n7 e 0 0 0 255\n").unwrap();
    (volume, labels, lut)
}

#[test]
fn the_lesion_label_is_drawn_in_3d_on_the_lesions_side_and_bricking_is_refused() {
    let dir = temp_dir("render");
    let (volume, labels, lut) = phantom(&dir);
    let out = dir.join("overlay.png");
    let common = [
        volume.to_str().unwrap(),
        "--size",
        "96x96",
        "--overlay",
        labels.to_str().unwrap(),
        "--overlay-lut",
        lut.to_str().unwrap(),
        "--overlay-opacity",
        "1",
        // Faint tissue, so the lesion inside the white matter shows through.
        "--opacity",
        "csf=0.02",
        "--opacity",
        "gm=0.02",
        "--opacity",
        "wm=0.02",
    ];
    let o = morphray(&[&["render", "-o", out.to_str().unwrap()], &common[..]].concat());
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(stdout.contains("overlay: 7 labels drawn in 3D"), "{stdout}");
    // Anterior view: the patient faces the viewer, so the left-hemisphere lesion is drawn on
    // the image's right. Green pixels are the label's (no tissue colour is green).
    let picture = Picture::read(&out);
    let green = picture.find(None, dominant(1));
    assert!(
        green.len() > 5,
        "the lesion label is drawn ({} px)",
        green.len()
    );
    let mean_x = green.iter().map(|&(x, _)| x as f64).sum::<f64>() / green.len() as f64;
    let width = picture.width as f64;
    assert!(
        mean_x > width / 2.0,
        "on the image's right: mean x {mean_x:.1} of {width}"
    );
    // Without the overlay: no green at all.
    let plain = dir.join("plain.png");
    let o = morphray(&[
        "render",
        volume.to_str().unwrap(),
        "--size",
        "96x96",
        "-o",
        plain.to_str().unwrap(),
    ]);
    assert!(o.status.success());
    assert!(Picture::read(&plain).find(None, dominant(1)).is_empty());
    // Bricked: refused with the way out; nothing written.
    let bricked = dir.join("bricked.png");
    let o = morphray(
        &[
            &["render", "--bricked", "-o", bricked.to_str().unwrap()],
            &common[..],
        ]
        .concat(),
    );
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{stderr}");
    assert!(
        stderr.contains("--overlay") && stderr.contains("drop --bricked"),
        "{stderr}"
    );
    assert!(!bricked.exists());
    // An opacity that is none.
    let o = morphray(
        &[
            &["render", "-o", bricked.to_str().unwrap()],
            &common[..7],
            &["--overlay-opacity", "1.5"],
        ]
        .concat(),
    );
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--overlay-opacity 1.5"));
}

#[test]
fn an_overlay_that_does_not_fit_the_memory_budget_is_refused_with_the_numbers() {
    let dir = temp_dir("budget");
    let (volume, labels, lut) = phantom(&dir);
    // The plan's own peak for this render, then a budget 1000 bytes above it: the scene fits,
    // the labels' 2 bytes a voxel (2 x 64 x 72 x 56) do not.
    let scene = ["--size", "96x96", "--shading", "on"];
    let o = morphray(&[&["plan", volume.to_str().unwrap(), "--json"], &scene[..]].concat());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let plan: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let peak = plan["peak_bytes"].as_u64().unwrap();
    let budget = (peak + 1000).to_string();
    let out = dir.join("x.png");
    let o = morphray(
        &[
            &[
                "render",
                volume.to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
            ],
            &scene[..],
            &[
                "--memory-budget",
                &budget,
                "--overlay",
                labels.to_str().unwrap(),
            ],
            &["--overlay-lut", lut.to_str().unwrap()],
        ]
        .concat(),
    );
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{stderr}");
    assert!(
        stderr.contains("--overlay needs 0.5 MiB") && stderr.contains("raise --memory-budget"),
        "{stderr}"
    );
    assert!(!out.exists());
}
