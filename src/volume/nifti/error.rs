//! Every way loading a NIfTI / ANALYZE file can fail.
//!
//! Decisions:
//! - One enum for the whole loader, so the engine matches one type whichever phase (read,
//!   inflate, parse) failed.
//! - Each `Display` is one sentence that names the offending field or byte position and what was
//!   expected, so a person can tell a truncated download from a wrong file type without a debugger.
//! - Repairs that still let the file load are not errors: they are warnings on the `Volume`.

use crate::files::read::ReadError;
use std::path::PathBuf;

/// A NIfTI / ANALYZE file could not be loaded (or written).
#[derive(Debug, thiserror::Error)]
pub enum NiftiError {
    /// Reading or writing a file failed at the operating-system level.
    #[error("could not {action} {path}: {source}")]
    Io {
        /// `read` or `write`.
        action: &'static str,
        /// The file concerned.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },

    /// The path is not a regular file, is larger than accepted, or changed while read.
    #[error(transparent)]
    File(ReadError),

    /// The gzip data inflates to more bytes than the header declares (a damaged file, or a
    /// "zip bomb"): inflation stops at the limit instead of filling memory.
    #[error(
        "the gzip data inflates past {limit} bytes, more than the {declared} bytes {what} (plus {slack} bytes of slack for trailing data): the file is damaged, or its header does not describe its contents"
    )]
    GzipTooLarge {
        /// Bytes accepted (the declared size plus the slack).
        limit: usize,
        /// Bytes the header declares.
        declared: usize,
        /// Slack accepted after the declared size.
        slack: usize,
        /// Whose declaration: `its header declares`, `the .hdr declares for the image`, ...
        what: &'static str,
    },

    /// What the header declares does not fit in the host's available memory (checked before
    /// inflating: a 2 MB `.nii.gz` may honestly declare 1024^3 voxels).
    #[error("{0}")]
    NotEnoughMemory(String),

    /// A gzip member could not be inflated (bad deflate data, checksum or length mismatch, or the
    /// file was cut short).
    #[error(
        "gzip member {member} starting at byte {offset} is corrupt or truncated: libdeflate could not inflate it (bad compressed data, CRC or length)"
    )]
    GzipCorrupt {
        /// 1-based number of the member.
        member: usize,
        /// Byte offset of the member in the compressed file.
        offset: usize,
    },

    /// Bytes after the last complete gzip member are neither zero padding nor another member.
    #[error(
        "the gzip data ends with {len} bytes at byte {offset} that are neither another gzip member nor zero padding"
    )]
    GzipTrailingGarbage {
        /// Where the unexpected bytes start.
        offset: usize,
        /// How many bytes follow.
        len: usize,
    },

    /// Memory for the inflated data (or converted samples) could not be allocated.
    #[error("could not allocate {bytes} bytes for {what}")]
    OutOfMemory {
        /// Size of the failed request.
        bytes: usize,
        /// What the memory was for.
        what: &'static str,
    },

    /// The data is shorter than the header it claims to start with.
    #[error("the file is {len} bytes long, too short for a {what} header of {needed} bytes")]
    TooShort {
        /// Length of the (inflated) data.
        len: usize,
        /// Bytes the header needs.
        needed: usize,
        /// `NIfTI-1`, `NIfTI-2`, ...
        what: &'static str,
    },

    /// `sizeof_hdr` is neither 348 nor 540 in either byte order.
    #[error(
        "not a NIfTI or ANALYZE file: sizeof_hdr reads {little} (little-endian) or {big} (big-endian), but must be 348 (NIfTI-1 / ANALYZE 7.5) or 540 (NIfTI-2)"
    )]
    NotNifti {
        /// First four bytes read as a little-endian i32.
        little: i32,
        /// First four bytes read as a big-endian i32.
        big: i32,
    },

    /// A NIfTI-2 header without the `n+2` / `ni2` magic.
    #[error(
        "the 540-byte header has magic {found:?}, but a NIfTI-2 header must say \"n+2\" or \"ni2\""
    )]
    BadMagic {
        /// The magic bytes found, lossily decoded.
        found: String,
    },

    /// The four bytes after the NIfTI-2 magic are not `\r\n\x1a\n`.
    #[error(
        "the NIfTI-2 magic is followed by {found:02x?} instead of 0d 0a 1a 0a: the file was probably altered by a text-mode transfer"
    )]
    Nifti2Eol {
        /// The four bytes found.
        found: [u8; 4],
    },

    /// `dim[0]` is not between 1 and 7.
    #[error("dim[0] is {dim0}, but a NIfTI image has 1 to 7 dimensions")]
    BadDimCount {
        /// The value read.
        dim0: i64,
    },

    /// One of `dim[1..=dim[0]]` is zero or negative.
    #[error("dim[{axis}] is {value}, but every used dimension must be at least 1")]
    BadDim {
        /// Index into `dim` (1-based axis number).
        axis: usize,
        /// The value read.
        value: i64,
    },

    /// The dimensions describe more bytes than can be addressed.
    #[error(
        "the dimensions {dims:?} with {bytes_per_voxel} bytes per voxel describe more data than this machine can address"
    )]
    SizeOverflow {
        /// `dim[1..=dim[0]]`.
        dims: Vec<i64>,
        /// Bytes per voxel of the datatype.
        bytes_per_voxel: usize,
    },

    /// `datatype` is not a code the NIfTI standard defines.
    #[error("datatype code {code} is not a NIfTI datatype")]
    UnknownDatatype {
        /// The code read.
        code: i16,
    },

    /// `datatype` is a valid NIfTI code that morphray does not render.
    #[error(
        "datatype {name} (code {code}) is not supported: morphray renders real-valued scalar or RGB intensities only"
    )]
    UnsupportedDatatype {
        /// NIfTI name of the datatype, e.g. `complex64`.
        name: &'static str,
        /// The code read.
        code: i16,
    },

    /// `vox_offset` is not a usable byte position.
    #[error(
        "vox_offset {value} is not a valid byte position: it must be a finite, whole, non-negative number"
    )]
    BadVoxOffset {
        /// The value read.
        value: f64,
    },

    /// `vox_offset` is a whole number, but larger than any file can be (2^63 bytes).
    #[error(
        "vox_offset {} is beyond any file (file sizes end before 2^63 bytes): the header is damaged",
        shortest(*value)
    )]
    VoxOffsetBeyondAnyFile {
        /// The value read.
        value: f64,
    },

    /// The voxel data does not fit in the file.
    #[error(
        "{file} ends at byte {len}, but the header promises {needed} bytes of voxels starting at byte {offset}"
    )]
    TruncatedData {
        /// `file` or `image file`.
        file: &'static str,
        /// Length of the (inflated) data.
        len: usize,
        /// Bytes of voxels the header describes (all frames).
        needed: usize,
        /// Where the voxels start.
        offset: usize,
    },

    /// `LoadOptions::frame` is beyond the last frame.
    #[error("frame {frame} was requested, but the file has {frames} frame(s) (numbered from 0)")]
    FrameOutOfRange {
        /// Requested frame.
        frame: usize,
        /// Frames in the file.
        frames: usize,
    },

    /// The header says the voxels are in a separate `.img` file, but only the header was given.
    #[error(
        "this {version} header keeps its voxels in a separate .img file: load it with load_path on the .hdr, or parse_pair with both files"
    )]
    SeparateImageFile {
        /// `NIfTI-1 (ni1)`, `NIfTI-2 (ni2)` or `ANALYZE 7.5`.
        version: &'static str,
    },

    /// The companion `.img` (or `.hdr`) file of a pair could not be found.
    #[error("{path} belongs to a header/image pair, but no {wanted} file was found next to it")]
    MissingCompanion {
        /// The file given.
        path: PathBuf,
        /// `.img` or `.hdr`.
        wanted: &'static str,
    },

    /// A 348-byte header whose magic is neither NIfTI-1's nor empty, with no `.img` next to it:
    /// damaged NIfTI-1 rather than ANALYZE 7.5 (which would need the `.img`).
    #[error(
        "{path}: the 348-byte header's magic is {found:?}, not NIfTI-1's \"n+1\" (single file) or \"ni1\" (pair){detail}, and there is no .img file next to it: the header is damaged (or it is an ANALYZE 7.5 header whose .img is missing)"
    )]
    BadNifti1Magic {
        /// The file given.
        path: PathBuf,
        /// The magic bytes found, lossily decoded, up to the first NUL.
        found: String,
        /// A hint for a recognisable mistake (for example NIfTI-2's magic), or empty.
        detail: &'static str,
    },

    /// The writer was given a volume NIfTI-1 cannot describe.
    #[error("cannot write {what} as NIfTI-1: {why}")]
    Unwritable {
        /// What was being written.
        what: String,
        /// Why it does not fit NIfTI-1.
        why: String,
    },
}

impl From<ReadError> for NiftiError {
    /// Operating-system failures keep the [`NiftiError::Io`] shape (action `read`); refusals
    /// (not a regular file, too large, grew while read) are [`NiftiError::File`].
    fn from(e: ReadError) -> Self {
        match e {
            ReadError::Io { path, source } => NiftiError::Io {
                action: "read",
                path,
                source,
            },
            other => NiftiError::File(other),
        }
    }
}

/// `value` in scientific notation with the fewest digits that identify it: as an f32 when it is
/// one (NIfTI-1 stores f32, so its 1e20 prints as `1e20`, not `1.0000000200408773e20`).
fn shortest(value: f64) -> String {
    let narrow = value as f32;
    if f64::from(narrow) == value {
        format!("{narrow:e}")
    } else {
        format!("{value:e}")
    }
}
