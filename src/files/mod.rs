//! Files the user names, read and written safely: the bottom layer, on `std` (and `libc` for
//! non-blocking opens) only, usable by every layer above it (volume's NIfTI reader and writer,
//! gpu's pipeline cache and profiles, the commands, the viewer).
//!
//! Decisions: reading a path a user gave is never `std::fs::read`, which blocks forever on a FIFO
//! and reads `/dev/zero` until memory runs out: [`read::read_regular`] opens without blocking,
//! refuses anything that is not a regular file and reads at most a cap. Writing never truncates
//! the target in place: [`write::AtomicFile`] writes a temporary file beside it and renames it
//! over the target only when complete, and [`write::check_output`] checks an output path before
//! any work is done.

pub mod base64;
pub mod cache_dir;
pub mod movie;
pub mod parallel;
pub mod png;
pub mod read;
pub mod stdout;
pub mod trace;
pub mod unfinished;
pub mod write;
