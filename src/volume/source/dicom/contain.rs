//! Containing panics of the DICOM parser: dicom-rs can panic on malformed files (its issue
//! 543: slicing past a buffer, arithmetic overflow), and one bad file in a folder must cost
//! only that file.
//!
//! Decisions: every call into dicom-rs on file contents runs inside [`contained`], which turns a
//! panic into the file's one-line reason. While such a call runs, [`panic_is_contained`] is true
//! on that thread, so a process-wide panic hook (the command line's "internal error" line) can
//! stay silent for a panic that is caught and reported as a skipped file.

use std::cell::Cell;
use std::panic::{AssertUnwindSafe, catch_unwind};

thread_local! {
    static CONTAINED: Cell<u32> = const { Cell::new(0) };
}

/// True while this thread runs a `contained` call (for panic hooks).
pub fn panic_is_contained() -> bool {
    CONTAINED.with(|c| c.get() > 0)
}

/// Runs `f`; a panic becomes `Err("the DICOM parser failed on it: MESSAGE")`.
pub fn contained<T>(f: impl FnOnce() -> T) -> Result<T, String> {
    CONTAINED.with(|c| c.set(c.get() + 1));
    let result = catch_unwind(AssertUnwindSafe(f));
    CONTAINED.with(|c| c.set(c.get().saturating_sub(1)));
    result.map_err(|payload| {
        let message = payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown panic".into());
        format!(
            "the DICOM parser failed on it ({})",
            super::headers::one_line(&message)
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panic_becomes_an_error_and_the_flag_is_reset() {
        let r: Result<(), String> = contained(|| panic!("index out of bounds"));
        assert!(r.unwrap_err().contains("index out of bounds"));
        assert!(!panic_is_contained());
        assert_eq!(contained(|| 7), Ok(7));
    }
}
