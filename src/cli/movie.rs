//! `render --turntable N --movie OUT.png`: the turntable's frames also as one looping animated
//! PNG (issue 16 item 7). The format and why: `files/movie.rs`.
//!
//! Decisions: the movie path is checked with the frames' paths before any work (never the
//! input, never one of the frames, right extension, writable directory); the movie is written
//! frame by frame as the turntable renders and put in place only when complete.

use crate::error::Error;
use crate::files::movie::MovieWriter;
use crate::files::png::Provenance;
use crate::files::write::{OutputKind, check_output};
use clap::Args;
use std::path::{Path, PathBuf};

/// Options of the turntable movie.
#[derive(Debug, Clone, Args)]
#[command(next_help_heading = "Output")]
pub struct MovieArgs {
    /// With --turntable N: also write the N frames as one looping animated PNG.
    ///
    /// APNG: lossless, plays in web browsers; `ffmpeg -i OUT.png out.mp4` converts it to a video.
    #[arg(long, value_name = "OUT.png", requires = "turntable")]
    pub movie: Option<PathBuf>,
    /// Frames per second of --movie.
    #[arg(long, default_value_t = 15, value_parser = clap::value_parser!(u16).range(1..=120))]
    pub fps: u16,
}

impl MovieArgs {
    /// Fails when the movie would overwrite an input or one of the frames, or cannot be written.
    pub fn check(&self, frames: &[PathBuf], inputs: &[&Path]) -> Result<(), Error> {
        let Some(movie) = &self.movie else {
            return Ok(());
        };
        if frames.iter().any(|f| f == movie) {
            return Err(Error::Usage(format!(
                "--movie {} is also one of the turntable's frames; name the movie differently \
                 from -o",
                movie.display()
            )));
        }
        check_output(movie, OutputKind::Png, inputs, false)?;
        Ok(())
    }
}

/// The movie being written (nothing when no --movie was given).
#[derive(Default)]
pub struct Movie {
    writer: Option<MovieWriter>,
}

impl Movie {
    /// Adds a frame; the first frame opens the file (with that frame's provenance).
    pub fn push(
        &mut self,
        args: &MovieArgs,
        frames: u32,
        size: (u32, u32),
        rgba: &[u8],
        provenance: &Provenance,
    ) -> Result<(), Error> {
        let Some(path) = &args.movie else {
            return Ok(());
        };
        if self.writer.is_none() {
            self.writer = Some(MovieWriter::create(
                path, size, frames, args.fps, provenance,
            )?);
        }
        if let Some(writer) = self.writer.as_mut() {
            writer.push(rgba)?;
        }
        Ok(())
    }

    /// Puts the finished movie in place and says so.
    pub fn finish(self, args: &MovieArgs, frames: u32) -> Result<(), Error> {
        if let (Some(writer), Some(path)) = (self.writer, &args.movie) {
            writer.finish()?;
            super::output::print_line(&format!(
                "wrote {} ({frames} frames at {} fps, animated PNG)",
                path.display(),
                args.fps
            ));
        }
        Ok(())
    }
}
