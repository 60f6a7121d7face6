//! Temporary files of unfinished writes (`.NAME.PID.N.tmp`, made by [`super::write`]): removed
//! when the program is interrupted, and those of a program that died removed on the next write
//! to the same folder.
//!
//! Decisions:
//! - Every live temporary file is in a process-wide list from its creation to its rename or
//!   removal. [`install_interrupt_cleanup`] (called by the command line, first thing) blocks
//!   SIGINT, SIGTERM and SIGHUP in the main thread, so every thread started later inherits the
//!   block, and a dedicated thread takes them with `sigwait`: it removes the listed files, says
//!   so in one line, and ends the process by the same signal (shells see "interrupted", not an
//!   error). Cleaning in a thread and not in a handler is what makes taking a lock and calling
//!   `unlink` safe. Plain `libc` (sigwait is the mechanism `signal-hook`'s iterator and `ctrlc`
//!   wrap): no registry was reachable to add either, and the few lines are all that is needed.
//!   The library alone installs nothing (the Python package's host owns its signals).
//! - `std::process::Command` resets the signal mask in the child, so programs it runs still
//!   get Ctrl-C.
//! - kill -9 cannot be caught, so the next write to a folder first removes the stale files of
//!   this program there ([`remove_stale`], once per folder and process): a name of the pattern
//!   whose PID is not a running process on this machine, and whose advisory lock (`flock`,
//!   which every writer holds on its temporary file until it is done and the kernel drops when
//!   the writer dies) can be taken. The lock is what protects a writer on another host sharing
//!   the folder (NFS), where the PID says nothing; a file system without locks keeps its
//!   files (nothing is removed that might be live).

use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

static LIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
static SWEPT: Mutex<Option<HashSet<PathBuf>>> = Mutex::new(None);

fn live() -> MutexGuard<'static, Vec<PathBuf>> {
    LIVE.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Lists a temporary file just created (and locks it; see the module doc).
pub fn register(path: &Path, file: &std::fs::File) {
    lock(file);
    live().push(path.to_path_buf());
}

/// Takes a temporary file off the list (renamed or removed).
pub fn unregister(path: &Path) {
    let mut list = live();
    if let Some(i) = list.iter().position(|p| p == path) {
        list.swap_remove(i);
    }
}

/// The temporary files now listed (for tests).
pub fn listed() -> Vec<PathBuf> {
    live().clone()
}

#[cfg(unix)]
fn lock(file: &std::fs::File) {
    use std::os::fd::AsRawFd;
    // Best effort: without locks, remove_stale leaves this file alone anyway.
    // SAFETY: flock on a file descriptor this function borrows.
    unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
}

#[cfg(not(unix))]
fn lock(_file: &std::fs::File) {}

/// The PID in a temporary file's name `.NAME.PID.N.tmp`, if it is one.
pub fn temp_pid(name: &str) -> Option<u32> {
    let core = name.strip_prefix('.')?.strip_suffix(".tmp")?;
    let mut parts = core.rsplitn(3, '.');
    let n = parts.next()?;
    let pid = parts.next()?;
    let stem = parts.next()?;
    let numeric = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    (numeric(n) && !stem.is_empty()).then_some(())?;
    pid.parse().ok().filter(|_| numeric(pid))
}

#[cfg(unix)]
fn process_dead(pid: u32) -> bool {
    let Ok(pid) = libc::pid_t::try_from(pid) else {
        return false;
    };
    // SAFETY: signal 0 only checks whether the process exists.
    let r = unsafe { libc::kill(pid, 0) };
    r == -1 && std::io::Error::last_os_error().raw_os_error() == Some(libc::ESRCH)
}

#[cfg(unix)]
fn unlocked(path: &Path) -> bool {
    use std::os::fd::AsRawFd;
    let Ok(file) = std::fs::File::open(path) else {
        return false;
    };
    // SAFETY: flock on a descriptor owned by `file`; the lock goes with it.
    unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) == 0 }
}

/// Removes the temporary files a dead writer of this program left in `dir` (module doc), the
/// first time this process writes there; returns how many.
pub fn remove_stale(dir: &Path) -> usize {
    {
        let mut swept = SWEPT.lock().unwrap_or_else(|p| p.into_inner());
        if !swept
            .get_or_insert_with(HashSet::new)
            .insert(dir.to_path_buf())
        {
            return 0;
        }
    }
    remove_stale_now(dir)
}

#[cfg(unix)]
fn remove_stale_now(dir: &Path) -> usize {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return 0;
    };
    let own = std::process::id();
    let mut removed = 0;
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some(pid) = temp_pid(&name) else { continue };
        let regular = entry.file_type().is_ok_and(|t| t.is_file());
        let path = entry.path();
        if regular
            && pid != own
            && process_dead(pid)
            && unlocked(&path)
            && std::fs::remove_file(&path).is_ok()
        {
            removed += 1;
        }
    }
    removed
}

#[cfg(not(unix))]
fn remove_stale_now(_dir: &Path) -> usize {
    0
}

/// Removes every listed temporary file; returns how many. Holding the list's lock afterwards
/// (the caller's guard) keeps any other thread from starting a new one.
fn remove_all(list: &mut MutexGuard<'static, Vec<PathBuf>>) -> usize {
    let removed = list
        .iter()
        .filter(|p| std::fs::remove_file(p).is_ok())
        .count();
    list.clear();
    removed
}

/// Installs the interrupt cleanup (module doc). Call it before any other thread is started:
/// threads started earlier keep receiving the signals themselves.
#[cfg(unix)]
pub fn install_interrupt_cleanup() {
    // SAFETY: sigset manipulation on a local set; pthread_sigmask on the calling thread.
    let set = unsafe {
        let mut set: libc::sigset_t = std::mem::zeroed();
        libc::sigemptyset(&mut set);
        for signal in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
            libc::sigaddset(&mut set, signal);
        }
        if libc::pthread_sigmask(libc::SIG_BLOCK, &set, std::ptr::null_mut()) != 0 {
            return;
        }
        set
    };
    let spawned = std::thread::Builder::new()
        .name("morphray-signals".into())
        .spawn(move || wait_and_clean(set));
    if spawned.is_err() {
        // No thread, no cleanup: let the signals act as before.
        // SAFETY: unblocking the set this function blocked.
        unsafe { libc::pthread_sigmask(libc::SIG_UNBLOCK, &set, std::ptr::null_mut()) };
    }
}

#[cfg(not(unix))]
pub fn install_interrupt_cleanup() {}

#[cfg(unix)]
fn wait_and_clean(set: libc::sigset_t) {
    let mut signal: libc::c_int = 0;
    // SAFETY: sigwait on a set blocked in every thread (inherited from the main thread).
    if unsafe { libc::sigwait(&set, &mut signal) } != 0 {
        return;
    }
    let mut list = live();
    let removed = remove_all(&mut list);
    let name = match signal {
        libc::SIGINT => "SIGINT",
        libc::SIGTERM => "SIGTERM",
        _ => "SIGHUP",
    };
    if removed > 0 {
        eprintln!("morphray: interrupted ({name}); removed {removed} unfinished output file(s)");
    } else {
        eprintln!("morphray: interrupted ({name})");
    }
    // End by the same signal, with the default action, from this thread (the only one that does
    // not block it), so the parent sees a process killed by SIGINT/SIGTERM. The list stays locked.
    // SAFETY: resetting a disposition and unblocking a signal in this thread, then raising it.
    unsafe {
        libc::signal(signal, libc::SIG_DFL);
        let mut one: libc::sigset_t = std::mem::zeroed();
        libc::sigemptyset(&mut one);
        libc::sigaddset(&mut one, signal);
        libc::pthread_sigmask(libc::SIG_UNBLOCK, &one, std::ptr::null_mut());
        libc::raise(signal);
    }
    std::process::exit(128 + signal);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_names_of_the_pattern_give_a_pid() {
        assert_eq!(temp_pid(".scan.nii.gz.4242.7.tmp"), Some(4242));
        assert_eq!(temp_pid(".a.png.1.0.tmp"), Some(1));
        for name in [
            "scan.4242.7.tmp",
            ".scan.4242.x.tmp",
            ".scan.42a.7.tmp",
            "..4242.7.tmp",
            ".4242.7.tmp",
            ".scan.4242.7.tmp.keep",
        ] {
            assert_eq!(temp_pid(name), None, "{name}");
        }
    }

    #[test]
    fn stale_files_of_dead_writers_go_and_live_or_foreign_ones_stay() {
        let dir = std::env::temp_dir().join(format!("morphray-stale-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        // A PID that cannot be running: above the kernel's pid_max (at most 2^22).
        let dead = dir.join(".scan.nii.4194400.0.tmp");
        let mine = dir.join(format!(".scan.nii.{}.0.tmp", std::process::id()));
        let parent = dir.join(format!(
            ".scan.nii.{}.0.tmp",
            std::os::unix::process::parent_id()
        ));
        let other = dir.join(".notes.txt");
        for p in [&dead, &mine, &parent, &other] {
            std::fs::write(p, b"partial").unwrap();
        }
        // A dead PID whose file is still locked (a writer on another host): kept.
        let locked = dir.join(".remote.png.4194401.0.tmp");
        let holder = std::fs::File::create(&locked).unwrap();
        lock(&holder);
        assert_eq!(remove_stale(&dir), 1);
        assert!(!dead.exists());
        for p in [&mine, &parent, &other, &locked] {
            assert!(p.exists(), "{}", p.display());
        }
        // Once per folder and process.
        std::fs::write(&dead, b"again").unwrap();
        assert_eq!(remove_stale(&dir), 0);
        drop(holder);
        assert_eq!(remove_stale_now(&dir), 2);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
