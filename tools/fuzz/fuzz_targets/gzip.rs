//! Arbitrary bytes into `gzip::inflate_within` (with the limit `gzip_limit` picks) and into
//! `gzip::peek`, checked against an independent decoder (RFC 1952 framing here, flate2's
//! miniz_oxide for DEFLATE, the same member loop and padding rule). Seeds (see README.md) are
//! small valid, multi-member, zero-padded, truncated and corrupted gzip files, so the fuzzer
//! starts inside the multi-member loop and the error paths.
//!
//! The oracle for the limit: output never exceeds it; a stream the reference accepts whole
//! within the limit gives the same bytes and member count; one whose reference output exceeds it
//! is `GzipTooLarge`. (Before the limit existed, the oracle asserted the input-ratio bound
//! 1032 x input, which let a small stream inflate far past what its header declares.)
#![no_main]

use libfuzzer_sys::fuzz_target;
use morphray::volume::nifti::NiftiError;
use morphray::volume::nifti::bounded::PEEK_LEN;
use morphray::volume::nifti::gzip::{inflate_within, peek};
use morphray_fuzz::{check_error, gzip_limit};
use std::io::Read;

/// One gzip member decoded independently: RFC 1952 header parsed here, raw DEFLATE by flate2
/// (miniz_oxide), CRC-32 and ISIZE checked here. Like libdeflate (and unlike flate2's own gzip
/// reader) the optional header CRC16 (FHCRC) is skipped, not verified: the data CRC-32 already
/// protects what is loaded, and the loader documents following libdeflate. Reserved flag bits are
/// an error (RFC 1952: "must give an error"). Returns the bytes after the member.
fn member<'a>(input: &'a [u8], out: &mut Vec<u8>) -> Option<&'a [u8]> {
    const FHCRC: u8 = 0x02;
    const FEXTRA: u8 = 0x04;
    const FNAME: u8 = 0x08;
    const FCOMMENT: u8 = 0x10;
    let (head, mut rest) = (input.get(..10)?, input.get(10..)?);
    if head[..3] != [0x1f, 0x8b, 8] || head[3] & 0xe0 != 0 {
        return None;
    }
    let flags = head[3];
    if flags & FEXTRA != 0 {
        let len = usize::from(u16::from_le_bytes([*rest.first()?, *rest.get(1)?]));
        rest = rest.get(2 + len..)?;
    }
    for flag in [FNAME, FCOMMENT] {
        if flags & flag != 0 {
            let nul = rest.iter().position(|&b| b == 0)?;
            rest = rest.get(nul + 1..)?;
        }
    }
    if flags & FHCRC != 0 {
        rest = rest.get(2..)?;
    }
    let start = out.len();
    let mut decoder = flate2::bufread::DeflateDecoder::new(rest);
    decoder.read_to_end(out).ok()?;
    let rest = decoder.into_inner();
    let trailer = rest.get(..8)?;
    let mut crc = flate2::Crc::new();
    crc.update(out.get(start..)?);
    let word =
        |i: usize| u32::from_le_bytes([trailer[i], trailer[i + 1], trailer[i + 2], trailer[i + 3]]);
    let isize = (out.len() - start) as u32; // mod 2^32, as the format defines it
    (word(0) == crc.sum() && word(4) == isize)
        .then(|| rest.get(8..))
        .flatten()
}

/// Independent multi-member inflation: members back to back, then only zero bytes allowed.
/// `None` when any member fails to decode or non-zero bytes follow the last member.
fn reference(bytes: &[u8]) -> Option<(Vec<u8>, usize)> {
    const MAGIC: [u8; 2] = [0x1f, 0x8b];
    if !bytes.starts_with(&MAGIC) {
        return Some((bytes.to_vec(), 0));
    }
    let mut rest = bytes;
    let mut out = Vec::new();
    let mut members = 0;
    while !rest.is_empty() {
        if !rest.starts_with(&MAGIC) {
            return rest.iter().all(|&b| b == 0).then_some((out, members));
        }
        members += 1;
        rest = member(rest, &mut out)?;
    }
    Some((out, members))
}

fuzz_target!(|data: &[u8]| {
    let limit = gzip_limit(data);
    let ours = inflate_within(data.to_vec(), limit);
    match &ours {
        Ok((out, 0)) => assert_eq!(out.as_slice(), data, "non-gzip input must pass through"),
        Ok((out, _)) => assert!(
            out.len() <= limit.bytes(),
            "{} bytes out, limit {}",
            out.len(),
            limit.bytes()
        ),
        Err(e) => {
            check_error(e);
            assert!(
                matches!(
                    e,
                    NiftiError::GzipCorrupt { .. }
                        | NiftiError::GzipTrailingGarbage { .. }
                        | NiftiError::GzipTooLarge { .. }
                ),
                "unexpected error kind from inflation: {e}"
            );
        }
    }
    // Differential check: both decoders accept the same streams and agree on the bytes; what
    // the reference inflates past the limit, ours refuses as too large.
    let theirs = reference(data);
    match (&ours, &theirs) {
        (Ok(a), Some(b)) => assert!(
            a == b,
            "decoders disagree on the inflated bytes or member count"
        ),
        (Err(NiftiError::GzipTooLarge { .. }), Some((out, _))) => assert!(
            out.len() > limit.bytes(),
            "GzipTooLarge for a stream of {} bytes, limit {}",
            out.len(),
            limit.bytes()
        ),
        (Err(_), None) => {}
        (Ok(_), None) => panic!("inflate_within accepted a stream that flate2 rejects"),
        (Err(e), Some(_)) => panic!("inflate_within rejected a stream that flate2 accepts: {e}"),
    }
    // The header peek: on every stream the reference accepts, exactly its first bytes.
    for want in [
        PEEK_LEN,
        1 + usize::from(data.first().copied().unwrap_or(0)),
    ] {
        let prefix = peek(data, want);
        if let Some((out, _)) = &theirs {
            let expect = out.get(..want).unwrap_or(out);
            match prefix {
                Ok(p) => assert_eq!(p.as_slice(), expect, "peek({want}) differs"),
                Err(e) => panic!("peek({want}) rejected a stream flate2 accepts: {e}"),
            }
        } else if let Err(e) = prefix {
            check_error(&e);
        }
    }
});
