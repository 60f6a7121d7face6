//! Writing to stdout without panicking when the reader goes away (`morphray peaks | head`).

use std::io::Write;

/// Prints `text` and a newline; a closed pipe ends output quietly instead of panicking.
pub fn print_line(text: &str) {
    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "{text}");
}

/// Pretty JSON of `value` (serialization of the engine's own types cannot fail; if it ever
/// did, the error text is printed instead of a panic).
pub fn json<T: serde::Serialize>(value: &T) -> String {
    serde_json::to_string_pretty(value).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
}

/// Milliseconds rounded to 3 decimals, for readable JSON.
pub fn ms(value: f64) -> f64 {
    (value * 1000.0).round() / 1000.0
}
