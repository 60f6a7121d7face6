//! The command line's whole input path: bytes written to disk as a `.nii`, `.nii.gz` or a
//! `.hdr`/`.img` pair (`input_files` decides), then `nifti::load_file_timed`, the function the
//! command line itself calls (regular-file read with its cap, bounded gzip inflation learnt from
//! the header, pair lookup in either direction and case, header validation, conversion).
//!
//! Checks beyond "no panic": an accepted volume is usable (`check_loaded`), the frame asked for
//! is the one loaded, the hash callback saw the file's bytes, errors are one line. Run with
//! `-malloc_limit_mb=64` (README.md): fuzz inputs are at most a few KB, so no honest allocation
//! comes near 64 MB (gzip output is capped at 1032x the input), and any allocation a header
//! could inflate is a crash.
#![no_main]

use libfuzzer_sys::fuzz_target;
use morphray_fuzz::run_input_path;
use std::path::PathBuf;
use std::sync::OnceLock;

/// One directory per fuzzing process, reused (files are overwritten, stale ones removed).
fn dir() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let d = std::env::temp_dir().join(format!("morphray-fuzz-input-{}", std::process::id()));
        std::fs::create_dir_all(&d).expect("a temporary directory");
        d
    })
}

fuzz_target!(|data: &[u8]| {
    let _ = run_input_path(dir(), data);
});
