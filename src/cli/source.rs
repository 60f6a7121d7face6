//! The input of a command: a NIfTI file or the built-in phantom, loaded with per-phase timings.
//!
//! Decisions:
//! - Reading, inflating and converting are separate phases (timed separately, and run on a
//!   worker thread by the commands that also create a GPU device, so the two overlap).
//! - The sequence itself is the library's [`nifti::load_file_timed`] (also what the
//!   `input_path` fuzz target runs); this file only adds the phantom, the hash and the error
//!   context (the file's name, unless the error names the path itself).

use crate::error::Error;
use crate::volume::Volume;
use crate::volume::nifti::{self, HeaderSummary, LoadOptions, NiftiError};
use crate::volume::phantom::{self, PhantomSpec};
use std::path::Path;
use std::time::Instant;

/// Host times of loading, in milliseconds (0 for phases that did not apply).
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
}

/// A loaded input.
pub struct Source {
    /// File name or `phantom`.
    pub label: String,
    /// Frame 0 (or the chosen frame).
    pub volume: Volume,
    /// Header facts (None for the phantom).
    pub header: Option<HeaderSummary>,
    /// SHA-256 of the file's bytes as read, or of the phantom's samples (when requested).
    pub sha256: Option<String>,
    /// Phase times.
    pub timings: LoadTimings,
}

/// Loads `file`, or generates the cohort-A phantom when `file` is None.
pub fn load(file: Option<&Path>, frame: usize, want_hash: bool) -> Result<Source, Error> {
    let mut timings = LoadTimings::default();
    let Some(path) = file else {
        let start = Instant::now();
        let generated = phantom::generate(&PhantomSpec::cohort_a())?;
        timings.phantom_ms = start.elapsed().as_secs_f64() * 1e3;
        let sha256 = want_hash.then(|| super::png::sha256_hex(generated.volume.samples.as_bytes()));
        return Ok(Source {
            label: "phantom".into(),
            volume: generated.volume,
            header: None,
            sha256,
            timings,
        });
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.display().to_string());
    let mut sha256 = None;
    let mut hash = |bytes: &[u8]| {
        if want_hash {
            sha256 = Some(super::png::sha256_hex(bytes));
        }
    };
    let (loaded, times) =
        nifti::load_file_timed(path, &LoadOptions { frame }, &mut hash).map_err(|source| {
            match source {
                // These name the path themselves.
                NiftiError::Io { .. }
                | NiftiError::File(_)
                | NiftiError::MissingCompanion { .. }
                | NiftiError::BadNifti1Magic { .. } => Error::Nifti(source),
                source => Error::Input {
                    file: name.clone(),
                    source,
                },
            }
        })?;
    timings.read_ms = times.read_ms;
    timings.inflate_ms = times.inflate_ms;
    timings.convert_ms = times.convert_ms;
    Ok(Source {
        label: name,
        volume: loaded.volume,
        header: Some(loaded.header),
        sha256,
        timings,
    })
}
