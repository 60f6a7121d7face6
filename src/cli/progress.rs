//! Progress on stderr for commands that can run longer than a second (issue 16 item 5): an
//! indicatif bar (frames of a turntable) or spinner (one large image) on a terminal.
//!
//! Decisions:
//! - Shown only where a person is watching: when stderr is a terminal, or when asked with
//!   `MORPHRAY_PROGRESS=always` (then, off a terminal, as one plain line per step, so a log file
//!   gets no control characters). `MORPHRAY_PROGRESS=never` silences it. Pipes and tests see
//!   nothing unless they ask.
//! - The spinner ticks on indicatif's own thread, so it moves while the render thread waits for
//!   the GPU (a 4096x4096 MIP on a CPU device took 37 s with no sign of life).
//! - stdout is untouched: the `wrote ...` lines stay machine-readable.
//! - Measuring commands (`bench`) say their phases as plain lines ([`say`]) instead: a ticking
//!   bar's thread would wake during the frames whose CPU wall they time.

use std::io::IsTerminal;
use std::time::Duration;

/// Where progress goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    Off,
    Bar,
    Lines,
}

fn mode() -> Mode {
    match std::env::var("MORPHRAY_PROGRESS").as_deref() {
        Ok("never") => Mode::Off,
        _ if std::io::stderr().is_terminal() => Mode::Bar,
        Ok("always") => Mode::Lines,
        _ => Mode::Off,
    }
}

/// One line on stderr naming a phase of a long command (`bench: orbit of 200 frames`), where
/// progress is shown at all (a terminal, or `MORPHRAY_PROGRESS=always`).
pub fn say(text: &str) {
    if mode() != Mode::Off {
        eprintln!("morphray: {text}");
    }
}

/// A progress display over `len` steps.
pub struct Progress {
    bar: Option<indicatif::ProgressBar>,
    lines: bool,
    len: u64,
    done: u64,
    unit: &'static str,
}

impl Progress {
    /// Progress over `len` steps called `unit` (`frames`); one step shows a spinner instead.
    pub fn new(len: u64, unit: &'static str) -> Self {
        let mode = mode();
        let bar = (mode == Mode::Bar).then(|| {
            let bar = if len > 1 {
                let b = indicatif::ProgressBar::new(len);
                if let Ok(style) = indicatif::ProgressStyle::with_template(&format!(
                    "{{bar:40}} {{pos}}/{{len}} {unit}  ETA {{eta}}  {{msg}}"
                )) {
                    b.set_style(style);
                }
                b
            } else {
                indicatif::ProgressBar::new_spinner()
            };
            bar.enable_steady_tick(Duration::from_millis(120));
            bar
        });
        Progress {
            bar,
            lines: mode == Mode::Lines,
            len,
            done: 0,
            unit,
        }
    }

    /// Says what is under way (`rendering 4096x4096`).
    pub fn message(&self, text: &str) {
        if let Some(bar) = &self.bar {
            bar.set_message(text.to_string());
        } else if self.lines {
            eprintln!("morphray: {text}");
        }
    }

    /// One step done.
    pub fn step(&mut self) {
        self.done += 1;
        if let Some(bar) = &self.bar {
            bar.inc(1);
        } else if self.lines && self.len > 1 {
            eprintln!("morphray: {} {}/{}", self.unit, self.done, self.len);
        }
    }

    /// Removes the bar (its last state is not left on the terminal).
    pub fn finish(self) {
        if let Some(bar) = self.bar {
            bar.finish_and_clear();
        }
    }
}
