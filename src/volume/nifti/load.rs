//! Loading from disk: the command line's whole input path, from a path to a volume, in timed
//! phases (read, inflate, convert), and the pairing of `.hdr` and `.img` files.
//!
//! Decisions:
//! - This is the one sequence both the command line (cli/source.rs) and the `input_path` fuzz
//!   target run, so the fuzzed code is the shipped code.
//! - Files are read with [`read_regular`]: a FIFO, a device or a directory is refused when
//!   opened (never blocks, never reads without end); the file's length is the cap.
//! - Either file of a pair may be given: `x.img`, `x.img.gz` or `X.IMG` finds its `.hdr`
//!   (same stem, the given case first, with or without `.gz`) just as a `.hdr` finds its `.img`.
//!   gzip is detected by content, never by name.
//! - A 348-byte header with a magic that is neither NIfTI-1's nor empty is read as ANALYZE 7.5,
//!   which needs an `.img`; when there is none, the error is about the magic (the likely cause:
//!   a damaged header), not a missing `.img`.

use super::error::NiftiError;
use super::header::{self, Decoded, Storage, Version};
use super::{LoadOptions, LoadedNifti, bounded, build_pair, build_single};
use crate::files::read::read_regular;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Host times of the three phases, milliseconds (summed over both files of a pair).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PhaseTimes {
    /// Reading the file(s).
    pub read_ms: f64,
    /// Inflating gzip (and decoding the header, which bounds it).
    pub inflate_ms: f64,
    /// Validation and conversion of the frame.
    pub convert_ms: f64,
}

/// Phase 1: reads a whole regular file (a FIFO, device or directory is refused at once). Errors
/// name the path.
pub fn read_file(path: &Path) -> Result<Vec<u8>, NiftiError> {
    Ok(read_regular(path, u64::MAX)?)
}

/// All three phases for a file on disk (`.nii`, `.nii.gz`, or either file of a `.hdr`/`.img`
/// pair). `Volume::name` is the given file's name.
pub fn load_path(path: &Path, opts: &LoadOptions) -> Result<LoadedNifti, NiftiError> {
    load_file_timed(path, opts, &mut |_| {}).map(|(loaded, _)| loaded)
}

/// What the command line does with an input path, phase by phase: reads the file (and, for a
/// pair, its companion), inflates within the sizes the header declares, converts the frame.
/// `on_read` sees the bytes of the given file as read (for its hash), before inflation; its
/// time is not counted in any phase.
pub fn load_file_timed(
    path: &Path,
    opts: &LoadOptions,
    on_read: &mut dyn FnMut(&[u8]),
) -> Result<(LoadedNifti, PhaseTimes), NiftiError> {
    let mut times = PhaseTimes::default();
    let name = file_name(path);
    let image_given = is_image_name(&name);

    let clock = Instant::now();
    let read_span = crate::files::trace::span("read", "io");
    let header_path = if image_given {
        companion(path, false)?
    } else {
        path.to_path_buf()
    };
    let first = read_file(&header_path)?;
    times.read_ms += ms(clock);
    drop(read_span);
    // After the clock: hashing is the caller's work, not reading.
    if !image_given {
        on_read(&first);
    }

    let clock = Instant::now();
    let inflate_span = crate::files::trace::span("inflate", "io");
    let (header_bytes, header_members) = bounded::inflate_if_gzip(first)?;
    let decoded = header::decode(&header_bytes)?;
    times.inflate_ms += ms(clock);
    drop(inflate_span);

    if decoded.storage == Storage::SingleFile && !image_given {
        let clock = Instant::now();
        let _span = crate::files::trace::span("convert", "io");
        let mut loaded = build_single(decoded, header_bytes, &name, opts, header_members)?;
        loaded.header.set_gzip_members(header_members);
        times.convert_ms += ms(clock);
        return Ok((loaded, times));
    }

    let clock = Instant::now();
    let read_span = crate::files::trace::span("read image", "io");
    let image_path = if image_given {
        path.to_path_buf()
    } else {
        companion(path, true).map_err(|e| bad_magic(&decoded, path).unwrap_or(e))?
    };
    let image = read_file(&image_path)?;
    times.read_ms += ms(clock);
    drop(read_span);
    if image_given {
        on_read(&image);
    }

    let clock = Instant::now();
    let inflate_span = crate::files::trace::span("inflate image", "io");
    let (image, image_members) = bounded::inflate_image(image, &decoded)?;
    times.inflate_ms += ms(clock);
    drop(inflate_span);

    let clock = Instant::now();
    let _span = crate::files::trace::span("convert", "io");
    let members = header_members + image_members;
    let mut loaded = build_pair(decoded, &header_bytes, image, &name, opts, members)?;
    loaded.header.set_gzip_members(members);
    times.convert_ms += ms(clock);
    Ok((loaded, times))
}

fn ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

/// For a header read as ANALYZE 7.5 only because its magic is not NIfTI-1's (and not empty):
/// the error to give when no `.img` goes with it.
fn bad_magic(decoded: &Decoded, path: &Path) -> Option<NiftiError> {
    let magic = decoded.header.magic;
    if decoded.version != Version::Analyze75 || magic == [0; 4] {
        return None;
    }
    let end = magic.iter().position(|&b| b == 0).unwrap_or(magic.len());
    let found = String::from_utf8_lossy(magic.get(..end).unwrap_or_default()).into_owned();
    let detail = if found == "n+2" || found == "ni2" {
        " (it is NIfTI-2's magic, but sizeof_hdr says 348, a NIfTI-1 header)"
    } else {
        ""
    };
    Some(NiftiError::BadNifti1Magic {
        path: path.to_path_buf(),
        found,
        detail,
    })
}

/// True for `.img` and `.img.gz` names, in any case.
fn is_image_name(name: &str) -> bool {
    let lower = name.to_ascii_lowercase();
    lower.ends_with(".img") || lower.ends_with(".img.gz")
}

/// The file name without directories, for `Volume::name`.
fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

/// Strips `.gz` and one more extension, case-insensitively: `a/b.hdr.gz` -> `a/b`. Also says
/// whether the given extension is upper case.
fn stem_path(path: &Path) -> (PathBuf, bool) {
    let name = file_name(path);
    let lower = name.to_ascii_lowercase();
    let gz = lower.ends_with(".gz");
    let base = if gz {
        name.get(..name.len() - 3).unwrap_or(&name)
    } else {
        &name
    };
    let base = match base.rfind('.') {
        Some(dot) if dot > 0 => base.get(..dot).unwrap_or(base),
        _ => base,
    };
    let upper = name
        .chars()
        .rev()
        .find(|c| c.is_ascii_alphabetic())
        .is_some_and(|c| c.is_ascii_uppercase());
    (path.with_file_name(base), upper)
}

/// Finds the other file of a pair next to `path`: `.img` for a header, `.hdr` for an image,
/// with or without `.gz`, matching the case of the given extension first. (`is_file` follows
/// links and only stats: nothing is opened here.)
fn companion(path: &Path, want_image: bool) -> Result<PathBuf, NiftiError> {
    let (stem, upper) = stem_path(path);
    let ext = if want_image { "img" } else { "hdr" };
    let exts = if upper {
        [ext.to_ascii_uppercase(), ext.to_string()]
    } else {
        [ext.to_string(), ext.to_ascii_uppercase()]
    };
    let stem_text = stem.as_os_str().to_owned();
    for e in &exts {
        for gz in ["", ".gz", ".GZ"] {
            let mut candidate = stem_text.clone();
            candidate.push(format!(".{e}{gz}"));
            let candidate = PathBuf::from(candidate);
            if candidate.is_file() {
                return Ok(candidate);
            }
        }
    }
    Err(NiftiError::MissingCompanion {
        path: path.to_path_buf(),
        wanted: if want_image { ".img" } else { ".hdr" },
    })
}
