//! A walk over a DICOM file's element headers, before dicom-rs parses it, that refuses files
//! whose declared lengths could make the parser allocate more than the file holds.
//!
//! Why: dicom-rs reserves and zero-fills an element's declared length before reading it, so a
//! 200-byte file declaring a 4 GB value makes it touch 4 GB (found by the `dicom_series` fuzz
//! target: a 1.4 GB allocation from a few hundred bytes). And its parser recurses into nested
//! sequences without a depth limit, so deep nesting could overflow the stack, which no
//! `catch_unwind` contains.
//!
//! Decisions:
//! - Every element and item length must fit in the bytes that follow it (for a deflated data
//!   set: in its inflated bytes, inflated here within what its own header declares, see
//!   [`deflated`]);
//!   sequences and items nest at most [`MAX_DEPTH`] deep. Undefined lengths are followed to
//!   their delimiters. Nothing else is judged: dicom-rs does the parsing.
//! - The walk runs over bytes in memory; when it runs past the end of what was read while the
//!   file has more, it says so ([`Walk::NeedMore`]) and the caller reads more. Header reads
//!   stop at the pixel data, as dicom-rs does with `read_until(PixelData)`.

use std::io::Read;

/// Deepest nesting of sequences accepted.
pub const MAX_DEPTH: usize = 32;
/// Most bytes a deflated data set may inflate to before its pixel data (its header part).
const MAX_DEFLATED_HEADER: usize = 64 << 20;
/// Bytes a deflated data set may hold beyond its header and declared pixels (trailing
/// elements, padding), plus 1/64 of the declared size.
const DEFLATE_SLACK: u64 = 1 << 20;

/// The outcome of a walk.
#[derive(Debug, PartialEq)]
pub enum Walk {
    /// Every length fits (or the bytes end where the file ends: dicom-rs reports that).
    Fits,
    /// The walk needs bytes past those given.
    NeedMore,
}

/// What a walk saw of the top-level image tags, for the checks against the data.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Seen {
    /// The PixelData element's length: Some(None) when undefined (encapsulated).
    pub pixel_len: Option<Option<usize>>,
    /// Rows, Columns, NumberOfFrames, BitsAllocated, SamplesPerPixel as declared.
    pub rows: Option<u64>,
    /// Columns.
    pub cols: Option<u64>,
    /// NumberOfFrames.
    pub frames: Option<u64>,
    /// BitsAllocated.
    pub bits: Option<u64>,
    /// SamplesPerPixel.
    pub samples: Option<u64>,
}

impl Seen {
    /// Rows x Columns x frames x samples x bytes, as the header declares them (absent tags
    /// count as the defaults: 1 frame, 1 sample, 16 bits; absent Rows or Columns as 0).
    pub fn declared_pixels(&self) -> u64 {
        let bytes = self.bits.unwrap_or(16).div_ceil(8);
        [
            self.rows.unwrap_or(0),
            self.cols.unwrap_or(0),
            self.frames.unwrap_or(1).max(1),
            self.samples.unwrap_or(1).max(1),
            bytes,
        ]
        .iter()
        .try_fold(1u64, |a, &b| a.checked_mul(b))
        .unwrap_or(u64::MAX)
    }
}

/// Walks `bytes` (a whole file from its start, or its first part when `file_len` is larger):
/// the meta group from offset 132, then the data set in its transfer syntax; stops at the
/// pixel data when `stop_at_pixels`.
pub fn check(bytes: &[u8], file_len: usize, stop_at_pixels: bool) -> Result<Walk, String> {
    check_seen(bytes, file_len, stop_at_pixels).map(|(walk, _)| walk)
}

/// [`check`], with what the walk saw of the image tags.
pub fn check_seen(
    bytes: &[u8],
    file_len: usize,
    stop_at_pixels: bool,
) -> Result<(Walk, Seen), String> {
    let mut meta = Walker::new(bytes, file_len, 132, stop_at_pixels);
    let ts = match meta.meta_group()? {
        Some(ts) => ts,
        None => return Ok((Walk::NeedMore, Seen::default())),
    };
    let start = meta.pos;
    if ts == "1.2.840.10008.1.2.1.99" {
        if bytes.len() < file_len {
            return Ok((Walk::NeedMore, Seen::default()));
        }
        return deflated(&bytes[start..], stop_at_pixels);
    }
    let mut w = Walker::new(bytes, file_len, start, stop_at_pixels);
    w.explicit = ts != "1.2.840.10008.1.2";
    w.little = ts != "1.2.840.10008.1.2.2";
    let walk = w.dataset(None, 0)?;
    Ok((walk, w.seen))
}

/// The walk of a deflated data set, inflated within what its own header declares: first up to
/// its pixel data (at most [`MAX_DEFLATED_HEADER`]), then, unless the caller stops there, up to
/// that header plus Rows x Columns x frames x bytes plus slack, after checking that much fits
/// in the host's available memory. A 3 MB file declaring a 384 x 384 image that inflates to
/// 3 GB is refused once it passes its bound, never held (issue 30).
fn deflated(stream: &[u8], stop_at_pixels: bool) -> Result<(Walk, Seen), String> {
    let mut decoder = flate2::read::DeflateDecoder::new(stream);
    let mut inflated: Vec<u8> = Vec::new();
    let mut step: usize = 64 * 1024;
    let inflate_error = |e: std::io::Error| format!("its deflated data set does not inflate ({e})");
    // The header part: inflate until the walk reaches the pixel data or the stream ends.
    let (ended, seen) = loop {
        let got = (&mut decoder)
            .take(step as u64)
            .read_to_end(&mut inflated)
            .map_err(inflate_error)?;
        let ended = got == 0;
        let len = if ended { inflated.len() } else { usize::MAX };
        let mut w = Walker::new(&inflated, len, 0, true);
        let walk = w.dataset(None, 0)?;
        if ended || (walk == Walk::Fits && w.seen.pixel_len.is_some()) {
            break (ended, w.seen);
        }
        if inflated.len() >= MAX_DEFLATED_HEADER {
            return Err(format!(
                "its deflated data set holds more than {} before its pixel data",
                crate::volume::host_memory::human(MAX_DEFLATED_HEADER as u64)
            ));
        }
        step = step.saturating_mul(2).min(MAX_DEFLATED_HEADER);
    };
    if stop_at_pixels || ended {
        let mut w = Walker::new(&inflated, inflated.len(), 0, stop_at_pixels);
        let walk = if ended {
            w.dataset(None, 0)?
        } else {
            Walk::Fits
        };
        return Ok((walk, if ended { w.seen } else { seen }));
    }
    let declared = seen.declared_pixels();
    let bound = (inflated.len() as u64)
        .saturating_add(declared)
        .saturating_add(declared / 64)
        .saturating_add(DEFLATE_SLACK);
    crate::volume::host_memory::check(bound, "inflating its deflated data set")?;
    let more = bound.saturating_sub(inflated.len() as u64);
    (&mut decoder)
        .take(more.saturating_add(1))
        .read_to_end(&mut inflated)
        .map_err(inflate_error)?;
    if inflated.len() as u64 > bound {
        return Err(format!(
            "its deflated data set inflates past {}, more than its header declares (Rows x \
             Columns x frames x BitsAllocated = {} of pixels, plus slack): a decompression \
             bomb or a corrupt file",
            crate::volume::host_memory::human(bound),
            crate::volume::host_memory::human(declared)
        ));
    }
    let mut w = Walker::new(&inflated, inflated.len(), 0, false);
    let walk = w.dataset(None, 0)?;
    Ok((walk, w.seen))
}

/// Where a walk stands.
struct Walker<'a> {
    bytes: &'a [u8],
    file_len: usize,
    pos: usize,
    explicit: bool,
    little: bool,
    stop_at_pixels: bool,
    seen: Seen,
}

/// An element or item header.
struct Header {
    tag: (u16, u16),
    sequence: bool,
    len: Option<usize>,
    /// Bytes per value of a binary VR (1 for text and bytes).
    unit: usize,
}

/// Bytes per value of binary VRs. dicom-rs reads `len / unit` values of such an element and
/// consumes only those bytes, so a length that is not a multiple desynchronizes its parse from
/// ours (third fuzz finding): such elements are refused.
fn unit_of(vr: &[u8; 2]) -> usize {
    match vr {
        b"US" | b"SS" | b"OW" => 2,
        b"UL" | b"SL" | b"FL" | b"AT" | b"OF" | b"OL" => 4,
        b"FD" | b"OD" | b"SV" | b"UV" | b"OV" => 8,
        _ => 1,
    }
}

const ITEM: (u16, u16) = (0xFFFE, 0xE000);
const ITEM_END: (u16, u16) = (0xFFFE, 0xE00D);
const SEQUENCE_END: (u16, u16) = (0xFFFE, 0xE0DD);
const PIXEL_DATA: (u16, u16) = (0x7FE0, 0x0010);

/// `Err(None)`: the bytes given end here (need more, or the file ends).
type Step<T> = Result<T, Option<String>>;

impl<'a> Walker<'a> {
    /// An explicit-VR little-endian walk from `pos`.
    fn new(bytes: &'a [u8], file_len: usize, pos: usize, stop_at_pixels: bool) -> Walker<'a> {
        Walker {
            bytes,
            file_len,
            pos,
            explicit: true,
            little: true,
            stop_at_pixels,
            seen: Seen::default(),
        }
    }

    /// Notes a top-level image tag's value (`value`: its bytes).
    fn note(&mut self, tag: (u16, u16), value: &[u8]) {
        let short = || -> Option<u64> {
            let b: [u8; 2] = value.try_into().ok()?;
            Some(if self.little {
                u16::from_le_bytes(b)
            } else {
                u16::from_be_bytes(b)
            } as u64)
        };
        match tag {
            (0x0028, 0x0010) => self.seen.rows = short(),
            (0x0028, 0x0011) => self.seen.cols = short(),
            (0x0028, 0x0100) => self.seen.bits = short(),
            (0x0028, 0x0002) => self.seen.samples = short(),
            (0x0028, 0x0008) => {
                self.seen.frames = String::from_utf8_lossy(value)
                    .trim_matches(|c: char| c == '\0' || c.is_whitespace())
                    .parse()
                    .ok()
            }
            _ => {}
        }
    }

    fn take(&mut self, n: usize) -> Step<&[u8]> {
        let end = self.pos.checked_add(n).ok_or(None)?;
        let slice = self.bytes.get(self.pos..end).ok_or(None)?;
        self.pos = end;
        Ok(slice)
    }

    fn u16(&mut self) -> Step<u16> {
        let little = self.little;
        let b = self.take(2)?;
        Ok(if little {
            u16::from_le_bytes([b[0], b[1]])
        } else {
            u16::from_be_bytes([b[0], b[1]])
        })
    }

    fn u32(&mut self) -> Step<u32> {
        let little = self.little;
        let b = self.take(4)?;
        let a = [b[0], b[1], b[2], b[3]];
        Ok(if little {
            u32::from_le_bytes(a)
        } else {
            u32::from_be_bytes(a)
        })
    }

    /// The explicit-VR little-endian meta group, read as dicom-rs reads it: (0002,0000) first,
    /// then elements until that many bytes were read (whatever their tags). Its
    /// TransferSyntaxUID; None: need more.
    fn meta_group(&mut self) -> Result<Option<String>, String> {
        let mut ts = String::new();
        let group_length = match self.header() {
            Ok(h) if h.tag == (0x0002, 0x0000) && h.len == Some(4) => match self.u32() {
                Ok(n) => n as usize,
                Err(_) => return Ok(self.or_more(ts)),
            },
            // dicom-rs refuses such a meta group before reading a value.
            Ok(_) => return Ok(Some(ts)),
            Err(None) => return Ok(self.or_more(ts)),
            Err(Some(e)) => return Err(e),
        };
        let start = self.pos;
        while self.pos - start < group_length {
            let header = match self.header() {
                Ok(h) => h,
                Err(None) => return Ok(self.or_more(ts)),
                Err(Some(e)) => return Err(e),
            };
            let len = header
                .len
                .ok_or("the file meta group has an undefined length")?;
            self.fits(len, header.tag)?;
            let Ok(value) = self.take(len) else {
                return Ok(self.or_more(ts));
            };
            if header.tag == (0x0002, 0x0010) {
                ts = String::from_utf8_lossy(value)
                    .trim_end_matches(['\0', ' '])
                    .to_string();
            }
        }
        Ok(Some(ts))
    }

    /// `ts` when the bytes given are the whole file (dicom-rs reports the truncation), else
    /// None: read more.
    fn or_more(&self, ts: String) -> Option<String> {
        (self.bytes.len() >= self.file_len).then_some(ts)
    }

    fn header(&mut self) -> Step<Header> {
        let tag = (self.u16()?, self.u16()?);
        if tag.0 == 0xFFFE {
            let len = self.u32()?;
            return Ok(Header {
                tag,
                sequence: false,
                len: (len != u32::MAX).then_some(len as usize),
                unit: 1,
            });
        }
        let (vr, len) = if self.explicit {
            let vr = self.take(2)?;
            let vr = [vr[0], vr[1]];
            // As dicom-rs reads them: these VRs have a 16-bit length; every other VR, unknown
            // ones included (dicom-rs takes those as UN), has 2 reserved bytes and a 32-bit one.
            let short = matches!(
                &vr,
                b"AE"
                    | b"AS"
                    | b"AT"
                    | b"CS"
                    | b"DA"
                    | b"DS"
                    | b"DT"
                    | b"FL"
                    | b"FD"
                    | b"IS"
                    | b"LO"
                    | b"LT"
                    | b"PN"
                    | b"SH"
                    | b"SL"
                    | b"SS"
                    | b"ST"
                    | b"TM"
                    | b"UI"
                    | b"UL"
                    | b"US"
            );
            let len = if short {
                self.u16()? as u32
            } else {
                self.take(2)?;
                self.u32()?
            };
            (Some(vr), len)
        } else {
            (None, self.u32()?)
        };
        let vr = vr.unwrap_or_else(|| implicit_vr(tag));
        Ok(Header {
            tag,
            sequence: &vr == b"SQ",
            len: (len != u32::MAX).then_some(len as usize),
            unit: unit_of(&vr),
        })
    }

    /// Refuses a length longer than what follows in the file.
    fn fits(&self, len: usize, tag: (u16, u16)) -> Result<(), String> {
        let left = self.file_len.saturating_sub(self.pos);
        if len > left {
            return Err(format!(
                "element ({:04X},{:04X}) declares {len} bytes but only {left} follow",
                tag.0, tag.1
            ));
        }
        Ok(())
    }

    /// A data set up to `end` (None: to its item delimiter, or the end of the file at the top).
    fn dataset(&mut self, end: Option<usize>, depth: usize) -> Result<Walk, String> {
        loop {
            if end.is_some_and(|e| self.pos >= e) {
                return Ok(Walk::Fits);
            }
            let at = self.pos;
            let header = match self.header() {
                Ok(h) => h,
                Err(None) => return Ok(self.ran_out()),
                Err(Some(e)) => return Err(e),
            };
            if header.tag == ITEM_END || header.tag == SEQUENCE_END {
                // dicom-rs skips a delimiter outside any sequence and reads on.
                if depth == 0 {
                    continue;
                }
                return Ok(Walk::Fits);
            }
            if depth == 0 && header.tag == PIXEL_DATA {
                self.seen.pixel_len = Some(header.len);
            }
            if depth == 0 && self.stop_at_pixels && header.tag >= PIXEL_DATA {
                self.pos = at;
                return Ok(Walk::Fits);
            }
            let walk = match header.len {
                Some(len) => {
                    self.fits(len, header.tag)?;
                    if len % header.unit != 0 {
                        return Err(format!(
                            "element ({:04X},{:04X}) has {len} bytes, not a whole number of \
                             {}-byte values",
                            header.tag.0, header.tag.1, header.unit
                        ));
                    }
                    if header.sequence {
                        let stop = self.pos + len;
                        self.items(Some(stop), depth + 1, false)?
                    } else if self.pos + len > self.bytes.len() {
                        return Ok(self.ran_out());
                    } else {
                        if depth == 0 && header.tag.0 == 0x0028 {
                            let bytes = self.bytes;
                            self.note(header.tag, &bytes[self.pos..self.pos + len]);
                        }
                        self.pos += len;
                        Walk::Fits
                    }
                }
                // Undefined length: a sequence, or encapsulated pixel data (fragments).
                None => self.items(None, depth + 1, header.tag == PIXEL_DATA)?,
            };
            if walk == Walk::NeedMore {
                return Ok(walk);
            }
        }
    }

    /// The items of a sequence (or pixel data fragments) up to `end` or its delimiter.
    fn items(&mut self, end: Option<usize>, depth: usize, fragments: bool) -> Result<Walk, String> {
        if depth > MAX_DEPTH {
            return Err(format!("sequences nest deeper than {MAX_DEPTH} levels"));
        }
        loop {
            if end.is_some_and(|e| self.pos >= e) {
                return Ok(Walk::Fits);
            }
            let header = match self.header() {
                Ok(h) => h,
                Err(None) => return Ok(self.ran_out()),
                Err(Some(e)) => return Err(e),
            };
            if header.tag == SEQUENCE_END {
                return Ok(Walk::Fits);
            }
            if header.tag != ITEM {
                return Err(format!(
                    "({:04X},{:04X}) where a sequence item was expected",
                    header.tag.0, header.tag.1
                ));
            }
            let walk = match header.len {
                Some(len) => {
                    self.fits(len, header.tag)?;
                    if fragments {
                        if self.pos + len > self.bytes.len() {
                            return Ok(self.ran_out());
                        }
                        self.pos += len;
                        Walk::Fits
                    } else {
                        let stop = self.pos + len;
                        self.dataset(Some(stop), depth)?
                    }
                }
                None if fragments => return Err("a pixel data fragment has no length".into()),
                None => self.dataset(None, depth)?,
            };
            if walk == Walk::NeedMore {
                return Ok(walk);
            }
        }
    }

    fn ran_out(&self) -> Walk {
        if self.bytes.len() < self.file_len {
            Walk::NeedMore
        } else {
            Walk::Fits
        }
    }
}

/// The VR the standard dictionary gives `tag` (implicit VR has no VR field), as dicom-rs
/// takes it; `UN` when the dictionary does not know the tag.
fn implicit_vr(tag: (u16, u16)) -> [u8; 2] {
    use dicom_core::dictionary::{DataDictionary, DataDictionaryEntry};
    dicom_dictionary_std::StandardDataDictionary
        .by_tag(dicom_core::Tag(tag.0, tag.1))
        .map(|e| e.vr().relaxed().to_bytes())
        .unwrap_or(*b"UN")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file: preamble, magic, a meta group with `ts`, then `body`.
    fn file(ts: &str, body: &[u8]) -> Vec<u8> {
        let mut f = vec![0u8; 128];
        f.extend_from_slice(b"DICM");
        let mut uid = ts.as_bytes().to_vec();
        if uid.len() % 2 == 1 {
            uid.push(0);
        }
        f.extend_from_slice(&[0x02, 0x00, 0x00, 0x00, b'U', b'L', 4, 0]);
        f.extend_from_slice(&(8 + uid.len() as u32).to_le_bytes());
        f.extend_from_slice(&[0x02, 0x00, 0x10, 0x00, b'U', b'I']);
        f.extend_from_slice(&(uid.len() as u16).to_le_bytes());
        f.extend_from_slice(&uid);
        f.extend_from_slice(body);
        f
    }

    #[test]
    fn a_length_beyond_the_file_is_refused_and_a_fitting_one_passes() {
        // (0008,0016) UI of 4 GB in explicit VR little endian.
        let mut body = vec![0x08, 0x00, 0x16, 0x00, b'O', b'B', 0, 0];
        body.extend_from_slice(&0xFFFF_FFF0u32.to_le_bytes());
        let f = file("1.2.840.10008.1.2.1", &body);
        let e = check(&f, f.len(), true).unwrap_err();
        assert!(e.contains("(0008,0016) declares 4294967280 bytes"), "{e}");
        let ok = file(
            "1.2.840.10008.1.2.1",
            &[0x08, 0x00, 0x60, 0x00, b'C', b'S', 2, 0, b'M', b'R'],
        );
        assert_eq!(check(&ok, ok.len(), true), Ok(Walk::Fits));
        // Only the first part given: more is needed.
        assert_eq!(
            check(&ok[..ok.len() - 1], ok.len(), true),
            Ok(Walk::NeedMore)
        );
    }

    #[test]
    fn deep_nesting_is_refused() {
        // Undefined-length sequences of undefined-length items, 40 deep (implicit VR: a tag
        // the dictionary calls a sequence).
        let mut body = Vec::new();
        for _ in 0..40 {
            body.extend_from_slice(&[0x08, 0x00, 0x15, 0x11, 0xFF, 0xFF, 0xFF, 0xFF]);
            body.extend_from_slice(&[0xFE, 0xFF, 0x00, 0xE0, 0xFF, 0xFF, 0xFF, 0xFF]);
        }
        let f = file("1.2.840.10008.1.2", &body);
        let e = check(&f, f.len(), true).unwrap_err();
        assert!(e.contains("deeper than 32"), "{e}");
    }
}
