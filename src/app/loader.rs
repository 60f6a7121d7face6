//! The loader thread: opens volumes through the library's open path (`Engine::open_with`: one
//! plan within the memory budget and the device profile, whole or bricked, analysis, the
//! recipe's scene, derived volumes) and computes derived volumes later asked for, so the
//! interface thread only ever records the raymarch and draws.
//!
//! Decisions:
//! - One worker thread with its own [`Engine`] on the interface's device (the queue is shared
//!   behind the device's lock): preparing a 256^3 volume or its Hessian takes seconds on a CPU
//!   device, and the window must keep drawing (spinner, camera on the previous volume) meanwhile.
//! - Jobs run in order; results and progress come back on a channel that the interface polls
//!   once per frame (never blocks on).
//! - The first load starts before the device exists (reading overlaps Vulkan start-up, as in
//!   `engine::Session::open`); the device is handed over when the window has made it. The read
//!   is the library's (`volume::source::read`), the rest is `Engine::open_with`, so `render`
//!   and the viewer open a file the same way (budget, `--bricked`, `--profile`).
//! - A cancel flag is checked between phases, so closing the window during a load ends the
//!   worker at the next phase boundary (a phase is at most one inflate or one GPU submission).
//! - Brick ranges for empty-space skipping are computed here right after preparing, so the
//!   first frame already runs the raymarch alone.
//! - A brain mask is read back here too (`app/brain_outline.rs`: the slices' outline), before
//!   the mask reaches the interface thread, so no frame reads it during the readback.

use super::brain_outline::BrainOutline;
use super::frames_job::{FrameInput, FrameReady, Holding, Like, hold_cap};
use crate::analysis::TissueReport;
use crate::engine::plan::Plan;
use crate::engine::{Derived, Engine, EngineConfig, OpenOptions, PreparedVolume, Twin};
use crate::gpu::{Device, GpuError, PassTiming};
use crate::passes::derivatives::DerivativeOutputs;
use crate::scene::Scene;
use crate::volume::source::{self, SeriesListing, VolumeSource};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Instant;

/// A volume ready to render.
pub struct LoadedVolume {
    /// Which request this answers.
    pub id: u64,
    /// File name or `phantom`.
    pub label: String,
    /// What was opened (a file, several DICOM files, or the phantom).
    pub source: VolumeSource,
    /// The series of a DICOM input and the one shown (None for other formats).
    pub series: Option<SeriesListing>,
    /// The frame read and how many the file has (`(0, 1)` for a 3-D volume).
    pub frame: (usize, usize),
    /// SHA-256 of the input (provenance of screenshots).
    pub sha256: String,
    /// Voxel spacing along the three index axes, millimetres.
    pub spacing_mm: [f64; 3],
    /// The volume on the GPU (whole or bricked) with the derived volumes the requested
    /// effects need (part of the load, so the first frame already shows them).
    pub twin: Twin,
    /// Histogram peaks and windows.
    pub report: TissueReport,
    /// The requested scene around this volume, with the planned (possibly degraded) effects.
    pub scene: Scene,
    /// The plan it was opened with (layout, degradations).
    pub plan: Plan,
    /// GPU passes that opening ran (min/max, normalize, histogram, derivatives), plus the
    /// brick ranges' host wall time.
    pub passes: Vec<PassTiming>,
    /// When the request was made (start of time to first pixel).
    pub requested_at: Instant,
    /// The loader's repairs and warnings about the file (shown on stderr, kept in screenshots'
    /// provenance).
    pub warnings: Vec<String>,
    /// A host copy of the twin's brain mask, for the slices' outline (None without a mask).
    pub brain_outline: Option<Arc<BrainOutline>>,
    /// The volume as read (stored samples and scaling), for the crosshair's value in the
    /// scanner's units (`app::readout`): kept on the host as other viewers keep it.
    pub host: Arc<crate::volume::Volume>,
}

/// Work for the thread.
enum Job {
    Load {
        id: u64,
        source: VolumeSource,
        requested_at: Instant,
        options: Box<OpenOptions>,
    },
    Derive {
        id: u64,
        prepared: Arc<PreparedVolume>,
        outputs: DerivativeOutputs,
    },
    /// Every frame of the 4-D file `template` is a frame of (`app::frames_job`).
    HoldFrames {
        id: u64,
        source: VolumeSource,
        template: Arc<crate::volume::Volume>,
    },
    /// Another frame prepared like the one on screen (`app::frames_job`).
    Frame {
        id: u64,
        index: usize,
        input: FrameInput,
        like: Box<Like>,
    },
    /// What the next volumes are taken to be (the viewer's modality and contrast menus).
    Identity {
        contrast: crate::analysis::ContrastChoice,
        modality: crate::analysis::ModalityChoice,
    },
}

/// What the thread reports.
pub enum Reply {
    /// A load moved to a new phase.
    Progress {
        /// Request.
        id: u64,
        /// What is happening, for the status line.
        stage: &'static str,
    },
    /// A load finished.
    Loaded(Box<LoadedVolume>),
    /// A load failed; the message is one line.
    LoadFailed {
        /// Request.
        id: u64,
        /// Why.
        message: String,
    },
    /// Derived volumes are ready.
    Derived {
        /// Request.
        id: u64,
        /// What was computed.
        outputs: DerivativeOutputs,
        /// The volumes (used with the volume they were derived from).
        derived: Box<Derived>,
        /// A host copy of their brain mask, for the slices' outline (None without a mask).
        brain_outline: Option<Arc<BrainOutline>>,
    },
    /// Derived volumes could not be computed.
    DeriveFailed {
        /// Request.
        id: u64,
        /// What was asked for.
        outputs: DerivativeOutputs,
        /// Why (one line).
        message: String,
        /// The device was lost (the viewer restarts the GPU).
        device_lost: bool,
    },
    /// 4-D work (held frames, a frame change).
    Frames(FrameReply),
}

/// The loader's 4-D replies (`app::frames_job`).
pub enum FrameReply {
    /// The frames of volume `id` are held, or streamed (and why).
    Held {
        /// The volume (request) whose frames these are.
        id: u64,
        /// The outcome.
        holding: Holding,
    },
    /// Frame `index` of volume `id` is prepared.
    Ready {
        /// The volume on screen when it was asked for.
        id: u64,
        /// Which frame.
        index: usize,
        /// The frame.
        ready: Box<FrameReady>,
    },
    /// Frame `index` could not be prepared (one line).
    Failed {
        /// The volume on screen when it was asked for.
        id: u64,
        /// Which frame.
        index: usize,
        /// Why.
        message: String,
    },
}

/// Handle of the loader thread.
pub struct Loader {
    jobs: Option<Sender<Job>>,
    replies: Receiver<Reply>,
    device: Arc<Mutex<Option<Sender<Device>>>>,
    cancel: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Loader {
    /// Starts the thread; it decodes files at once but waits for [`Loader::provide_device`]
    /// before its first GPU work.
    pub fn spawn(config: EngineConfig) -> Loader {
        let (jobs_tx, jobs_rx) = channel();
        let (replies_tx, replies_rx) = channel();
        let (device_tx, device_rx) = channel();
        let cancel = Arc::new(AtomicBool::new(false));
        let flag = cancel.clone();
        let thread = std::thread::Builder::new()
            .name("morphray-loader".into())
            .spawn(move || {
                let mut worker = Worker {
                    engine: None,
                    config,
                    device: device_rx,
                    replies: replies_tx,
                    cancel: flag,
                };
                worker.run(jobs_rx);
            })
            .ok();
        Loader {
            jobs: Some(jobs_tx),
            replies: replies_rx,
            device: Arc::new(Mutex::new(Some(device_tx))),
            cancel,
            thread,
        }
    }

    /// True when the thread could be started.
    pub fn is_running(&self) -> bool {
        self.thread.is_some()
    }

    /// Hands the device to the thread (its engine is created on it). A second call replaces
    /// the device after a device loss.
    pub fn provide_device(&self, device: Device) {
        // A poisoned lock is recovered, not skipped: the slot holds only a sender, which a
        // panic elsewhere cannot leave half-written, and skipping would lose the device.
        let guard = self
            .device
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        if let Some(tx) = guard.as_ref() {
            let _ = tx.send(device);
        }
    }

    /// Queues opening `source` with `options` (the recipe's effects are planned for and
    /// derived; `options.read.series` picks a DICOM series).
    pub fn load(&self, id: u64, source: VolumeSource, requested_at: Instant, options: OpenOptions) {
        if let Some(jobs) = &self.jobs {
            let _ = jobs.send(Job::Load {
                id,
                source,
                requested_at,
                options: Box::new(options),
            });
        }
    }

    /// Takes the volumes queued after this call as `modality` and `contrast` (`auto`: what
    /// the file says), as `--modality` and `--contrast` do; jobs run in order, so the next load
    /// sees it.
    pub fn set_identity(
        &self,
        contrast: crate::analysis::ContrastChoice,
        modality: crate::analysis::ModalityChoice,
    ) {
        if let Some(jobs) = &self.jobs {
            let _ = jobs.send(Job::Identity { contrast, modality });
        }
    }

    /// Queues computing `outputs` of `prepared`.
    pub fn derive(&self, id: u64, prepared: Arc<PreparedVolume>, outputs: DerivativeOutputs) {
        if let Some(jobs) = &self.jobs {
            let _ = jobs.send(Job::Derive {
                id,
                prepared,
                outputs,
            });
        }
    }

    /// Queues holding every frame of the 4-D file `template` is a frame of (volume `id`).
    pub fn hold_frames(&self, id: u64, source: VolumeSource, template: Arc<crate::volume::Volume>) {
        self.send_job(Job::HoldFrames {
            id,
            source,
            template,
        });
    }

    /// Queues preparing frame `index` of volume `id` from `input` like `like`.
    pub fn frame(&self, id: u64, index: usize, input: FrameInput, like: Like) {
        self.send_job(Job::Frame {
            id,
            index,
            input,
            like: Box::new(like),
        });
    }

    fn send_job(&self, job: Job) {
        if let Some(jobs) = &self.jobs {
            let _ = jobs.send(job);
        }
    }

    /// Everything reported since the last call (never blocks).
    pub fn poll(&self) -> Vec<Reply> {
        self.replies.try_iter().collect()
    }

    /// Stops the thread: cancels its current job at the next phase boundary, lets it finish
    /// the GPU submission it may be waiting for, and joins it (so its engine, which shares the
    /// device, is gone before the device is).
    pub fn shutdown(&mut self) {
        self.cancel.store(true, Ordering::SeqCst);
        self.jobs = None;
        // Recovered when poisoned (see provide_device): the sender must be dropped for the
        // thread to end.
        *self
            .device
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner()) = None;
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

impl Drop for Loader {
    fn drop(&mut self) {
        self.shutdown();
    }
}

struct Worker {
    engine: Option<Engine>,
    config: EngineConfig,
    device: Receiver<Device>,
    replies: Sender<Reply>,
    cancel: Arc<AtomicBool>,
}

impl Worker {
    fn run(&mut self, jobs: Receiver<Job>) {
        while let Ok(job) = jobs.recv() {
            if self.cancelled() {
                return;
            }
            match job {
                Job::Load {
                    id,
                    source,
                    requested_at,
                    options,
                } => match self.load(id, source, requested_at, &options) {
                    Ok(Some(loaded)) => self.send(Reply::Loaded(Box::new(loaded))),
                    Ok(None) => return,
                    Err(message) => self.send(Reply::LoadFailed { id, message }),
                },
                Job::Derive {
                    id,
                    prepared,
                    outputs,
                } => self.derive(id, &prepared, outputs),
                Job::HoldFrames {
                    id,
                    source,
                    template,
                } => self.hold(id, &source, &template),
                Job::Frame {
                    id,
                    index,
                    input,
                    like,
                } => self.frame(id, index, input, &like),
                Job::Identity { contrast, modality } => {
                    // Kept in the configuration too: an engine made after a device loss
                    // starts from it.
                    self.config.analysis.contrast = contrast;
                    self.config.analysis.modality = modality;
                    let normalize = self.config.normalize;
                    if let Some(engine) = self.engine.as_mut() {
                        engine.set_identity(normalize, contrast, modality);
                    }
                }
            }
        }
    }

    fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::SeqCst)
    }

    fn send(&self, reply: Reply) {
        let _ = self.replies.send(reply);
    }

    /// Makes sure there is an engine, waiting for the device if none was handed over yet;
    /// false when shutting down.
    fn ensure_engine(&mut self) -> Result<bool, String> {
        // A newer device (after a loss) replaces the engine.
        let newest = self.device.try_iter().last();
        let device = match (newest, self.engine.is_some()) {
            (Some(d), _) => Some(d),
            (None, true) => None,
            (None, false) => match self.device.recv() {
                Ok(d) => Some(d),
                Err(_) => return Ok(false),
            },
        };
        if let Some(device) = device {
            self.engine = None;
            let engine = Engine::with_device(device, self.config.clone())
                .map_err(|e| one_line(&e.to_string()))?;
            self.engine = Some(engine);
        }
        Ok(self.engine.is_some())
    }

    fn load(
        &mut self,
        id: u64,
        input: VolumeSource,
        requested_at: Instant,
        options: &OpenOptions,
    ) -> Result<Option<LoadedVolume>, String> {
        self.send(Reply::Progress {
            id,
            stage: if input.path().is_some() {
                "reading and decoding the file"
            } else {
                "generating the phantom"
            },
        });
        let read = source::read(&input, &options.read).map_err(|e| one_line(&e.to_string()))?;
        if self.cancelled() {
            return Ok(None);
        }
        self.send(Reply::Progress {
            id,
            stage: "waiting for the GPU device",
        });
        if !self.ensure_engine()? {
            return Ok(None);
        }
        let Some(engine) = self.engine.as_mut() else {
            return Ok(None);
        };
        if self.cancel.load(Ordering::SeqCst) {
            return Ok(None);
        }
        let _ = self.replies.send(Reply::Progress {
            id,
            stage: "planning; preparing the volume (whole or bricked), histogram, derived volumes",
        });
        let opened = engine
            .open_with(&read.volume, options)
            .map_err(|e| one_line(&e.to_string()))?;
        if self.cancel.load(Ordering::SeqCst) {
            return Ok(None);
        }
        let before = Instant::now();
        // Cached already for a bricked volume (its ranges come from the host preparation).
        engine
            .brick_ranges(&opened.twin.prepared)
            .map_err(|e| one_line(&e.to_string()))?;
        let occupancy_ms = before.elapsed().as_secs_f64() * 1e3;
        let linear = opened.twin.prepared.linear_part;
        let spacing_mm =
            [0, 1, 2].map(|c| (0..3).map(|r| linear[r][c].powi(2)).sum::<f64>().sqrt());
        let mut passes = opened.twin.prepared.gpu_timings.clone();
        passes.push(PassTiming {
            name: "occupancy (brick ranges; host wall time)".into(),
            gpu_ms: occupancy_ms,
        });
        if let Some(derived) = opened.twin.derived() {
            passes.extend(derived.gpu_timings.iter().cloned());
        }
        let brain_outline =
            outline_of(engine, opened.twin.derived()).map_err(|e| one_line(&e.to_string()))?;
        let host = Arc::new(read.volume);
        Ok(Some(LoadedVolume {
            id,
            warnings: host.warnings.clone(),
            label: read.label,
            source: input,
            series: read.series,
            frame: (
                options.read.frame,
                read.header.as_ref().map_or(1, |h| h.frames.max(1)),
            ),
            sha256: read.sha256.unwrap_or_default(),
            spacing_mm,
            twin: opened.twin,
            report: opened.report,
            scene: opened.scene,
            plan: opened.plan,
            passes,
            requested_at,
            brain_outline,
            host,
        }))
    }

    fn hold(&mut self, id: u64, source: &VolumeSource, template: &crate::volume::Volume) {
        let holding = match (self.ensure_engine(), self.engine.as_ref()) {
            (Ok(true), Some(engine)) => {
                super::frames_job::hold_frames(source, template, hold_cap(engine.memory_budget()))
            }
            // Shutting down.
            (Ok(_), _) => return,
            // Always an answer: the viewer waits for one before its next frame change.
            (Err(message), _) => Holding::Streamed(format!("no GPU engine: {message}")),
        };
        self.send(Reply::Frames(FrameReply::Held { id, holding }));
    }

    fn frame(&mut self, id: u64, index: usize, input: FrameInput, like: &Like) {
        let result = match (self.ensure_engine(), self.engine.as_mut()) {
            (Ok(true), Some(engine)) => super::frames_job::prepare_frame(engine, input, like),
            (Ok(_), _) => return,
            (Err(message), _) => Err(message),
        };
        self.send(Reply::Frames(match result {
            Ok(ready) => FrameReply::Ready {
                id,
                index,
                ready: Box::new(ready),
            },
            Err(message) => FrameReply::Failed { id, index, message },
        }));
    }

    fn derive(&mut self, id: u64, prepared: &PreparedVolume, outputs: DerivativeOutputs) {
        let ready = self.ensure_engine();
        let result = match (ready, self.engine.as_mut()) {
            (Ok(true), Some(engine)) => engine.derive(prepared, outputs),
            (Ok(_), _) => return,
            (Err(message), _) => {
                self.send(Reply::DeriveFailed {
                    id,
                    outputs,
                    message,
                    device_lost: false,
                });
                return;
            }
        };
        let result = result.and_then(|derived| {
            let engine = self.engine.as_ref();
            let outline = match engine {
                Some(engine) => outline_of(engine, Some(&derived))?,
                None => None,
            };
            Ok((derived, outline))
        });
        match result {
            Ok((derived, brain_outline)) => self.send(Reply::Derived {
                id,
                outputs,
                derived: Box::new(derived),
                brain_outline,
            }),
            Err(e) => self.send(Reply::DeriveFailed {
                id,
                outputs,
                device_lost: matches!(e, GpuError::DeviceLost(_)),
                message: one_line(&e.to_string()),
            }),
        }
    }
}

/// The host copy of `derived`'s brain mask, read before any frame uses the mask (the
/// readback moves the image through TRANSFER_SRC and back).
fn outline_of(
    engine: &Engine,
    derived: Option<&Derived>,
) -> Result<Option<Arc<BrainOutline>>, GpuError> {
    match derived.and_then(|d| d.brain.as_ref()) {
        Some(mask) => Ok(BrainOutline::read(engine.device(), mask)?.map(Arc::new)),
        None => Ok(None),
    }
}

/// An error message as one line.
pub fn one_line(text: &str) -> String {
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}
