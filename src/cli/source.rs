//! The input of a command: a file or the built-in phantom, read through the library's source
//! registry (`volume::source`); this file only maps the command line's `FILE`/`--frame`/
//! `--series` onto it.
//!
//! Decision: `--series` is a global option, kept here once per process (`set_series`, by
//! `cli::run`) and read when any command builds its read options, so the commands' own
//! argument structs and signatures need not carry it.

use crate::error::Error;
use crate::volume::source::dicom::SeriesChoice;
use crate::volume::source::{self, ReadOptions, VolumeSource};
use std::path::PathBuf;
use std::sync::OnceLock;

pub use crate::volume::source::{LoadTimings, SourceVolume as Source};

static SERIES: OnceLock<Option<SeriesChoice>> = OnceLock::new();

/// Records `--series` (the first call wins; one command per process).
pub fn set_series(series: Option<SeriesChoice>) {
    let _ = SERIES.set(series);
}

/// The read options of a command: `frame`, the hash when wanted, and `--series`.
pub fn read_options(frame: usize, want_hash: bool) -> ReadOptions {
    ReadOptions {
        frame,
        hash: want_hash,
        series: SERIES.get().cloned().flatten(),
    }
}

/// Reads the command line's inputs (see [`VolumeSource::from_paths`]): none is the cohort-A
/// phantom, several are one DICOM input.
pub fn load(files: &[PathBuf], frame: usize, want_hash: bool) -> Result<Source, Error> {
    Ok(source::read(
        &VolumeSource::from_paths(files),
        &read_options(frame, want_hash),
    )?)
}
