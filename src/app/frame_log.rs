//! The scripted session's log: which GPU passes ran for each frame, and for each interface
//! action the time until the first frame that shows it.
//!
//! Decisions:
//! - Passes are attributed to the frame that first shows their result: the raymarch of that
//!   frame, plus any loader work (preparing a volume, computing a derived volume) delivered
//!   since the previous frame, named as such. Composition passes (blit, egui, copy to the
//!   window) are listed apart: they are graphics/transfer work, not compute.
//! - An action's latency runs from the moment it is applied (before the frame's interface and
//!   raymarch are recorded) to the moment the GPU finished the first frame whose rendered scene
//!   differs from the one before the action (or, for `open`, which shows the new volume). The
//!   viewer waits for that frame's fence to stamp it; presentation to the screen comes after
//!   and is not included (no portable way to see scanout).
//! - The summary proves the paper's "only uniforms change" claim from the log itself: it lists
//!   every frame after the first one that ran a compute pass other than the raymarch.

use crate::gpu::PassTiming;
use crate::scene::Scene;
use std::collections::BTreeMap;
use std::time::Instant;

/// What resolves a pending action.
#[derive(Clone, Debug, PartialEq)]
pub enum Until {
    /// The first frame whose rendered scene differs from this one.
    SceneChanges(Box<Scene>),
    /// The first frame that shows volume request `id`.
    VolumeShown(u64),
}

/// An action waiting for the frame that shows it.
#[derive(Clone, Debug)]
pub struct Pending {
    /// The action as written.
    pub label: String,
    /// When it was applied.
    pub since: Instant,
    /// What resolves it.
    pub until: Until,
}

/// A resolved action.
#[derive(Clone, Debug, PartialEq)]
pub struct Latency {
    /// The action.
    pub label: String,
    /// The frame that first showed it.
    pub frame: u64,
    /// Milliseconds from the action to that frame's GPU completion.
    pub ms: f64,
}

/// Passes of one frame.
#[derive(Clone, Debug, Default)]
pub struct FrameRecord {
    /// Frame number (1 = the first frame that showed a volume).
    pub number: u64,
    /// Compute passes: (group, pass timings). Group "raymarch" for the frame's own render, or
    /// e.g. "load phantom" / "derived volume (curvature)" for loader work shown first here.
    pub compute: Vec<(String, Vec<PassTiming>)>,
    /// Composition passes (filled in when the frame's fence is seen).
    pub compose: Vec<PassTiming>,
    /// Host time of the frame, ms.
    pub cpu_ms: f64,
    /// Its composition finished.
    pub complete: bool,
    /// The adaptive quality level of the image shown (`full`, `step x4, scale 0.5`; empty:
    /// not recorded).
    pub quality: String,
}

impl FrameRecord {
    /// Names of the compute passes, in order.
    pub fn compute_names(&self) -> Vec<String> {
        self.compute
            .iter()
            .flat_map(|(_, passes)| passes.iter().map(|p| p.name.clone()))
            .collect()
    }

    /// One log line.
    pub fn line(&self) -> String {
        let group = |(label, passes): &(String, Vec<PassTiming>)| {
            let inner: Vec<String> = passes
                .iter()
                .map(|p| format!("{} {:.2} ms", p.name, p.gpu_ms))
                .collect();
            if label == "raymarch" {
                inner.join(", ")
            } else {
                format!("[{label}: {}]", inner.join(", "))
            }
        };
        let compute: Vec<String> = self.compute.iter().map(group).collect();
        let compose: Vec<String> = self
            .compose
            .iter()
            .map(|p| format!("{} {:.2}", p.name, p.gpu_ms))
            .collect();
        let quality = if self.quality.is_empty() {
            String::new()
        } else {
            format!("  |  quality {}", self.quality)
        };
        format!(
            "frame {:>4}  compute: {}  |  compose: {}  |  cpu {:.1} ms{quality}",
            self.number,
            if compute.is_empty() {
                "none".to_string()
            } else {
                compute.join(" ")
            },
            compose.join(", "),
            self.cpu_ms
        )
    }
}

/// The log of a session.
#[derive(Debug, Default)]
pub struct FrameLog {
    /// Print lines to stdout as frames complete.
    pub print: bool,
    records: BTreeMap<u64, FrameRecord>,
    done: Vec<FrameRecord>,
    /// Actions not yet shown.
    pub pending: Vec<Pending>,
    /// Actions shown.
    pub latencies: Vec<Latency>,
}

impl FrameLog {
    /// A log that prints (or only collects).
    pub fn new(print: bool) -> Self {
        FrameLog {
            print,
            ..FrameLog::default()
        }
    }

    /// Prints a line when printing.
    pub fn say(&self, text: &str) {
        if self.print {
            crate::files::stdout::print_line(text);
        }
    }

    /// Records a frame that was submitted (its composition times come later).
    pub fn submitted(&mut self, serial: u64, record: FrameRecord) {
        self.records.insert(serial, record);
    }

    /// Completes a frame with the times of its one submission: the raymarch (when the frame
    /// rendered one) goes with the compute passes, the rest is composition. Prints completed
    /// frames in order (a frame waited for early, to stamp a latency, waits for the ones before
    /// it).
    pub fn completed(&mut self, serial: u64, passes: Vec<PassTiming>) {
        if let Some(record) = self.records.get_mut(&serial) {
            let (raymarch, compose): (Vec<_>, Vec<_>) =
                passes.into_iter().partition(|p| p.name == "raymarch");
            if !raymarch.is_empty() {
                record.compute.push(("raymarch".into(), raymarch));
            }
            record.compose = compose;
            record.complete = true;
        }
        while let Some(entry) = self.records.first_entry() {
            if !entry.get().complete {
                break;
            }
            let record = entry.remove();
            self.say(&record.line());
            self.done.push(record);
        }
    }

    /// Forgets frames whose composition will never be reported (their device is gone).
    pub fn abandon_in_flight(&mut self) {
        let lost: Vec<u64> = self.records.keys().copied().collect();
        for serial in lost {
            if let Some(record) = self.records.remove(&serial) {
                self.say(&format!("frame {:>4}  lost with the device", record.number));
            }
        }
    }

    /// Resolves pending actions against a frame that just finished on the GPU.
    pub fn resolve(&mut self, frame: u64, rendered: &Scene, volume: Option<u64>, now: Instant) {
        let mut still = Vec::new();
        for p in std::mem::take(&mut self.pending) {
            let shown = match &p.until {
                Until::SceneChanges(before) => **before != *rendered,
                Until::VolumeShown(id) => volume == Some(*id),
            };
            if shown {
                let ms = now.duration_since(p.since).as_secs_f64() * 1e3;
                self.say(&format!(
                    "action \"{}\" -> first shown by frame {frame}: {ms:.1} ms",
                    p.label
                ));
                self.latencies.push(Latency {
                    label: p.label,
                    frame,
                    ms,
                });
            } else {
                still.push(p);
            }
        }
        self.pending = still;
    }

    /// True when some pending action would be resolved by a frame rendering `rendered`.
    pub fn would_resolve(&self, rendered: &Scene, volume: Option<u64>) -> bool {
        self.pending.iter().any(|p| match &p.until {
            Until::SceneChanges(before) => **before != *rendered,
            Until::VolumeShown(id) => volume == Some(*id),
        })
    }

    /// Frames completed so far.
    pub fn frames(&self) -> &[FrameRecord] {
        &self.done
    }

    /// The summary lines: frames, compute passes after the first frame, action latencies.
    pub fn summary(&self) -> Vec<String> {
        let mut lines = Vec::new();
        let frames = &self.done;
        lines.push(format!("summary: {} frames logged", frames.len()));
        if let Some(first) = frames.first() {
            lines.push(format!(
                "  frame {} (first): compute passes {}",
                first.number,
                first.compute_names().join(", ")
            ));
        }
        let later = frames.iter().skip(1);
        let mut only_raymarch = 0;
        let mut exceptions = Vec::new();
        for f in later {
            let names = f.compute_names();
            if names.iter().all(|n| n == "raymarch") {
                only_raymarch += 1;
            } else {
                let extra: Vec<String> = f
                    .compute
                    .iter()
                    .filter(|(label, _)| label != "raymarch")
                    .map(|(label, passes)| {
                        let names: Vec<&str> = passes.iter().map(|p| p.name.as_str()).collect();
                        format!("{label} ({})", names.join(", "))
                    })
                    .collect();
                exceptions.push(format!("frame {}: {}", f.number, extra.join("; ")));
            }
        }
        lines.push(format!(
            "  frames after the first with no compute pass but the raymarch: {} of {}",
            only_raymarch,
            frames.len().saturating_sub(1)
        ));
        if exceptions.is_empty() {
            lines.push("  other compute passes after the first frame: none".into());
        } else {
            for e in exceptions {
                lines.push(format!("  other compute passes after the first frame: {e}"));
            }
        }
        let raymarch: Vec<f64> = frames
            .iter()
            .flat_map(|f| f.compute.iter())
            .filter(|(label, _)| label == "raymarch")
            .flat_map(|(_, p)| p.iter().map(|p| p.gpu_ms))
            .collect();
        if !raymarch.is_empty() {
            let mut sorted = raymarch.clone();
            sorted.sort_by(f64::total_cmp);
            lines.push(format!(
                "  raymarch GPU ms: median {:.2}, min {:.2}, max {:.2}",
                sorted[sorted.len() / 2],
                sorted[0],
                sorted[sorted.len() - 1]
            ));
        }
        lines.push("  action -> first frame showing it (GPU done):".into());
        for l in &self.latencies {
            lines.push(format!(
                "    {:<32} frame {:>4}  {:>8.1} ms",
                l.label, l.frame, l.ms
            ));
        }
        for p in &self.pending {
            lines.push(format!("    {:<32} never changed the picture", p.label));
        }
        lines
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Classification, TissueClass};

    fn pass(name: &str, ms: f64) -> PassTiming {
        PassTiming {
            name: name.into(),
            gpu_ms: ms,
        }
    }

    #[test]
    fn the_summary_names_every_extra_compute_pass_after_the_first_frame() {
        let mut log = FrameLog::new(false);
        let raymarch = |n| FrameRecord {
            number: n,
            compute: vec![("raymarch".into(), vec![pass("raymarch", 2.0)])],
            ..FrameRecord::default()
        };
        let mut first = raymarch(1);
        first
            .compute
            .insert(0, ("load phantom".into(), vec![pass("minmax", 1.0)]));
        log.submitted(1, first);
        log.submitted(2, raymarch(2));
        let mut third = raymarch(3);
        third.compute.push((
            "derived volume (curvature)".into(),
            vec![pass("derivatives", 9.0)],
        ));
        log.submitted(3, third);
        for s in 1..=3 {
            log.completed(s, vec![pass("interface", 0.5)]);
        }
        let summary = log.summary().join("\n");
        assert!(
            summary.contains("no compute pass but the raymarch: 1 of 2"),
            "{summary}"
        );
        assert!(
            summary.contains("frame 3: derived volume (curvature) (derivatives)"),
            "{summary}"
        );
        assert!(
            log.frames()[0]
                .line()
                .contains("[load phantom: minmax 1.00 ms]")
        );
    }

    #[test]
    fn one_submission_times_split_into_the_raymarch_and_the_composition() {
        let mut log = FrameLog::new(false);
        let mut record = FrameRecord {
            number: 1,
            ..FrameRecord::default()
        };
        record.compute.push((
            "derived volume (curvature)".into(),
            vec![pass("derivatives", 9.0)],
        ));
        log.submitted(7, record);
        log.completed(
            7,
            vec![
                pass("raymarch", 2.0),
                pass("compose", 0.1),
                pass("interface", 0.5),
                pass("to window", 0.2),
            ],
        );
        let frame = &log.frames()[0];
        assert_eq!(frame.compute_names(), ["derivatives", "raymarch"]);
        let compose: Vec<&str> = frame.compose.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(compose, ["compose", "interface", "to window"]);
        assert!(
            frame.line().contains("raymarch 2.00 ms"),
            "{}",
            frame.line()
        );
    }

    #[test]
    fn actions_resolve_at_the_first_frame_that_differs() {
        let mut log = FrameLog::new(false);
        let before = Scene::new(Classification::with_windows([None; 4]));
        let t0 = Instant::now();
        log.pending.push(Pending {
            label: "toggle wm".into(),
            since: t0,
            until: Until::SceneChanges(Box::new(before)),
        });
        log.pending.push(Pending {
            label: "open x".into(),
            since: t0,
            until: Until::VolumeShown(7),
        });
        assert!(!log.would_resolve(&before, Some(6)));
        log.resolve(5, &before, Some(6), t0);
        assert!(log.latencies.is_empty());
        let mut after = before;
        after.classification.style_mut(TissueClass::Wm).visible = false;
        assert!(log.would_resolve(&after, Some(6)));
        log.resolve(
            6,
            &after,
            Some(6),
            t0 + std::time::Duration::from_millis(20),
        );
        assert_eq!(log.latencies.len(), 1);
        assert_eq!(log.latencies[0].frame, 6);
        assert!((log.latencies[0].ms - 20.0).abs() < 1e-6);
        log.resolve(9, &after, Some(7), t0);
        assert_eq!(log.latencies[1].label, "open x");
        assert!(log.pending.is_empty());
    }
}
