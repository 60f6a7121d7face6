//! Inflation bounded by the header: how many inflated bytes a file may have is what its header
//! declares, learnt from the first bytes of the stream before the rest is inflated.
//!
//! Decisions:
//! - A stream that starts with a header (`.nii.gz`, `.hdr.gz`): [`gzip::peek`] inflates only its
//!   first [`PEEK_LEN`] bytes (a NIfTI-2 header and its extender), the header is decoded and
//!   validated (dims, datatype, vox_offset: the same errors the full parse gives), and the limit
//!   is what it declares: for a single file the header, extensions and every frame's voxels
//!   (`vox_offset` + data), for a `.hdr` (pair magic) [`HEADER_FILE_LIMIT`], room for the header
//!   and any extensions. Then libdeflate inflates within that limit plus
//!   [`gzip::TRAILING_SLACK`].
//! - A stream shorter than [`PEEK_LEN`] is inflated within that length, so tiny files keep the
//!   exact errors of the full inflation (trailing garbage, corrupt member).
//! - The `.img` of a pair ([`inflate_image`]) is bounded by what its `.hdr` declares.
//! - Non-gzip bytes pass through untouched, whatever they are (the parser judges them), once
//!   their conversion (about as many bytes again) is known to fit in available memory.
//! - Before inflating, twice the declared size (the inflated bytes, and the samples converted
//!   from them) plus the compressed bytes must fit in the host's available memory
//!   (`host_memory::check`): a refusal names both numbers instead of the OOM killer acting.

use super::error::NiftiError;
use super::gzip::{self, Limit};
use super::header::{self, Decoded, NIFTI2_HEADER_LEN, Storage};
use super::layout::declared_len;

/// Bytes inflated before the limit is known: the largest fixed header (NIfTI-2) and its
/// four extender bytes.
pub const PEEK_LEN: usize = NIFTI2_HEADER_LEN + 4;

/// Most bytes a `.hdr` (pair magic) may inflate to: the header plus 16 MiB of extensions. A
/// `.hdr` declares no size of its own, so this is a fixed, generous cap: extensions are
/// metadata, and a header file inflating past it is refused rather than trusted.
pub const HEADER_FILE_LIMIT: usize = NIFTI2_HEADER_LEN + 4 + (16 << 20);

/// The limit for a stream that starts with the header `decoded`.
pub fn header_limit(decoded: &Decoded) -> Result<Limit, NiftiError> {
    Ok(match decoded.storage {
        Storage::SingleFile => {
            Limit::declared(declared_len(decoded, false)?, "its header declares")
        }
        Storage::Pair => Limit {
            declared: HEADER_FILE_LIMIT,
            slack: 0,
            what: "a header file may hold (header and extensions)",
        },
    })
}

/// The limit for the `.img` of the pair whose header is `decoded`.
pub fn image_limit(decoded: &Decoded) -> Result<Limit, NiftiError> {
    Ok(Limit::declared(
        declared_len(decoded, true)?,
        "the .hdr declares for its image",
    ))
}

/// Inflates `bytes` if they are gzip, within the size declared by the header they start with
/// (see the module's decisions); otherwise returns them untouched. Returns the bytes and the
/// number of gzip members (0: not gzip). Errors: the gzip ones, [`NiftiError::GzipTooLarge`]
/// past the limit, and the header's own errors when its first bytes are not a valid header.
pub fn inflate_if_gzip(bytes: Vec<u8>) -> Result<(Vec<u8>, usize), NiftiError> {
    if !gzip::is_gzip(&bytes) {
        converts_in_memory(bytes.len())?;
        return Ok((bytes, 0));
    }
    let prefix = gzip::peek(&bytes, PEEK_LEN)?;
    let limit = if prefix.len() < PEEK_LEN {
        // The whole stream is this short: inflate it within that, header or not.
        Limit {
            declared: prefix.len(),
            slack: PEEK_LEN - prefix.len(),
            what: "a first streaming pass found in it",
        }
    } else {
        header_limit(&header::decode(&prefix)?)?
    };
    fits_in_memory(&limit, bytes.len())?;
    gzip::inflate_within(bytes, limit)
}

/// Refuses an inflation whose declared result, converted, cannot fit in available memory.
fn fits_in_memory(limit: &Limit, compressed: usize) -> Result<(), NiftiError> {
    let needed = (limit.declared as u64)
        .saturating_mul(2)
        .saturating_add(compressed as u64);
    crate::volume::host_memory::check(
        needed,
        &format!(
            "inflating the {} {}",
            crate::volume::host_memory::human(limit.declared as u64),
            limit.what
        ),
    )
    .map_err(NiftiError::NotEnoughMemory)
}

/// Refuses an uncompressed image of `len` bytes (already read) whose conversion, about as much
/// again, cannot fit in available memory.
fn converts_in_memory(len: usize) -> Result<(), NiftiError> {
    crate::volume::host_memory::check(
        len as u64,
        &format!(
            "converting the {} uncompressed image",
            crate::volume::host_memory::human(len as u64)
        ),
    )
    .map_err(NiftiError::NotEnoughMemory)
}

/// Inflates the `.img` bytes of the pair whose header is `decoded`, within the size that header
/// declares for it (validating the header's sizes first); non-gzip bytes pass through.
pub fn inflate_image(bytes: Vec<u8>, decoded: &Decoded) -> Result<(Vec<u8>, usize), NiftiError> {
    if !gzip::is_gzip(&bytes) {
        converts_in_memory(bytes.len())?;
        return Ok((bytes, 0));
    }
    let limit = image_limit(decoded)?;
    fits_in_memory(&limit, bytes.len())?;
    gzip::inflate_within(bytes, limit)
}
