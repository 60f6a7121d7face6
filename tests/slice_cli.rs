//! `morphray slice` as a user runs it: a bright blob in the LEFT, ANTERIOR, SUPERIOR part of a
//! tiny synthetic head (written by the test, stored RAS and again stored flipped LPS-style with
//! the same world content) must appear on the correct side of the picture in every plane and
//! both conventions; `--index` and `--mm` give the same pixels; the convention is printed; the
//! input is never overwritten; letters land on their edges. Runs the built binary with the
//! validation layer required.

use morphray::volume::nifti::write_nifti1;
use morphray::volume::{LinearMap, Samples, Volume};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn morphray(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_morphray"))
        .args(args)
        .env("MORPHRAY_VALIDATION", "required")
        .output()
        .expect("the morphray binary runs")
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("morphray-slice-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

const DIMS: [usize; 3] = [21, 17, 15];
const SPACING: [f64; 3] = [1.0, 1.2, 1.5];
/// The blob's world centre: left (x < 0), anterior (y > 0), superior (z > 0).
const BLOB: [f64; 3] = [-5.0, 4.8, 4.5];

/// The head stored with i along +x, j along +y (RAS) or with both flipped (LPS-like, as DICOM
/// converters often leave it); the world content is the same.
fn head(flipped: bool, path: &Path) {
    let sign = if flipped { -1.0 } else { 1.0 };
    let half = |a: usize| (DIMS[a] as f64 - 1.0) / 2.0 * SPACING[a];
    let affine = [
        [sign * SPACING[0], 0.0, 0.0, -sign * half(0)],
        [0.0, sign * SPACING[1], 0.0, -sign * half(1)],
        [0.0, 0.0, SPACING[2], -half(2)],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let mut voxels = Vec::new();
    for k in 0..DIMS[2] {
        for j in 0..DIMS[1] {
            for i in 0..DIMS[0] {
                let idx = [i as f64, j as f64, k as f64];
                let world: Vec<f64> = (0..3)
                    .map(|r| (0..3).map(|c| affine[r][c] * idx[c]).sum::<f64>() + affine[r][3])
                    .collect();
                let d2: f64 = (0..3).map(|a| (world[a] - BLOB[a]).powi(2)).sum();
                voxels.push(if d2 < 3.2 * 3.2 {
                    1000
                } else {
                    100 + (i + j + k) as u16 % 3
                });
            }
        }
    }
    let v = Volume::from_voxels(
        "head",
        DIMS,
        Samples::from_u16(&voxels),
        affine,
        LinearMap::IDENTITY,
    )
    .unwrap();
    write_nifti1(&v, path, false).unwrap();
}

/// Pixels (RGBA8), width and height of a PNG.
fn pixels(path: &Path) -> (Vec<u8>, u32, u32) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    buf.truncate(info.buffer_size());
    (buf, info.width, info.height)
}

/// Centroid of the bright (blob) pixels, as fractions of the width and height.
fn blob_centroid(path: &Path) -> (f64, f64) {
    let (px, w, h) = pixels(path);
    let (mut sx, mut sy, mut n) = (0.0, 0.0, 0.0);
    for (i, p) in px.chunks_exact(4).enumerate() {
        assert!(p[0] == p[1] && p[1] == p[2], "greyscale by default");
        if p[0] > 128 {
            sx += (i as u32 % w) as f64 + 0.5;
            sy += (i as u32 / w) as f64 + 0.5;
            n += 1.0;
        }
    }
    assert!(
        n >= 4.0,
        "{}: the blob is missing ({n} bright pixels)",
        path.display()
    );
    (sx / n / w as f64, sy / n / h as f64)
}

fn slice(input: &Path, out: &Path, extra: &[&str]) -> String {
    let mut args = vec![
        "--normalize",
        "minmax",
        "slice",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = morphray(&args);
    let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    stdout
}

#[test]
fn a_left_anterior_superior_blob_is_on_the_right_side_in_every_plane_and_convention() {
    for flipped in [false, true] {
        let input = temp(if flipped {
            "head-lps.nii"
        } else {
            "head-ras.nii"
        });
        head(flipped, &input);
        for (plane, mm) in [
            ("axial", BLOB[2]),
            ("coronal", BLOB[1]),
            ("sagittal", BLOB[0]),
        ] {
            for convention in ["radiological", "neurological"] {
                let out = temp(&format!("{plane}-{convention}-{flipped}.png"));
                let mm = mm.to_string();
                let said = slice(
                    &input,
                    &out,
                    &["--plane", plane, "--mm", &mm, "--convention", convention],
                );
                assert!(
                    said.contains(&format!("convention: {convention}")),
                    "{said}"
                );
                let (cx, cy) = blob_centroid(&out);
                let case = format!("{plane} {convention} flipped={flipped}: ({cx:.2}, {cy:.2})");
                // Anterior (axial) and superior (coronal, sagittal) are at the top.
                assert!(cy < 0.4, "{case}: expected in the top part");
                match (plane, convention) {
                    // Sagittal: anterior on the left whatever the convention.
                    ("sagittal", _) => assert!(cx < 0.4, "{case}: anterior is on the left"),
                    // The patient's LEFT is on the image's right in radiological convention.
                    (_, "radiological") => assert!(cx > 0.6, "{case}: left blob on the right"),
                    _ => assert!(cx < 0.4, "{case}: left blob on the left"),
                }
            }
        }
    }
}

#[test]
fn index_and_mm_name_the_same_plane_and_the_default_is_radiological() {
    let input = temp("head-index.nii");
    head(true, &input);
    // Flipped storage: x = 10 - i, y = 9.6 - 1.2 j, z = -10.5 + 1.5 k.
    for (plane, index, mm) in [
        ("axial", "10", "4.5"),
        ("coronal", "4", "4.8"),
        ("sagittal", "15", "-5"),
    ] {
        let by_index = temp(&format!("{plane}-index.png"));
        let by_mm = temp(&format!("{plane}-mm.png"));
        let said = slice(&input, &by_index, &["--plane", plane, "--index", index]);
        assert!(said.contains("convention: radiological"), "default: {said}");
        slice(&input, &by_mm, &["--plane", plane, "--mm", mm]);
        assert_eq!(pixels(&by_index), pixels(&by_mm), "{plane}");
    }
    let o = morphray(&[
        "slice",
        input.to_str().unwrap(),
        "-o",
        temp("x.png").to_str().unwrap(),
        "--plane",
        "axial",
        "--index",
        "15",
    ]);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.starts_with("morphray: ") && err.contains("outside the volume"),
        "{err}"
    );
    // A bricked volume cannot be sliced yet: said in one line, with what to do.
    let o = morphray(&[
        "--bricked",
        "slice",
        input.to_str().unwrap(),
        "-o",
        temp("y.png").to_str().unwrap(),
        "--plane",
        "axial",
    ]);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("bricked") && err.contains("--memory-budget"),
        "{err}"
    );
    assert!(
        !err.contains("this device"),
        "the device is not the problem: {err}"
    );
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
}

#[test]
fn the_input_is_never_overwritten_and_letters_land_on_their_edges() {
    let input = temp("head-keep.nii");
    head(false, &input);
    let before = std::fs::read(&input).unwrap();
    let o = morphray(&[
        "slice",
        input.to_str().unwrap(),
        "-o",
        input.to_str().unwrap(),
        "--plane",
        "axial",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("input"),
        "{:?}",
        o
    );
    assert_eq!(
        std::fs::read(&input).unwrap(),
        before,
        "the input is untouched"
    );
    // Letters: at 0.25 mm pixels the axial picture is 84x81, room for 5x7 glyphs.
    let out = temp("letters.png");
    slice(
        &input,
        &out,
        &["--plane", "axial", "--letters", "--pixel-mm", "0.25"],
    );
    let (px, w, h) = pixels(&out);
    let yellow = |x0: u32, x1: u32, y0: u32, y1: u32| {
        (y0..y1)
            .flat_map(|y| (x0..x1).map(move |x| (x, y)))
            .any(|(x, y)| {
                let p = &px[4 * (y * w + x) as usize..][..4];
                p[0] == 255 && p[1] == 255 && p[2] == 0
            })
    };
    // R on the left, L on the right, A at the top, P at the bottom; nothing in the corners.
    assert!(yellow(0, w / 6, h / 3, 2 * h / 3), "left letter");
    assert!(yellow(5 * w / 6, w, h / 3, 2 * h / 3), "right letter");
    assert!(yellow(w / 3, 2 * w / 3, 0, h / 6), "top letter");
    assert!(yellow(w / 3, 2 * w / 3, 5 * h / 6, h), "bottom letter");
    assert!(!yellow(0, w / 6, 0, h / 6), "corner");
    // The left letter is an R: its top row is four pixels of R's 11110.
    let left: Vec<(u32, u32)> = (0..h)
        .flat_map(|y| (0..w / 6).map(move |x| (x, y)))
        .filter(|&(x, y)| px[4 * (y * w + x) as usize..][..3] == [255, 255, 0])
        .collect();
    let top = left.iter().map(|p| p.1).min().unwrap();
    assert_eq!(left.iter().filter(|p| p.1 == top).count(), 4, "R's top row");
    assert_eq!(left.len(), 18, "R has 18 set pixels at scale 1");
}

/// A label map on a coarser (2 mm), x-flipped grid: label 7 around the blob, 0 elsewhere.
fn blob_labels(path: &Path) {
    let dims = [11usize, 11, 12];
    let affine = [
        [-2.0, 0.0, 0.0, 10.0],
        [0.0, 2.0, 0.0, -10.0],
        [0.0, 0.0, 2.0, -11.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let mut labels = Vec::new();
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let w = [
                    10.0 - 2.0 * i as f64,
                    -10.0 + 2.0 * j as f64,
                    -11.0 + 2.0 * k as f64,
                ];
                let d2: f64 = (0..3).map(|a| (w[a] - BLOB[a]).powi(2)).sum();
                labels.push(if d2 < 3.5 * 3.5 { 7u8 } else { 0 });
            }
        }
    }
    let v = Volume::from_voxels(
        "labels",
        dims,
        Samples::from_u8(labels),
        affine,
        LinearMap::IDENTITY,
    )
    .unwrap();
    write_nifti1(&v, path, false).unwrap();
}

#[test]
fn an_overlay_on_another_grid_colours_the_blob_with_its_table_colour() {
    let input = temp("head-overlay.nii");
    head(true, &input);
    let labels = temp("labels.nii");
    blob_labels(&labels);
    let lut = temp("lut.txt");
    std::fs::write(
        &lut,
        "# index name R G B A\n0 Unknown 0 0 0 0\n7 Blob 255 0 0 0\n",
    )
    .unwrap();
    let out = temp("overlay.png");
    let mm = BLOB[2].to_string();
    let args = [
        "--plane",
        "axial",
        "--mm",
        &mm,
        "--overlay",
        labels.to_str().unwrap(),
        "--overlay-lut",
        lut.to_str().unwrap(),
        "--overlay-opacity",
        "1",
    ];
    let said = slice(&input, &out, &args);
    assert!(said.contains("overlay: "), "{said}");
    let (px, w, h) = pixels(&out);
    let red: Vec<(u32, u32)> = px
        .chunks_exact(4)
        .enumerate()
        .filter(|(_, p)| p[..3] == [255, 0, 0])
        .map(|(i, _)| (i as u32 % w, i as u32 / w))
        .collect();
    assert!(red.len() >= 4, "the label is drawn ({} px)", red.len());
    // Every other pixel stays grey, and the red sits where the blob is: the image's right
    // (the patient's left, radiological) and its top (anterior).
    assert!(
        px.chunks_exact(4)
            .all(|p| p[..3] == [255, 0, 0] || (p[0] == p[1] && p[1] == p[2]))
    );
    let cx = red.iter().map(|p| p.0 as f64 + 0.5).sum::<f64>() / red.len() as f64 / w as f64;
    let cy = red.iter().map(|p| p.1 as f64 + 0.5).sum::<f64>() / red.len() as f64 / h as f64;
    assert!(cx > 0.6 && cy < 0.4, "label at ({cx:.2}, {cy:.2})");
    // The same picture without the overlay has the blob's bright grey in the same place.
    let plain = temp("overlay-plain.png");
    slice(&input, &plain, &["--plane", "axial", "--mm", &mm]);
    let (bx, by) = blob_centroid(&plain);
    assert!(
        (bx - cx).abs() < 0.1 && (by - cy).abs() < 0.1,
        "blob ({bx:.2}, {by:.2})"
    );
    // A map of non-integers is no label map: one line naming the file.
    let bad = temp("not-labels.nii");
    let v = Volume::from_voxels(
        "not-labels.nii",
        [2, 1, 1],
        Samples::from_f32(&[1.0, 2.5]),
        [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ],
        LinearMap::IDENTITY,
    )
    .unwrap();
    write_nifti1(&v, &bad, false).unwrap();
    let o = morphray(&[
        "slice",
        input.to_str().unwrap(),
        "-o",
        temp("bad.png").to_str().unwrap(),
        "--plane",
        "axial",
        "--overlay",
        bad.to_str().unwrap(),
    ]);
    assert_ne!(o.status.code(), Some(0));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.starts_with("morphray: ") && err.contains("not a label"),
        "{err}"
    );
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
}

#[test]
fn the_phantom_s_labels_overlay_its_lesion_in_the_left_hemisphere() {
    let (volume, labels) = (temp("ph.nii"), temp("ph-labels.nii"));
    let o = morphray(&[
        "phantom",
        "--dims",
        "40x40x32",
        "-o",
        volume.to_str().unwrap(),
        "--labels",
        labels.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let lut = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tools/figures/phantom-labels-lut.txt"
    );
    let out = temp("ph-overlay.png");
    // The lesion's centre: z = 0.30 of the brain's semi-axis (0.64 of 16 mm), x < 0.
    let said = slice(
        &volume,
        &out,
        &[
            "--plane",
            "axial",
            "--mm",
            "3",
            "--overlay",
            labels.to_str().unwrap(),
            "--overlay-lut",
            lut,
            "--overlay-opacity",
            "1",
        ],
    );
    assert!(said.contains("overlay: "), "{said}");
    let (px, w, _) = pixels(&out);
    let lesion: Vec<u32> = px
        .chunks_exact(4)
        .enumerate()
        .filter(|(_, p)| p[..3] == [255, 0, 0])
        .map(|(i, _)| i as u32 % w)
        .collect();
    assert!(!lesion.is_empty(), "the lesion label is drawn");
    let cx = lesion.iter().map(|&x| x as f64 + 0.5).sum::<f64>() / lesion.len() as f64;
    assert!(
        cx > w as f64 / 2.0,
        "left lesion on the image's right: x {cx:.1} of {w}"
    );
}
