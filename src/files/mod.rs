//! Files: the one place that opens files the user names, below every other layer.
//!
//! Decision: reading a path a user gave is never `std::fs::read`, which blocks forever on a FIFO
//! and reads `/dev/zero` until memory runs out. [`read::read_regular`] opens without blocking,
//! refuses anything that is not a regular file and reads at most a cap.

pub mod read;
