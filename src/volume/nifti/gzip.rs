//! gzip detection, bounded inflation of every member, and compression for the writer.
//!
//! Decisions:
//! - gzip is recognised by its magic bytes `1f 8b` alone, never by the file name: `.nii` files
//!   that are really compressed, and `.nii.gz` files that are not, both exist. A NIfTI/ANALYZE
//!   header can never start with `1f 8b` (its first field is 348 or 540).
//! - libdeflate inflates (about 3x faster than flate2's default miniz_oxide, measured when the
//!   loader was written). It needs the output buffer up front, and its safe wrapper does not say
//!   where a member ends, so this module calls `libdeflate_gzip_decompress_ex` through
//!   `libdeflate-sys` to learn each member's compressed length; that is what makes multi-member
//!   files (concatenated `.gz`, bgzip, pigz `--independent`) load whole. Multi-member files are
//!   first tried on several threads (gzip_parallel.rs), with this sequential loop as the fallback
//!   that names errors.
//! - Written files are multi-member ([`WRITE_MEMBER_BYTES`] per member, compressed in
//!   parallel), so what morphray writes, it reads back on every core.
//! - Inflation is bounded by what the header declares, never by the input alone: the caller
//!   passes a [`Limit`] (the header's size, extensions and all frames' voxels, plus
//!   [`TRAILING_SLACK`] bytes for trailing data some writers leave), and [`inflate_within`]
//!   reserves exactly that (or DEFLATE's 1032:1 maximum expansion of the input, when smaller)
//!   and inflates every member into it in one pass. Output past the limit is
//!   [`NiftiError::GzipTooLarge`]; no retry, no doubling, so a 2 MB file that inflates to 2 GB
//!   costs the limit, not 2 GB. Allocation failures are typed errors (`try_reserve`).
//! - The header must be known before the limit: [`peek`] inflates only the first bytes of the
//!   stream (enough for a NIfTI-2 header) with a streaming decoder (flate2's raw DEFLATE,
//!   miniz_oxide; libdeflate cannot stop early), framing members itself like libdeflate (the
//!   optional header CRC16 is skipped, not checked). The voxels are then inflated by libdeflate.
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
/// gives 1032:1. Caps the buffer when the input could not fill the declared size anyway, with
/// 1 KiB of slack for tiny inputs.
const MAX_RATIO: usize = 1032;
const RATIO_SLACK: usize = 1024;

/// Bytes accepted after the size a header declares: room for the trailing bytes some writers
/// leave (block padding), small enough that a damaged file fails fast.
pub const TRAILING_SLACK: usize = 64 * 1024;

/// How many inflated bytes a caller accepts, and whose declaration that is (for the message).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limit {
    /// Bytes declared.
    pub declared: usize,
    /// Bytes accepted after `declared`.
    pub slack: usize,
    /// Whose declaration, completing "more than the N bytes ...": `its header declares`.
    pub what: &'static str,
}

impl Limit {
    /// `declared` bytes plus [`TRAILING_SLACK`].
    pub fn declared(declared: usize, what: &'static str) -> Limit {
        Limit {
            declared,
            slack: TRAILING_SLACK,
            what,
        }
    }

    /// Total bytes accepted.
    pub fn bytes(&self) -> usize {
        self.declared.saturating_add(self.slack)
    }
}

/// True when `bytes` starts with the gzip magic.
pub fn is_gzip(bytes: &[u8]) -> bool {
    bytes.starts_with(&GZIP_MAGIC)
}

/// Owns one libdeflate decompressor (freed on drop).
pub(super) struct Decompressor(NonNull<libdeflate_sys::libdeflate_decompressor>);

/// What one call of libdeflate made of one member.
pub(super) enum RawResult {
    /// Input bytes consumed and output bytes written.
    Done { consumed: usize, written: usize },
    /// The output space was too small.
    NeedsMoreSpace,
    /// The data is corrupt or truncated.
    Bad,
}

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
    pub(super) fn new() -> Result<Self, NiftiError> {
        // SAFETY: plain allocation call with no arguments; a null result is handled.
        let ptr = unsafe { libdeflate_sys::libdeflate_alloc_decompressor() };
        NonNull::new(ptr)
            .map(Decompressor)
            .ok_or(NiftiError::OutOfMemory {
                bytes: 32 * 1024,
                what: "a libdeflate decompressor",
            })
    }

    /// Inflates the first gzip member of `input` into `out`, which may be uninitialised: on
    /// success, exactly the first `written` bytes of `out` are initialised.
    ///
    /// # Safety
    /// `out` must be valid for writes of `out_len` bytes.
    pub(super) unsafe fn inflate_raw(
        &mut self,
        input: &[u8],
        out: *mut u8,
        out_len: usize,
    ) -> RawResult {
        let mut consumed = 0usize;
        let mut written = 0usize;
        // SAFETY: `input` is a valid readable slice; `out` is writable for `out_len` bytes (the
        // caller's contract; libdeflate writes at most `out_nbytes_avail` bytes and never reads
        // the output before writing it); both out-pointers are valid locals. The decompressor
        // pointer came from libdeflate_alloc_decompressor.
        let result = unsafe {
            libdeflate_sys::libdeflate_gzip_decompress_ex(
                self.0.as_ptr(),
                input.as_ptr().cast(),
                input.len(),
                out.cast(),
                out_len,
                &mut consumed,
                &mut written,
            )
        };
        match result {
            libdeflate_sys::libdeflate_result_LIBDEFLATE_SUCCESS
                if written <= out_len && consumed <= input.len() =>
            {
                RawResult::Done { consumed, written }
            }
            libdeflate_sys::libdeflate_result_LIBDEFLATE_INSUFFICIENT_SPACE => {
                RawResult::NeedsMoreSpace
            }
            _ => RawResult::Bad,
        }
    }

    /// Inflates the first gzip member of `input` into the spare capacity of `out`, appending to
    /// it. Never writes beyond `out.capacity()`.
    fn inflate_member(&mut self, input: &[u8], out: &mut Vec<u8>) -> MemberResult {
        let spare = out.spare_capacity_mut();
        // SAFETY: the spare capacity is writable for its length.
        let result = unsafe { self.inflate_raw(input, spare.as_mut_ptr().cast(), spare.len()) };
        match result {
            RawResult::Done { consumed, written } => {
                let new_len = out.len() + written;
                // SAFETY: libdeflate reported success and initialised exactly `written` bytes
                // of the spare capacity, which inflate_raw checked fits.
                unsafe { out.set_len(new_len) };
                MemberResult::Done { consumed }
            }
            RawResult::NeedsMoreSpace => MemberResult::NeedsMoreSpace,
            RawResult::Bad => MemberResult::Bad,
        }
    }
}

impl Drop for Decompressor {
    fn drop(&mut self) {
        // SAFETY: the pointer came from libdeflate_alloc_decompressor and is freed once.
        unsafe { libdeflate_sys::libdeflate_free_decompressor(self.0.as_ptr()) }
    }
}

/// Inflates `bytes` if they start with the gzip magic, into at most `limit.bytes()` bytes;
/// otherwise returns them untouched.
///
/// Returns the inflated bytes and the number of gzip members read (0 when the input was not
/// gzip). All members are inflated and concatenated, in order. More output than the limit is
/// [`NiftiError::GzipTooLarge`].
pub fn inflate_within(bytes: Vec<u8>, limit: Limit) -> Result<(Vec<u8>, usize), NiftiError> {
    if !is_gzip(&bytes) {
        return Ok((bytes, 0));
    }
    let ratio_cap = bytes
        .len()
        .saturating_mul(MAX_RATIO)
        .saturating_add(RATIO_SLACK);
    let capacity = limit.bytes().min(ratio_cap);
    if let Some((mut out, members)) = super::gzip_parallel::inflate_members(&bytes, capacity)? {
        release_slack(&mut out);
        return Ok((out, members));
    }
    let mut decompressor = Decompressor::new()?;
    let mut out = reserve_output(capacity)?;
    let mut pos = 0usize;
    let mut members = 0usize;
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
        let corrupt = NiftiError::GzipCorrupt {
            member: members,
            offset: pos,
        };
        if rest.len() < MIN_MEMBER {
            return Err(corrupt);
        }
        match decompressor.inflate_member(rest, &mut out) {
            // `consumed == 0` cannot happen for a successful member (>= 18 bytes); guards the loop.
            MemberResult::Done { consumed } if consumed > 0 => pos = pos.saturating_add(consumed),
            // Out of room: past the declared size, unless the ratio cap was the smaller one (then
            // the input cannot really expand this far, and the data is corrupt).
            MemberResult::NeedsMoreSpace if capacity == limit.bytes() => {
                return Err(NiftiError::GzipTooLarge {
                    limit: limit.bytes(),
                    declared: limit.declared,
                    slack: limit.slack,
                    what: limit.what,
                });
            }
            _ => return Err(corrupt),
        }
    }
    release_slack(&mut out);
    Ok((out, members))
}

/// An empty vector with room for `capacity` inflated bytes (a typed error when the memory is
/// not there).
pub(super) fn reserve_output(capacity: usize) -> Result<Vec<u8>, NiftiError> {
    let mut out = Vec::new();
    out.try_reserve_exact(capacity)
        .map_err(|_| NiftiError::OutOfMemory {
            bytes: capacity,
            what: "the inflated gzip data",
        })?;
    Ok(out)
}

/// Releases a large over-estimate (a header declaring more than the file holds; the parser
/// then reports the truncation). Small slack is kept.
fn release_slack(out: &mut Vec<u8>) {
    if out.capacity() - out.len() > out.len() / 8 + 4096 {
        out.shrink_to_fit();
    }
}

/// Skips a gzip member's header (RFC 1952: magic, CM = 8, flags, MTIME, XFL, OS, then the
/// optional FEXTRA, FNAME, FCOMMENT and FHCRC fields); returns where its DEFLATE data starts.
/// Like libdeflate, reserved flag bits are an error and the header CRC16 is skipped, not checked.
fn member_data_start(member: &[u8]) -> Option<usize> {
    const FHCRC: u8 = 0x02;
    const FEXTRA: u8 = 0x04;
    const FNAME: u8 = 0x08;
    const FCOMMENT: u8 = 0x10;
    const FRESERVED: u8 = 0xe0;
    let head = member.get(..10)?;
    let flags = head[3];
    if head[..3] != [0x1f, 0x8b, 8] || flags & FRESERVED != 0 {
        return None;
    }
    let mut at = 10usize;
    if flags & FEXTRA != 0 {
        let len = u16::from_le_bytes([*member.get(at)?, *member.get(at + 1)?]);
        at = at.checked_add(2 + usize::from(len))?;
    }
    for flag in [FNAME, FCOMMENT] {
        if flags & flag != 0 {
            let nul = member.get(at..)?.iter().position(|&b| b == 0)?;
            at = at.checked_add(nul + 1)?;
        }
    }
    if flags & FHCRC != 0 {
        at = at.checked_add(2)?;
    }
    (at <= member.len()).then_some(at)
}

/// The first `want` bytes the gzip stream `bytes` inflates to (fewer when the stream holds
/// fewer), inflating no more than that: a streaming decoder stops as soon as it has them.
/// Non-gzip input is returned cut to `want`. Bytes after the last member are not judged here
/// (the full inflation does that); a member that fails to decode before `want` bytes is
/// [`NiftiError::GzipCorrupt`]. Trailers are skipped unchecked (the full inflation checks them).
pub fn peek(bytes: &[u8], want: usize) -> Result<Vec<u8>, NiftiError> {
    use std::io::Read;
    if !is_gzip(bytes) {
        return Ok(bytes.get(..want).unwrap_or(bytes).to_vec());
    }
    let mut out = Vec::with_capacity(want);
    let mut pos = 0usize;
    let mut members = 0usize;
    while out.len() < want {
        let rest = bytes.get(pos..).unwrap_or_default();
        if !is_gzip(rest) {
            break;
        }
        members += 1;
        let corrupt = |offset| NiftiError::GzipCorrupt {
            member: members,
            offset,
        };
        let data = member_data_start(rest)
            .and_then(|at| rest.get(at..))
            .ok_or(corrupt(pos))?;
        let need = want - out.len();
        let mut decoder = flate2::bufread::DeflateDecoder::new(data);
        let got = (&mut decoder)
            .take(need as u64)
            .read_to_end(&mut out)
            .map_err(|_| corrupt(pos))?;
        if got >= need {
            break;
        }
        // The member's DEFLATE stream ended: skip its 8-byte trailer (CRC-32, ISIZE).
        let after = decoder.into_inner();
        if after.len() < 8 {
            return Err(corrupt(pos));
        }
        pos = bytes.len() - after.len() + 8;
    }
    Ok(out)
}

/// Uncompressed bytes per member of the files morphray writes: 1 MiB members inflate on
/// separate threads (gzip_parallel.rs; the 25 MB default phantom becomes 25 members, enough for
/// 16 cores) and cost 0.17 % in size on that phantom (each member restarts the 32 KiB window
/// and adds 18 bytes of framing; zlib level 6 in Python: 13,384,829 bytes against 13,362,317
/// as one member, 4 MiB members 13,377,179).
pub const WRITE_MEMBER_BYTES: usize = 1 << 20;

/// Compresses `data` as consecutive gzip members of [`WRITE_MEMBER_BYTES`] each (one member
/// when smaller), compressed on several threads; any gzip reader inflates the concatenation
/// to `data`.
pub fn gzip_compress(data: &[u8]) -> Result<Vec<u8>, NiftiError> {
    let pieces: Vec<&[u8]> = if data.is_empty() {
        vec![data]
    } else {
        data.chunks(WRITE_MEMBER_BYTES).collect()
    };
    let compressed: Vec<std::sync::Mutex<Vec<u8>>> = pieces
        .iter()
        .map(|_| std::sync::Mutex::new(Vec::new()))
        .collect();
    let threads = crate::files::parallel::thread_budget();
    crate::files::parallel::for_each_index(
        pieces.len(),
        threads,
        || Ok::<(), NiftiError>(()),
        |_, i| {
            let member = gzip_compress_member(pieces[i])?;
            if let Ok(mut slot) = compressed[i].lock() {
                *slot = member;
            }
            Ok(())
        },
    )?;
    let mut out = Vec::new();
    for slot in compressed {
        let member = slot.into_inner().map_err(|_| NiftiError::Unwritable {
            what: "the volume".into(),
            why: "a compression thread failed".into(),
        })?;
        out.try_reserve(member.len())
            .map_err(|_| NiftiError::OutOfMemory {
                bytes: member.len(),
                what: "the gzip-compressed output",
            })?;
        out.extend_from_slice(&member);
    }
    Ok(out)
}

/// Compresses `data` as one gzip member (libdeflate, level 6: the usual speed/size balance).
pub fn gzip_compress_member(data: &[u8]) -> Result<Vec<u8>, NiftiError> {
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
