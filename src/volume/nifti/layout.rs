//! Where the voxels are and how many bytes the header declares: the size checks that come
//! before any allocation for samples or inflated data.
//!
//! Decisions:
//! - Dims above `dim[0]` are ignored; missing spatial dims are 1; dims 4..7 multiply into
//!   frames; every product is checked, so no header can overflow the arithmetic.
//! - vox_offset must be finite, whole and >= 0; a single file's offset below 352 (NIfTI-1) or
//!   544 (NIfTI-2) is raised to that minimum with a warning, as the standard says. An offset of
//!   2^63 or more is beyond any file and is its own error (never printed as a saturated usize).
//! - [`plan`] needs only the header, so the same numbers bound gzip inflation ([`declared_len`],
//!   before the voxels are inflated) and check the data's length (in `build`, after).

use super::datatype::Datatype;
use super::error::NiftiError;
use super::header::Decoded;

/// Validated sizes.
pub(crate) struct Layout {
    /// `dim[1..=dim[0]]`.
    pub dims: Vec<usize>,
    /// The three spatial dims (1 where absent).
    pub dims3: [usize; 3],
    /// Product of dims 4..=`dim[0]`.
    pub frames: usize,
    /// Bytes of one frame.
    pub frame_bytes: usize,
    /// Byte position of the voxels (after the minimum-offset rule).
    pub offset: usize,
    /// Bytes of voxels of every frame.
    pub total: usize,
    /// `offset + total`: the bytes the header declares for its data (file or image file).
    pub end: usize,
}

/// The datatype and its bytes per voxel, or the named error for unknown and unsupported codes.
pub(crate) fn datatype_of(decoded: &Decoded) -> Result<(Datatype, usize), NiftiError> {
    let code = decoded.header.datatype;
    let datatype = Datatype::from_code(code).ok_or(NiftiError::UnknownDatatype { code })?;
    let bytes_per_voxel = datatype
        .bytes_per_voxel()
        .ok_or(NiftiError::UnsupportedDatatype {
            name: datatype.name(),
            code,
        })?;
    Ok((datatype, bytes_per_voxel))
}

/// Offsets at or beyond 2^63 cannot be in any file (file sizes are signed 64-bit).
const BEYOND_ANY_FILE: f64 = 9_223_372_036_854_775_808.0;

/// Validates dims, bitpix and vox_offset of `decoded` (with `bytes_per_voxel` of its datatype)
/// and computes where the voxels are. `pair`: the offset counts from the start of an `.img`.
pub(crate) fn plan(
    decoded: &Decoded,
    datatype: Datatype,
    bytes_per_voxel: usize,
    pair: bool,
    warnings: &mut Vec<String>,
) -> Result<Layout, NiftiError> {
    let h = &decoded.header;
    let dim0 = usize::try_from(h.dim[0]).unwrap_or(0).min(7);
    let mut dims = Vec::with_capacity(dim0);
    for axis in 1..=dim0 {
        let value = h.dim.get(axis).copied().unwrap_or(0);
        if value < 1 {
            return Err(NiftiError::BadDim { axis, value });
        }
        dims.push(value);
    }
    let overflow = || NiftiError::SizeOverflow {
        dims: dims.clone(),
        bytes_per_voxel,
    };
    let as_usize: Vec<usize> = dims
        .iter()
        .map(|&d| usize::try_from(d))
        .collect::<Result<_, _>>()
        .map_err(|_| overflow())?;
    let dims3 = [
        as_usize.first().copied().unwrap_or(1),
        as_usize.get(1).copied().unwrap_or(1),
        as_usize.get(2).copied().unwrap_or(1),
    ];
    let product = |v: &[usize]| v.iter().try_fold(1usize, |acc, &d| acc.checked_mul(d));
    let voxels = product(&dims3).ok_or_else(overflow)?;
    let frames = product(as_usize.get(3..).unwrap_or_default()).ok_or_else(overflow)?;
    let frame_bytes = voxels.checked_mul(bytes_per_voxel).ok_or_else(overflow)?;
    let total = frame_bytes.checked_mul(frames).ok_or_else(overflow)?;

    if h.bitpix != datatype.bitpix() {
        warnings.push(format!(
            "bitpix is {} but datatype {} has {} bits per voxel; the datatype is trusted",
            h.bitpix,
            datatype.name(),
            datatype.bitpix()
        ));
    }

    let raw = h.vox_offset;
    if !raw.is_finite() || raw.fract() != 0.0 || raw < 0.0 {
        return Err(NiftiError::BadVoxOffset { value: raw });
    }
    let beyond = NiftiError::VoxOffsetBeyondAnyFile { value: raw };
    if raw >= BEYOND_ANY_FILE {
        return Err(beyond);
    }
    // Exact: raw is a whole number below 2^63.
    let read = usize::try_from(raw as u64).map_err(|_| beyond)?;
    let minimum = if pair {
        0
    } else {
        decoded.version.header_len() + 4
    };
    let offset = if read < minimum {
        warnings.push(format!(
            "vox_offset {raw} is below {minimum}, the first byte after a {} header and its extender; the voxels are read from byte {minimum}",
            decoded.version.label()
        ));
        minimum
    } else {
        read
    };
    let end = offset.checked_add(total).ok_or_else(overflow)?;
    Ok(Layout {
        dims: as_usize,
        dims3,
        frames,
        frame_bytes,
        offset,
        total,
        end,
    })
}

/// The bytes `decoded` declares for the data it describes: for a single file the whole file
/// (header, extensions, voxels of every frame), for a pair the `.img`. Errors are the same as
/// the full parse would give for this header, so a bad header is reported before inflation.
pub(crate) fn declared_len(decoded: &Decoded, pair: bool) -> Result<usize, NiftiError> {
    let (datatype, bytes_per_voxel) = datatype_of(decoded)?;
    Ok(plan(decoded, datatype, bytes_per_voxel, pair, &mut Vec::new())?.end)
}
