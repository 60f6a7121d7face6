//! The DICOM series reader, end to end: the input is split at each `DICM` into files (each
//! written with a 128-byte zero preamble and the magic, as `fNN.dcm` in one folder), then
//! `dicom::survey` and `dicom::load` run on the folder as `morphray info` and every command do
//! (parallel header reads, grouping, splitting, sorting, layout checks, parallel decoding,
//! rescale, resampling).
//!
//! Checks beyond "no panic": panics inside dicom-rs are contained by the reader (its issue
//! 543) and reported as skipped files, so the target lets those unwind (the first few are
//! printed) and aborts on any other panic; an accepted volume has as many samples as its dims
//! say, a finite invertible affine with last row 0 0 0 1, positive spacing and a usable
//! intensity map; errors and warnings are one line; every series listed has consistent dims.
//! Run with `-malloc_limit_mb=512` (README.md).
#![no_main]

use libfuzzer_sys::fuzz_target;
use morphray::volume::source::dicom;
use std::path::PathBuf;
use std::sync::OnceLock;
use std::sync::atomic::{AtomicUsize, Ordering};

/// One directory per fuzzing process, emptied before each input.
fn dir() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let d = std::env::temp_dir().join(format!("morphray-fuzz-dicom-{}", std::process::id()));
        std::fs::create_dir_all(&d).expect("a temporary directory");
        // libFuzzer's hook aborts on every panic; a panic the reader contains is not a crash.
        let abort = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if dicom::panic_is_contained() {
                static SEEN: AtomicUsize = AtomicUsize::new(0);
                if SEEN.fetch_add(1, Ordering::Relaxed) < 5 {
                    eprintln!("contained dicom-rs panic: {info}");
                }
                return;
            }
            abort(info);
        }));
        d
    })
}

/// The files the input stands for (at most 8).
fn files(data: &[u8]) -> Vec<Vec<u8>> {
    let mut starts: Vec<usize> = data
        .windows(4)
        .enumerate()
        .filter(|(_, w)| *w == b"DICM")
        .map(|(i, _)| i)
        .take(8)
        .collect();
    if starts.first() != Some(&0) {
        starts.insert(0, 0);
    }
    starts
        .iter()
        .enumerate()
        .map(|(n, &s)| {
            let end = starts.get(n + 1).copied().unwrap_or(data.len());
            let mut file = vec![0u8; 128];
            if !data[s..].starts_with(b"DICM") {
                file.extend_from_slice(b"DICM");
            }
            file.extend_from_slice(&data[s..end]);
            file
        })
        .collect()
}

fn one_line(text: &str) {
    assert!(!text.is_empty() && !text.contains('\n'), "not one line: {text:?}");
}

fuzz_target!(|data: &[u8]| {
    let dir = dir();
    for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let _ = std::fs::remove_file(e.path());
    }
    for (n, f) in files(data).iter().enumerate() {
        std::fs::write(dir.join(format!("f{n:02}.dcm")), f).expect("a temporary file");
    }
    match dicom::survey(dir) {
        Err(e) => one_line(&e.to_string()),
        Ok(survey) => {
            for s in survey.series() {
                if let Some(d) = s.dims {
                    assert!(d.iter().all(|&n| n > 0), "empty dims {d:?}");
                    assert!(s.affine.is_some() && s.spacing.is_some());
                }
                s.warnings.iter().for_each(|w| one_line(w));
            }
            survey.skipped().iter().for_each(|s| one_line(&s.reason));
        }
    }
    match dicom::load(dir, None) {
        Err(e) => one_line(&e.to_string()),
        Ok((v, _)) => {
            assert_eq!(v.samples.len(), v.dims.iter().product::<usize>());
            morphray_fuzz::check_orientation(&v.orientation);
            morphray_fuzz::check_warnings(&v.warnings);
            assert!(v.spacing_mm.iter().all(|s| s.is_finite() && *s > 0.0));
            assert!(v.to_physical.slope.is_finite() && v.to_physical.slope != 0.0);
            assert!(v.to_physical.intercept.is_finite());
        }
    }
});
