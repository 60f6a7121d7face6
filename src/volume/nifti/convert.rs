//! Voxel bytes of one frame to [`Samples`] plus the stored-to-physical [`LinearMap`].
//!
//! Decisions:
//! - u8, i8, u16, i16, f32 keep their encoding. The frame is moved to the front of the buffer it
//!   was read into (one `memmove`, no second allocation; none at all when the voxels already start
//!   at byte 0) and byte-swapped in place when big-endian. That is the single copy of the voxels.
//! - int32, uint32, int64, uint64, float64 are converted to f32 into a new buffer (the single
//!   copy) by `pack.rs`, which chooses an offset and a scale (`stored = (x - offset) / scale`)
//!   so that f32 keeps the spread of the data, the minimum and maximum of integers stay exact,
//!   and a handful of float64 voxels beyond f32's reach (the 1e300 voxel) is clamped with a
//!   warning instead of scaling every other voxel to 0; every loss is a warning.
//!   The map absorbs both: `physical = stored * (scale * slope) + (offset * slope + inter)`.
//! - NaN and infinities stay (f32 can hold them); they are excluded from the offset's range.
//! - RGB24 / RGBA32 become f32 luminance with the Rec. 709 weights 0.2126 R + 0.7152 G +
//!   0.0722 B (alpha ignored), never scaled by scl_slope, with a warning.
//! - Scaling (the loader contract's point 5, `tests/nifti_loader.rs`): scl_slope 0 or non-finite
//!   means no scaling at all (NaN and infinities also warn; 0 is the standard's "unused"); a
//!   non-finite scl_inter with a usable slope is replaced by 0 with a warning. A finite scaling
//!   that would push some stored value outside the f64 range (only NIfTI-2's f64 fields can) is
//!   dropped with a warning, so the map and every physical value stay finite.

use super::datatype::Datatype;
use super::error::NiftiError;
use super::header::ByteOrder;
use super::pack::{floats, integers};
use crate::volume::{LinearMap, SampleKind, Samples};

/// The converted frame.
pub struct Converted {
    /// Stored samples, little-endian.
    pub samples: Samples,
    /// Stored-to-physical map.
    pub to_physical: LinearMap,
    /// Conversions and repairs worth telling the user about.
    pub warnings: Vec<String>,
}

/// File scaling after applying the contract's rules.
fn file_scaling(slope: f64, inter: f64, warnings: &mut Vec<String>) -> LinearMap {
    if slope == 0.0 {
        return LinearMap::IDENTITY;
    }
    if !slope.is_finite() {
        warnings.push(format!(
            "scl_slope is {slope}, so no intensity scaling is applied"
        ));
        return LinearMap::IDENTITY;
    }
    let intercept = if inter.is_finite() {
        inter
    } else {
        warnings.push(format!(
            "scl_inter is {inter}; it is ignored (taken as 0) and scl_slope {slope} is applied"
        ));
        0.0
    };
    LinearMap { slope, intercept }
}

fn alloc(bytes: usize) -> Result<Vec<u8>, NiftiError> {
    let mut v = Vec::new();
    v.try_reserve_exact(bytes)
        .map_err(|_| NiftiError::OutOfMemory {
            bytes,
            what: "the converted voxels",
        })?;
    Ok(v)
}

/// Converts the frame at `buf[start..start + len]`. `buf` is consumed so that the native kinds
/// can reuse its allocation. The caller has checked that the range lies inside `buf` and that
/// `len` is a whole number of voxels; a violated range gives a `TruncatedData` error, never a
/// panic.
pub fn convert_frame(
    mut buf: Vec<u8>,
    start: usize,
    len: usize,
    datatype: Datatype,
    order: ByteOrder,
    scl_slope: f64,
    scl_inter: f64,
) -> Result<Converted, NiftiError> {
    let mut warnings = Vec::new();
    let end =
        start
            .checked_add(len)
            .filter(|&e| e <= buf.len())
            .ok_or(NiftiError::TruncatedData {
                file: "file",
                len: buf.len(),
                needed: len,
                offset: start,
            })?;
    let big = order == ByteOrder::BigEndian;

    if datatype.is_colour() {
        if scl_slope != 0.0 && scl_slope.is_finite() && (scl_slope != 1.0 || scl_inter != 0.0) {
            warnings.push(format!(
                "scl_slope {scl_slope} / scl_inter {scl_inter} are not applied to {} colour data",
                datatype.name()
            ));
        }
        warnings.push(format!(
            "{} colour voxels were converted to luminance 0.2126 R + 0.7152 G + 0.0722 B",
            datatype.name()
        ));
        let src = buf.get(start..end).unwrap_or_default();
        let stride = if datatype == Datatype::Rgb24 { 3 } else { 4 };
        let mut out = alloc(src.len() / stride * 4)?;
        for px in src.chunks_exact(stride) {
            if let [r, g, b, ..] = *px {
                let y = 0.2126 * f32::from(r) + 0.7152 * f32::from(g) + 0.0722 * f32::from(b);
                out.extend_from_slice(&y.to_le_bytes());
            }
        }
        let samples = samples(SampleKind::F32, out)?;
        return Ok(Converted {
            samples,
            to_physical: LinearMap::IDENTITY,
            warnings,
        });
    }

    let file_map = file_scaling(scl_slope, scl_inter, &mut warnings);
    let native = matches!(
        datatype,
        Datatype::Uint8 | Datatype::Int8 | Datatype::Int16 | Datatype::Uint16 | Datatype::Float32
    );
    if native {
        let kind = datatype.sample_kind();
        // The samples stay where they are, after the header, unless what lies before them is
        // large (big extensions): then they move down so that memory is not held twice.
        let mut start = start;
        if start > KEEP_IN_FRONT {
            buf.copy_within(start..end, 0);
            start = 0;
        }
        buf.truncate(start + len);
        if buf.capacity() > len.saturating_mul(2).saturating_add(KEEP_IN_FRONT) {
            buf.shrink_to_fit(); // e.g. frame 0 of a long 4-D file
        }
        if big {
            let data = buf.get_mut(start..).unwrap_or_default();
            match kind.size_bytes() {
                2 => data.chunks_exact_mut(2).for_each(|c| c.reverse()),
                4 => data.chunks_exact_mut(4).for_each(|c| c.reverse()),
                _ => {}
            }
        }
        let to_physical = safe_map(
            LinearMap::IDENTITY,
            file_map,
            largest_stored(kind),
            &mut warnings,
        );
        let samples = samples_at(kind, buf, start)?;
        return Ok(Converted {
            samples,
            to_physical,
            warnings,
        });
    }

    let src = buf.get(start..end).unwrap_or_default();
    let name = datatype.name();
    let w = &mut warnings;
    let packed = match datatype {
        Datatype::Int32 => integers(
            src,
            |b: [u8; 4]| i128::from(read_i32(b, big)),
            name,
            w,
            alloc,
        )?,
        Datatype::Uint32 => integers(
            src,
            |b: [u8; 4]| i128::from(read_u32(b, big)),
            name,
            w,
            alloc,
        )?,
        Datatype::Int64 => integers(
            src,
            |b: [u8; 8]| i128::from(read_i64(b, big)),
            name,
            w,
            alloc,
        )?,
        Datatype::Uint64 => integers(
            src,
            |b: [u8; 8]| i128::from(read_u64(b, big)),
            name,
            w,
            alloc,
        )?,
        _ => floats(src, big, w, alloc)?,
    };
    let (out, offset, scale, reach) = (packed.bytes, packed.offset, packed.scale, packed.reach);
    let conversion = LinearMap {
        slope: scale,
        intercept: offset,
    };
    let to_physical = safe_map(conversion, file_map, reach, &mut warnings);
    Ok(Converted {
        samples: samples(SampleKind::F32, out)?,
        to_physical,
        warnings,
    })
}

/// Largest magnitude a stored sample of `kind` can have.
fn largest_stored(kind: SampleKind) -> f64 {
    match kind {
        SampleKind::U8 => 255.0,
        SampleKind::I8 => 128.0,
        SampleKind::U16 => 65535.0,
        SampleKind::I16 => 32768.0,
        SampleKind::F32 => f64::from(f32::MAX),
    }
}

/// Composes the conversion map (offset/scale of convert.rs, identity for native kinds) with the
/// file's scaling. If the result could not represent every stored value in f64 (a NIfTI-2
/// scl_slope near 1e308, say), the file's scaling is dropped with a warning: the map must stay
/// finite with a non-zero slope, and physical values must stay finite.
fn safe_map(
    conversion: LinearMap,
    file: LinearMap,
    reach: f64,
    warnings: &mut Vec<String>,
) -> LinearMap {
    let combined = LinearMap {
        slope: conversion.slope * file.slope,
        intercept: conversion.intercept * file.slope + file.intercept,
    };
    let largest = combined.slope.abs() * reach + combined.intercept.abs();
    if combined.slope.is_finite()
        && combined.slope != 0.0
        && combined.intercept.is_finite()
        && largest.is_finite()
    {
        combined
    } else {
        warnings.push(format!(
            "scl_slope {} with scl_inter {} would take these voxels outside the f64 range, so no scaling is applied",
            file.slope, file.intercept
        ));
        conversion
    }
}

/// Bytes in front of the samples that may stay in their vector (a header and small extensions)
/// instead of being moved out: 1 MiB.
const KEEP_IN_FRONT: usize = 1 << 20;

/// [`samples`] for the bytes of `bytes` from `start` on.
fn samples_at(kind: SampleKind, bytes: Vec<u8>, start: usize) -> Result<Samples, NiftiError> {
    let len = bytes.len().saturating_sub(start);
    Samples::from_le_bytes_at(kind, bytes, start).map_err(|_| NiftiError::TruncatedData {
        file: "file",
        len,
        needed: len.div_ceil(kind.size_bytes()) * kind.size_bytes(),
        offset: 0,
    })
}

fn samples(kind: SampleKind, bytes: Vec<u8>) -> Result<Samples, NiftiError> {
    let len = bytes.len();
    Samples::from_le_bytes(kind, bytes).map_err(|_| NiftiError::TruncatedData {
        file: "file",
        len,
        needed: len.div_ceil(kind.size_bytes()) * kind.size_bytes(),
        offset: 0,
    })
}

fn read_i32(b: [u8; 4], big: bool) -> i32 {
    if big {
        i32::from_be_bytes(b)
    } else {
        i32::from_le_bytes(b)
    }
}
fn read_u32(b: [u8; 4], big: bool) -> u32 {
    if big {
        u32::from_be_bytes(b)
    } else {
        u32::from_le_bytes(b)
    }
}
fn read_i64(b: [u8; 8], big: bool) -> i64 {
    if big {
        i64::from_be_bytes(b)
    } else {
        i64::from_le_bytes(b)
    }
}
fn read_u64(b: [u8; 8], big: bool) -> u64 {
    if big {
        u64::from_be_bytes(b)
    } else {
        u64::from_le_bytes(b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn convert_f64(values: &[f64]) -> Converted {
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let len = bytes.len();
        convert_frame(
            bytes,
            0,
            len,
            Datatype::Float64,
            ByteOrder::LittleEndian,
            0.0,
            0.0,
        )
        .unwrap()
    }

    #[test]
    fn float64_next_to_the_f64_limit_says_which_distinctions_float32_lost() {
        // Ordinary intensities beside +-1.7e308: scaled into f32's range, they underflow to 0.
        let c = convert_f64(&[1.7e308, 1.0, 2.0, 3.0, -1.7e308]);
        let warning = c
            .warnings
            .iter()
            .find(|w| w.contains("stored as float32"))
            .unwrap_or_else(|| panic!("{:?}", c.warnings));
        assert!(warning.contains("2 pairs"), "{warning}");
        for i in 0..5 {
            assert!(c.to_physical.apply(c.samples.get(i)).is_finite());
        }
        // An ordinary float64 volume keeps every distinction: no warning.
        let c = convert_f64(&[1.0, 2.0, 3.5, -7.25, 1e6]);
        assert!(c.warnings.is_empty(), "{:?}", c.warnings);
    }

    #[test]
    fn one_hot_float64_voxel_leaves_the_others_exact() {
        let mut values: Vec<f64> = (0..1000).map(|i| f64::from(i % 300)).collect();
        values[500] = 1e300;
        let c = convert_f64(&values);
        for (i, &x) in values.iter().enumerate() {
            let y = c.to_physical.apply(c.samples.get(i));
            if i == 500 {
                assert_eq!(y, 1e36_f32 as f64);
            } else {
                assert_eq!(y, x, "voxel {i}");
            }
        }
        assert!(
            c.warnings.iter().any(|w| w.contains("clamped")),
            "{:?}",
            c.warnings
        );
    }
}
