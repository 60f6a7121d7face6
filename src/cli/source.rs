//! The input of a command: a file or the built-in phantom, read through the library's source
//! registry (`volume::source`); this file only maps the command line's `FILE`/`--frame` onto it.

use crate::error::Error;
use crate::volume::source::{self, ReadOptions, VolumeSource};
use std::path::Path;

pub use crate::volume::source::{LoadTimings, SourceVolume as Source};

/// Reads `file`, or generates the cohort-A phantom when `file` is None.
pub fn load(file: Option<&Path>, frame: usize, want_hash: bool) -> Result<Source, Error> {
    let options = ReadOptions {
        frame,
        hash: want_hash,
    };
    Ok(source::read(
        &VolumeSource::file_or_phantom(file),
        &options,
    )?)
}
