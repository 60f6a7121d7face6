//! Reading DICOM headers without pixel data: which files a path names, and what each image
//! file says about its series, its frames' geometry and its pixel encoding.
//!
//! Decisions:
//! - A folder is walked recursively (symbolic links to folders are not followed, so a link loop
//!   cannot make the walk endless; at most [`MAX_FILES`] files and [`MAX_DEPTH`] levels). A
//!   DICOMDIR names its files in `ReferencedFileID`; components that climb out (`..`) or are
//!   absolute are ignored.
//! - Only files with the `DICM` magic at offset 128 are parsed (the standard's file format);
//!   other files in a folder (READMEs, thumbnails) are counted, not reported one by one.
//! - Declared lengths are checked against the file before dicom-rs parses it (`lengths`).
//! - Headers are read up to the pixel data (`read_until(PixelData)`), on scoped threads (one
//!   per core, at most 8), each file inside `catch_unwind`: dicom-rs has known panics on
//!   malformed input (its issue 543), and one bad file must cost only that file. A file that
//!   fails to parse, or panics, is listed with its reason and skipped.
//! - Enhanced (multi-frame) objects give one [`FrameHeader`] per frame from the per-frame and
//!   shared functional groups (per-frame first, then shared, then the top level).

use super::contain::contained;
use super::lengths;
use super::mosaic;
use crate::files::read::open_regular;
use dicom_dictionary_std::tags;
use dicom_object::{InMemDicomObject, OpenFileOptions};
use std::io::Read;
use std::path::{Path, PathBuf};

/// Most files a folder walk collects (a whole archive would be the wrong input).
pub const MAX_FILES: usize = 200_000;
/// Deepest folder level walked.
pub const MAX_DEPTH: usize = 32;
/// Most frames one multi-frame object may declare.
const MAX_FRAMES: usize = 100_000;

/// What one frame (a slice) of an image file says about its geometry and intensities.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameHeader {
    /// Frame number inside its file (0 for single-frame files).
    pub frame: u32,
    /// ImagePositionPatient: the centre of the first transmitted pixel, LPS mm.
    pub position: Option<[f64; 3]>,
    /// ImageOrientationPatient: row direction then column direction, LPS.
    pub orientation: Option<[f64; 6]>,
    /// PixelSpacing: between rows, then between columns, mm.
    pub pixel_spacing: Option<[f64; 2]>,
    /// RescaleSlope and RescaleIntercept (1 and 0 when absent).
    pub rescale: (f64, f64),
}

/// What one image file says, without its pixel data.
#[derive(Clone, Debug, PartialEq)]
pub struct FileHeader {
    /// The file.
    pub path: PathBuf,
    /// SeriesInstanceUID.
    pub series_uid: String,
    /// SeriesNumber.
    pub series_number: Option<i64>,
    /// SeriesDescription.
    pub description: String,
    /// Modality (MR, CT, ...).
    pub modality: String,
    /// SOPClassUID.
    pub sop_class: String,
    /// ImageType values (ORIGINAL\PRIMARY\M\ND, DERIVED\SECONDARY, ...), upper case.
    pub image_type: Vec<String>,
    /// InstanceNumber (only a tie-breaker: never used for ordering slices).
    pub instance_number: Option<i64>,
    /// EchoNumbers, as written.
    pub echo: String,
    /// FrameOfReferenceUID (the patient frame the positions are in).
    pub frame_of_reference: String,
    /// Rows and Columns.
    pub rows: u32,
    /// Columns.
    pub cols: u32,
    /// BitsAllocated.
    pub bits_allocated: u16,
    /// BitsStored.
    pub bits_stored: u16,
    /// PixelRepresentation 1 (two's complement).
    pub signed: bool,
    /// SamplesPerPixel.
    pub samples_per_pixel: u16,
    /// PhotometricInterpretation (MONOCHROME2, MONOCHROME1, ...), upper case.
    pub photometric: String,
    /// TransferSyntaxUID of the file meta group.
    pub transfer_syntax: String,
    /// SpacingBetweenSlices, else SliceThickness (used only for a single slice).
    pub slice_thickness: Option<f64>,
    /// One entry per frame.
    pub frames: Vec<FrameHeader>,
    /// What the file says about the scan: Modality, sequence, TR/TE/TI, contrast agent,
    /// SeriesDescription, ProtocolName (`analysis::modality` decides from them).
    pub facts: crate::analysis::ScanFacts,
    /// A Siemens mosaic: `rows` and `cols` are then one tile's, and each frame a tile.
    pub mosaic: Option<super::mosaic::Tiles>,
    /// The length PixelData declares (None: encapsulated, or not known).
    pub pixel_bytes: Option<u64>,
    /// Named on the command line (not found beside a named file): wins a tie of positions.
    pub named: bool,
}

impl FileHeader {
    /// Rows and Columns as stored (the whole mosaic for a mosaic).
    pub fn stored_size(&self) -> (u32, u32) {
        match &self.mosaic {
            Some(t) => (t.rows, t.cols),
            None => (self.rows, self.cols),
        }
    }

    /// Frames as stored (one for a mosaic).
    pub fn stored_frames(&self) -> usize {
        if self.mosaic.is_some() {
            1
        } else {
            self.frames.len()
        }
    }
}

/// A file that looked like DICOM but could not be used, and why.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Skipped {
    /// The file.
    pub path: PathBuf,
    /// One line.
    pub reason: String,
}

/// The headers of everything a path names.
#[derive(Clone, Debug, Default)]
pub struct Scan {
    /// Image files (with pixel data), sorted by path.
    pub images: Vec<FileHeader>,
    /// Corrupt or unreadable DICOM files.
    pub skipped: Vec<Skipped>,
    /// Files without the DICM magic (not DICOM files).
    pub not_dicom: usize,
    /// DICOM files without pixel data (DICOMDIR, reports, presentation states).
    pub no_pixels: usize,
    /// Notes about the input form (a single slice expanded to its folder, ...).
    pub notes: Vec<String>,
}

/// The outcome of reading one file's header.
enum Outcome {
    Image(Box<FileHeader>),
    NoPixels,
    NotDicom,
    Bad(Skipped),
}

/// True when the 132 first bytes carry the DICM magic at offset 128.
pub fn has_magic(path: &Path) -> bool {
    let mut head = [0u8; 132];
    open_regular(path).is_ok_and(|(mut f, _)| f.read_exact(&mut head).is_ok())
        && &head[128..132] == b"DICM"
}

/// Every regular file under `dir` (recursively), sorted; errors name the folder.
pub fn walk(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    let mut pending = vec![(dir.to_path_buf(), 0usize)];
    while let Some((folder, depth)) = pending.pop() {
        let entries = match std::fs::read_dir(&folder) {
            Ok(entries) => entries,
            // The top folder must be readable; a sub-folder that is not is left out.
            Err(e) if depth == 0 => return Err(e),
            Err(_) => continue,
        };
        for entry in entries.flatten() {
            let Ok(kind) = entry.file_type() else {
                continue;
            };
            let path = entry.path();
            if kind.is_dir() && depth < MAX_DEPTH {
                pending.push((path, depth + 1));
            } else if kind.is_file() || (kind.is_symlink() && path.is_file()) {
                files.push(path);
                if files.len() >= MAX_FILES {
                    files.sort();
                    return Ok(files);
                }
            }
        }
    }
    files.sort();
    Ok(files)
}

/// The files a DICOMDIR references (resolved against its folder), or None when `path` is not
/// a readable DICOMDIR.
pub fn dicomdir_files(path: &Path) -> Option<Vec<PathBuf>> {
    let base = path.parent().unwrap_or(Path::new("."));
    let bytes = crate::files::read::read_regular(path, u64::MAX).ok()?;
    if bytes.len() < 132 || &bytes[128..132] != b"DICM" {
        return None;
    }
    lengths::check(&bytes, bytes.len(), false).ok()?;
    let result = contained(|| {
        let obj = OpenFileOptions::new().from_reader(&bytes[128..]).ok()?;
        let records = obj.get(tags::DIRECTORY_RECORD_SEQUENCE)?.items()?;
        let mut files = Vec::new();
        for record in records {
            let Some(parts) = record
                .get(tags::REFERENCED_FILE_ID)
                .and_then(|e| e.to_multi_str().ok())
            else {
                continue;
            };
            let mut file = base.to_path_buf();
            let mut safe = !parts.is_empty();
            for part in parts.iter() {
                let part = part.trim();
                safe &= !part.is_empty() && part != ".." && part != "." && !part.contains('/');
                file.push(part);
            }
            if safe {
                files.push(file);
            }
        }
        files.sort();
        files.dedup();
        Some(files)
    });
    result.ok().flatten()
}

/// Reads the headers of `files` on scoped threads; the scan lists them sorted by path.
pub fn read_all(files: &[PathBuf]) -> Scan {
    let workers = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
        .clamp(1, 8)
        .min(files.len().max(1));
    let next = std::sync::atomic::AtomicUsize::new(0);
    let mut outcomes: Vec<(usize, Outcome)> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..workers)
            .map(|_| {
                scope.spawn(|| {
                    let mut mine = Vec::new();
                    loop {
                        let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(path) = files.get(i) else { break };
                        mine.push((i, read_one(path)));
                    }
                    mine
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap_or_default())
            .collect()
    });
    outcomes.sort_by_key(|(i, _)| *i);
    let mut scan = Scan::default();
    for (_, outcome) in outcomes {
        match outcome {
            Outcome::Image(h) => scan.images.push(*h),
            Outcome::NoPixels => scan.no_pixels += 1,
            Outcome::NotDicom => scan.not_dicom += 1,
            Outcome::Bad(s) => scan.skipped.push(s),
        }
    }
    scan
}

/// One file's header.
fn read_one(path: &Path) -> Outcome {
    // Non-blocking open of regular files only: a FIFO must not hang the read.
    let (mut file, meta) = match open_regular(path) {
        Ok(f) => f,
        Err(e) => {
            return Outcome::Bad(Skipped {
                path: path.to_path_buf(),
                reason: format!("cannot be read: {e}"),
            });
        }
    };
    let mut head = [0u8; 132];
    if file.read_exact(&mut head).is_err() || &head[128..132] != b"DICM" {
        return Outcome::NotDicom;
    }
    let bad = |reason: String| {
        Outcome::Bad(Skipped {
            path: path.to_path_buf(),
            reason,
        })
    };
    let file_len = usize::try_from(meta.len()).unwrap_or(usize::MAX);
    // The lengths up to the pixel data are checked before dicom-rs sees them (lengths.rs);
    // usually the first 16 KB hold them all.
    let mut bytes = head.to_vec();
    let mut want = 16 * 1024;
    let seen = loop {
        let more = want.min(file_len).saturating_sub(bytes.len());
        if let Err(e) = (&mut file).take(more as u64).read_to_end(&mut bytes) {
            return bad(format!("cannot be read: {e}"));
        }
        match lengths::check_seen(&bytes, file_len.max(bytes.len()), true) {
            Err(reason) => return bad(reason),
            Ok((lengths::Walk::NeedMore, _)) if bytes.len() < file_len => {
                want = want.saturating_mul(4)
            }
            Ok((_, s)) => break s,
        }
    };
    // The parser starts at the magic; the file goes on where `bytes` ends.
    let reader = (&bytes[128..]).chain(std::io::BufReader::with_capacity(16 * 1024, file));
    match parse_header(reader, path) {
        Ok(Some(mut h)) => {
            h.pixel_bytes = seen.pixel_len.flatten().map(|n| n as u64);
            match super::consistency::check(&h) {
                Ok(()) => Outcome::Image(Box::new(h)),
                Err(reason) => bad(reason),
            }
        }
        Ok(None) => Outcome::NoPixels,
        Err(reason) => Outcome::Bad(Skipped {
            path: path.to_path_buf(),
            reason,
        }),
    }
}

/// Parses a header from what follows the 128-byte preamble (the `DICM` magic, then the file
/// meta group).
/// Ok(None): a valid DICOM object without pixel data. Also the fuzz target's entry point.
pub fn parse_header(reader: impl Read, path: &Path) -> Result<Option<FileHeader>, String> {
    let parsed = contained(|| {
        OpenFileOptions::new()
            .read_until(tags::PIXEL_DATA)
            .from_reader(reader)
    })?;
    let obj = parsed.map_err(|e| one_line(&e.to_string()))?;
    let transfer_syntax = obj
        .meta()
        .transfer_syntax()
        .trim_end_matches('\0')
        .to_string();
    contained(|| describe(&obj, path, transfer_syntax))?
}

/// The header facts of a parsed object.
fn describe(
    obj: &InMemDicomObject,
    path: &Path,
    transfer_syntax: String,
) -> Result<Option<FileHeader>, String> {
    let (Some(rows), Some(cols)) = (int(obj, tags::ROWS), int(obj, tags::COLUMNS)) else {
        return Ok(None);
    };
    if !(1..=65535).contains(&rows) || !(1..=65535).contains(&cols) {
        return Err(format!(
            "Rows x Columns {rows} x {cols} is not an image size"
        ));
    }
    let frame_count = int(obj, tags::NUMBER_OF_FRAMES).unwrap_or(1).max(1);
    if frame_count as usize > MAX_FRAMES {
        return Err(format!(
            "declares {frame_count} frames (at most {MAX_FRAMES})"
        ));
    }
    let (bits_allocated, bits_stored) = bits(obj)?;
    let slice_thickness = float(obj, tags::SPACING_BETWEEN_SLICES)
        .or_else(|| float(obj, tags::SLICE_THICKNESS))
        .filter(|t| t.is_finite() && *t > 0.0);
    let mut frames = frames(obj, frame_count as usize);
    let image_type: Vec<String> = strings(obj, tags::IMAGE_TYPE)
        .iter()
        .map(|s| s.trim().to_ascii_uppercase())
        .collect();
    let csa = obj
        .get(dicom_core::Tag(0x0029, 0x1010))
        .and_then(|e| e.to_bytes().ok())
        .map(|b| b.into_owned());
    let mosaic = if frame_count == 1 {
        mosaic::tiles(
            &image_type,
            private_us(obj, dicom_core::Tag(0x0019, 0x100A)),
            csa.as_deref(),
            rows as u32,
            cols as u32,
        )?
    } else {
        None
    };
    let (rows, cols) = match &mosaic {
        Some(tiles) => {
            let spacing = slice_thickness.unwrap_or(1.0);
            frames = mosaic::frames(&frames[0], tiles, csa.as_deref(), spacing);
            (tiles.tile_rows() as i64, tiles.tile_cols() as i64)
        }
        None => (rows, cols),
    };
    Ok(Some(FileHeader {
        path: path.to_path_buf(),
        series_uid: text(obj, tags::SERIES_INSTANCE_UID),
        series_number: int(obj, tags::SERIES_NUMBER),
        description: text(obj, tags::SERIES_DESCRIPTION),
        modality: text(obj, tags::MODALITY),
        sop_class: text(obj, tags::SOP_CLASS_UID),
        image_type,
        instance_number: int(obj, tags::INSTANCE_NUMBER),
        echo: text(obj, tags::ECHO_NUMBERS),
        frame_of_reference: text(obj, tags::FRAME_OF_REFERENCE_UID),
        rows: rows as u32,
        cols: cols as u32,
        bits_allocated,
        bits_stored,
        signed: int(obj, tags::PIXEL_REPRESENTATION) == Some(1),
        samples_per_pixel: int(obj, tags::SAMPLES_PER_PIXEL).unwrap_or(1).clamp(0, 16) as u16,
        photometric: text(obj, tags::PHOTOMETRIC_INTERPRETATION)
            .trim()
            .to_ascii_uppercase(),
        transfer_syntax,
        slice_thickness,
        frames,
        facts: scan_facts(obj),
        mosaic,
        pixel_bytes: None,
        named: false,
    }))
}

/// BitsAllocated and BitsStored, refused when they contradict each other (BitsStored 0 or
/// above BitsAllocated would turn every value into garbage: issue 30).
fn bits(obj: &InMemDicomObject) -> Result<(u16, u16), String> {
    let allocated = int(obj, tags::BITS_ALLOCATED).unwrap_or(16);
    if !(1..=64).contains(&allocated) {
        return Err(format!(
            "BitsAllocated {allocated} is not a pixel size (1 to 64 bits)"
        ));
    }
    let stored = int(obj, tags::BITS_STORED).unwrap_or(allocated);
    if !(1..=allocated).contains(&stored) {
        return Err(format!(
            "BitsStored {stored} contradicts BitsAllocated {allocated} (it must be 1 to \
             {allocated})"
        ));
    }
    Ok((allocated as u16, stored as u16))
}

/// An unsigned 16-bit private value: US in explicit VR, two raw bytes (UN) in implicit VR.
fn private_us(obj: &InMemDicomObject, tag: dicom_core::Tag) -> Option<i64> {
    let e = obj.get(tag)?;
    e.to_int::<i64>().ok().or_else(|| {
        let b = e.to_bytes().ok()?;
        (b.len() == 2).then(|| u16::from_le_bytes([b[0], b[1]]) as i64)
    })
}

/// The tags `analysis::modality` reads: top level first, then the shared functional groups of
/// an enhanced MR object (its TR, effective TE and TI live there).
fn scan_facts(obj: &InMemDicomObject) -> crate::analysis::ScanFacts {
    let some = |s: String| Some(s).filter(|s| !s.is_empty());
    let shared = obj
        .get(tags::SHARED_FUNCTIONAL_GROUPS_SEQUENCE)
        .and_then(|e| e.items())
        .and_then(|items| items.first());
    let grouped = |seq, tag| {
        let item = shared?.get(seq)?.items()?.first()?;
        floats(item, tag)?.first().copied()
    };
    let time = |v: Option<f64>| v.filter(|t| t.is_finite() && *t > 0.0);
    crate::analysis::ScanFacts {
        modality: some(text(obj, tags::MODALITY)),
        scanning_sequence: some(strings(obj, tags::SCANNING_SEQUENCE).join("\\")),
        sequence_variant: some(strings(obj, tags::SEQUENCE_VARIANT).join("\\")),
        repetition_time_ms: time(float(obj, tags::REPETITION_TIME).or_else(|| {
            grouped(
                tags::MR_TIMING_AND_RELATED_PARAMETERS_SEQUENCE,
                tags::REPETITION_TIME,
            )
        })),
        echo_time_ms: time(
            float(obj, tags::ECHO_TIME)
                .or_else(|| grouped(tags::MR_ECHO_SEQUENCE, tags::EFFECTIVE_ECHO_TIME)),
        ),
        inversion_time_ms: time(
            float(obj, tags::INVERSION_TIME)
                .or_else(|| grouped(tags::MR_MODIFIER_SEQUENCE, tags::INVERSION_TIMES)),
        ),
        contrast_agent: some(text(obj, tags::CONTRAST_BOLUS_AGENT)),
        series_description: some(text(obj, tags::SERIES_DESCRIPTION)),
        protocol_name: some(text(obj, tags::PROTOCOL_NAME)),
        sources: vec!["DICOM header".into()],
        ..Default::default()
    }
}

/// One [`FrameHeader`] per frame: functional groups (per-frame, then shared), then the top
/// level.
fn frames(obj: &InMemDicomObject, count: usize) -> Vec<FrameHeader> {
    let per_frame = obj
        .get(tags::PER_FRAME_FUNCTIONAL_GROUPS_SEQUENCE)
        .and_then(|e| e.items())
        .unwrap_or(&[]);
    let shared = obj
        .get(tags::SHARED_FUNCTIONAL_GROUPS_SEQUENCE)
        .and_then(|e| e.items())
        .and_then(|items| items.first());
    (0..count)
        .map(|f| {
            let groups: Vec<&InMemDicomObject> =
                per_frame.get(f).into_iter().chain(shared).collect();
            let find = |seq, tag| {
                groups
                    .iter()
                    .find_map(|g| {
                        let item = g.get(seq)?.items()?.first()?;
                        floats(item, tag)
                    })
                    .or_else(|| floats(obj, tag))
            };
            let position = find(tags::PLANE_POSITION_SEQUENCE, tags::IMAGE_POSITION_PATIENT)
                .and_then(|v| fixed::<3>(&v));
            let orientation = find(
                tags::PLANE_ORIENTATION_SEQUENCE,
                tags::IMAGE_ORIENTATION_PATIENT,
            )
            .and_then(|v| fixed::<6>(&v));
            let pixel_spacing = find(tags::PIXEL_MEASURES_SEQUENCE, tags::PIXEL_SPACING)
                .and_then(|v| fixed::<2>(&v));
            let slope = find(
                tags::PIXEL_VALUE_TRANSFORMATION_SEQUENCE,
                tags::RESCALE_SLOPE,
            )
            .and_then(|v| v.first().copied())
            .filter(|s| s.is_finite() && *s != 0.0)
            .unwrap_or(1.0);
            let intercept = find(
                tags::PIXEL_VALUE_TRANSFORMATION_SEQUENCE,
                tags::RESCALE_INTERCEPT,
            )
            .and_then(|v| v.first().copied())
            .filter(|s| s.is_finite())
            .unwrap_or(0.0);
            FrameHeader {
                frame: f as u32,
                position,
                orientation,
                pixel_spacing,
                rescale: (slope, intercept),
            }
        })
        .collect()
}

/// The first N values, when there are N finite ones.
fn fixed<const N: usize>(values: &[f64]) -> Option<[f64; N]> {
    let array: [f64; N] = values.get(..N)?.try_into().ok()?;
    array.iter().all(|v| v.is_finite()).then_some(array)
}

/// A trimmed text value ("" when absent).
fn text(obj: &InMemDicomObject, tag: dicom_core::Tag) -> String {
    obj.get(tag)
        .and_then(|e| e.to_str().ok())
        .map(|s| {
            s.trim_matches(|c: char| c.is_whitespace() || c == '\0')
                .to_string()
        })
        .unwrap_or_default()
}

/// All text values.
fn strings(obj: &InMemDicomObject, tag: dicom_core::Tag) -> Vec<String> {
    obj.get(tag)
        .and_then(|e| e.to_multi_str().ok())
        .map(|v| v.to_vec())
        .unwrap_or_default()
}

/// An integer value.
fn int(obj: &InMemDicomObject, tag: dicom_core::Tag) -> Option<i64> {
    obj.get(tag).and_then(|e| e.to_int::<i64>().ok())
}

/// A finite float value.
fn float(obj: &InMemDicomObject, tag: dicom_core::Tag) -> Option<f64> {
    obj.get(tag)
        .and_then(|e| e.to_float64().ok())
        .filter(|v| v.is_finite())
}

/// All float values.
fn floats(obj: &InMemDicomObject, tag: dicom_core::Tag) -> Option<Vec<f64>> {
    obj.get(tag).and_then(|e| e.to_multi_float64().ok())
}

/// `text` on one line.
pub fn one_line(text: &str) -> String {
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}
