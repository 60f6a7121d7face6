//! DICOM series for benchmarks and figures, written by the tests' writer
//! (tests/common/dicom.rs):
//!
//! - `cargo run --release --example dicom_series -- bench DIR [SLICES] [SIZE] [RUNS]`: writes
//!   DIR/series (SLICES files of SIZE x SIZE int16, explicit little endian; defaults 400, 512)
//!   and DIR/same.nii (the volume read from that series, written as NIfTI-1), then times the
//!   library's read of each (`volume::source::read`, what every command calls), alternating,
//!   RUNS times (default 5), and prints the medians and their ratio (BENCHMARKS.md, DICOM).
//! - `cargo run --release --example dicom_series -- from NII DIR`: writes the volume of a NIfTI
//!   file as an axial DICOM series in DIR (the README's DICOM figure is rendered from the
//!   MNI152 template written this way).

#[path = "../../tests/common/dicom.rs"]
mod writer;

use morphray::volume::source::{ReadOptions, VolumeSource, read};
use std::path::{Path, PathBuf};
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize| args.get(i).map(String::as_str);
    match arg(0) {
        Some("bench") if args.len() >= 2 => {
            let n = |i: usize, d: usize| arg(i).and_then(|s| s.parse().ok()).unwrap_or(d);
            bench(Path::new(&args[1]), n(2, 400), n(3, 512), n(4, 5));
        }
        Some("from") if args.len() == 3 => {
            let volume = morphray::volume::Volume::open(Path::new(&args[1])).unwrap();
            let spec = writer::from_volume("1.2.826.0.1.3680043.2.1125.5.1", &volume);
            let files = writer::write_series(Path::new(&args[2]), &spec);
            println!("wrote {} files to {}", files.len(), args[2]);
        }
        _ => {
            eprintln!("usage: dicom_series bench DIR [SLICES] [SIZE] [RUNS] | from NII DIR");
            std::process::exit(2);
        }
    }
}

fn open_ms(path: &Path) -> f64 {
    let start = Instant::now();
    let v = read(
        &VolumeSource::File(path.to_path_buf()),
        &ReadOptions::default(),
    )
    .unwrap();
    let ms = start.elapsed().as_secs_f64() * 1e3;
    assert!(v.volume.voxel_count() > 0);
    ms
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn bench(dir: &Path, slices: usize, size: usize, runs: usize) {
    let series = dir.join("series");
    let nii: PathBuf = dir.join("same.nii");
    if !series.is_dir() {
        let spec = writer::Spec {
            rows: size as u16,
            cols: size as u16,
            slices,
            pixel_spacing: [0.5, 0.5],
            gap: 1.0,
            signed: true,
            ..writer::Spec::oblique("1.2.826.0.1.3680043.2.1125.5.2")
        };
        writer::write_series(&series, &spec);
        let _ = std::fs::remove_file(&nii);
    }
    if !nii.is_file() {
        let v = read(&VolumeSource::File(series.clone()), &ReadOptions::default()).unwrap();
        morphray::volume::nifti::write_nifti1(&v.volume, &nii, false).unwrap();
    }
    // One untimed read of each: both from the page cache afterwards.
    open_ms(&series);
    open_ms(&nii);
    let (mut d, mut n) = (Vec::new(), Vec::new());
    for _ in 0..runs {
        d.push(open_ms(&series));
        n.push(open_ms(&nii));
    }
    let mut headers = Vec::new();
    for _ in 0..runs {
        let start = Instant::now();
        morphray::volume::source::dicom::survey(&series).unwrap();
        headers.push(start.elapsed().as_secs_f64() * 1e3);
    }
    println!(
        "of which headers only (dicom::survey): median {:.1} ms",
        median(headers)
    );
    let (dm, nm) = (median(d.clone()), median(n.clone()));
    println!("DICOM {slices} files of {size}x{size}: runs {d:.1?} ms, median {dm:.1} ms");
    println!("same volume as .nii: runs {n:.1?} ms, median {nm:.1} ms");
    println!("ratio DICOM / NIfTI: {:.2}", dm / nm);
}
