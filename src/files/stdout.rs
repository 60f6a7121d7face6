//! Standard output that a closed pipe cannot turn into a panic (`morphray peaks | head`): the
//! commands and the viewer's log print through [`print_line`].

use std::io::Write;

/// Prints `text` and a newline; a closed pipe ends output quietly instead of panicking.
pub fn print_line(text: &str) {
    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "{text}");
}
