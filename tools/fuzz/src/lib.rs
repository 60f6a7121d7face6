//! Invariants the fuzz targets check on every input (the loader contract's point 9,
//! tests/nifti_loader.rs: no panics, and whatever is accepted must be usable by the engine).
//!
//! A violated invariant panics, which libFuzzer reports as a crash with the input saved under
//! `artifacts/`. The checks are deliberately stronger than "does not panic": an accepted volume
//! that does not fit its data, or an affine the derivative twin cannot invert, would reach the
//! GPU and fail (or render garbage) there.

// The DICOM targets' helpers; tests/fuzz_regressions.rs includes this file but not them.
#[allow(dead_code)]
pub mod dicom_check;
#[allow(dead_code)]
pub mod dicom_file;

use morphray::reference::derivatives::IndexToWorld;
use morphray::reference::minmax::finite_min_max;
use morphray::volume::nifti::gzip::Limit;
use morphray::volume::nifti::{
    LoadOptions, LoadedNifti, NiftiError, OrientationFields, ResolvedGeometry, load_file_timed,
};
use morphray::volume::stats::intensity_stats;
use morphray::volume::{Orientation, Volume};

/// Every error is one non-empty line (the loader promises one readable sentence).
pub fn check_error(e: &NiftiError) {
    let text = e.to_string();
    assert!(
        !text.is_empty() && !text.contains('\n'),
        "error message is not one line: {text:?}"
    );
}

/// Warnings are one non-empty line each, like errors.
pub fn check_warnings(warnings: &[String]) {
    for w in warnings {
        assert!(
            !w.is_empty() && !w.contains('\n'),
            "warning is not one line: {w:?}"
        );
    }
}

/// The affine is finite, affine (last row 0 0 0 1) and its 3x3 part is accepted by the f64
/// derivative twin's inverse (which is what the engine's derivative path needs).
pub fn check_orientation(o: &Orientation) {
    let a = &o.affine;
    assert!(
        a.iter().flatten().all(|v| v.is_finite()),
        "non-finite affine {a:?}"
    );
    assert_eq!(a[3], [0.0, 0.0, 0.0, 1.0], "last row of {a:?}");
    if let Err(e) = IndexToWorld::new(o.linear_part()) {
        panic!("affine accepted by the loader but not invertible for the twin: {e}");
    }
}

/// Spacing finite and > 0 on every axis.
pub fn check_spacing(spacing: &[f64; 3]) {
    assert!(
        spacing.iter().all(|s| s.is_finite() && *s > 0.0),
        "spacing {spacing:?}"
    );
}

/// What `orientation::resolve` promises for any input.
pub fn check_geometry(g: &ResolvedGeometry) {
    check_orientation(&g.orientation);
    check_spacing(&g.spacing_mm);
    check_warnings(&g.warnings);
}

/// A volume the engine can take: sizes, samples, geometry and intensity map consistent.
pub fn check_volume(v: &Volume) {
    assert!(v.dims.iter().all(|&d| d >= 1), "dims {:?}", v.dims);
    let count = v.dims.iter().try_fold(1usize, |acc, &d| acc.checked_mul(d));
    assert_eq!(Some(v.samples.len()), count, "samples vs dims {:?}", v.dims);
    check_spacing(&v.spacing_mm);
    check_orientation(&v.orientation);
    check_warnings(&v.warnings);
    let map = v.to_physical;
    assert!(
        map.slope.is_finite() && map.slope != 0.0 && map.intercept.is_finite(),
        "intensity map {map:?}"
    );
    // Every finite stored value has a finite physical value (convert.rs drops scalings that
    // would overflow), so min/max/normalization never see an infinity they did not read.
    for i in 0..v.samples.len() {
        let s = v.samples.get(i);
        if s.is_finite() {
            let p = map.apply(s);
            assert!(p.is_finite(), "voxel {i}: stored {s} -> physical {p}");
        }
    }
    // The CPU statistics and the min/max twin agree, and count every voxel once.
    let stats = intensity_stats(v);
    assert_eq!(stats.finite + stats.nonfinite, v.samples.len());
    match (finite_min_max(&v.samples), stats.imin, stats.imax) {
        (Some((lo, hi)), Some(imin), Some(imax)) => {
            assert!(
                lo <= hi && imin <= imax,
                "range {lo}..{hi} / {imin}..{imax}"
            );
            let (a, b) = (map.apply(lo), map.apply(hi));
            assert_eq!((a.min(b), a.max(b)), (imin, imax), "stats vs twin");
            assert!(stats.finite > 0);
        }
        (None, None, None) => assert_eq!(stats.finite, 0),
        other => panic!("stats and twin disagree on finiteness: {other:?}"),
    }
}

/// A loaded file: the volume is usable and the header summary agrees with it.
pub fn check_loaded(l: &LoadedNifti) {
    let v = &l.volume;
    check_volume(v);
    let h = &l.header;
    assert!(
        !h.dims.is_empty() && h.dims.len() <= 7,
        "header dims {:?}",
        h.dims
    );
    for axis in 0..3 {
        assert_eq!(
            v.dims[axis],
            h.dims.get(axis).copied().unwrap_or(1),
            "axis {axis}"
        );
    }
    assert!(
        h.frame_loaded < h.frames,
        "frame {} of {}",
        h.frame_loaded,
        h.frames
    );
    assert_eq!(h.gzip, h.gzip_members > 0);
}

// ---------------------------------------------------------------------------------------------
// How the targets read their input (shared with tests/fuzz_regressions.rs, which replays the
// seeds and the crashes found through the same functions).

/// Where the `.hdr` ends: after the fixed header and its extender when the first four bytes
/// say which version this is, plus 0..=3 extensions' worth of 16 bytes chosen by the last
/// byte (so the fuzzer can put extensions into the header file); half the input otherwise.
pub fn split_point(data: &[u8]) -> usize {
    let fixed = match data.get(..4) {
        Some(b) => match (
            i32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            i32::from_be_bytes([b[0], b[1], b[2], b[3]]),
        ) {
            (348, _) | (_, 348) => 352,
            (540, _) | (_, 540) => 544,
            _ => data.len() / 2,
        },
        None => data.len() / 2,
    };
    let extra = 16 * usize::from(data.last().copied().unwrap_or(0) & 3);
    (fixed + extra).min(data.len())
}

/// Reads the fields in the order of the struct. The first byte picks how floats are read:
/// even = f32 widened to f64 (what a NIfTI-1 file can hold), odd = raw f64 (NIfTI-2), so both
/// the common range and the extremes beyond f32 are explored. Missing bytes read as zero.
pub fn orientation_fields(data: &[u8]) -> OrientationFields {
    let wide = data.first().is_some_and(|b| b & 1 == 1);
    let mut at = 1usize;
    let mut take = |n: usize| -> Vec<u8> {
        let mut out = vec![0u8; n];
        for (i, b) in out.iter_mut().enumerate() {
            *b = data.get(at + i).copied().unwrap_or(0);
        }
        at += n;
        out
    };
    let mut int = || {
        let b = take(4);
        i32::from_le_bytes([b[0], b[1], b[2], b[3]])
    };
    let qform_code = int();
    let sform_code = int();
    let xyzt_units = int();
    let mut float = || {
        if wide {
            let b = take(8);
            f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]])
        } else {
            let b = take(4);
            f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        }
    };
    let quatern = [float(), float(), float()];
    let qoffset = [float(), float(), float()];
    let pixdim = [float(), float(), float(), float()];
    let srow = std::array::from_fn(|_| [float(), float(), float(), float()]);
    OrientationFields {
        qform_code,
        sform_code,
        quatern,
        qoffset,
        pixdim,
        srow,
        xyzt_units,
    }
}

/// The inflation limit the `gzip` target uses for `data`: 16 MiB (more than any input the fuzzer
/// makes can inflate to, so the differential check sees every stream whole) unless bit 4 of the
/// last byte is set, when it is 64 << (last byte & 15) bytes (64 B .. 2 MiB), so the
/// limit's own error path is explored too.
pub fn gzip_limit(data: &[u8]) -> Limit {
    let last = data.last().copied().unwrap_or(0);
    let declared = if last & 0x10 == 0 {
        16 << 20
    } else {
        64usize << (last & 15)
    };
    Limit {
        declared,
        slack: 0,
        what: "the fuzz target allows",
    }
}

/// How the `input_path` target lays out its input on disk: bits 2..3 of the last byte pick a
/// single file (`scan.nii`, `scan.nii.gz`: the name does not decide gzip, the content does) or a
/// pair split at [`split_point`] (which uses bits 0..1) and loaded by its `.hdr` or by its
/// `.IMG` (upper case, so the case-matching lookup runs). Returns (file name, bytes) to write,
/// and the name to load.
pub fn input_files(data: &[u8]) -> (Vec<(&'static str, &[u8])>, &'static str) {
    match (data.last().copied().unwrap_or(0) >> 2) & 3 {
        0 => (vec![("scan.nii", data)], "scan.nii"),
        1 => (vec![("scan.nii.gz", data)], "scan.nii.gz"),
        pair => {
            let (hdr, img) = data.split_at(split_point(data));
            if pair == 2 {
                (vec![("pair.hdr", hdr), ("pair.img", img)], "pair.hdr")
            } else {
                (vec![("PAIR.HDR", hdr), ("PAIR.IMG", img)], "PAIR.IMG")
            }
        }
    }
}

/// The `input_path` target's body, shared with tests/fuzz_regressions.rs: writes `data` into
/// `dir` as [`input_files`] says (removing what a previous input left), loads it with the
/// command line's own function and checks the result. Returns the load's outcome.
pub fn run_input_path(dir: &std::path::Path, data: &[u8]) -> Result<LoadedNifti, NiftiError> {
    for stale in [
        "scan.nii",
        "scan.nii.gz",
        "pair.hdr",
        "pair.img",
        "PAIR.HDR",
        "PAIR.IMG",
    ] {
        let _ = std::fs::remove_file(dir.join(stale));
    }
    let (files, load) = input_files(data);
    for (name, bytes) in files {
        std::fs::write(dir.join(name), bytes).expect("writing the input");
    }
    let frame = usize::from(data.first().copied().unwrap_or(0) >> 7);
    let mut seen = None;
    let result = load_file_timed(
        &dir.join(load),
        &LoadOptions { frame, mean: false },
        &mut |b| seen = Some(b.len()),
    );
    match &result {
        Ok((loaded, times)) => {
            check_loaded(loaded);
            assert!(
                seen.is_some_and(|n| n <= data.len()),
                "on_read saw {seen:?}"
            );
            assert!(times.read_ms >= 0.0 && times.inflate_ms >= 0.0 && times.convert_ms >= 0.0);
            assert_eq!(loaded.header.frame_loaded, frame);
        }
        Err(e) => check_error(e),
    }
    result.map(|(loaded, _)| loaded)
}
