//! DICOM geometry and values against dcm2niix, the converter users trust (issue 14 item 5):
//! the same series written by the tests' writer is read by morphray and converted by dcm2niix
//! (from the tests' Python environment, tools/pyenv.sh); the voxel corners' world positions
//! must agree within 0.1 mm and every voxel's physical value must be the same.
//!
//! The comparison goes through world space, so it holds whatever index order dcm2niix picks
//! (it flips rows, and may reverse slices).

#[path = "common/dicom.rs"]
mod writer;

use morphray::volume::Volume;
use morphray::volume::source::{self as source, ReadOptions, VolumeSource};
use std::path::{Path, PathBuf};
use std::process::Command;
use writer::Spec;

/// dcm2niix from the tests' venv; fails (never skips) when it is absent.
fn dcm2niix() -> PathBuf {
    let env = std::env::var_os("MORPHRAY_PYENV")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            let cache = std::env::var_os("XDG_CACHE_HOME")
                .map(PathBuf::from)
                .unwrap_or_else(|| PathBuf::from(std::env::var_os("HOME").unwrap()).join(".cache"));
            cache.join("morphray/pyenv")
        });
    let exe = env.join("bin/dcm2niix");
    assert!(
        exe.is_file(),
        "{} is missing: run tools/setup.sh (or tools/pyenv.sh) to create the tests' Python \
         environment with dcm2niix",
        exe.display()
    );
    exe
}

fn folder(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("morphray-d2n-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// dcm2niix's NIfTI of the series in `dicom`.
fn convert_with_dcm2niix(dicom: &Path, out: &Path) -> Volume {
    std::fs::create_dir_all(out).unwrap();
    let o = Command::new(dcm2niix())
        .args(["-z", "n", "-b", "n", "-f", "ref", "-o"])
        .arg(out)
        .arg(dicom)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "dcm2niix failed: {}",
        String::from_utf8_lossy(&o.stdout)
    );
    let nii: Vec<PathBuf> = std::fs::read_dir(out)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "nii"))
        .collect();
    assert_eq!(nii.len(), 1, "one NIfTI expected: {nii:?}");
    Volume::open(&nii[0]).unwrap()
}

fn world(a: &[[f64; 4]; 4], p: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|r| a[r][0] * p[0] + a[r][1] * p[1] + a[r][2] * p[2] + a[r][3])
}

/// The inverse of an affine's linear part and its translation.
#[allow(clippy::needless_range_loop)] // index arithmetic of the cofactors reads best as loops
fn inverse(a: &[[f64; 4]; 4]) -> [[f64; 4]; 4] {
    let m = |r: usize, c: usize| a[r][c];
    let det = m(0, 0) * (m(1, 1) * m(2, 2) - m(1, 2) * m(2, 1))
        - m(0, 1) * (m(1, 0) * m(2, 2) - m(1, 2) * m(2, 0))
        + m(0, 2) * (m(1, 0) * m(2, 1) - m(1, 1) * m(2, 0));
    let mut inv = [[0.0; 4]; 4];
    for r in 0..3 {
        for c in 0..3 {
            let (r1, r2) = ((c + 1) % 3, (c + 2) % 3);
            let (c1, c2) = ((r + 1) % 3, (r + 2) % 3);
            inv[r][c] = (m(r1, c1) * m(r2, c2) - m(r1, c2) * m(r2, c1)) / det;
        }
    }
    for r in 0..3 {
        inv[r][3] = -(0..3).map(|c| inv[r][c] * a[c][3]).sum::<f64>();
    }
    inv[3][3] = 1.0;
    inv
}

/// The 8 corners of the voxel grid (outer faces of the corner voxels), in world space.
fn corners(v: &Volume) -> Vec<[f64; 3]> {
    let d = v.dims.map(|n| n as f64);
    let mut out = Vec::new();
    for bits in 0..8 {
        let p = [0, 1, 2].map(|a| if bits >> a & 1 == 1 { d[a] - 0.5 } else { -0.5 });
        out.push(world(&v.orientation.affine, p));
    }
    out
}

fn compare(name: &str, spec: &Spec) {
    let dir = folder(name);
    let dicom = dir.join("dicom");
    writer::write_series(&dicom, spec);
    let ours = source::read(&VolumeSource::File(dicom.clone()), &ReadOptions::default())
        .unwrap()
        .volume;
    let reference = convert_with_dcm2niix(&dicom, &dir.join("nii"));
    let mut theirs_dims = reference.dims;
    let mut ours_dims = ours.dims;
    theirs_dims.sort();
    ours_dims.sort();
    assert_eq!(ours_dims, theirs_dims, "{name}: dims");
    // Corners: each of ours within 0.1 mm of one of dcm2niix's.
    let theirs = corners(&reference);
    for c in corners(&ours) {
        let nearest = theirs
            .iter()
            .map(|t| (0..3).map(|a| (t[a] - c[a]).powi(2)).sum::<f64>().sqrt())
            .fold(f64::INFINITY, f64::min);
        assert!(
            nearest < 0.1,
            "{name}: corner {c:?} is {nearest} mm from dcm2niix's"
        );
    }
    // Values: every dcm2niix voxel, found in ours through world space.
    let to_ours = inverse(&ours.orientation.affine);
    let [nx, ny, nz] = reference.dims;
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let w = world(&reference.orientation.affine, [i, j, k].map(|x| x as f64));
                let idx = world(&to_ours, w);
                let r = idx.map(|x| x.round());
                assert!(
                    (0..3).all(|a| (idx[a] - r[a]).abs() < 0.01),
                    "{name}: voxel centres do not coincide: {idx:?}"
                );
                let [oi, oj, ok] = r.map(|x| x as usize);
                let mine = ours.to_physical.apply(
                    ours.samples
                        .get(oi + ours.dims[0] * (oj + ours.dims[1] * ok)),
                );
                let want = reference
                    .to_physical
                    .apply(reference.samples.get(i + nx * (j + ny * k)));
                assert!(
                    (mine - want).abs() <= 1e-3 * want.abs().max(1.0),
                    "{name}: voxel ({i},{j},{k}) of dcm2niix: {want} vs ours {mine}"
                );
            }
        }
    }
}

#[test]
fn axial_oblique_sagittal_and_coronal_agree_with_dcm2niix() {
    compare("axial", &Spec::axial("1.2.826.0.1.3680043.2.1125.2.1"));
    compare("oblique", &Spec::oblique("1.2.826.0.1.3680043.2.1125.2.2"));
    compare(
        "sagittal",
        &Spec::sagittal("1.2.826.0.1.3680043.2.1125.2.3"),
    );
    compare("coronal", &Spec::coronal("1.2.826.0.1.3680043.2.1125.2.4"));
}

#[test]
fn rescaled_rle_and_jpeg_lossless_series_agree_with_dcm2niix() {
    compare(
        "rescale",
        &Spec {
            rescale: |_| (2.0, -100.0),
            signed: true,
            ..Spec::oblique("1.2.826.0.1.3680043.2.1125.2.5")
        },
    );
    compare(
        "rle",
        &Spec {
            encoding: writer::RLE,
            ..Spec::sagittal("1.2.826.0.1.3680043.2.1125.2.6")
        },
    );
    compare(
        "jpeg-lossless",
        &Spec {
            encoding: writer::JPEG_LOSSLESS,
            ..Spec::coronal("1.2.826.0.1.3680043.2.1125.2.7")
        },
    );
}

#[test]
fn siemens_mosaics_agree_with_dcm2niix() {
    // 5 slices in a 3 x 3 grid (4 empty tiles): an oblique axial stored along row x column,
    // and a sagittal stored against it (the CSA normal says so), as Siemens stores R to L.
    compare(
        "mosaic-oblique",
        &Spec {
            slices: 5,
            mosaic: writer::Mosaic::Along,
            ..Spec::oblique("1.2.826.0.1.3680043.2.1125.2.8")
        },
    );
    compare(
        "mosaic-sagittal-against",
        &Spec {
            slices: 7,
            mosaic: writer::Mosaic::Against,
            ..Spec::sagittal("1.2.826.0.1.3680043.2.1125.2.9")
        },
    );
}
