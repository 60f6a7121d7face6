//! Multi-member gzip (pigz `--independent` files split by tools, bgzip/BGZF, concatenated `.gz`,
//! and every `.nii.gz` morphray writes) inflated on several threads.
//!
//! Decisions:
//! - Why: one thread of libdeflate inflated the 134 M-voxel phantom (268 MB) in 790 ms on the
//!   H100 machine, 70 % of its first pixel (benches/results/h100-2026-11-24-scaling). Members
//!   are independent DEFLATE streams, so they inflate in parallel when each one's place in the
//!   output is known.
//! - Where members start is found by searching the compressed bytes for a member header
//!   (`1f 8b 08`, no reserved flag bits, a known XFL and OS byte); where each one's output goes
//!   comes from the ISIZE field of the previous member's trailer, the 4 bytes before the next
//!   header. A search can also hit those bytes inside compressed data, so nothing is trusted:
//!   every member must inflate with libdeflate (which checks its CRC-32 and ISIZE), consume
//!   exactly the bytes up to the next candidate, and write exactly the ISIZE bytes. When all of
//!   them do, the chain from byte 0 is exactly the one the sequential loop finds (each member
//!   ends where the next begins, by induction from the first), so the result is the same.
//!   When any does not (a false candidate, damage, a member over 4 GiB whose ISIZE wrapped),
//!   this returns `None` and the caller inflates sequentially, which gives the exact error.
//! - The last member's size is not written anywhere before it, so it gets the rest of the
//!   caller's capacity (the header's declared size plus slack, as sequentially); zero bytes
//!   after it are padding, as sequentially; anything else falls back.
//! - A single-member file (gzip(1), most `.nii.gz` from other tools) cannot be split this way;
//!   it goes the sequential path at one thread's speed. That bound is stated in BENCHMARKS.md.

use super::error::NiftiError;
use super::gzip::{Decompressor, RawResult, is_gzip, reserve_output};
use crate::files::parallel::{Dest, for_each_index, thread_budget};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Bytes of the smallest member: a 10-byte header and an 8-byte trailer.
const MIN_MEMBER: usize = 18;

/// Where the members of `bytes` (gzip data starting at byte 0) start, by header search: 0 and
/// every later position that looks like a member header at least [`MIN_MEMBER`] bytes after
/// the previous one. Candidates, not facts: see the module's decisions.
pub fn member_candidates(bytes: &[u8]) -> Vec<usize> {
    let mut starts = vec![0usize];
    for at in memchr::memmem::find_iter(bytes, &[0x1f, 0x8b, 0x08]) {
        let last = starts.last().copied().unwrap_or(0);
        if at >= last + MIN_MEMBER && looks_like_member_header(bytes.get(at..).unwrap_or_default())
        {
            starts.push(at);
        }
    }
    starts
}

/// The fixed part of a member header: magic, CM 8, no reserved flag bits, XFL 0/2/4 and an OS
/// byte gzip defines (0-13) or 255 (unknown).
fn looks_like_member_header(head: &[u8]) -> bool {
    match head.get(..10) {
        Some(h) => {
            is_gzip(h)
                && h[2] == 8
                && h[3] & 0xe0 == 0
                && matches!(h[8], 0 | 2 | 4)
                && (h[9] <= 13 || h[9] == 255)
        }
        None => false,
    }
}

/// Inflates every member of `bytes` into one vector of at most `capacity` bytes, on several
/// threads. `Ok(None)`: not several members, one thread only, or the candidates did not
/// verify; the caller then inflates sequentially. Errors: only running out of memory.
pub fn inflate_members(
    bytes: &[u8],
    capacity: usize,
) -> Result<Option<(Vec<u8>, usize)>, NiftiError> {
    let threads = thread_budget();
    if threads <= 1 {
        return Ok(None);
    }
    let starts = member_candidates(bytes);
    let members = starts.len();
    if members < 2 {
        return Ok(None);
    }
    let Some(offsets) = output_offsets(bytes, &starts, capacity) else {
        return Ok(None);
    };
    let mut out = reserve_output(capacity)?;
    let dest = Dest(out.spare_capacity_mut().as_mut_ptr().cast());
    let last_written = AtomicUsize::new(0);
    let verified = for_each_index(
        members,
        threads.min(members),
        || Decompressor::new().map_err(Some),
        |decompressor, i| {
            let member = Member::new(bytes, &starts, &offsets, capacity, i);
            // SAFETY: `member.out` lies within the reserved capacity (output_offsets checked
            // the prefix sums against it), and members' output ranges are disjoint.
            let result = unsafe {
                decompressor.inflate_raw(member.input, dest.at(member.out.start), member.out.len())
            };
            match member.check(result, bytes) {
                Some(written) => {
                    if i + 1 == members {
                        last_written.store(written, Ordering::Relaxed);
                    }
                    Ok(())
                }
                None => Err(None),
            }
        },
    );
    match verified {
        Ok(()) => {}
        Err(None) => return Ok(None),
        Err(Some(e)) => return Err(e),
    }
    let total = offsets.last().copied().unwrap_or(0) + last_written.load(Ordering::Relaxed);
    // SAFETY: every member reported success and wrote exactly its range: the members before
    // the last fill [0, offsets[last]) without gaps, and the last wrote `last_written` bytes.
    unsafe { out.set_len(total) };
    Ok(Some((out, members)))
}

/// Where each member's output starts: the prefix sums of the ISIZE fields (the 4 bytes before
/// each later candidate). `None` when they pass `capacity` (the sequential path reports that).
fn output_offsets(bytes: &[u8], starts: &[usize], capacity: usize) -> Option<Vec<usize>> {
    let mut offsets = Vec::with_capacity(starts.len());
    let mut at = 0usize;
    for (i, &start) in starts.iter().enumerate() {
        offsets.push(at);
        let Some(&next) = starts.get(i + 1) else {
            break;
        };
        // Candidates are at least MIN_MEMBER bytes apart, so `next - 4` lies after `start`.
        let field = bytes.get(next.checked_sub(4).filter(|&f| f > start)?..next)?;
        let size = u32::from_le_bytes([field[0], field[1], field[2], field[3]]);
        at = at.checked_add(size as usize)?;
    }
    (at <= capacity).then_some(offsets)
}

/// One member's input and output ranges.
struct Member<'a> {
    input: &'a [u8],
    out: std::ops::Range<usize>,
    is_last: bool,
    end: usize,
}

impl<'a> Member<'a> {
    fn new(
        bytes: &'a [u8],
        starts: &[usize],
        offsets: &[usize],
        capacity: usize,
        i: usize,
    ) -> Self {
        let start = starts[i];
        let is_last = i + 1 == starts.len();
        let end = if is_last { bytes.len() } else { starts[i + 1] };
        let out_end = if is_last { capacity } else { offsets[i + 1] };
        Member {
            input: bytes.get(start..end).unwrap_or_default(),
            out: offsets[i]..out_end,
            is_last,
            end,
        }
    }

    /// The bytes written when the member verified (see the module's decisions), else `None`.
    fn check(&self, result: RawResult, bytes: &[u8]) -> Option<usize> {
        let RawResult::Done { consumed, written } = result else {
            return None;
        };
        if self.is_last {
            let after = self.end - self.input.len() + consumed;
            let padding = bytes.get(after..).unwrap_or_default();
            return padding.iter().all(|&b| b == 0).then_some(written);
        }
        (consumed == self.input.len() && written == self.out.len()).then_some(written)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn member(data: &[u8]) -> Vec<u8> {
        super::super::gzip::gzip_compress_member(data).unwrap()
    }

    fn sample(len: usize, seed: u32) -> Vec<u8> {
        let mut x = seed;
        (0..len)
            .map(|i| {
                x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                if i % 7 == 0 {
                    (x >> 24) as u8
                } else {
                    (i / 97) as u8
                }
            })
            .collect()
    }

    #[test]
    fn several_members_inflate_to_their_concatenation() {
        let parts = [
            sample(50_000, 1),
            sample(1, 2),
            sample(0, 3),
            sample(123_457, 4),
        ];
        let mut file = Vec::new();
        for p in &parts {
            file.extend(member(p));
        }
        file.extend([0u8; 5]); // padding
        let want: Vec<u8> = parts.concat();
        let (out, members) = inflate_members(&file, want.len() + 100).unwrap().unwrap();
        assert_eq!(members, 4);
        assert!(out == want);
    }

    #[test]
    fn a_false_candidate_or_damage_falls_back_instead_of_guessing() {
        // A member whose data holds a header-like run: the candidate search finds it, the
        // verification refuses the chain, and the caller goes sequential.
        let mut file = member(&sample(20_000, 5));
        // Stored, not compressed, so the header-like bytes appear verbatim.
        let mut raw = vec![9u8; 40];
        raw.extend([0x1f, 0x8b, 0x08, 0, 0, 0, 0, 0, 0, 3]);
        raw.extend([9u8; 40]);
        let stored = stored_member(&raw);
        file.extend(&stored);
        assert!(
            member_candidates(&file).len() > 2,
            "the stored bytes look like a member"
        );
        assert!(inflate_members(&file, 1 << 20).unwrap().is_none());
        // Damage in a member: no result, no panic.
        let mut two = member(&sample(30_000, 6));
        two.extend(member(&sample(30_000, 7)));
        let mid = two.len() / 4;
        two[mid] ^= 0x55;
        assert!(inflate_members(&two, 1 << 20).unwrap().is_none());
    }

    #[test]
    fn output_past_the_capacity_is_left_to_the_sequential_path() {
        let mut file = member(&sample(10_000, 8));
        file.extend(member(&sample(10_000, 9)));
        assert!(inflate_members(&file, 15_000).unwrap().is_none());
        assert!(inflate_members(&file, 20_000).unwrap().is_some());
    }

    #[test]
    fn what_morphray_writes_inflates_in_parallel_and_sequentially_alike() {
        use super::super::gzip::{Limit, WRITE_MEMBER_BYTES, gzip_compress, inflate_within};
        let data = sample(2 * WRITE_MEMBER_BYTES + 5, 10);
        let file = gzip_compress(&data).unwrap();
        assert_eq!(member_candidates(&file).len(), 3);
        let (parallel, members) = inflate_members(&file, data.len() + 64).unwrap().unwrap();
        assert_eq!(members, 3);
        assert!(parallel == data);
        let (whole, members) = inflate_within(file, Limit::declared(data.len(), "test")).unwrap();
        assert_eq!(members, 3);
        assert!(whole == data);
    }

    /// One gzip member holding `data` in a stored (uncompressed) DEFLATE block.
    fn stored_member(data: &[u8]) -> Vec<u8> {
        let mut m = vec![0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 3, 1];
        let len = data.len() as u16;
        m.extend(len.to_le_bytes());
        m.extend((!len).to_le_bytes());
        m.extend(data);
        let mut crc = libdeflater::Crc::new();
        crc.update(data);
        m.extend(crc.sum().to_le_bytes());
        m.extend((data.len() as u32).to_le_bytes());
        m
    }
}
