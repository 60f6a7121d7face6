//! The NIfTI-1/NIfTI-2/ANALYZE 7.5 reader (`.nii`, `.nii.gz`, `.hdr`/`.img` pairs) behind
//! [`VolumeReader`].
//!
//! Decisions: the sequence is the library's [`load_file_timed`] (also what the `input_path`
//! fuzz target runs); this file only sorts its errors into the two [`InputError`] kinds (those
//! that name the path themselves, and those about the contents of a named file).

use super::{InputError, LoadTimings, ReadOptions, SourceVolume, VolumeReader, sha256_hex};
use crate::volume::nifti::{LoadOptions, NiftiError, load_file_timed};
use std::path::Path;

/// Reads NIfTI and ANALYZE files.
pub struct NiftiReader;

impl VolumeReader for NiftiReader {
    fn name(&self) -> &'static str {
        "NIfTI/ANALYZE"
    }

    fn claims(&self, path: &Path) -> bool {
        let name = super::file_name(path).to_ascii_lowercase();
        let name = name.strip_suffix(".gz").unwrap_or(&name);
        [".nii", ".hdr", ".img"].iter().any(|e| name.ends_with(e))
    }

    fn read(&self, path: &Path, options: &ReadOptions) -> Result<SourceVolume, InputError> {
        read_nifti(path, options, false)
    }
}

/// Reads `path`: frame `options.frame`, or with `mean` the mean over the frames.
pub(super) fn read_nifti(
    path: &Path,
    options: &ReadOptions,
    mean: bool,
) -> Result<SourceVolume, InputError> {
    let label = super::file_name(path);
    let mut sha256 = None;
    let mut hash = |bytes: &[u8]| {
        if options.hash {
            sha256 = Some(sha256_hex(bytes));
        }
    };
    let load = LoadOptions {
        frame: options.frame,
        mean,
    };
    let (loaded, times) = load_file_timed(path, &load, &mut hash).map_err(|e| match e {
        NiftiError::Io { .. }
        | NiftiError::File(_)
        | NiftiError::MissingCompanion { .. }
        | NiftiError::BadNifti1Magic { .. } => InputError::Path(Box::new(e)),
        e => InputError::Contents {
            file: label.clone(),
            source: Box::new(e),
        },
    })?;
    let gzip_members = loaded.header.gzip_members;
    let mut volume = loaded.volume;
    crate::volume::facts::add_path_facts(path, &mut volume.facts, &mut volume.warnings);
    Ok(SourceVolume {
        label,
        volume,
        header: Some(loaded.header),
        sha256,
        timings: LoadTimings {
            read_ms: times.read_ms,
            inflate_ms: times.inflate_ms,
            convert_ms: times.convert_ms,
            phantom_ms: 0.0,
            io_threads: crate::files::parallel::thread_budget(),
            gzip_members,
        },
        series: None,
    })
}
