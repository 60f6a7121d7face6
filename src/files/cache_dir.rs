//! Whether a cache folder can take files, checked before any cache is used: a cache is only a
//! speed-up, so one that cannot be written (a file in its place, a read-only or full file
//! system) is turned off with one line instead of failing later. Mesa's shader disk cache
//! memory-maps its index, and on a full file system the first write to that mapping is a
//! SIGBUS that kills every GPU command without a word: the only defence is to turn it off
//! (`MESA_SHADER_CACHE_DISABLE`) before the Vulkan instance exists.
//!
//! Decisions:
//! - Nothing is created to check: a folder that does not exist yet is judged by its nearest
//!   existing ancestor (the cache creates the rest when it writes), so `morphray info` leaves no
//!   empty cache folders behind.
//! - A folder is usable when it (or that ancestor) is a directory, a file can be created and
//!   removed in it (permission bits do not tell for root or a read-only mount), and the file
//!   system has at least [`MIN_FREE_BYTES`] free.
//! - Mesa's folder is found as Mesa 22-24 find it: `$MESA_SHADER_CACHE_DIR` (or the older
//!   `$MESA_GLSL_CACHE_DIR`), else `$XDG_CACHE_HOME`, else `$HOME/.cache`, each with
//!   `mesa_shader_cache` appended. A user who turned the cache off already is left alone.

use std::path::{Path, PathBuf};

/// Free space below which a cache folder counts as full (Mesa's index alone is 1.3 MB, and a
/// cache file of a big driver is tens of MB).
pub const MIN_FREE_BYTES: u64 = 64 << 20;

/// Why `dir` cannot be used as a cache folder, in words (None: usable).
pub fn unusable(dir: &Path) -> Option<String> {
    let mut existing = dir;
    loop {
        match std::fs::metadata(existing) {
            Ok(meta) if meta.is_dir() => break,
            Ok(_) => return Some(format!("{} is a file, not a folder", existing.display())),
            // A missing folder, or one under a file: judged by the parent (which says "a file").
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::NotFound | std::io::ErrorKind::NotADirectory
                ) =>
            {
                match existing.parent() {
                    Some(parent) if !parent.as_os_str().is_empty() => existing = parent,
                    _ => return Some(format!("{} does not exist", dir.display())),
                }
            }
            Err(e) => return Some(format!("{} cannot be read ({e})", existing.display())),
        }
    }
    if let Err(e) = probe(existing) {
        return Some(format!(
            "no file can be created in {} ({e})",
            existing.display()
        ));
    }
    match free_bytes(existing) {
        Some(free) if free < MIN_FREE_BYTES => Some(format!(
            "the file system of {} is full ({} MiB free)",
            existing.display(),
            free >> 20
        )),
        _ => None,
    }
}

fn probe(dir: &Path) -> std::io::Result<()> {
    let path = dir.join(format!(".morphray-cache-probe.{}", std::process::id()));
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&path)?;
    std::fs::remove_file(&path)
}

#[cfg(unix)]
fn free_bytes(dir: &Path) -> Option<u64> {
    use std::os::unix::ffi::OsStrExt;
    let c = std::ffi::CString::new(dir.as_os_str().as_bytes()).ok()?;
    // SAFETY: statvfs fills the zeroed struct for a NUL-terminated path.
    let mut stat: libc::statvfs = unsafe { std::mem::zeroed() };
    if unsafe { libc::statvfs(c.as_ptr(), &mut stat) } != 0 {
        return None;
    }
    Some((stat.f_bavail as u64).saturating_mul(stat.f_frsize as u64))
}

#[cfg(not(unix))]
fn free_bytes(_dir: &Path) -> Option<u64> {
    None
}

/// Mesa's shader cache folder from these environment values (module doc); None when Mesa's
/// cache is already off or no folder can be named.
pub fn mesa_cache_dir(var: impl Fn(&str) -> Option<String>) -> Option<PathBuf> {
    let set = |name: &str| var(name).filter(|v| !v.is_empty());
    let truthy = |name: &str| {
        set(name).is_some_and(|v| matches!(v.to_ascii_lowercase().as_str(), "1" | "true" | "yes"))
    };
    if truthy("MESA_SHADER_CACHE_DISABLE") || truthy("MESA_GLSL_CACHE_DISABLE") {
        return None;
    }
    let base = set("MESA_SHADER_CACHE_DIR")
        .or_else(|| set("MESA_GLSL_CACHE_DIR"))
        .map(PathBuf::from)
        .or_else(|| set("XDG_CACHE_HOME").map(PathBuf::from))
        .or_else(|| set("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
    Some(base.join("mesa_shader_cache"))
}

/// Turns Mesa's shader disk cache off when its folder cannot take files; returns the one line
/// to show. Call it first thing in `main`, before any thread or Vulkan instance exists.
pub fn guard_mesa_cache() -> Option<String> {
    let dir = mesa_cache_dir(|name| std::env::var(name).ok())?;
    let why = unusable(&dir)?;
    // SAFETY: called from `main` before any other thread exists (nothing reads the environment
    // concurrently); the Vulkan loader reads these variables later, on this thread.
    unsafe {
        std::env::set_var("MESA_SHADER_CACHE_DISABLE", "true");
        std::env::set_var("MESA_GLSL_CACHE_DISABLE", "true");
    }
    Some(format!(
        "the driver's shader cache is off for this run: {why}; free space or point \
         MESA_SHADER_CACHE_DIR at a writable folder"
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_a_folder_without_room_for_files_and_a_fine_folder() {
        let root = std::env::temp_dir().join(format!("morphray-cachedir-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        std::fs::create_dir_all(&root).unwrap();
        let file = root.join("cache");
        std::fs::write(&file, b"x").unwrap();
        let why = unusable(&file.join("morphray")).unwrap();
        assert!(why.contains("is a file, not a folder"), "{why}");
        // /proc takes no new file, even for root (chmod does not stop root).
        let why = unusable(Path::new("/proc/morphray-cache")).unwrap();
        assert!(why.contains("no file can be created in /proc"), "{why}");
        // Not created yet: judged by its existing parent, and nothing is created.
        let later = root.join("a/b");
        assert_eq!(unusable(&later), None);
        assert!(!root.join("a").exists());
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn mesa_folder_follows_its_variables() {
        let env = |pairs: &'static [(&'static str, &'static str)]| {
            move |name: &str| {
                pairs
                    .iter()
                    .find(|(k, _)| *k == name)
                    .map(|(_, v)| v.to_string())
            }
        };
        assert_eq!(
            mesa_cache_dir(env(&[("HOME", "/h"), ("XDG_CACHE_HOME", "/x")])),
            Some(PathBuf::from("/x/mesa_shader_cache"))
        );
        assert_eq!(
            mesa_cache_dir(env(&[("HOME", "/h"), ("MESA_SHADER_CACHE_DIR", "/m")])),
            Some(PathBuf::from("/m/mesa_shader_cache"))
        );
        assert_eq!(
            mesa_cache_dir(env(&[("HOME", "/h")])),
            Some(PathBuf::from("/h/.cache/mesa_shader_cache"))
        );
        assert_eq!(
            mesa_cache_dir(env(&[
                ("HOME", "/h"),
                ("MESA_SHADER_CACHE_DISABLE", "true")
            ])),
            None
        );
    }
}
