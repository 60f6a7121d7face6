//! Pixel data of a laid-out stack: decoded in parallel into the volume's samples, then
//! rescaled and (when the layout says so) resampled.
//!
//! Decisions:
//! - Transfer syntaxes are decoded by dicom-pixeldata's pure-Rust codecs (native, deflated,
//!   RLE Lossless, JPEG baseline/extended/lossless). JPEG 2000 and JPEG-LS have only C/C++ (or
//!   c2rust) decoders, which this crate does not link: they are refused with one line naming
//!   the transfer syntax and `dcm2niix`, before any file is decoded.
//! - Samples keep the stored encoding (8/16-bit, signed or not) so the GPU reads them directly;
//!   32-bit integers become f32. Bits above BitsStored are cleared (or sign-extended), since
//!   scanners may leave overlay bits there.
//! - One RescaleSlope/Intercept for the whole stack becomes the volume's stored-to-physical map
//!   (samples untouched). When they vary from slice to slice (per-frame rescale), the samples
//!   are converted to f32 physical values with the identity map, and a warning says so.
//! - Files are decoded on scoped threads (one per core, at most 8), each inside
//!   `catch_unwind`; each writes its frames straight into their slots of the output, so the
//!   samples are not copied again. A file that fails is returned, with its reason, so the
//!   caller can leave it out and lay the stack out again.

use super::contain::contained;
use super::headers::{FileHeader, Scan};
use super::photometric;
use super::series::Layout;
use crate::volume::{LinearMap, SampleKind, Samples};
use dicom_pixeldata::PixelDecoder;
use std::collections::BTreeMap;
use std::sync::Mutex;

/// Transfer syntaxes refused, with their names.
const REFUSED: &[(&str, &str)] = &[
    ("1.2.840.10008.1.2.4.80", "JPEG-LS Lossless"),
    ("1.2.840.10008.1.2.4.81", "JPEG-LS Near-Lossless"),
    ("1.2.840.10008.1.2.4.90", "JPEG 2000 Lossless"),
    ("1.2.840.10008.1.2.4.91", "JPEG 2000"),
    ("1.2.840.10008.1.2.4.92", "JPEG 2000 Part 2 Lossless"),
    ("1.2.840.10008.1.2.4.93", "JPEG 2000 Part 2"),
    ("1.2.840.10008.1.2.4.201", "HTJ2K Lossless"),
    ("1.2.840.10008.1.2.4.202", "HTJ2K Lossless RPCL"),
    ("1.2.840.10008.1.2.4.203", "HTJ2K"),
];

/// Why a stack's pixels could not be read as a whole.
#[derive(Debug)]
pub enum PixelError {
    /// The encoding is not supported (one line, names what to do).
    Unsupported(String),
    /// These files failed; the others decoded.
    Files(Vec<(usize, String)>),
}

/// Decoded samples with their stored-to-physical map.
pub struct Decoded {
    /// The volume's samples, i fastest.
    pub samples: Samples,
    /// Stored to physical.
    pub to_physical: LinearMap,
    /// What was done, one sentence each.
    pub warnings: Vec<String>,
}

/// Refuses JPEG 2000 / JPEG-LS and unsupported bit depths of the stack's first file.
pub fn check_encoding(h: &FileHeader) -> Result<SampleKind, String> {
    if let Some((_, name)) = REFUSED.iter().find(|(uid, _)| *uid == h.transfer_syntax) {
        return Err(format!(
            "{}: transfer syntax {name} ({}) needs a C/C++ decoder that morphray does not \
             include; convert the series with dcm2niix and open the NIfTI",
            h.path.display(),
            h.transfer_syntax
        ));
    }
    Ok(match (h.bits_allocated, h.signed) {
        (8, false) => SampleKind::U8,
        (8, true) => SampleKind::I8,
        (16, false) => SampleKind::U16,
        (16, true) => SampleKind::I16,
        (32, _) => SampleKind::F32,
        (bits, _) => {
            return Err(format!(
                "{}: {bits} bits allocated per pixel is not supported (8, 16 or 32)",
                h.path.display()
            ));
        }
    })
}

/// Decodes the frames of `layout` (in its order), then rescales and resamples.
pub fn decode(layout: &Layout, scan: &Scan) -> Result<Decoded, PixelError> {
    let first = &scan.images[layout.order[0].file];
    let kind = check_encoding(first).map_err(PixelError::Unsupported)?;
    let slice_len = layout.dims[0] * layout.dims[1];
    let slice_bytes = slice_len * kind.size_bytes();
    let total = slice_bytes
        .checked_mul(layout.order.len())
        .ok_or_else(|| PixelError::Unsupported("the series is too large to hold".into()))?;
    check_size(total, layout, scan)?;
    check_memory(total, layout, scan, kind)?;
    // A failed reservation is an error rather than an abort; the samples themselves come from
    // a zeroed allocation (pages the kernel zeroes as they are first written, not a memset of
    // the whole volume before the decoders overwrite it).
    Vec::<u8>::new()
        .try_reserve_exact(total)
        .map_err(|_| PixelError::Unsupported(format!("{total} bytes of samples do not fit")))?;
    let mut bytes = vec![0u8; total];
    let mut by_file: BTreeMap<usize, Vec<(usize, u32)>> = BTreeMap::new();
    for (slot, s) in layout.order.iter().enumerate() {
        by_file.entry(s.file).or_default().push((slot, s.frame));
    }
    let jobs: Vec<(usize, Vec<(usize, u32)>)> = by_file.into_iter().collect();
    let slots: Vec<Mutex<Option<&mut [u8]>>> = bytes
        .chunks_mut(slice_bytes.max(1))
        .map(|c| Mutex::new(Some(c)))
        .collect();
    let failures = decode_parallel(&jobs, &slots, scan, kind, slice_len);
    drop(slots);
    if !failures.is_empty() {
        return Err(PixelError::Files(failures));
    }
    let samples =
        Samples::from_le_bytes(kind, bytes).map_err(|e| PixelError::Unsupported(e.to_string()))?;
    let mut decoded = finish(samples, layout, slice_len)?;
    let (samples, note) = photometric::to_monochrome2(decoded.samples, layout, scan);
    decoded.samples = samples;
    decoded.warnings.extend(note);
    Ok(decoded)
}

/// Most bytes of samples one byte of a file can decode to: deflate's limit (RLE reaches 64,
/// JPEG Lossless 32).
const MAX_RATIO: u64 = 1032;

/// Refuses a stack whose declared size its files cannot hold, before allocating it (a small
/// file may declare 65535 x 65535 pixels).
fn check_size(total: usize, layout: &Layout, scan: &Scan) -> Result<(), PixelError> {
    let mut files: Vec<usize> = layout.order.iter().map(|s| s.file).collect();
    files.sort_unstable();
    files.dedup();
    let on_disk: u64 = files
        .iter()
        .map(|&f| {
            std::fs::metadata(&scan.images[f].path)
                .map(|m| m.len())
                .unwrap_or(0)
        })
        .sum();
    // Resampling may add slices: compare the decoded frames, not the output.
    let decoded = total as u64;
    if decoded > on_disk.saturating_mul(MAX_RATIO) {
        return Err(PixelError::Unsupported(format!(
            "its headers declare {decoded} bytes of pixels, more than its {} file(s) of {on_disk} \
             bytes can hold",
            files.len()
        )));
    }
    Ok(())
}

/// Refuses a stack whose decoding needs more memory than the host has available, before
/// anything is allocated or decoded (issue 30: two deflated files were OOM-killed with no
/// message). Needed: the samples, a second copy when slices are resampled or converted to
/// float, and per decoding thread the largest file's declared pixels twice (its bytes read or
/// inflated, and dicom-rs' decoded frame).
fn check_memory(
    total: usize,
    layout: &Layout,
    scan: &Scan,
    kind: SampleKind,
) -> Result<(), PixelError> {
    let mut files: Vec<usize> = layout.order.iter().map(|s| s.file).collect();
    files.sort_unstable();
    files.dedup();
    let largest = files
        .iter()
        .map(|&f| super::consistency::declared_pixel_bytes(&scan.images[f]).unwrap_or(u64::MAX))
        .max()
        .unwrap_or(0);
    let workers = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
        .clamp(1, 8)
        .min(files.len().max(1)) as u64;
    let slices_out = layout.dims[2] as u64;
    let per_slice = (layout.dims[0] * layout.dims[1]) as u64;
    let rescale_varies = layout
        .order
        .iter()
        .any(|s| s.rescale != layout.order[0].rescale);
    let second_copy = if layout.resample.is_some() || rescale_varies {
        slices_out
            .saturating_mul(per_slice)
            .saturating_mul(4.max(kind.size_bytes() as u64))
    } else {
        0
    };
    let needed = (total as u64)
        .saturating_add(second_copy)
        .saturating_add(workers.saturating_mul(largest).saturating_mul(2));
    crate::volume::host_memory::check(
        needed,
        &format!(
            "decoding its {} file(s) ({} of pixels declared)",
            files.len(),
            crate::volume::host_memory::human(total as u64)
        ),
    )
    .map_err(PixelError::Unsupported)
}

/// Runs the jobs on scoped threads; returns the files that failed.
fn decode_parallel(
    jobs: &[(usize, Vec<(usize, u32)>)],
    slots: &[Mutex<Option<&mut [u8]>>],
    scan: &Scan,
    kind: SampleKind,
    slice_len: usize,
) -> Vec<(usize, String)> {
    let workers = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
        .clamp(1, 8)
        .min(jobs.len().max(1));
    let next = std::sync::atomic::AtomicUsize::new(0);
    std::thread::scope(|scope| {
        let handles: Vec<_> = (0..workers)
            .map(|_| {
                scope.spawn(|| {
                    let mut failed = Vec::new();
                    loop {
                        let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some((file, frames)) = jobs.get(i) else {
                            break;
                        };
                        let h = &scan.images[*file];
                        let result = contained(|| decode_file(h, frames, slots, kind, slice_len))
                            .and_then(|r| r);
                        if let Err(reason) = result {
                            failed.push((*file, reason));
                        }
                    }
                    failed
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| {
                h.join()
                    .unwrap_or_else(|_| vec![(0, "a decoding thread stopped".into())])
            })
            .collect()
    })
}

/// Decodes the frames of one file into their slots.
fn decode_file(
    h: &FileHeader,
    frames: &[(usize, u32)],
    slots: &[Mutex<Option<&mut [u8]>>],
    kind: SampleKind,
    slice_len: usize,
) -> Result<(), String> {
    if let Some(done) = read_native(h, frames, slots, kind, slice_len) {
        return done;
    }
    let bytes = crate::files::read::read_regular(&h.path, u64::MAX)
        .map_err(|e| reason(&h.path, &e.to_string()))?;
    if bytes.len() < 132 || &bytes[128..132] != b"DICM" {
        return Err("it is no longer a DICOM file".into());
    }
    super::lengths::check(&bytes, bytes.len(), false)?;
    let obj = dicom_object::OpenFileOptions::new()
        .from_reader(&bytes[128..])
        .map_err(|e| reason(&h.path, &e.to_string()))?;
    if obj.meta().transfer_syntax().trim_end_matches('\0') != h.transfer_syntax || frames.is_empty()
    {
        return Err("its encoding changed since its header was read".into());
    }
    if h.transfer_syntax == RLE_LOSSLESS {
        check_rle_headers(&obj)?;
    }
    if let Some(tiles) = &h.mosaic {
        return decode_mosaic(&obj, h, tiles, frames, slots, kind);
    }
    for &(slot, frame) in frames {
        let decoded = obj
            .decode_pixel_data_frame(frame)
            .map_err(|e| reason(&h.path, &e.to_string()))?;
        let bytes_per = (h.bits_allocated as usize).div_ceil(8);
        let data = decoded.data();
        if data.len() < slice_len * bytes_per
            || decoded.bits_allocated() != h.bits_allocated
            || decoded.samples_per_pixel() != 1
        {
            return Err(format!(
                "frame {frame} decodes to {} bytes at {} bits, not {} pixels of {} bits",
                data.len(),
                decoded.bits_allocated(),
                slice_len,
                h.bits_allocated
            ));
        }
        let mut guard = slots[slot].lock().map_err(|_| "a slot lock failed")?;
        let out = guard.take().ok_or("two frames were given one slot")?;
        convert(&data[..slice_len * bytes_per], out, h, kind);
    }
    Ok(())
}

/// Decodes a mosaic's one stored image and cuts each frame's tile out of it.
fn decode_mosaic(
    obj: &dicom_object::DefaultDicomObject,
    h: &FileHeader,
    tiles: &super::mosaic::Tiles,
    frames: &[(usize, u32)],
    slots: &[Mutex<Option<&mut [u8]>>],
    kind: SampleKind,
) -> Result<(), String> {
    let decoded = obj
        .decode_pixel_data_frame(0)
        .map_err(|e| reason(&h.path, &e.to_string()))?;
    let bytes_per = (h.bits_allocated as usize).div_ceil(8);
    if decoded.bits_allocated() != h.bits_allocated || decoded.samples_per_pixel() != 1 {
        return Err(format!(
            "its mosaic decodes to {} bits and {} samples per pixel, not {} bits and 1",
            decoded.bits_allocated(),
            decoded.samples_per_pixel(),
            h.bits_allocated
        ));
    }
    let data = decoded.data();
    for &(slot, tile) in frames {
        let cut = tiles.cut(data, tile as usize, bytes_per).ok_or_else(|| {
            format!(
                "its mosaic decodes to {} bytes, too few for {} x {} pixels",
                data.len(),
                tiles.rows,
                tiles.cols
            )
        })?;
        let mut guard = slots[slot].lock().map_err(|_| "a slot lock failed")?;
        let out = guard.take().ok_or("two frames were given one slot")?;
        convert(&cut, out, h, kind);
    }
    Ok(())
}

/// RLE Lossless.
const RLE_LOSSLESS: &str = "1.2.840.10008.1.2.5";

/// dicom-rs allocates as many segment offsets as an RLE fragment's first word says, and slices
/// the fragment by it without a check (the `dicom_series` fuzz target: a 4.9 GB allocation, and
/// contained index panics). The standard allows at most 15 segments in a 64-byte header:
/// anything else is refused before decoding.
fn check_rle_headers(obj: &dicom_object::DefaultDicomObject) -> Result<(), String> {
    let fragments = obj
        .get(dicom_dictionary_std::tags::PIXEL_DATA)
        .and_then(|e| match e.value() {
            dicom_core::value::Value::PixelSequence(seq) => Some(seq.fragments().to_vec()),
            _ => None,
        })
        .ok_or("its RLE pixel data is not encapsulated")?;
    for fragment in &fragments {
        let segments = fragment
            .get(0..4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .unwrap_or(0);
        if fragment.len() < 64 || !(1..=15).contains(&segments) {
            return Err(format!(
                "an RLE fragment of {} bytes declares {segments} segments (1 to 15 in a 64-byte \
                 header)",
                fragment.len()
            ));
        }
    }
    Ok(())
}

/// Native little-endian transfer syntaxes (implicit and explicit VR).
const NATIVE_LE: [&str; 2] = ["1.2.840.10008.1.2", "1.2.840.10008.1.2.1"];

/// The fast path for uncompressed little-endian 8/16-bit files, by far the most common: each
/// frame is read from the file straight into its slot of the samples (positioned reads, no
/// intermediate buffer), instead of dicom-rs' parse into typed values and its copies
/// (BENCHMARKS.md, DICOM). Taken only when the 8 or 12 bytes right before the last
/// `frames x rows x cols` bytes of the file are exactly the PixelData (7FE0,0010) element
/// header with that length; anything else (trailing elements, odd layouts) returns None and
/// goes through dicom-rs.
fn read_native(
    h: &FileHeader,
    frames: &[(usize, u32)],
    slots: &[Mutex<Option<&mut [u8]>>],
    kind: SampleKind,
    slice_len: usize,
) -> Option<Result<(), String>> {
    use std::os::unix::fs::FileExt;
    if !cfg!(target_endian = "little")
        || h.mosaic.is_some()
        || kind == SampleKind::F32
        || !NATIVE_LE.contains(&h.transfer_syntax.as_str())
        || h.bits_allocated as usize != 8 * kind.size_bytes()
    {
        return None;
    }
    let frame_bytes = slice_len.checked_mul(kind.size_bytes())?;
    let expected = frame_bytes.checked_mul(h.frames.len())?;
    let padded = expected + expected % 2;
    let (file, meta) = crate::files::read::open_regular(&h.path).ok()?;
    let len = usize::try_from(meta.len()).ok()?;
    let start = len.checked_sub(padded).filter(|s| *s >= 12)?;
    let mut head = [0u8; 12];
    file.read_exact_at(&mut head, (start - 12) as u64).ok()?;
    let length = u32::try_from(padded).ok()?.to_le_bytes();
    let tag = [0xE0, 0x7F, 0x10, 0x00];
    let explicit = head[0..4] == tag
        && (head[4..8] == *b"OW\0\0" || head[4..8] == *b"OB\0\0")
        && head[8..12] == length;
    let implicit = head[4..8] == tag && head[8..12] == length;
    if !(explicit || implicit) {
        return None;
    }
    for &(slot, frame) in frames {
        let Ok(mut guard) = slots[slot].lock() else {
            return Some(Err("a slot lock failed".into()));
        };
        let Some(out) = guard.take() else {
            return Some(Err("two frames were given one slot".into()));
        };
        let at = start + frame as usize * frame_bytes;
        if let Err(e) = file.read_exact_at(out, at as u64) {
            return Some(Err(reason(&h.path, &e.to_string())));
        }
        clear_unused_bits(out, h, kind);
    }
    Some(Ok(()))
}

/// [`convert`] in place, for little-endian samples already in their slot.
fn clear_unused_bits(out: &mut [u8], h: &FileHeader, kind: SampleKind) {
    if h.bits_stored < h.bits_allocated {
        let copy = out.to_vec();
        convert(&copy, out, h, kind);
    }
}

/// One line naming the file.
fn reason(path: &std::path::Path, e: &str) -> String {
    format!("{} ({})", super::headers::one_line(e), path.display())
}

/// Native-endian decoded samples into little-endian samples of `kind`, clearing bits above
/// BitsStored (sign-extending for signed data).
fn convert(data: &[u8], out: &mut [u8], h: &FileHeader, kind: SampleKind) {
    let stored = h.bits_stored.clamp(1, h.bits_allocated.max(1)) as u32;
    match kind {
        SampleKind::U8 | SampleKind::I8 => {
            let shift = 8 - stored.min(8);
            for (o, &v) in out.iter_mut().zip(data) {
                *o = if kind == SampleKind::I8 {
                    (((v << shift) as i8) >> shift) as u8
                } else {
                    (v << shift) >> shift
                };
            }
        }
        SampleKind::U16 | SampleKind::I16 => {
            let shift = 16 - stored.min(16);
            let signed = kind == SampleKind::I16;
            for (o, v) in out.chunks_exact_mut(2).zip(data.chunks_exact(2)) {
                let v = u16::from_ne_bytes([v[0], v[1]]);
                let v = if signed {
                    (((v << shift) as i16) >> shift) as u16
                } else {
                    (v << shift) >> shift
                };
                o.copy_from_slice(&v.to_le_bytes());
            }
        }
        SampleKind::F32 => {
            for (o, v) in out.chunks_exact_mut(4).zip(data.chunks_exact(4)) {
                let raw = [v[0], v[1], v[2], v[3]];
                let value = if h.signed {
                    i32::from_ne_bytes(raw) as f32
                } else {
                    u32::from_ne_bytes(raw) as f32
                };
                o.copy_from_slice(&value.to_le_bytes());
            }
        }
    }
}

/// Rescale (one map, or per-slice to f32) and resampling.
fn finish(samples: Samples, layout: &Layout, slice_len: usize) -> Result<Decoded, PixelError> {
    let mut warnings = Vec::new();
    let maps: Vec<(f64, f64)> = layout.order.iter().map(|s| s.rescale).collect();
    let same = maps.iter().all(|m| *m == maps[0]);
    let (physical, to_physical) = if same {
        let (slope, intercept) = maps[0];
        (None, LinearMap { slope, intercept })
    } else {
        warnings.push(
            "RescaleSlope/RescaleIntercept vary between slices: samples were converted to \
             float32 physical values"
                .into(),
        );
        let physical: Vec<f32> = (0..samples.len())
            .map(|i| {
                let (slope, intercept) = maps[i / slice_len];
                (samples.get(i) * slope + intercept) as f32
            })
            .collect();
        (Some(Samples::from_f32(&physical)), LinearMap::IDENTITY)
    };
    let samples = physical.unwrap_or(samples);
    let samples = match &layout.resample {
        None => samples,
        Some(plan) => resample(&samples, plan, slice_len),
    };
    Ok(Decoded {
        samples,
        to_physical,
        warnings,
    })
}

/// Linear interpolation between neighbouring slices (integers rounded to nearest).
fn resample(source: &Samples, plan: &[(usize, usize, f64)], slice_len: usize) -> Samples {
    let kind = source.kind();
    let size = kind.size_bytes();
    let mut out = Vec::with_capacity(plan.len() * slice_len * size);
    for &(a, b, w) in plan {
        for p in 0..slice_len {
            let v = source.get(a * slice_len + p) * (1.0 - w) + source.get(b * slice_len + p) * w;
            match kind {
                SampleKind::U8 => out.push(v.round().clamp(0.0, 255.0) as u8),
                SampleKind::I8 => out.push(v.round().clamp(-128.0, 127.0) as i8 as u8),
                SampleKind::U16 => {
                    out.extend_from_slice(&(v.round().clamp(0.0, 65535.0) as u16).to_le_bytes())
                }
                SampleKind::I16 => out
                    .extend_from_slice(&(v.round().clamp(-32768.0, 32767.0) as i16).to_le_bytes()),
                SampleKind::F32 => out.extend_from_slice(&(v as f32).to_le_bytes()),
            }
        }
    }
    // The length is a whole number of samples by construction.
    Samples::from_le_bytes(kind, out).unwrap_or_else(|_| Samples::from_f32(&[]))
}
