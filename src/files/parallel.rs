//! Large host copies, file reads and per-item work split across threads.
//!
//! Decisions:
//! - Why threads for plain copies: on the H100 machine one thread wrote the 268 MB of a
//!   512^3 int16 volume into a fresh staging buffer in 140-153 ms, and read the 268 MB `.nii`
//!   from the page cache into a fresh vector in 134 ms (1.7-2.0 GB/s; `bench`'s first-pixel
//!   phases `upload` and `read` in benches/results/h100-2026-11-24-scaling). Memory bandwidth
//!   is an order of magnitude higher, so what bounds one thread is the first touch of each new
//!   page (a fault, a zeroed page, a page-table entry). Faults of different threads proceed in
//!   parallel, so the work is split into contiguous chunks, one per thread.
//! - Threads: `std::thread::scope`, no pool. A spawn costs tens of microseconds, nothing next
//!   to the tens of milliseconds these calls take, and nothing stays alive between calls. At
//!   most [`MAX_THREADS`], never more than `available_parallelism`, and no chunk smaller than
//!   [`MIN_CHUNK`] (below that the spawn is not worth it and one thread does the work).
//!   `MORPHRAY_IO_THREADS=N` overrides the count (N = 1: the single-thread path), so the gain
//!   can be measured in the same run (`benches/device-streamed.sh`).
//! - The buffer a large file is read into asks for transparent huge pages
//!   ([`advise_huge_pages`]): one fault per 2 MiB instead of per 4 KiB, where the kernel allows
//!   it (`madvise` mode, Debian's default). On the H100 machine (benches/results/
//!   h100-2026-11-24-hugepages, same run, on/off) the 13 MB phantom read in 5.3-5.9 ms instead
//!   of 8.3-10.8 and the 268 MB `.nii` in 31-33 ms instead of 40-41. The inflation output does
//!   not ask: there 16 threads write members of 1 MiB into shared 2 MiB pages, and the phantom's
//!   inflation got slower (18-22 ms against 14-16). `MORPHRAY_HUGE_PAGES=off` leaves the advice
//!   out (for measurements).
//! - Reads use `pread` on the shared file handle into memory not yet initialised (no zeroing
//!   pass before the read, which would be one more single-threaded touch of every page).

use std::fs::File;

/// Most threads one call uses: 16 covers the lent machines' cores; past that the page-fault
/// path's own locks make more threads useless.
pub const MAX_THREADS: usize = 16;

/// Smallest chunk worth a thread for copies and inflation: 4 MiB.
pub const MIN_CHUNK: usize = 4 << 20;

/// Smallest chunk worth a thread for file reads: 16 MiB. Reads of small files are faster on one
/// thread: the 13 MB default phantom read in 8-9 ms on one thread and 13-17 ms on three (H100
/// machine, benches/results/h100-2026-11-24-streamed), while the 268 MB `.nii` went from 134 ms
/// on one thread to 24-34 ms on sixteen.
pub const MIN_READ_CHUNK: usize = 16 << 20;

/// The environment variable that sets the thread count (for measurements).
pub const THREADS_ENV: &str = "MORPHRAY_IO_THREADS";

/// How many threads to use for `bytes` of work: `MORPHRAY_IO_THREADS` when set to a positive
/// number (still capped by [`MAX_THREADS`]), otherwise the cores available; never more than
/// one per [`MIN_CHUNK`], at least 1.
pub fn threads_for(bytes: usize) -> usize {
    let by_size = (bytes / MIN_CHUNK).max(1);
    thread_budget().min(by_size)
}

/// How many threads to use for reading `bytes` of a file: as [`threads_for`], with chunks of at
/// least [`MIN_READ_CHUNK`].
pub fn read_threads_for(bytes: usize) -> usize {
    thread_budget().min((bytes / MIN_READ_CHUNK).max(1))
}

/// Threads available to one call, before the size is taken into account.
pub fn thread_budget() -> usize {
    let requested = std::env::var(THREADS_ENV)
        .ok()
        .and_then(|v| v.trim().parse::<usize>().ok())
        .filter(|&n| n > 0);
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    requested.unwrap_or(cores).clamp(1, MAX_THREADS)
}

/// The environment variable that turns the huge-page advice off (`off`).
pub const HUGE_PAGES_ENV: &str = "MORPHRAY_HUGE_PAGES";

/// Asks the kernel to back the whole 2 MiB pages inside `[ptr, ptr + len)` with transparent huge
/// pages (Linux `MADV_HUGEPAGE`; advice only: refused or unsupported, nothing changes). Call it
/// on memory this process owns, before its first touch.
pub fn advise_huge_pages(ptr: *mut u8, len: usize) {
    const HUGE: usize = 2 << 20;
    if len < 2 * HUGE || std::env::var(HUGE_PAGES_ENV).is_ok_and(|v| v == "off") {
        return;
    }
    let start = (ptr as usize).next_multiple_of(HUGE);
    let end = (ptr as usize).saturating_add(len) / HUGE * HUGE;
    if end > start {
        // SAFETY: the range lies inside memory the caller owns; MADV_HUGEPAGE only changes how
        // the kernel backs it and never its contents.
        unsafe { libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE) };
    }
}

/// `len` split into `parts` contiguous ranges of nearly equal length, each starting on a
/// multiple of `align` (the last takes the remainder).
pub fn chunks(len: usize, parts: usize, align: usize) -> Vec<std::ops::Range<usize>> {
    let parts = parts.max(1);
    let align = align.max(1);
    let step = len.div_ceil(parts).div_ceil(align) * align;
    (0..parts)
        .map(|i| (i * step).min(len)..((i + 1) * step).min(len))
        .filter(|r| !r.is_empty())
        .collect()
}

/// A raw destination address that may cross into scoped threads; every thread writes only its
/// own disjoint range (the users' safety argument).
#[derive(Clone, Copy)]
pub struct Dest(pub *mut u8);

// SAFETY: the pointer is only dereferenced inside disjoint ranges by the scoped threads that
// receive it, which all end before the functions below return.
unsafe impl Send for Dest {}
unsafe impl Sync for Dest {}

impl Dest {
    /// The address `offset` bytes in (a method, so closures capture the whole `Send` wrapper).
    pub fn at(self, offset: usize) -> *mut u8 {
        self.0.wrapping_add(offset)
    }
}

/// Copies `src` to `dst`, split across threads for large copies.
///
/// # Safety
/// `dst` must be valid for writes of `src.len()` bytes and must not overlap `src`.
pub unsafe fn copy_to(dst: *mut u8, src: &[u8]) {
    let threads = threads_for(src.len());
    if threads <= 1 {
        // SAFETY: the caller's contract.
        unsafe { std::ptr::copy_nonoverlapping(src.as_ptr(), dst, src.len()) };
        return;
    }
    let dest = Dest(dst);
    std::thread::scope(|scope| {
        for range in chunks(src.len(), threads, 4096) {
            let part = src.get(range.clone()).unwrap_or_default();
            scope.spawn(move || {
                // SAFETY: `range` lies within `src.len()`, so the destination range lies within
                // the caller's valid `dst` range; the ranges of the threads are disjoint.
                unsafe {
                    std::ptr::copy_nonoverlapping(part.as_ptr(), dest.at(range.start), part.len())
                };
            });
        }
    });
}

/// Reads `len` bytes of `file` starting at file offset `offset` into `dst`, split across
/// threads. Returns how many bytes were read: less than `len` only when the file ended first
/// (it shrank); then the first missing byte is at the returned count, and bytes after it may
/// or may not have been written.
///
/// # Safety
/// `dst` must be valid for writes of `len` bytes.
pub unsafe fn read_at(
    file: &File,
    offset: u64,
    dst: *mut u8,
    len: usize,
) -> std::io::Result<usize> {
    let threads = read_threads_for(len);
    let dest = Dest(dst);
    let ranges = chunks(len, threads, 1 << 16);
    let results: Vec<std::io::Result<usize>> = if ranges.len() <= 1 {
        // SAFETY: the caller's contract.
        vec![unsafe { pread_full(file, offset, dest.at(0), len) }]
    } else {
        std::thread::scope(|scope| {
            let handles: Vec<_> = ranges
                .iter()
                .cloned()
                .map(|r| {
                    scope.spawn(move || {
                        // SAFETY: `r` lies within `len`, so the destination lies within the
                        // caller's valid range; the threads' ranges are disjoint.
                        unsafe {
                            pread_full(file, offset + r.start as u64, dest.at(r.start), r.len())
                        }
                    })
                })
                .collect();
            handles
                .into_iter()
                .map(|h| {
                    h.join()
                        .unwrap_or_else(|_| Err(std::io::Error::other("a read thread panicked")))
                })
                .collect()
        })
    };
    let mut total = 0usize;
    for (range, result) in ranges.iter().zip(results) {
        let got = result?;
        if got < range.len() {
            return Ok(range.start + got);
        }
        total = range.end;
    }
    Ok(total)
}

/// `pread` until `len` bytes are in or the file ends; retries interrupted calls. Returns the
/// bytes read.
///
/// # Safety
/// `dst` must be valid for writes of `len` bytes.
unsafe fn pread_full(file: &File, offset: u64, dst: *mut u8, len: usize) -> std::io::Result<usize> {
    use std::os::unix::io::AsRawFd;
    let mut done = 0usize;
    while done < len {
        let at = i64::try_from(offset + done as u64).map_err(std::io::Error::other)?;
        // At most 1 GiB per call (Linux caps a read at about 2 GiB anyway).
        let want = (len - done).min(1 << 30);
        // SAFETY: `dst + done .. dst + done + want` lies within the caller's valid range.
        let n = unsafe { libc::pread(file.as_raw_fd(), dst.add(done).cast(), want, at) };
        if n < 0 {
            let err = std::io::Error::last_os_error();
            if err.kind() == std::io::ErrorKind::Interrupted {
                continue;
            }
            return Err(err);
        }
        if n == 0 {
            break; // end of file
        }
        done += n as usize;
    }
    Ok(done)
}

/// Runs `work(i)` for every `i` in `0..count` on up to `threads` threads, each taking the next
/// index from a shared counter (items of unequal cost balance themselves). Stops handing out
/// indices after the first error and returns it; every thread's state comes from `init`.
pub fn for_each_index<S, E: Send>(
    count: usize,
    threads: usize,
    init: impl Fn() -> Result<S, E> + Sync,
    work: impl Fn(&mut S, usize) -> Result<(), E> + Sync,
) -> Result<(), E> {
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
    let next = AtomicUsize::new(0);
    let failed = AtomicBool::new(false);
    let run = || -> Result<(), E> {
        let mut state = init()?;
        loop {
            if failed.load(Ordering::Relaxed) {
                return Ok(());
            }
            let i = next.fetch_add(1, Ordering::Relaxed);
            if i >= count {
                return Ok(());
            }
            if let Err(e) = work(&mut state, i) {
                failed.store(true, Ordering::Relaxed);
                return Err(e);
            }
        }
    };
    let threads = threads.clamp(1, count.max(1));
    if threads == 1 {
        return run();
    }
    std::thread::scope(|scope| {
        let handles: Vec<_> = (0..threads).map(|_| scope.spawn(run)).collect();
        let mut first = Ok(());
        for h in handles {
            // A panic in a worker is passed on unchanged (the work functions do not panic).
            let result = h.join().unwrap_or_else(|p| std::panic::resume_unwind(p));
            if first.is_ok() {
                first = result;
            }
        }
        first
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_cover_the_range_in_order_without_gaps() {
        for (len, parts, align) in [(0, 4, 1), (10, 3, 1), (10_000, 7, 4096), (5, 16, 4096)] {
            let c = chunks(len, parts, align);
            let mut at = 0;
            for r in &c {
                assert_eq!(r.start, at);
                assert!(r.start % align == 0);
                at = r.end;
            }
            assert_eq!(at, len);
            assert!(c.len() <= parts.max(1));
        }
    }

    #[test]
    fn a_parallel_copy_equals_the_source() {
        let src: Vec<u8> = (0..(3 * MIN_CHUNK + 12_345))
            .map(|i| (i * 7 + i / 251) as u8)
            .collect();
        let mut dst = vec![0u8; src.len()];
        // SAFETY: dst has src.len() bytes and does not overlap src.
        unsafe { copy_to(dst.as_mut_ptr(), &src) };
        assert!(dst == src);
    }

    #[test]
    fn a_parallel_read_equals_the_file_and_reports_a_short_file() {
        let path = std::env::temp_dir().join(format!("morphray-pread-{}", std::process::id()));
        let data: Vec<u8> = (0..(2 * MIN_READ_CHUNK + 999))
            .map(|i| (i % 253) as u8)
            .collect();
        std::fs::write(&path, &data).unwrap();
        let file = File::open(&path).unwrap();
        let mut out = vec![0u8; data.len() - 100];
        // SAFETY: out has the length passed.
        let got = unsafe { read_at(&file, 100, out.as_mut_ptr(), out.len()) }.unwrap();
        assert_eq!(got, out.len());
        assert!(out[..] == data[100..]);
        let mut longer = vec![0u8; data.len()];
        // SAFETY: longer has the length passed.
        let got = unsafe { read_at(&file, 100, longer.as_mut_ptr(), longer.len()) }.unwrap();
        assert_eq!(got, data.len() - 100, "the file ends 100 bytes early");
        std::fs::remove_file(&path).unwrap();
    }

    #[test]
    fn every_index_runs_once_and_the_first_error_stops_the_rest() {
        use std::sync::atomic::{AtomicUsize, Ordering};
        let seen: Vec<AtomicUsize> = (0..100).map(|_| AtomicUsize::new(0)).collect();
        for_each_index(
            100,
            4,
            || Ok::<_, ()>(()),
            |_, i| {
                seen[i].fetch_add(1, Ordering::Relaxed);
                Ok(())
            },
        )
        .unwrap();
        assert!(seen.iter().all(|s| s.load(Ordering::Relaxed) == 1));
        let r = for_each_index(
            1000,
            3,
            || Ok::<_, usize>(()),
            |_, i| if i == 10 { Err(i) } else { Ok(()) },
        );
        assert_eq!(r, Err(10));
    }
}
