//! How much host memory a request may take: the kernel's estimate of what can be allocated
//! without swapping (`MemAvailable` in /proc/meminfo).
//!
//! Decisions: allocation sizes that come from a user (a phantom's `--dims`) are checked against
//! this before allocating, because Linux overcommits: `try_reserve` of 25 GB succeeds on a
//! 24 GB machine and the process is killed later, while touching the pages, with no message.
//! Where the number is unknown (another OS, no /proc), only the allocator's own refusal remains.
//! - [`check`] is the one refusal every input path uses (DICOM series, DICOM deflate, NIfTI
//!   inflation): one line saying what the input needs and what is free, so a smaller machine
//!   gets a message instead of the OOM killer.
//! - `MORPHRAY_MEM_AVAILABLE` (bytes) replaces MemAvailable when set: tests and the reliability
//!   probe use it to make a refusal happen on any machine, and a user on a shared machine can
//!   use it to refuse earlier than the kernel would.

/// The variable that replaces MemAvailable (bytes).
pub const OVERRIDE_VAR: &str = "MORPHRAY_MEM_AVAILABLE";

/// Bytes the kernel says can be allocated now, or None where it does not say.
pub fn available_bytes() -> Option<u64> {
    if let Some(bytes) = std::env::var(OVERRIDE_VAR)
        .ok()
        .and_then(|v| v.trim().parse::<u64>().ok())
    {
        return Some(bytes);
    }
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    parse_meminfo(&text)
}

/// Refuses `needed` bytes for `what` when the host has less available: one line, e.g.
/// "series 3 needs 3.2 GB of memory (its 130 files declare ...) but only 1.1 GB is available
/// (MemAvailable); close other programs or use a machine with more memory". Unknown
/// availability passes.
pub fn check(needed: u64, what: &str) -> Result<(), String> {
    match available_bytes() {
        Some(free) if needed > free => Err(format!(
            "{what} needs {} of memory but only {} is available (MemAvailable); close other \
             programs or use a machine with more memory",
            human(needed),
            human(free)
        )),
        _ => Ok(()),
    }
}

/// Bytes for people: "3.2 GB", "640 MB", "12 KB", "100 bytes" (powers of 1000, one decimal).
pub fn human(bytes: u64) -> String {
    let b = bytes as f64;
    if bytes >= 1_000_000_000 {
        format!("{:.1} GB", b / 1e9)
    } else if bytes >= 1_000_000 {
        format!("{:.1} MB", b / 1e6)
    } else if bytes >= 1_000 {
        format!("{:.1} KB", b / 1e3)
    } else {
        format!("{bytes} bytes")
    }
}

/// `MemAvailable` of a /proc/meminfo text, in bytes.
fn parse_meminfo(text: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line
        .trim_start_matches("MemAvailable:")
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    kib.checked_mul(1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mem_available_is_read_in_bytes() {
        let text = "MemTotal:       24000000 kB\nMemFree:  100 kB\nMemAvailable:   20000000 kB\n";
        assert_eq!(parse_meminfo(text), Some(20_000_000 * 1024));
        assert_eq!(parse_meminfo("MemTotal: 5 kB\n"), None);
        assert_eq!(parse_meminfo("MemAvailable: lots kB\n"), None);
    }

    #[test]
    fn sizes_read_as_people_write_them() {
        assert_eq!(human(3_200_000_000), "3.2 GB");
        assert_eq!(human(640_000_000), "640.0 MB");
        assert_eq!(human(999), "999 bytes");
    }
}
