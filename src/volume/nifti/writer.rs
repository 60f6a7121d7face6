//! A small NIfTI-1 writer: the engine's volumes (for example the phantom) as `.nii` / `.nii.gz`,
//! for benchmarks, peers and round-trip tests.
//!
//! Decisions:
//! - Single file (`n+1`), little-endian, `vox_offset` 352, no extensions, the samples' own
//!   encoding (u8 -> uint8, i8 -> int8, u16 -> uint16, i16 -> int16, f32 -> float32), so the
//!   voxel bytes are written exactly as stored.
//! - sform = the volume's affine with code 2 (aligned). A qform (also code 2) is written only
//!   when it reproduces the affine: orthogonal columns whose lengths equal the spacing (relative
//!   1e-6); otherwise `qform_code` is 0 rather than a misleading approximation.
//! - `scl_slope` / `scl_inter` come from `to_physical`, narrowed to f32 (NIfTI-1 has no wider
//!   field): exact for the usual maps (identity, small integers, powers of two); a map that f32
//!   cannot hold (for example a 1e30 offset from float64 data) is rounded.
//! - `xyzt_units` = mm; `descrip` = `"morphray: <name>"` (79 bytes at most).
//! - gzip output is one member compressed by libdeflate at level 6.

use super::datatype::Datatype;
use super::error::NiftiError;
use super::gzip::gzip_compress;
use super::header::{ByteOrder, RawHeader, Version, fits_i16};
use crate::volume::Volume;
use std::path::Path;

/// Quaternion (b, c, d) and qfac reproducing the 3x3 part of `affine` with voxel sizes
/// `spacing`, when it is a rotation (or rotation with flip) times that scaling.
fn derive_qform(affine: &[[f64; 4]; 4], spacing: [f64; 3]) -> Option<([f64; 3], f64)> {
    let mut r = [[0.0f64; 3]; 3];
    for col in 0..3 {
        let n = (0..3)
            .map(|row| affine[row][col] * affine[row][col])
            .sum::<f64>()
            .sqrt();
        if !(n.is_finite() && n > 0.0) || (n - spacing[col]).abs() > 1e-6 * spacing[col] {
            return None;
        }
        for row in 0..3 {
            r[row][col] = affine[row][col] / n;
        }
    }
    for a in 0..3 {
        for b in a + 1..3 {
            let dot: f64 = (0..3).map(|row| r[row][a] * r[row][b]).sum();
            if dot.abs() > 1e-6 {
                return None;
            }
        }
    }
    let det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
        - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
        + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
    let qfac = if det < 0.0 { -1.0 } else { 1.0 };
    if qfac < 0.0 {
        for row in r.iter_mut() {
            row[2] = -row[2];
        }
    }
    // nifti_mat44_to_quatern: pick the numerically safest formula.
    let trace = r[0][0] + r[1][1] + r[2][2] + 1.0;
    let (mut a, mut b, mut c, mut d);
    if trace > 0.5 {
        a = 0.5 * trace.sqrt();
        b = 0.25 * (r[2][1] - r[1][2]) / a;
        c = 0.25 * (r[0][2] - r[2][0]) / a;
        d = 0.25 * (r[1][0] - r[0][1]) / a;
    } else {
        let xd = 1.0 + r[0][0] - (r[1][1] + r[2][2]);
        let yd = 1.0 + r[1][1] - (r[0][0] + r[2][2]);
        let zd = 1.0 + r[2][2] - (r[0][0] + r[1][1]);
        if xd > 1.0 {
            b = 0.5 * xd.sqrt();
            c = 0.25 * (r[0][1] + r[1][0]) / b;
            d = 0.25 * (r[0][2] + r[2][0]) / b;
            a = 0.25 * (r[2][1] - r[1][2]) / b;
        } else if yd > 1.0 {
            c = 0.5 * yd.sqrt();
            b = 0.25 * (r[0][1] + r[1][0]) / c;
            d = 0.25 * (r[1][2] + r[2][1]) / c;
            a = 0.25 * (r[0][2] - r[2][0]) / c;
        } else {
            d = 0.5 * zd.sqrt();
            b = 0.25 * (r[0][2] + r[2][0]) / d;
            c = 0.25 * (r[1][2] + r[2][1]) / d;
            a = 0.25 * (r[1][0] - r[0][1]) / d;
        }
        if a < 0.0 {
            (a, b, c, d) = (-a, -b, -c, -d);
        }
    }
    let _ = a; // a is implied by (b, c, d) in NIfTI
    let q = [b, c, d];
    q.iter().all(|v| v.is_finite()).then_some((q, qfac))
}

/// Writes `volume` as a NIfTI-1 file at `path` (gzip-compressed when `gzip`), as the module doc
/// describes, replacing an existing file only with the complete new one. Fails when a dimension
/// exceeds 32767 (NIfTI-1's i16 dims), when the samples do not match the dims, when the affine or
/// spacing is not finite, or on I/O errors.
pub fn write_nifti1(volume: &Volume, path: &Path, gzip: bool) -> Result<(), NiftiError> {
    let file = encode_nifti1(volume, gzip)?;
    // Atomically (files::write): a failed write leaves any previous file whole.
    crate::files::write::write_file(path, &file).map_err(|e| io_error(path, e))
}

/// [`write_nifti1`] that never replaces an existing file, not even one created while the volume
/// was being encoded (a scan is precious: the no-clobber check happens at the rename).
pub fn write_new_nifti1(volume: &Volume, path: &Path, gzip: bool) -> Result<(), NiftiError> {
    let file = encode_nifti1(volume, gzip)?;
    crate::files::write::write_new_file(path, &file).map_err(|e| io_error(path, e))
}

fn io_error(path: &Path, e: crate::files::write::OutputError) -> NiftiError {
    NiftiError::Io {
        action: "write",
        path: path.to_path_buf(),
        source: e.into_io_error(),
    }
}

/// The bytes of a NIfTI-1 file of `volume` (gzip-compressed when `gzip`).
fn encode_nifti1(volume: &Volume, gzip: bool) -> Result<Vec<u8>, NiftiError> {
    let unwritable = |why: String| NiftiError::Unwritable {
        what: format!("volume {:?}", volume.name),
        why,
    };
    if let Some(d) = volume.dims.iter().find(|&&d| d == 0 || !fits_i16(d as i64)) {
        return Err(unwritable(format!(
            "dimension {d} is outside NIfTI-1's range 1..=32767"
        )));
    }
    let voxels = volume
        .dims
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d));
    if voxels != Some(volume.samples.len()) {
        return Err(unwritable(format!(
            "it has {} samples but its dims {:?} describe {:?} voxels",
            volume.samples.len(),
            volume.dims,
            voxels
        )));
    }
    let affine = &volume.orientation.affine;
    if !affine.iter().flatten().all(|v| v.is_finite()) {
        return Err(unwritable("its affine has non-finite entries".to_string()));
    }
    if !volume.spacing_mm.iter().all(|s| s.is_finite() && *s > 0.0) {
        return Err(unwritable(format!(
            "its spacing {:?} is not finite and positive",
            volume.spacing_mm
        )));
    }
    let map = volume.to_physical;
    if !(map.slope.is_finite() && map.slope != 0.0 && map.intercept.is_finite()) {
        return Err(unwritable(format!(
            "its intensity map {map:?} is not a finite non-zero slope and a finite intercept"
        )));
    }

    let datatype = Datatype::from_sample_kind(volume.samples.kind());
    let mut h = RawHeader {
        dim: [
            3,
            volume.dims[0] as i64,
            volume.dims[1] as i64,
            volume.dims[2] as i64,
            1,
            1,
            1,
            1,
        ],
        datatype: datatype.code(),
        bitpix: datatype.bitpix(),
        pixdim: [
            1.0,
            volume.spacing_mm[0],
            volume.spacing_mm[1],
            volume.spacing_mm[2],
            0.0,
            0.0,
            0.0,
            0.0,
        ],
        vox_offset: 352.0,
        scl_slope: map.slope,
        scl_inter: map.intercept,
        xyzt_units: 2,
        sform_code: 2,
        srow: [affine[0], affine[1], affine[2]],
        qoffset: [affine[0][3], affine[1][3], affine[2][3]],
        ..RawHeader::default()
    };
    if let Some((quatern, qfac)) = derive_qform(affine, volume.spacing_mm) {
        h.qform_code = 2;
        h.quatern = quatern;
        h.pixdim[0] = qfac;
    }
    h.set_description(&format!("morphray: {}", volume.name));

    let header = h.encode(Version::Nifti1, ByteOrder::LittleEndian);
    let data = volume.samples.as_bytes();
    let total = header.len().saturating_add(data.len());
    let mut file = Vec::new();
    file.try_reserve_exact(total)
        .map_err(|_| NiftiError::OutOfMemory {
            bytes: total,
            what: "the NIfTI file",
        })?;
    file.extend_from_slice(&header);
    file.extend_from_slice(data);
    if gzip { gzip_compress(&file) } else { Ok(file) }
}
