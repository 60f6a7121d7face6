//! How much host memory a request may take: the kernel's estimate of what can be allocated
//! without swapping (`MemAvailable` in /proc/meminfo).
//!
//! Decisions: allocation sizes that come from a user (a phantom's `--dims`) are checked against
//! this before allocating, because Linux overcommits: `try_reserve` of 25 GB succeeds on a
//! 24 GB machine and the process is killed later, while touching the pages, with no message.
//! Where the number is unknown (another OS, no /proc), only the allocator's own refusal remains.

/// Bytes the kernel says can be allocated now, or None where it does not say.
pub fn available_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    parse_meminfo(&text)
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
}
