//! Voxel bytes of one frame to [`Samples`] plus the stored-to-physical [`LinearMap`].
//!
//! Decisions:
//! - u8, i8, u16, i16, f32 keep their encoding. The frame is moved to the front of the buffer it
//!   was read into (one `memmove`, no second allocation; none at all when the voxels already start
//!   at byte 0) and byte-swapped in place when big-endian. That is the single copy of the voxels.
//! - int32, uint32, int64, uint64, float64 are converted to f32 into a new buffer (the single
//!   copy), after subtracting an offset chosen in f64 / i128 so that f32 keeps the spread of the
//!   data: `stored = (x - offset) / scale`. Offset: integers whose finite range lies within
//!   +-2^24 (exact in f32) get none; other integers get the integer midpoint of their range
//!   (exact in i128); floats get the midpoint only when the data sits far from zero relative to
//!   its spread (|midpoint| > 64 * half-range, e.g. 1e30 + tiny), because subtracting a midpoint
//!   from data that straddles or approaches zero would destroy small values. Scale is 1 unless
//!   the centred data would overflow f32 (beyond 1e36), then a power of two (exact).
//!   The map absorbs both: `physical = stored * (scale * slope) + (offset * slope + inter)`.
//! - NaN and infinities stay (f32 can hold them); they are excluded from the offset's range.
//! - RGB24 / RGBA32 become f32 luminance with the Rec. 709 weights 0.2126 R + 0.7152 G +
//!   0.0722 B (alpha ignored), never scaled by scl_slope, with a warning.
//! - Scaling (NIFTI.md point 5): scl_slope 0 or non-finite means no scaling at all (NaN and
//!   infinities also warn; 0 is the standard's "unused"); a non-finite scl_inter with a usable
//!   slope is replaced by 0 with a warning. A finite scaling that would push some stored value
//!   outside the f64 range (only NIfTI-2's f64 fields can) is dropped with a warning, so the map
//!   and every physical value stay finite.

use super::datatype::Datatype;
use super::error::NiftiError;
use super::header::ByteOrder;
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
    let (out, offset, scale, reach) = match datatype {
        Datatype::Int32 => integers(src, |b: [u8; 4]| i128::from(read_i32(b, big)))?,
        Datatype::Uint32 => integers(src, |b: [u8; 4]| i128::from(read_u32(b, big)))?,
        Datatype::Int64 => integers(src, |b: [u8; 8]| i128::from(read_i64(b, big)))?,
        Datatype::Uint64 => integers(src, |b: [u8; 8]| i128::from(read_u64(b, big)))?,
        _ => floats(src, big)?,
    };
    if datatype == Datatype::Float64 {
        precision_warning(src, &out, big, &mut warnings);
    }
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

/// Iterates fixed-size chunks of `src` as arrays.
fn arrays<const N: usize>(src: &[u8]) -> impl Iterator<Item = [u8; N]> + '_ {
    src.chunks_exact(N).map(|c| {
        let mut a = [0u8; N];
        a.copy_from_slice(c);
        a
    })
}

/// Integer datatypes to f32 with an exact integer offset. Returns (bytes, offset, scale, largest
/// |stored|).
fn integers<const N: usize>(
    src: &[u8],
    read: impl Fn([u8; N]) -> i128,
) -> Result<(Vec<u8>, f64, f64, f64), NiftiError> {
    let (mut lo, mut hi) = (i128::MAX, i128::MIN);
    for x in arrays::<N>(src).map(&read) {
        lo = lo.min(x);
        hi = hi.max(x);
    }
    const EXACT: i128 = 1 << 24;
    let offset: i128 = if lo > hi || (lo >= -EXACT && hi <= EXACT) {
        0
    } else {
        lo + (hi - lo) / 2
    };
    let mut out = alloc(src.len() / N * 4)?;
    // The reach is measured on the f32 values written, not on the exact integers: rounding to
    // f32 can move a value up by half an ulp, and `safe_map` must bound what is stored.
    let mut reach = 0.0f64;
    for x in arrays::<N>(src).map(&read) {
        let stored = (x - offset) as f32;
        reach = reach.max(f64::from(stored).abs());
        out.extend_from_slice(&stored.to_le_bytes());
    }
    Ok((out, offset as f64, 1.0, reach))
}

/// Says so when storing float64 as f32 lost distinctions the data had: neighbouring voxels (in
/// file order) with different finite float64 values whose f32 values are equal. Either f32's
/// 24-bit rounding at the data's reach, or underflow of small values once data reaching 1e308
/// is scaled into f32's range; both lose less than 2^-23 of the range, below I_norm's 1/65536,
/// so the warning says the image is unaffected and the exact values are not kept.
fn precision_warning(src: &[u8], out: &[u8], big: bool, warnings: &mut Vec<String>) {
    let read = |b: [u8; 8]| {
        if big {
            f64::from_be_bytes(b)
        } else {
            f64::from_le_bytes(b)
        }
    };
    let originals = arrays::<8>(src).map(read);
    let stored = arrays::<4>(out).map(f32::from_le_bytes);
    let mut previous: Option<(f64, f32)> = None;
    let (mut merged, mut reach) = (0usize, 0.0f64);
    for (x, y) in originals.zip(stored) {
        if !x.is_finite() {
            previous = None;
            continue;
        }
        reach = reach.max(x.abs());
        if let Some((px, py)) = previous
            && px != x
            && py == y
        {
            merged += 1;
        }
        previous = Some((x, y));
    }
    if merged > 0 {
        warnings.push(format!(
            "float64 voxels are stored as float32: {merged} pairs of neighbouring voxels with \
             different values became equal (the data reaches {reach:e}); the differences lost \
             are below 1/65536 of the intensity range, so I_norm and the image do not change, \
             but the float64 values are not kept exactly"
        ));
    }
}

/// float64 to f32 with the offset/scale rule of the module doc. Returns (bytes, offset, scale,
/// largest |stored|).
fn floats(src: &[u8], big: bool) -> Result<(Vec<u8>, f64, f64, f64), NiftiError> {
    let read = |b: [u8; 8]| {
        if big {
            f64::from_be_bytes(b)
        } else {
            f64::from_le_bytes(b)
        }
    };
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for x in arrays::<8>(src).map(read).filter(|x| x.is_finite()) {
        lo = lo.min(x);
        hi = hi.max(x);
    }
    let (offset, scale) = if lo <= hi {
        // Halves first: (lo + hi) could overflow for values near f64::MAX.
        let mid = lo / 2.0 + hi / 2.0;
        let half = hi / 2.0 - lo / 2.0;
        let offset = if mid.abs() > 64.0 * half { mid } else { 0.0 };
        // Finite: with an offset, |x - mid| <= half; without one, |x| <= max(|lo|, |hi|).
        let reach = (hi - offset).abs().max((lo - offset).abs());
        let mut scale = 1.0f64;
        // Powers of two: dividing by them is exact, and the loop runs at most ~60 times.
        while reach.is_finite() && reach / scale > 1e36 {
            scale *= 65536.0;
        }
        (offset, scale)
    } else {
        (0.0, 1.0)
    };
    let mut out = alloc(src.len() / 8 * 4)?;
    let mut stored_reach = 0.0f64;
    for x in arrays::<8>(src).map(read) {
        let mut stored = ((x - offset) / scale) as f32;
        // Found by fuzzing: for |x| within half an f32 ulp of f64::MAX, rounding to f32 moves
        // the stored value past x, and `stored * scale + offset` overflows to infinity. One
        // f32 step toward zero (an error no larger than the rounding itself) keeps it finite.
        if x.is_finite() && !(f64::from(stored) * scale + offset).is_finite() {
            stored = f32::from_bits(stored.to_bits().saturating_sub(1));
        }
        if stored.is_finite() {
            stored_reach = stored_reach.max(f64::from(stored).abs());
        }
        out.extend_from_slice(&stored.to_le_bytes());
    }
    Ok((out, offset, scale, stored_reach))
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
        assert!(warning.contains("do not change"), "{warning}");
        for i in 0..5 {
            assert!(c.to_physical.apply(c.samples.get(i)).is_finite());
        }
        // An ordinary float64 volume keeps every distinction: no warning.
        let c = convert_f64(&[1.0, 2.0, 3.5, -7.25, 1e6]);
        assert!(c.warnings.is_empty(), "{:?}", c.warnings);
    }
}
