//! 4-D files in the viewer (issue 31 item 5): frames held in memory, frame changes that
//! re-prepare only the new frame, wall-clock playback and the time course at the crosshair.
//!
//! Decisions:
//! - When a 4-D file is adopted, the loader is asked to hold its frames (`app::frames_job`: the
//!   memory rule, a quarter of the memory budget and at most 2 GiB); the log says whether they
//!   are held or streamed, and why.
//! - A frame change keeps the volume on screen's plan, analysis, windows, look and brain mask:
//!   the loader prepares the new frame like it (`Engine::prepare_frame`, `derive_frame`) from
//!   the held samples, or from the one frame read from the file when streamed. The viewer then
//!   swaps the twin and the host volume (the readout's values) under a new volume id, so the 3D
//!   view and the slices are drawn again; the slices keep their crosshair and window.
//! - The full open path (read, plan, analyse) is kept for what a prepared frame cannot be: a
//!   bricked volume (its resident bricks follow its values), a constant first frame, a
//!   denoised session (the filter is part of the open), and a frame change that failed.
//! - One frame change at a time; it makes the viewer busy, so a script's `frame N` followed by
//!   `screenshot` shows frame N. A request while busy is kept (the last one wins) and made when
//!   the viewer is free: never a queue.
//! - Playback (`app::cine_panel::FrameClock`) asks for the frame the wall clock says whenever no
//!   change is in progress, so slow changes skip frames; the log names the skipped count.

use super::Viewer;
use crate::app::cine_panel::{Course, FrameClock, skipped};
use crate::app::frame_log::{Pending, Until};
use crate::app::frames_job::{FrameInput, HeldFrames, Holding, Like};
use crate::app::loader::FrameReply;
use crate::volume::source::{ReadOptions, VolumeSource};
use std::sync::Arc;
use std::time::Instant;

/// The viewer's 4-D state.
#[derive(Default)]
pub(super) struct CineState {
    /// The held frames and the source they are of.
    held: Option<(VolumeSource, Arc<HeldFrames>)>,
    /// The volume whose frames the loader was asked to hold, and its source.
    asked: Option<(u64, VolumeSource)>,
    /// Why the frames are streamed (None while holding is pending or done).
    streamed: Option<String>,
    /// The frame change in progress.
    pending: Option<PendingFrame>,
    /// A frame asked for while the viewer was busy (the last one wins), with its log label.
    wanted: Option<(usize, Option<String>)>,
    /// Playback, while playing.
    clock: Option<FrameClock>,
    /// The voxel and held frames the logged time course is of.
    course_of: Option<([usize; 3], usize)>,
    /// `view --play` applied (to the first 4-D volume).
    started: bool,
    /// The frame asked for now comes from playback (not a person or a script).
    by_clock: bool,
}

impl CineState {
    /// A frame change, or the reading of the frames into memory, is in progress: the viewer is
    /// busy (a script's next step waits; a frame asked for meanwhile is made after, from
    /// memory, rather than read from the file a second time).
    pub(super) fn busy(&self) -> bool {
        let holding = self.asked.is_some() && self.held.is_none() && self.streamed.is_none();
        self.pending.is_some() || holding
    }

    /// A frame change is in progress (its twin will replace the one on screen).
    pub(super) fn changing(&self) -> bool {
        self.pending.is_some()
    }
}

/// A frame change in progress.
pub(super) struct PendingFrame {
    index: usize,
    /// The volume id the frame gets when shown.
    new_id: u64,
    since: Instant,
    /// Frames playback skipped to get to it.
    skipped: usize,
    /// Asked for by playback; else playback goes on from it when it is shown.
    by_clock: bool,
}

impl Viewer {
    /// A volume was adopted (opened in full): its frame count in the panel; a 4-D file's frames
    /// are asked to be held unless they are already.
    pub(super) fn cine_adopted(&mut self) {
        let Some(current) = &self.current else {
            return;
        };
        let (frame, count) = current.loaded.frame;
        self.controls.cine.frame = (frame, count);
        self.status.frame = (count > 1).then(|| format!("frame {frame}/{count}"));
        self.cine.pending = None;
        if count < 2 {
            self.cine.held = None;
            self.cine.asked = None;
            self.controls.cine.playing = false;
            self.controls.cine.course = None;
            return;
        }
        if !self.cine.started {
            self.cine.started = true;
            self.controls.cine.fps = self.config.cine.fps;
            self.controls.cine.playing = self.config.cine.play;
        }
        let source = &current.loaded.source;
        let known = |s: Option<&VolumeSource>| s == Some(source);
        if known(self.cine.held.as_ref().map(|h| &h.0))
            || known(self.cine.asked.as_ref().map(|a| &a.1))
        {
            return;
        }
        self.cine.held = None;
        self.cine.streamed = None;
        self.cine.course_of = None;
        self.cine.asked = Some((current.loaded.id, source.clone()));
        self.loader.hold_frames(
            current.loaded.id,
            source.clone(),
            current.loaded.host.clone(),
        );
        self.log.say(&format!(
            "4-D: {count} frames; reading them into memory if they fit"
        ));
    }

    /// The loader's 4-D replies.
    pub(super) fn frame_reply(&mut self, reply: FrameReply) {
        match reply {
            FrameReply::Held { id, holding } => {
                let Some((asked, source)) = self.cine.asked.clone() else {
                    return;
                };
                if asked != id {
                    return;
                }
                match holding {
                    Holding::Held(frames) => {
                        self.log.say(&format!(
                            "4-D: {} frames held in memory ({} KiB): a frame change re-prepares from memory",
                            frames.volumes.len(),
                            frames.bytes >> 10
                        ));
                        self.cine.held = Some((source, frames));
                    }
                    Holding::Streamed(why) => {
                        self.log
                            .say(&format!("4-D: frames streamed from the file: {why}"));
                        self.cine.streamed = Some(why);
                    }
                }
            }
            FrameReply::Ready { id, index, ready } => {
                let Some(pending) = self.cine.pending.take_if(|p| p.index == index) else {
                    return;
                };
                let Some(current) = self.current.as_mut().filter(|c| c.loaded.id == id) else {
                    return;
                };
                let loaded = &mut current.loaded;
                loaded.twin = ready.twin;
                loaded.host = ready.host;
                // The provenance of screenshots names the frame shown.
                loaded.warnings = loaded.host.warnings.clone();
                loaded.id = pending.new_id;
                let count = loaded.frame.1;
                loaded.frame = (index, count);
                self.frame = index;
                self.controls.cine.frame = (index, count);
                self.status.frame = Some(format!("frame {index}/{count}"));
                // The slices show the new frame at the same crosshair and window.
                self.controls.slices.volume = pending.new_id;
                self.controls.slices.dirty = true;
                self.render_blocked = None;
                if !pending.by_clock
                    && let Some(clock) = &mut self.cine.clock
                {
                    // A frame chosen while playing: playback goes on from it.
                    clock.from = index;
                    clock.start_s = self.config.started.elapsed().as_secs_f64();
                }
                self.arrived.push((format!("frame {index}"), ready.passes));
                let source = match ready.read_ms {
                    Some(ms) => format!("read from the file in {ms:.1} ms"),
                    None => "held in memory, no file read".to_string(),
                };
                let skipped = match pending.skipped {
                    0 => String::new(),
                    n => format!("; {n} skipped"),
                };
                let [normalize, derive, ranges] = ready.steps_ms;
                self.log.say(&format!(
                    "frame {index}/{count} shown in {:.1} ms ({source}; upload and normalization {normalize:.1} ms, derived volumes {derive:.1} ms, brick ranges {ranges:.1} ms{skipped})",
                    pending.since.elapsed().as_secs_f64() * 1e3,
                ));
            }
            FrameReply::Failed { id, index, message } => {
                self.cine.pending = None;
                if self.current.as_ref().map(|c| c.loaded.id) != Some(id) {
                    return;
                }
                self.log.say(&format!(
                    "frame {index}: {message}; opening that frame the full way"
                ));
                self.reopen_frame(index, None);
            }
        }
    }

    /// Asks for frame `index` prepared like the volume on screen (module decisions); false when
    /// it must be opened the full way. A request while busy is kept for later (true).
    pub(super) fn change_frame(&mut self, index: usize, label: Option<String>) -> bool {
        if self.busy() {
            self.cine.wanted = Some((index, label));
            return true;
        }
        let Some(current) = &self.current else {
            return false;
        };
        let prepared = &current.loaded.twin.prepared;
        let whole = matches!(
            current.loaded.plan.layout,
            crate::engine::plan::Layout::Whole
        );
        let denoised = self.config.recipe.denoise != crate::passes::denoise::Denoise::None;
        if !whole || prepared.normalization.constant || denoised {
            return false;
        }
        let input = match &self.cine.held {
            Some((source, frames)) if *source == current.loaded.source => {
                match frames.volumes.get(index) {
                    Some(v) => FrameInput::Held(v.clone()),
                    None => return false,
                }
            }
            _ => FrameInput::Read(
                current.loaded.source.clone(),
                ReadOptions {
                    frame: index,
                    hash: false,
                    series: super::opening::shown_series(&current.loaded),
                },
            ),
        };
        let twin = &current.loaded.twin;
        let like = Like {
            prepared: twin.prepared.clone(),
            outputs: twin.outputs(),
            brain: twin.derived().and_then(|d| d.brain.clone()),
        };
        let (shown, count) = current.loaded.frame;
        let id = current.loaded.id;
        let new_id = self.next_id;
        self.next_id += 1;
        let now = Instant::now();
        self.loader.frame(id, index, input, like);
        let by_clock = self.cine.by_clock;
        self.cine.pending = Some(PendingFrame {
            index,
            new_id,
            since: now,
            skipped: if by_clock {
                skipped(shown, index, count)
            } else {
                0
            },
            by_clock,
        });
        if let Some(label) = label {
            self.log.pending.push(Pending {
                label,
                since: now,
                until: Until::VolumeShown(new_id),
            });
        }
        true
    }

    /// Once per frame: a kept frame request, playback, and the time course.
    pub(super) fn tick_cine(&mut self) {
        if !self.busy()
            && let Some((index, label)) = self.cine.wanted.take()
        {
            self.open_frame(index, label);
        }
        self.play_step();
        self.update_course();
    }

    /// While playing, wakes a window that waits for input when the next frame is due.
    pub(super) fn cine_repaint(&self, result: &mut super::FrameResult) {
        let after = match self.cine.clock {
            Some(clock) => clock.seconds_to_next(self.config.started.elapsed().as_secs_f64()),
            // Play was pressed in this frame's interface: the next frame starts the clock.
            None if self.controls.cine.playing => 0.0,
            None => return,
        };
        result.repaint_after = Some(result.repaint_after.map_or(after, |r| r.min(after)));
    }

    /// Playback: starts, stops or changes rate as the panel says, and asks for the frame the
    /// wall clock says when no change is in progress.
    fn play_step(&mut self) {
        // The frame on screen (the panel's slider may be mid-drag).
        let Some((shown, count)) = self.current.as_ref().map(|c| c.loaded.frame) else {
            return;
        };
        let now_s = self.config.started.elapsed().as_secs_f64();
        let cine = &self.controls.cine;
        if !cine.playing || count < 2 {
            if self.cine.clock.take().is_some() {
                self.log.say(&format!("paused at frame {shown}/{count}"));
            }
            return;
        }
        let fps = cine.fps;
        let clock = match self.cine.clock {
            Some(clock) if clock.fps == fps => clock,
            _ => {
                self.log
                    .say(&format!("playing at {fps} fps from frame {shown}/{count}"));
                let clock = FrameClock {
                    start_s: now_s,
                    from: shown,
                    fps,
                };
                self.cine.clock = Some(clock);
                clock
            }
        };
        if self.busy() {
            return;
        }
        let next = clock.frame_at(now_s, count);
        if next != shown {
            self.cine.by_clock = true;
            self.open_frame(next, None);
            self.cine.by_clock = false;
        }
    }

    /// The time course at the crosshair's voxel (held frames), logged when it changes.
    fn update_course(&mut self) {
        let panel = &mut self.controls.cine;
        let Some(current) = &self.current else {
            return;
        };
        if current.loaded.frame.1 < 2 {
            return;
        }
        let Some(world) = self.controls.slices.crosshair else {
            panel.course = None;
            panel.note = Some("Click a slice to place the crosshair".into());
            return;
        };
        let Some((_, frames)) = self
            .cine
            .held
            .as_ref()
            .filter(|(s, _)| *s == current.loaded.source)
        else {
            panel.course = None;
            panel.note = Some(match &self.cine.streamed {
                Some(_) => "The time course needs the frames in memory (they are streamed)".into(),
                None => "Reading the frames for the time course...".into(),
            });
            return;
        };
        let hu = crate::scene::preset::values_are_hu(&current.loaded.report);
        let readout = crate::app::readout::readout(&current.loaded.host, world, hu);
        let Some(voxel) = readout.voxel else {
            panel.course = None;
            panel.note = Some("The crosshair is outside the volume".into());
            return;
        };
        let key = (voxel, Arc::as_ptr(frames) as usize);
        if self.cine.course_of == Some(key) && panel.course.is_some() {
            return;
        }
        let [nx, ny, _] = current.loaded.host.dims;
        let values = frames.time_course(voxel[0] + nx * (voxel[1] + ny * voxel[2]));
        let text: Vec<String> = values.iter().map(|v| v.to_string()).collect();
        self.log.say(&format!(
            "time course at voxel ({}, {}, {}): {}",
            voxel[0],
            voxel[1],
            voxel[2],
            text.join(", ")
        ));
        panel.note = None;
        panel.course = Some(Course {
            voxel,
            values,
            unit: readout.unit,
        });
        self.cine.course_of = Some(key);
    }
}
