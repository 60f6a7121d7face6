//! Volume sources behind one interface: what to open ([`VolumeSource`]), the readers that turn
//! a file into a [`Volume`] ([`VolumeReader`]), the registry that picks one, and the
//! format-independent [`InputError`].
//!
//! Decisions:
//! - A reader says whether a path looks like its format (`claims`: NIfTI by name only; DICOM,
//!   asked after it, also claims folders and files with the DICM magic, so it may stat the path
//!   and read 132 bytes) and reads it with per-phase timings. The registry ([`READERS`]) asks
//!   them in order; a path no reader claims goes to the first (NIfTI), whose magic check then
//!   says precisely why the file is not a volume. Nothing in the engine or the CLI names a
//!   format; DICOM's series listing (`dicom::survey`) is public for `morphray info`.
//! - [`InputError`] is the same for every format: either the reader's error names the path
//!   itself (I/O, a missing companion, a wrong magic) or it is about the contents and is
//!   prefixed with the file's name. The reader's own typed error stays reachable
//!   ([`InputError::nifti`] downcasts), so tests and integrators can still match on it.
//! - The phantom is a source like a file (generated instead of read), so every client opens it
//!   through the same path.
//! - The hash of the input (PNG provenance) is taken here, over the bytes as read (a file) or
//!   the samples (the phantom), outside the timed phases.

pub mod dicom;
mod nifti;

use super::Volume;
use super::nifti::HeaderSummary;
use super::phantom::{self, PhantomError, PhantomSpec};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What to open.
#[derive(Clone, Debug, PartialEq)]
pub enum VolumeSource {
    /// A file on disk, read by the reader the registry picks.
    File(PathBuf),
    /// Several paths read as one input: the files (or folders) of one DICOM exam, as a shell
    /// glob gives them. Every path must be DICOM; a NIfTI volume is one file.
    Files(Vec<PathBuf>),
    /// A generated phantom.
    Phantom(PhantomSpec),
}

impl VolumeSource {
    /// A file, or the cohort-A phantom when `path` is None (the command line's default).
    pub fn file_or_phantom(path: Option<&Path>) -> VolumeSource {
        match path {
            Some(p) => VolumeSource::File(p.to_path_buf()),
            None => VolumeSource::Phantom(PhantomSpec::cohort_a()),
        }
    }

    /// The command line's inputs: none is the cohort-A phantom, one a file, several one
    /// DICOM input.
    pub fn from_paths(paths: &[PathBuf]) -> VolumeSource {
        match paths {
            [] => VolumeSource::Phantom(PhantomSpec::cohort_a()),
            [one] => VolumeSource::File(one.clone()),
            many => VolumeSource::Files(many.to_vec()),
        }
    }

    /// The file's name (without directories), or `phantom`.
    pub fn label(&self) -> String {
        match self {
            VolumeSource::File(path) => file_name(path),
            VolumeSource::Files(paths) => format!(
                "{} and {} more",
                paths.first().map(|p| file_name(p)).unwrap_or_default(),
                paths.len().saturating_sub(1)
            ),
            VolumeSource::Phantom(_) => "phantom".into(),
        }
    }

    /// The file (the first of several), None for a phantom.
    pub fn path(&self) -> Option<&Path> {
        match self {
            VolumeSource::File(path) => Some(path),
            VolumeSource::Files(paths) => paths.first().map(PathBuf::as_path),
            VolumeSource::Phantom(_) => None,
        }
    }

    /// Every path the source reads (none for a phantom): what an output must not overwrite.
    pub fn paths(&self) -> Vec<&Path> {
        match self {
            VolumeSource::File(path) => vec![path.as_path()],
            VolumeSource::Files(paths) => paths.iter().map(PathBuf::as_path).collect(),
            VolumeSource::Phantom(_) => Vec::new(),
        }
    }
}

/// How to read a source.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// Which frame of a 4-D (or higher) file, from 0.
    pub frame: usize,
    /// Compute the SHA-256 of the input (provenance).
    pub hash: bool,
    /// Which series of a DICOM input (None: the largest 3-D series); ignored by other formats.
    pub series: Option<dicom::SeriesChoice>,
}

/// Host times of reading, in milliseconds (0 for phases that did not apply).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct LoadTimings {
    /// Reading the file.
    pub read_ms: f64,
    /// Inflating gzip.
    pub inflate_ms: f64,
    /// Header validation and sample conversion.
    pub convert_ms: f64,
    /// Generating the phantom.
    pub phantom_ms: f64,
    /// Threads the reader may use for a large read, inflation or copy
    /// (files/parallel.rs: the cores, at most 16, or `MORPHRAY_IO_THREADS`).
    pub io_threads: usize,
    /// gzip members of the file (0: not compressed; more than 1 inflate in parallel).
    pub gzip_members: usize,
}

/// A volume read from a source.
#[derive(Clone, Debug)]
pub struct SourceVolume {
    /// File name or `phantom`.
    pub label: String,
    /// The chosen frame, ready for the engine (repairs listed in `volume.warnings`).
    pub volume: Volume,
    /// NIfTI/ANALYZE header facts (None for the phantom and for formats without one).
    pub header: Option<HeaderSummary>,
    /// SHA-256 of the file's bytes as read, or of the phantom's samples (when requested).
    pub sha256: Option<String>,
    /// Phase times.
    pub timings: LoadTimings,
    /// The series of a DICOM input (None for other formats): what a viewer offers to switch to.
    pub series: Option<SeriesListing>,
}

/// Every stack of a DICOM input and the one that was read.
#[derive(Clone, Debug)]
pub struct SeriesListing {
    /// Index of the stack read, in `all`.
    pub chosen: usize,
    /// The stacks, in `morphray info`'s order (index = `--series` index).
    pub all: Vec<dicom::SeriesInfo>,
}

/// Why a source could not be read, whatever its format.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    /// The reader's message names the path itself (I/O, a missing companion file, a magic
    /// that belongs to no format).
    #[error(transparent)]
    Path(Box<dyn std::error::Error + Send + Sync + 'static>),
    /// What is wrong with the contents of a named file.
    #[error("{file}: {source}")]
    Contents {
        /// The file's name.
        file: String,
        /// The reader's error.
        source: Box<dyn std::error::Error + Send + Sync + 'static>,
    },
    /// Generating the phantom.
    #[error(transparent)]
    Phantom(#[from] PhantomError),
    /// The thread that read the source stopped without an answer (a bug).
    #[error("the thread reading the volume stopped unexpectedly; please report it")]
    ReaderStopped,
}

impl InputError {
    /// The NIfTI/ANALYZE reader's error, when that reader failed.
    pub fn nifti(&self) -> Option<&super::nifti::NiftiError> {
        match self {
            InputError::Path(e) | InputError::Contents { source: e, .. } => e.downcast_ref(),
            _ => None,
        }
    }
}

/// A file format.
pub trait VolumeReader: Sync {
    /// The format's name, for messages (`NIfTI/ANALYZE`).
    fn name(&self) -> &'static str;
    /// True when `path`'s name looks like this format (no I/O).
    fn claims(&self, path: &Path) -> bool;
    /// Reads `path`: the frame `options.frame`, its hash when asked, with phase times.
    fn read(&self, path: &Path, options: &ReadOptions) -> Result<SourceVolume, InputError>;
}

/// Every reader, in the order they are asked; the first also takes what nobody claims.
pub static READERS: &[&dyn VolumeReader] = &[&nifti::NiftiReader, &dicom::DicomReader];

/// The reader for `path`: the first that claims it, else the first of [`READERS`].
pub fn reader_for(path: &Path) -> &'static dyn VolumeReader {
    READERS
        .iter()
        .copied()
        .find(|r| r.claims(path))
        .unwrap_or(READERS[0])
}

/// Reads `source` (see [`VolumeReader::read`]); a phantom is generated.
pub fn read(source: &VolumeSource, options: &ReadOptions) -> Result<SourceVolume, InputError> {
    match source {
        VolumeSource::File(path) => reader_for(path).read(path, options),
        VolumeSource::Files(paths) => read_several(paths, options),
        VolumeSource::Phantom(spec) => {
            let start = Instant::now();
            let _span = crate::files::trace::span("generate phantom", "io");
            let generated = phantom::generate(spec)?;
            let timings = LoadTimings {
                phantom_ms: start.elapsed().as_secs_f64() * 1e3,
                ..LoadTimings::default()
            };
            let sha256 = options
                .hash
                .then(|| sha256_hex(generated.volume.samples.as_bytes()));
            Ok(SourceVolume {
                label: "phantom".into(),
                volume: generated.volume,
                header: None,
                sha256,
                timings,
                series: None,
            })
        }
    }
}

/// `source` read as the mean over the frames of its 4-D NIfTI file (`options.frame` is
/// ignored; `nifti::frame_mean`), or None when it is no single NIfTI file (DICOM series and the
/// phantom have one frame here).
pub fn read_mean_of_frames(
    source: &VolumeSource,
    options: &ReadOptions,
) -> Result<Option<SourceVolume>, InputError> {
    match source {
        VolumeSource::File(path) if nifti::NiftiReader.claims(path) => {
            nifti::read_nifti(path, options, true).map(Some)
        }
        _ => Ok(None),
    }
}

/// Several paths as one input: DICOM only (see [`VolumeSource::Files`]).
fn read_several(paths: &[PathBuf], options: &ReadOptions) -> Result<SourceVolume, InputError> {
    check_several(paths)?;
    dicom::read_files(paths, options)
}

/// Several paths are one input only when every one is DICOM (one path always passes).
pub fn check_several(paths: &[PathBuf]) -> Result<(), InputError> {
    match paths.iter().find(|p| reader_for(p).name() != "DICOM") {
        Some(other) if paths.len() > 1 => Err(InputError::Path(Box::new(SeveralNotDicom {
            path: other.clone(),
            count: paths.len(),
        }))),
        _ => Ok(()),
    }
}

/// A path among several inputs that is not DICOM.
#[derive(Debug, thiserror::Error)]
#[error(
    "{}: {count} inputs were given, which is one input only for the files of a DICOM series, \
     and this one is not DICOM; give a NIfTI volume alone",
    path.display()
)]
pub struct SeveralNotDicom {
    /// The path that is not DICOM.
    pub path: PathBuf,
    /// How many paths were given.
    pub count: usize,
}

/// SHA-256 of bytes, as lowercase hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// The file name without directories (the whole path when it has none).
fn file_name(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.display().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nifti_names_are_claimed_and_unknown_names_fall_back_to_nifti() {
        for name in ["a.nii", "a.NII.GZ", "b.hdr", "b.img.gz", "c.HDR"] {
            assert!(
                nifti::NiftiReader.claims(Path::new(name)),
                "{name} should be NIfTI's"
            );
        }
        assert!(!nifti::NiftiReader.claims(Path::new("scan.dcm")));
        assert_eq!(reader_for(Path::new("scan.dcm")).name(), "DICOM");
        assert_eq!(reader_for(&std::env::temp_dir()).name(), "DICOM");
        assert_eq!(
            reader_for(Path::new("no-such-file.txt")).name(),
            "NIfTI/ANALYZE"
        );
    }

    #[test]
    fn a_missing_file_is_an_input_error_naming_the_path_with_the_nifti_cause() {
        let path = std::env::temp_dir().join("morphray-no-such-file-source-test.nii");
        let e = read(&VolumeSource::File(path.clone()), &ReadOptions::default()).unwrap_err();
        assert!(matches!(e, InputError::Path(_)), "{e:?}");
        assert!(e.to_string().contains(&path.display().to_string()), "{e}");
        assert!(e.nifti().is_some());
    }

    #[test]
    fn bad_contents_are_prefixed_with_the_file_name() {
        let dir = std::env::temp_dir().join(format!("morphray-source-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("short.nii");
        // 348 bytes of NIfTI-1 size field and magic, nothing valid after: a header error.
        let mut bytes = vec![0u8; 352];
        bytes[0..4].copy_from_slice(&348i32.to_le_bytes());
        bytes[344..348].copy_from_slice(b"n+1\0");
        std::fs::write(&path, &bytes).unwrap();
        let e = read(&VolumeSource::File(path), &ReadOptions::default()).unwrap_err();
        std::fs::remove_dir_all(&dir).unwrap();
        assert!(e.to_string().starts_with("short.nii: "), "{e}");
        assert!(e.nifti().is_some());
    }

    #[test]
    fn the_phantom_is_a_source_with_its_hash() {
        let spec = PhantomSpec {
            dims: [8, 8, 6],
            ..PhantomSpec::cohort_a()
        };
        let read = read(
            &VolumeSource::Phantom(spec),
            &ReadOptions {
                frame: 0,
                hash: true,
                series: None,
            },
        )
        .unwrap();
        assert_eq!(read.label, "phantom");
        assert_eq!(read.volume.dims, [8, 8, 6]);
        assert_eq!(read.sha256.map(|h| h.len()), Some(64));
    }
}
