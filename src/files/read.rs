//! Reading a regular file with a hard cap, for inputs the user names (volumes) and files the
//! program keeps (the pipeline cache).
//!
//! Decisions:
//! - Open with `O_NONBLOCK` (Unix), so opening a FIFO never waits for a writer; then `fstat`
//!   the opened handle (not the path, so a file swapped between the check and the read cannot
//!   slip through) and refuse everything that is not a regular file, naming what it is
//!   ("is a FIFO", "is a character device", "is a directory"). Symbolic links are followed, so a
//!   link to a regular file is fine and a link to `/dev/zero` is refused as a character device.
//!   `O_NONBLOCK` has no effect on reads of regular files.
//! - The length is the handle's metadata length: a file longer than the caller's cap is refused
//!   before any byte is read or allocated. At most that length is read; a file that turns out
//!   longer (it grew while being read) is refused rather than silently cut, since a half-written
//!   input is not the file the user meant. A file that shrank is returned as read (the parser
//!   reports it as truncated, naming what is missing).
//! - Files of more than a few MiB are read by several threads at once (`pread` of contiguous
//!   chunks, files/parallel.rs): one thread reading a large file from the page cache into new
//!   memory is bound by first-touch page faults, which threads take in parallel.
//! - Memory for the bytes is reserved with `try_reserve_exact`, so a huge regular file within the
//!   cap is a typed error on a machine without the memory, not an abort.

use std::fs::{File, Metadata};
use std::io::Read;
use std::path::{Path, PathBuf};

/// Why a file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// Opening, inspecting or reading failed at the operating-system level.
    #[error("could not read {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// The path names something that is not a regular file.
    #[error("{path} {kind}, not a regular file: give the path of a file")]
    NotRegular {
        /// The path as given.
        path: PathBuf,
        /// What it is, as a verb phrase: `is a FIFO`, `is a directory`, ...
        kind: &'static str,
    },
    /// The file is longer than the caller accepts.
    #[error("{path} has {len} bytes, more than the {cap} bytes accepted here")]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its length.
        len: u64,
        /// The caller's cap.
        cap: u64,
    },
    /// The file grew while it was being read.
    #[error(
        "{path} grew while it was read (it had {len} bytes when opened): wait until whatever writes it has finished, then try again"
    )]
    Grew {
        /// The file.
        path: PathBuf,
        /// Its length when opened.
        len: u64,
    },
    /// Memory for the contents could not be reserved.
    #[error("could not allocate {len} bytes to read {path}")]
    OutOfMemory {
        /// The file.
        path: PathBuf,
        /// Its length.
        len: u64,
    },
}

impl ReadError {
    /// True when the file does not exist (callers for which a missing file is normal, like a
    /// cache that was never written, treat it as "nothing yet").
    pub fn is_not_found(&self) -> bool {
        matches!(self, ReadError::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound)
    }
}

/// What a non-regular file is, as the verb phrase of an error message.
fn kind_of(meta: &Metadata) -> &'static str {
    let t = meta.file_type();
    if t.is_dir() {
        return "is a directory";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "is a FIFO (named pipe)";
        }
        if t.is_char_device() {
            return "is a character device";
        }
        if t.is_block_device() {
            return "is a block device";
        }
        if t.is_socket() {
            return "is a socket";
        }
    }
    "is not a regular file"
}

/// Opens `path` for reading without blocking (a FIFO with no writer would otherwise block the
/// open itself) and returns the handle with its own metadata, refusing non-regular files.
pub fn open_regular(path: &Path) -> Result<(File, Metadata), ReadError> {
    let io = |source| ReadError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NONBLOCK);
    }
    let file = options.open(path).map_err(io)?;
    let meta = file.metadata().map_err(io)?;
    if !meta.is_file() {
        return Err(ReadError::NotRegular {
            path: path.to_path_buf(),
            kind: kind_of(&meta),
        });
    }
    Ok((file, meta))
}

/// Reads `want` bytes of `file` from its start into the spare capacity of the empty `bytes`
/// (which holds at least `want + 1`) on several threads ([`super::parallel::read_at`]), then
/// one byte more to see whether the file grew. A file that shrank keeps what was read, as the
/// sequential read does.
fn read_parallel(file: &File, want: usize, bytes: &mut Vec<u8>) -> std::io::Result<()> {
    let spare = bytes.spare_capacity_mut();
    if spare.len() <= want {
        return Err(std::io::Error::other(
            "the read buffer is smaller than the file",
        ));
    }
    let dst = spare.as_mut_ptr().cast::<u8>();
    // SAFETY: the spare capacity holds more than `want` bytes.
    let mut got = unsafe { super::parallel::read_at(file, 0, dst, want) }?;
    if got == want {
        // SAFETY: one more byte fits (capacity > want).
        got += unsafe { super::parallel::read_at(file, want as u64, dst.add(want), 1) }?;
    }
    // SAFETY: read_at initialised the first `got` bytes (it reports the first missing one).
    unsafe { bytes.set_len(got) };
    Ok(())
}

/// Reads the whole regular file at `path`, refusing non-regular files, files longer than `cap`
/// bytes and files that grow while read. Pass `u64::MAX` for "its own length is the only cap".
pub fn read_regular(path: &Path, cap: u64) -> Result<Vec<u8>, ReadError> {
    let (file, meta) = open_regular(path)?;
    let len = meta.len();
    if len > cap {
        return Err(ReadError::TooLarge {
            path: path.to_path_buf(),
            len,
            cap,
        });
    }
    let too_big = || ReadError::OutOfMemory {
        path: path.to_path_buf(),
        len,
    };
    let want = usize::try_from(len).map_err(|_| too_big())?;
    let mut bytes = Vec::new();
    // One spare byte, so that a file that grew is seen without reading all of its growth.
    bytes
        .try_reserve_exact(want.saturating_add(1))
        .map_err(|_| too_big())?;
    let spare = bytes.spare_capacity_mut();
    super::parallel::advise_huge_pages(spare.as_mut_ptr().cast(), spare.len());
    let io = |source| ReadError::Io {
        path: path.to_path_buf(),
        source,
    };
    if super::parallel::read_threads_for(want) > 1 {
        read_parallel(&file, want, &mut bytes).map_err(io)?;
    } else {
        file.take(len.saturating_add(1))
            .read_to_end(&mut bytes)
            .map_err(io)?;
    }
    if bytes.len() > want {
        return Err(ReadError::Grew {
            path: path.to_path_buf(),
            len,
        });
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("morphray-read-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn regular_files_and_links_to_them_are_read_whole() {
        let d = dir("regular");
        let path = d.join("a.bin");
        std::fs::write(&path, b"hello").unwrap();
        assert_eq!(read_regular(&path, u64::MAX).unwrap(), b"hello");
        let link = d.join("link.bin");
        std::os::unix::fs::symlink(&path, &link).unwrap();
        assert_eq!(read_regular(&link, 5).unwrap(), b"hello");
        std::fs::write(d.join("empty"), b"").unwrap();
        assert!(read_regular(&d.join("empty"), 0).unwrap().is_empty());
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_file_large_enough_for_threads_is_read_whole_and_exact() {
        let d = dir("parallel");
        let path = d.join("big.bin");
        let len = 2 * super::super::parallel::MIN_READ_CHUNK + 4097;
        let data: Vec<u8> = (0..len)
            .map(|i| (i % 251) as u8 ^ (i >> 16) as u8)
            .collect();
        std::fs::write(&path, &data).unwrap();
        let read = read_regular(&path, u64::MAX).unwrap();
        assert_eq!(read.len(), len);
        assert!(read == data);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn files_over_the_cap_are_refused_unread() {
        let d = dir("cap");
        let path = d.join("big.bin");
        let f = File::create(&path).unwrap();
        f.set_len(1 << 40).unwrap(); // sparse: 1 TiB that is never read
        let e = read_regular(&path, 1 << 20).unwrap_err();
        assert!(
            matches!(e, ReadError::TooLarge { len, cap, .. } if len == 1 << 40 && cap == 1 << 20),
            "{e}"
        );
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn devices_directories_and_fifos_are_refused_at_once() {
        let d = dir("special");
        let fifo = d.join("fifo");
        let status = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(status.success());
        let zero_link = d.join("zero");
        std::os::unix::fs::symlink("/dev/zero", &zero_link).unwrap();
        let start = std::time::Instant::now();
        for (path, kind) in [
            (fifo.as_path(), "is a FIFO (named pipe)"),
            (Path::new("/dev/zero"), "is a character device"),
            (zero_link.as_path(), "is a character device"),
            (d.as_path(), "is a directory"),
        ] {
            let e = read_regular(path, u64::MAX).unwrap_err();
            assert!(
                matches!(&e, ReadError::NotRegular { kind: k, .. } if *k == kind),
                "{}: {e}",
                path.display()
            );
            assert!(e.to_string().contains(&path.display().to_string()), "{e}");
        }
        assert!(start.elapsed() < std::time::Duration::from_secs(1));
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_missing_file_is_an_io_error_that_says_not_found() {
        let e = read_regular(Path::new("/nonexistent/morphray/x.nii"), u64::MAX).unwrap_err();
        assert!(e.is_not_found(), "{e}");
        assert!(e.to_string().contains("/nonexistent/morphray/x.nii"));
    }
}
