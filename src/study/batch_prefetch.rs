//! Reading a batch's scans ahead of the engine: reader threads read and inflate the next scans
//! while the engine works on the current one, so a process's throughput is bound by the slower
//! of the two, not their sum.
//!
//! Decisions:
//! - On the H100, 100 MNI152-sized scans took 70 ms each for peaks only, one after another:
//!   inflate 50-53 ms on the host, GPU work 16-17 ms (`benches/device-batch.sh`, BENCHMARKS.md).
//!   With the inflate of later scans on other cores, a scan costs the engine's share alone.
//! - Readers: one per spare core (the engine's thread keeps one), at most 4; reader `r` reads
//!   scans `r, r + R, r + 2R, ...` and hands each over through its own channel of one slot, so
//!   scans arrive in order and at most 2R volumes are in memory at once.
//! - A read that panics (a bug in a decoder) is contained and reported as that scan's error; the
//!   reader goes on with its next scan.

use crate::volume::source::{self, InputError, ReadOptions, SourceVolume, VolumeSource};
use std::path::PathBuf;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::time::Instant;

/// A scan as read ahead: the volume (or why it could not be read) and how long the engine's
/// thread then waited for it.
pub struct Prefetched {
    /// The read.
    pub read: Result<SourceVolume, String>,
    /// When the reader finished it.
    pub ready_at: Instant,
}

/// How many reader threads to use on this machine.
pub fn reader_count() -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    cores.saturating_sub(1).clamp(1, 4)
}

/// Reads `paths` ahead on `readers` threads spawned in `scope`; the returned receivers, taken in
/// turn (`i % readers`), give the scans in order.
pub fn start<'scope>(
    scope: &'scope std::thread::Scope<'scope, '_>,
    paths: Vec<PathBuf>,
    readers: usize,
) -> Vec<Receiver<Prefetched>> {
    let readers = readers.max(1);
    let mut receivers = Vec::with_capacity(readers);
    for r in 0..readers {
        let (sender, receiver) = sync_channel(1);
        let mine: Vec<PathBuf> = paths.iter().skip(r).step_by(readers).cloned().collect();
        std::thread::Builder::new()
            .name(format!("scan reader {r}"))
            .spawn_scoped(scope, move || read_all(mine, sender))
            .map(drop)
            .unwrap_or_else(|_| {
                // No thread: the receiver's disconnection reports these scans as unread.
            });
        receivers.push(receiver);
    }
    receivers
}

fn read_all(paths: Vec<PathBuf>, sender: SyncSender<Prefetched>) {
    for path in paths {
        let read = std::panic::catch_unwind(|| {
            source::read(&VolumeSource::File(path.clone()), &ReadOptions::default())
        })
        .unwrap_or(Err(InputError::ReaderStopped))
        .map_err(|e| e.to_string());
        let item = Prefetched {
            read,
            ready_at: Instant::now(),
        };
        if sender.send(item).is_err() {
            return; // The batch stopped.
        }
    }
}

/// The next scan from `receivers` (scan `index`), or the error that its reader is gone.
pub fn next(receivers: &[Receiver<Prefetched>], index: usize) -> Prefetched {
    receivers[index % receivers.len()]
        .recv()
        .unwrap_or_else(|_| Prefetched {
            read: Err(InputError::ReaderStopped.to_string()),
            ready_at: Instant::now(),
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::phantom::{PhantomSpec, generate};

    #[test]
    fn scans_arrive_in_order_from_several_readers_and_a_bad_one_is_its_own_error() {
        let dir = std::env::temp_dir().join(format!("morphray-prefetch-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut paths = Vec::new();
        for (i, side) in [6usize, 7, 8, 9, 10, 11, 12].into_iter().enumerate() {
            let path = dir.join(format!("scan{i}.nii"));
            if i == 3 {
                std::fs::write(&path, b"not a volume").unwrap();
            } else {
                let volume = generate(&PhantomSpec::cube(side)).unwrap().volume;
                crate::volume::nifti::write_nifti1(&volume, &path, false).unwrap();
            }
            paths.push(path);
        }
        let dims: Vec<Result<usize, String>> = std::thread::scope(|scope| {
            let receivers = start(scope, paths.clone(), 3);
            (0..paths.len())
                .map(|i| next(&receivers, i).read.map(|r| r.volume.dims[0]))
                .collect()
        });
        std::fs::remove_dir_all(&dir).unwrap();
        for (i, d) in dims.iter().enumerate() {
            if i == 3 {
                assert!(d.as_ref().is_err_and(|e| e.contains("scan3.nii")), "{d:?}");
            } else {
                assert_eq!(d.as_ref().ok(), Some(&(6 + i)), "scan {i}");
            }
        }
    }
}
