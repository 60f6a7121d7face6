//! gzip detection, inflation of every member, and compression for the writer.
//!
//! Decisions:
//! - gzip is recognised by its magic bytes `1f 8b` alone, never by the file name: `.nii` files
//!   that are really compressed, and `.nii.gz` files that are not, both exist. A NIfTI/ANALYZE
//!   header can never start with `1f 8b` (its first field is 348 or 540).
//! - libdeflate inflates (FACTS.md: about 3x faster than flate2's default miniz_oxide). It needs
//!   the output size up front, and its safe wrapper does not say where a member ends, so this
//!   module calls `libdeflate_gzip_decompress_ex` through `libdeflate-sys` to learn each
//!   member's compressed length; that is what makes multi-member files (concatenated `.gz`,
//!   bgzip, pigz `--independent`) load whole.
//! - Allocation is bounded by the input, never by a header: a DEFLATE stream expands at most
//!   about 1032:1, so a member's output buffer never grows beyond `1032 * remaining input + 1 KiB`.
//!   The first guess is the ISIZE trailer (the last four bytes: the last member's size mod 2^32,
//!   exact for the usual single-member file); when a guess is too small it is doubled (each retry
//!   re-inflates that member; libdeflate has no resumable state). Allocation failures are typed
//!   errors (`try_reserve`), not aborts.
//! - After the last member, zero bytes are accepted as padding (as gzip(1) and Python do); any
//!   other trailing byte is an error, because silently ignoring data hides truncated uploads.
//! - Truncated and corrupt members cannot be told apart reliably from libdeflate's result, so
//!   both produce [`NiftiError::GzipCorrupt`] naming the member and its byte offset.

use super::error::NiftiError;
use std::ptr::NonNull;

/// The first two bytes of every gzip member (RFC 1952).
pub const GZIP_MAGIC: [u8; 2] = [0x1f, 0x8b];

/// A member is at least a 10-byte header plus an 8-byte trailer.
const MIN_MEMBER: usize = 18;

/// Upper bound on DEFLATE's expansion: 258 bytes per length/distance code of at least 2 bits
/// gives 1032:1. Used as a hard cap, with 1 KiB of slack for tiny inputs.
const MAX_RATIO: usize = 1032;
const SLACK: usize = 1024;

/// True when `bytes` starts with the gzip magic.
pub fn is_gzip(bytes: &[u8]) -> bool {
    bytes.starts_with(&GZIP_MAGIC)
}

/// Owns one libdeflate decompressor (freed on drop).
struct Decompressor(NonNull<libdeflate_sys::libdeflate_decompressor>);

/// Result of inflating one member into spare capacity.
enum MemberResult {
    /// Bytes of input consumed (the output was appended to the vector).
    Done { consumed: usize },
    /// The output space was too small.
    NeedsMoreSpace,
    /// The data is corrupt or truncated.
    Bad,
}

impl Decompressor {
    fn new() -> Result<Self, NiftiError> {
        // SAFETY: plain allocation call with no arguments; a null result is handled.
        let ptr = unsafe { libdeflate_sys::libdeflate_alloc_decompressor() };
        NonNull::new(ptr)
            .map(Decompressor)
            .ok_or(NiftiError::OutOfMemory {
                bytes: 32 * 1024,
                what: "a libdeflate decompressor",
            })
    }

    /// Inflates the first gzip member of `input` into the spare capacity of `out`, appending to
    /// it. Never writes beyond `out.capacity()`.
    fn inflate_member(&mut self, input: &[u8], out: &mut Vec<u8>) -> MemberResult {
        let spare = out.spare_capacity_mut();
        let mut consumed = 0usize;
        let mut written = 0usize;
        // SAFETY: `input` is a valid readable slice; `spare` is writable memory of exactly
        // `spare.len()` bytes owned by `out` (libdeflate writes at most `out_nbytes_avail`
        // bytes and never reads the output before writing it); both out-pointers are valid
        // locals. The decompressor pointer came from libdeflate_alloc_decompressor.
        let result = unsafe {
            libdeflate_sys::libdeflate_gzip_decompress_ex(
                self.0.as_ptr(),
                input.as_ptr().cast(),
                input.len(),
                spare.as_mut_ptr().cast(),
                spare.len(),
                &mut consumed,
                &mut written,
            )
        };
        match result {
            libdeflate_sys::libdeflate_result_LIBDEFLATE_SUCCESS
                if written <= spare.len() && consumed <= input.len() =>
            {
                let new_len = out.len() + written;
                // SAFETY: libdeflate reported success and initialised exactly `written` bytes
                // of the spare capacity, which we checked fits.
                unsafe { out.set_len(new_len) };
                MemberResult::Done { consumed }
            }
            libdeflate_sys::libdeflate_result_LIBDEFLATE_INSUFFICIENT_SPACE => {
                MemberResult::NeedsMoreSpace
            }
            _ => MemberResult::Bad,
        }
    }
}

impl Drop for Decompressor {
    fn drop(&mut self) {
        // SAFETY: the pointer came from libdeflate_alloc_decompressor and is freed once.
        unsafe { libdeflate_sys::libdeflate_free_decompressor(self.0.as_ptr()) }
    }
}

/// Makes sure `out` has at least `extra` bytes of spare capacity.
fn reserve(out: &mut Vec<u8>, extra: usize) -> Result<(), NiftiError> {
    out.try_reserve_exact(extra)
        .map_err(|_| NiftiError::OutOfMemory {
            bytes: out.len().saturating_add(extra),
            what: "the inflated gzip data",
        })
}

/// Inflates `bytes` if they start with the gzip magic; otherwise returns them untouched.
///
/// Returns the inflated bytes and the number of gzip members read (0 when the input was not
/// gzip). All members are inflated and concatenated, in order.
pub fn inflate_if_gzip(bytes: Vec<u8>) -> Result<(Vec<u8>, usize), NiftiError> {
    if !is_gzip(&bytes) {
        return Ok((bytes, 0));
    }
    let mut decompressor = Decompressor::new()?;
    let mut out: Vec<u8> = Vec::new();
    let mut pos = 0usize;
    let mut members = 0usize;
    // ISIZE of the last member: exact for single-member files (below 4 GiB).
    let trailer_isize = bytes
        .len()
        .checked_sub(4)
        .and_then(|at| bytes.get(at..))
        .and_then(|s| <[u8; 4]>::try_from(s).ok())
        .map_or(0, |b| u32::from_le_bytes(b) as usize);

    while pos < bytes.len() {
        let rest = bytes.get(pos..).unwrap_or_default();
        if !is_gzip(rest) {
            if rest.iter().all(|&b| b == 0) {
                break; // zero padding after the last member
            }
            return Err(NiftiError::GzipTrailingGarbage {
                offset: pos,
                len: rest.len(),
            });
        }
        members += 1;
        if rest.len() < MIN_MEMBER {
            return Err(NiftiError::GzipCorrupt {
                member: members,
                offset: pos,
            });
        }
        let bound = rest.len().saturating_mul(MAX_RATIO).saturating_add(SLACK);
        // First member: trust ISIZE as a hint (capped by the bound). Later members: a guess
        // proportional to their compressed size; doubling fixes an underestimate.
        let mut guess = if members == 1 && trailer_isize > 0 {
            trailer_isize.min(bound)
        } else {
            rest.len().saturating_mul(4).max(64 * 1024).min(bound)
        };
        loop {
            reserve(&mut out, guess)?;
            match decompressor.inflate_member(rest, &mut out) {
                MemberResult::Done { consumed } => {
                    if consumed == 0 {
                        // Cannot happen for a successful member (>= 18 bytes); guards the loop.
                        return Err(NiftiError::GzipCorrupt {
                            member: members,
                            offset: pos,
                        });
                    }
                    pos = pos.saturating_add(consumed);
                    break;
                }
                MemberResult::NeedsMoreSpace if guess < bound => {
                    // `reserve` may have given more than asked; grow from what is available.
                    let available = out.capacity() - out.len();
                    guess = available.max(guess).saturating_mul(2).min(bound);
                }
                MemberResult::NeedsMoreSpace | MemberResult::Bad => {
                    return Err(NiftiError::GzipCorrupt {
                        member: members,
                        offset: pos,
                    });
                }
            }
        }
    }
    // Release a large over-estimate (for example a wrong ISIZE hint); small slack is kept.
    if out.capacity() - out.len() > out.len() / 8 + 4096 {
        out.shrink_to_fit();
    }
    Ok((out, members))
}

/// Compresses `data` as one gzip member (libdeflate, level 6: the usual speed/size balance).
pub fn gzip_compress(data: &[u8]) -> Result<Vec<u8>, NiftiError> {
    let level = libdeflater::CompressionLvl::default();
    let mut compressor = libdeflater::Compressor::new(level);
    let bound = compressor.gzip_compress_bound(data.len());
    let mut out = Vec::new();
    out.try_reserve_exact(bound)
        .map_err(|_| NiftiError::OutOfMemory {
            bytes: bound,
            what: "the gzip-compressed output",
        })?;
    out.resize(bound, 0);
    let written = compressor
        .gzip_compress(data, &mut out)
        .map_err(|_| NiftiError::Unwritable {
            what: "the volume".into(),
            why: "libdeflate could not compress the data".into(),
        })?;
    out.truncate(written);
    Ok(out)
}
