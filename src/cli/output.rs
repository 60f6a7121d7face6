//! Writing to stdout without panicking when the reader goes away (`morphray peaks | head`), and
//! the input's warnings on stderr.
//!
//! Decision: every command that loads a volume prints the loader's repairs and warnings (the
//! 4-D frame chosen, a repaired pixdim, ...) as `morphray: warning: ...` lines on stderr before
//! its work, so a result computed from a repaired file never looks like one from a clean file;
//! `--json` outputs carry the same sentences in a `warnings` list, PNGs in a tEXt chunk.

use std::io::Write;

pub use crate::files::stdout::print_line;

/// Pretty JSON of `value` (serialization of the engine's own types cannot fail; if it ever
/// did, the error text is printed instead of a panic).
pub fn json<T: serde::Serialize>(value: &T) -> String {
    serde_json::to_string_pretty(value).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
}

/// Milliseconds rounded to 3 decimals, for readable JSON.
pub fn ms(value: f64) -> f64 {
    (value * 1000.0).round() / 1000.0
}

/// Prints each of the input's warnings as one `morphray: warning: ...` line on stderr.
pub fn print_warnings(warnings: &[String]) {
    let mut err = std::io::stderr().lock();
    for warning in warnings {
        let _ = writeln!(err, "morphray: warning: {}", super::one_line(warning));
    }
}
