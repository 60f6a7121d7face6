//! Traces for Perfetto and chrome://tracing (`--trace out.json`): host phases as spans on the
//! threads that ran them, GPU passes from timestamp queries on a track of their own.
//!
//! Decisions:
//! - One recorder per process, off unless a command asks for it ([`enable`]): a disabled
//!   [`span`] is one relaxed atomic load and no allocation, so the instrumentation stays in
//!   the hot paths.
//! - The format is the Chrome trace event JSON (complete events `"ph": "X"` with microsecond
//!   `ts`/`dur`, and thread-name metadata), which ui.perfetto.dev and chrome://tracing open
//!   as is.
//! - GPU passes have GPU durations but no host clock: a submission's passes are laid end to end
//!   so that the last ends when the host saw its fence signalled (no earlier than the submit),
//!   on the track "GPU queue". Gaps the GPU spent between passes of one submission are thus not
//!   shown; the durations are exact.
//! - This file sits in the bottom layer (std and serde_json only) so that every layer can
//!   record spans; the command writes the file through [`super::write::AtomicFile`].

use std::borrow::Cow;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Mutex, OnceLock};
use std::time::Instant;

static ENABLED: AtomicBool = AtomicBool::new(false);
static NEXT_THREAD: AtomicU64 = AtomicU64::new(1);
/// The GPU track's thread id (host threads count up from 1).
const GPU_TRACK: u64 = 1_000_000;

struct Recorder {
    origin: Instant,
    events: Vec<Event>,
    threads: Vec<(u64, String)>,
}

struct Event {
    name: String,
    category: &'static str,
    thread: u64,
    start_us: f64,
    duration_us: f64,
}

fn recorder() -> &'static Mutex<Recorder> {
    static RECORDER: OnceLock<Mutex<Recorder>> = OnceLock::new();
    RECORDER.get_or_init(|| {
        Mutex::new(Recorder {
            origin: Instant::now(),
            events: Vec::new(),
            threads: Vec::new(),
        })
    })
}

thread_local! {
    static THREAD: u64 = {
        let id = NEXT_THREAD.fetch_add(1, Ordering::Relaxed);
        let name = std::thread::current()
            .name()
            .map(str::to_string)
            .unwrap_or_else(|| format!("thread {id}"));
        let mut r = recorder().lock().unwrap_or_else(|p| p.into_inner());
        r.threads.push((id, name));
        id
    };
}

/// Starts recording (timestamps count from `origin`, e.g. the process start).
pub fn enable(origin: Instant) {
    let mut r = recorder().lock().unwrap_or_else(|p| p.into_inner());
    r.origin = origin;
    ENABLED.store(true, Ordering::Relaxed);
}

/// True while recording.
pub fn enabled() -> bool {
    ENABLED.load(Ordering::Relaxed)
}

/// A host phase, recorded when dropped.
pub struct Span {
    name: Cow<'static, str>,
    category: &'static str,
    start: Instant,
}

/// Starts a span named `name` in `category` (`io`, `gpu-setup`, `pipelines`, `prepare`, ...);
/// None (and nothing recorded) while tracing is off.
pub fn span(name: impl Into<Cow<'static, str>>, category: &'static str) -> Option<Span> {
    enabled().then(|| Span {
        name: name.into(),
        category,
        start: Instant::now(),
    })
}

impl Drop for Span {
    fn drop(&mut self) {
        let end = Instant::now();
        let thread = THREAD.with(|t| *t);
        let mut r = recorder().lock().unwrap_or_else(|p| p.into_inner());
        let start_us = self.start.saturating_duration_since(r.origin).as_secs_f64() * 1e6;
        let duration_us = end.saturating_duration_since(self.start).as_secs_f64() * 1e6;
        r.events.push(Event {
            name: std::mem::take(&mut self.name).into_owned(),
            category: self.category,
            thread,
            start_us,
            duration_us,
        });
    }
}

/// Records a submission's GPU passes (`(name, milliseconds)`, in order) that were submitted at
/// `submitted` and seen complete at `completed` (see the module doc for the placement).
pub fn gpu_passes(submitted: Instant, completed: Instant, passes: &[(&str, f64)]) {
    if !enabled() || passes.is_empty() {
        return;
    }
    let mut r = recorder().lock().unwrap_or_else(|p| p.into_inner());
    let total_us: f64 = passes.iter().map(|(_, ms)| ms * 1e3).sum();
    let submitted_us = submitted.saturating_duration_since(r.origin).as_secs_f64() * 1e6;
    let completed_us = completed.saturating_duration_since(r.origin).as_secs_f64() * 1e6;
    let mut at = (completed_us - total_us).max(submitted_us);
    for (name, ms) in passes {
        let duration_us = ms.max(0.0) * 1e3;
        r.events.push(Event {
            name: (*name).to_string(),
            category: "gpu",
            thread: GPU_TRACK,
            start_us: at,
            duration_us,
        });
        at += duration_us;
    }
}

/// The recording so far as a Chrome trace document.
pub fn document() -> serde_json::Value {
    let r = recorder().lock().unwrap_or_else(|p| p.into_inner());
    let mut events: Vec<serde_json::Value> = vec![serde_json::json!({
        "name": "process_name", "ph": "M", "pid": 1, "args": {"name": "morphray"}
    })];
    let mut threads = r.threads.clone();
    threads.push((GPU_TRACK, "GPU queue".into()));
    for (id, name) in threads {
        events.push(serde_json::json!({
            "name": "thread_name", "ph": "M", "pid": 1, "tid": id, "args": {"name": name}
        }));
    }
    for e in &r.events {
        events.push(serde_json::json!({
            "name": e.name,
            "cat": e.category,
            "ph": "X",
            "pid": 1,
            "tid": e.thread,
            "ts": e.start_us,
            "dur": e.duration_us,
        }));
    }
    serde_json::json!({ "traceEvents": events, "displayTimeUnit": "ms" })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spans_and_gpu_passes_become_complete_events_on_their_tracks() {
        // The recorder is process-wide: this is the only unit test that enables it.
        let origin = Instant::now();
        enable(origin);
        {
            let _s = span("host phase", "test");
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
        let submitted = Instant::now();
        std::thread::sleep(std::time::Duration::from_millis(5));
        gpu_passes(
            submitted,
            Instant::now(),
            &[("minmax", 1.0), ("normalize", 2.0)],
        );
        let doc = document();
        let events = doc["traceEvents"].as_array().unwrap();
        let find = |name: &str| {
            events
                .iter()
                .find(|e| e["name"] == name && e["ph"] == "X")
                .unwrap_or_else(|| panic!("{name} missing: {doc}"))
                .clone()
        };
        let host = find("host phase");
        assert!(host["dur"].as_f64().unwrap() >= 2000.0, "{host}");
        let (a, b) = (find("minmax"), find("normalize"));
        assert_eq!(a["tid"], GPU_TRACK);
        assert_eq!(a["dur"].as_f64().unwrap(), 1000.0);
        // End to end, the second right after the first, both after the submit.
        let a_end = a["ts"].as_f64().unwrap() + 1000.0;
        assert!((b["ts"].as_f64().unwrap() - a_end).abs() < 1e-6);
        let submitted_us = submitted.duration_since(origin).as_secs_f64() * 1e6;
        assert!(a["ts"].as_f64().unwrap() >= submitted_us - 1e-6);
        assert!(
            events
                .iter()
                .any(|e| e["ph"] == "M" && e["args"]["name"] == "GPU queue")
        );
    }
}
