//! The participant level of a cohort batch (`morphray batch BIDS_DIR OUT_DIR participant`):
//! every anatomical scan of the shard is opened on one engine, analysed, rendered as three
//! thumbnails and written as BIDS Derivatives ([`super::batch_outputs`]).
//!
//! Decisions:
//! - One engine (one device, one pipeline cache) for all the scans of a process: the device and
//!   the pipelines are started once, so a scan costs its read, inflate, GPU work and encode.
//! - The scans are read and inflated ahead on other cores ([`super::batch_prefetch`]) while the
//!   engine works, so the host's inflate and the engine's work overlap.
//! - A scan that fails (unreadable file, a volume that does not fit) is logged with its error,
//!   recorded in its `desc-error` file and skipped; the batch goes on. A panic inside the engine
//!   is contained the same way, and the engine is then started afresh, since its state is
//!   unknown. The run fails only when nothing can be written or no device can be started.
//! - A scan whose summary is whole and records its input as it is now (size and time), with
//!   whole thumbnails, is finished and skipped, so a rerun (after a crash, a timeout or with
//!   more scans) does only what is left ([`super::batch_guard`]). The summary is written after
//!   the thumbnails.
//! - OUT_DIR is checked before anything is written: the input itself or a folder holding
//!   another dataset's `dataset_description.json` is refused ([`super::batch_guard`]).
//! - The library prints nothing: progress is reported through a callback ([`Progress`]), which
//!   the command turns into a progress bar on a terminal and plain lines otherwise.

use super::batch_guard::{STAMP_KEY, SourceStamp, refuse_output_dir};
use super::batch_outputs::{
    ScanOutputs, VIEWS, append_line, log_path, write_dataset_description, write_json,
};
use super::batch_prefetch;
use super::batch_summary::ScanSummary;
use super::bids::{BidsError, Scan, Shard, discover};
use crate::engine::{Engine, EngineConfig, OpenOptions, RenderTarget};
use crate::files::png::{Provenance, write_rgba8};
use crate::files::write::OutputError;
use crate::gpu::GpuError;
use crate::scene::SceneRecipe;
use crate::volume::source::{ReadOptions, SourceVolume};
use ash::vk;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What the participant level does.
#[derive(Clone, Debug)]
pub struct ParticipantOptions {
    /// The BIDS dataset.
    pub bids: PathBuf,
    /// The derivatives folder.
    pub out: PathBuf,
    /// Subjects to process (all when empty).
    pub participants: Vec<String>,
    /// This process's part of the scan list.
    pub shard: Shard,
    /// Thumbnail width and height, pixels.
    pub thumbnail: u32,
    /// Render thumbnails (off: peaks only).
    pub thumbnails: bool,
    /// Thumbnails of the whole head (`--thumbnails head`: brain extraction off) instead of the
    /// brain; the default shows the brain, so a report meant to be shared shows no faces.
    pub head_thumbnails: bool,
}

/// Why the participant level stopped (a scan's own failure never stops it).
#[derive(Debug, thiserror::Error)]
pub enum BatchError {
    /// The dataset could not be listed.
    #[error(transparent)]
    Bids(#[from] BidsError),
    /// The outputs could not be written.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// No device could be started.
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// The output folder is the input or another dataset (the message says which and the fix).
    #[error("{0}")]
    Refused(String),
}

/// Per-scan host times, milliseconds (the throughput breakdown).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct ScanTimings {
    /// Reading the file.
    pub read_ms: f64,
    /// Inflating gzip.
    pub inflate_ms: f64,
    /// How long the engine waited for this scan's read (0 when it was read ahead in time; the
    /// read, inflate and convert times ran on a reader thread).
    pub wait_ms: f64,
    /// Header checks and sample conversion.
    pub convert_ms: f64,
    /// Plan, upload, normalization, histogram, peaks and derived volumes (GPU work, waited for).
    pub gpu_ms: f64,
    /// The three thumbnails' raymarches and readbacks.
    pub render_ms: f64,
    /// PNG encoding and writing of the thumbnails.
    pub encode_ms: f64,
    /// The whole scan, summary writing included.
    pub total_ms: f64,
}

/// A progress event.
#[derive(Clone, Debug)]
pub enum Progress<'a> {
    /// The scan list is known: `todo` scans to process, `skipped` finished earlier.
    Start {
        /// Scans to process now.
        todo: usize,
        /// Scans of this shard finished by an earlier run.
        skipped: usize,
    },
    /// A scan was processed (`error` is its one-line message when it failed).
    Scan {
        /// The scan.
        scan: &'a Scan,
        /// Its failure, if any.
        error: Option<&'a str>,
        /// Its times.
        timings: &'a ScanTimings,
    },
}

/// What the participant level did.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct ParticipantReport {
    /// Scans of this shard.
    pub scans: usize,
    /// Processed successfully now.
    pub done: usize,
    /// Finished by an earlier run.
    pub skipped: usize,
    /// Failed now (logged and recorded).
    pub failed: usize,
    /// Wall time of the processing, seconds (device start included).
    pub wall_s: f64,
    /// The shard's JSON-lines log.
    pub log: PathBuf,
    /// Things the user may want to know that did not fail a scan (a pipeline cache not saved).
    pub notes: Vec<String>,
}

fn ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

/// The engine and its thumbnail target, shared by every scan of the process.
struct Worker {
    engine: Engine,
    target: Option<RenderTarget>,
}

impl Worker {
    fn new(config: &EngineConfig) -> Result<Worker, GpuError> {
        Ok(Worker {
            engine: Engine::new(config.clone())?,
            target: None,
        })
    }
}

/// The scene of the thumbnails (a still as `render` makes it, `scene::lighting::still_effects`:
/// the brain of a head scan, or with `head` the whole head), or for peaks only a MIP scene: it
/// needs no derived volumes, so no derivative pass runs on a scan that is never rendered.
fn recipe(thumbnails: bool, head: bool) -> SceneRecipe {
    let mut recipe = SceneRecipe::default();
    if thumbnails {
        recipe.effects = crate::scene::lighting::still_effects(recipe.effects);
    } else {
        recipe.effects.mode = crate::scene::RenderMode::Mip;
    }
    if head {
        recipe.effects.brain = crate::passes::brain::BrainSwitch::Off;
    }
    recipe
}

/// Processes one scan; returns its summary JSON and times, or its one-line error.
fn process(
    worker: &mut Worker,
    scan: &Scan,
    read: Result<SourceVolume, String>,
    outputs: &ScanOutputs,
    options: &ParticipantOptions,
    stamp: Option<SourceStamp>,
) -> Result<(serde_json::Value, ScanTimings), String> {
    let start = Instant::now();
    let read = read?;
    let size = options.thumbnail;
    let open = OpenOptions {
        read: ReadOptions::default(),
        image: [size, size],
        recipe: recipe(options.thumbnails, options.head_thumbnails),
        first_frame: options.thumbnails,
    };
    let before_gpu = Instant::now();
    let mut opened = worker
        .engine
        .open_with(&read.volume, &open)
        .map_err(|e| e.to_string())?;
    let load = read.timings.clone();
    let mut timings = ScanTimings {
        read_ms: load.read_ms,
        inflate_ms: load.inflate_ms,
        convert_ms: load.convert_ms,
        gpu_ms: ms(before_gpu),
        ..ScanTimings::default()
    };
    std::fs::create_dir_all(&outputs.dir)
        .map_err(|e| OutputError::io(&outputs.dir, e).to_string())?;
    let mut thumbnails = Vec::new();
    // Pixels off the background of each thumbnail (the blank-picture flag).
    let mut lit = Vec::new();
    if options.thumbnails {
        if worker.target.is_none() {
            let target = worker
                .engine
                .render_target(size, size, vk::Format::R8G8B8A8_UNORM)
                .map_err(|e| e.to_string())?;
            worker.target = Some(target);
        }
        for ((view, azimuth, elevation), path) in VIEWS.iter().zip(&outputs.thumbnails) {
            let mut scene = opened.scene;
            scene.camera.azimuth_deg = *azimuth;
            scene.camera.elevation_deg = *elevation;
            let before = Instant::now();
            let Some(target) = worker.target.as_mut() else {
                return Err("the thumbnail target was not created".into());
            };
            let frame = worker
                .engine
                .render_twin(target, &mut opened.twin, &scene)
                .map_err(|e| e.to_string())?;
            timings.render_ms += ms(before);
            lit.push(crate::scene::visibility::pixels_off_background(
                &frame.rgba8,
                scene.background,
            ));
            let before = Instant::now();
            let provenance = Provenance {
                scene: None,
                input: scan.relative.clone(),
                input_sha256: String::new(),
                command: format!("morphray batch participant ({view} thumbnail)"),
                parameters: serde_json::json!({ "scene": scene }).to_string(),
                warnings: read.volume.warnings.clone(),
            };
            write_rgba8(path, frame.width, frame.height, &frame.rgba8, &provenance)
                .map_err(|e| e.to_string())?;
            timings.encode_ms += ms(before);
            thumbnails.push(path.file_name().map(|n| n.to_string_lossy().into_owned()));
        }
    }
    let summary = ScanSummary::new(
        &scan.relative,
        opened.twin.prepared.dims,
        &opened.report,
        &read.volume.warnings,
    );
    timings.total_ms = ms(start);
    let brain = opened
        .twin
        .derived()
        .and_then(|d| d.brain.as_ref())
        .map(|b| b.report.decision);
    let qc = super::batch_qc::flags(&opened.report, brain, &lit);
    let mut value = serde_json::to_value(&summary).map_err(|e| e.to_string())?;
    if let Some(map) = value.as_object_mut() {
        map.insert("qc".into(), serde_json::json!(qc));
        map.insert("brain".into(), serde_json::json!(brain));
        map.insert("subject".into(), scan.subject.clone().into());
        map.insert("session".into(), scan.session.clone().into());
        map.insert("suffix".into(), scan.suffix.clone().into());
        map.insert("thumbnails".into(), serde_json::json!(thumbnails));
        map.insert("layout".into(), serde_json::json!(opened.plan.layout));
        map.insert(
            "device".into(),
            worker.engine.device().adapter().name.clone().into(),
        );
        map.insert("timings_ms".into(), serde_json::json!(timings));
        // Taken before the read: an input replaced while it was read is redone next time.
        map.insert(STAMP_KEY.into(), serde_json::json!(stamp));
    }
    Ok((value, timings))
}

/// [`process`] with a panic contained (module doc); `None` from a panic.
fn process_contained(
    worker: &mut Worker,
    scan: &Scan,
    read: Result<SourceVolume, String>,
    outputs: &ScanOutputs,
    options: &ParticipantOptions,
    stamp: Option<SourceStamp>,
) -> Option<Result<(serde_json::Value, ScanTimings), String>> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        process(worker, scan, read, outputs, options, stamp)
    }))
    .ok()
}

/// Records a processed scan: its summary (done marker) or its error file, and the log line.
fn record(
    scan: &Scan,
    outputs: &ScanOutputs,
    log: &Path,
    result: &Result<(serde_json::Value, ScanTimings), String>,
) -> Result<(), OutputError> {
    match result {
        Ok((summary, _)) => {
            write_json(&outputs.summary, summary)?;
            if outputs.error.exists() {
                std::fs::remove_file(&outputs.error)
                    .map_err(|e| OutputError::io(&outputs.error, e))?;
            }
            let mut line = serde_json::json!({ "status": "ok", "scan": scan.relative });
            if let (Some(map), Some(s)) = (line.as_object_mut(), summary.as_object()) {
                for key in ["table1", "timings_ms"] {
                    if let Some(v) = s.get(key) {
                        map.insert(key.into(), v.clone());
                    }
                }
            }
            append_line(log, &line)
        }
        Err(message) => {
            let error = serde_json::json!({
                "status": "error",
                "scan": scan.relative,
                "subject": scan.subject,
                "session": scan.session,
                "error": message,
            });
            write_json(&outputs.error, &error)?;
            append_line(log, &error)
        }
    }
}

/// Runs the participant level (module doc). `config` makes the process's one engine.
pub fn run_participant(
    options: &ParticipantOptions,
    config: &EngineConfig,
    progress: &mut dyn FnMut(Progress<'_>),
) -> Result<ParticipantReport, BatchError> {
    let start = Instant::now();
    let scans: Vec<Scan> = discover(&options.bids, &options.participants)?
        .into_iter()
        .enumerate()
        .filter(|(i, _)| options.shard.takes(*i))
        .map(|(_, s)| s)
        .collect();
    refuse_output_dir(&options.bids, &options.out).map_err(BatchError::Refused)?;
    std::fs::create_dir_all(&options.out).map_err(|e| OutputError::io(&options.out, e))?;
    write_dataset_description(&options.out, &options.bids)?;
    let log = log_path(&options.out, options.shard);
    let todo: Vec<(&Scan, ScanOutputs, Option<SourceStamp>)> = scans
        .iter()
        .map(|s| (s, ScanOutputs::of(&options.out, s)))
        .filter(|(s, o)| !o.finished(&s.path, options.thumbnails))
        .map(|(s, o)| (s, o, SourceStamp::of(&s.path)))
        .collect();
    let mut report = ParticipantReport {
        scans: scans.len(),
        skipped: scans.len() - todo.len(),
        log: log.clone(),
        ..ParticipantReport::default()
    };
    progress(Progress::Start {
        todo: todo.len(),
        skipped: report.skipped,
    });
    let paths = todo.iter().map(|(s, _, _)| s.path.clone()).collect();
    std::thread::scope(|scope| {
        let reads = batch_prefetch::start(scope, paths, batch_prefetch::reader_count());
        process_all(&todo, &reads, options, config, &log, &mut report, progress)
    })?;
    report.wall_s = start.elapsed().as_secs_f64();
    Ok(report)
}

/// Processes the scans to do in order, each from its read-ahead.
fn process_all(
    todo: &[(&Scan, ScanOutputs, Option<SourceStamp>)],
    reads: &[std::sync::mpsc::Receiver<batch_prefetch::Prefetched>],
    options: &ParticipantOptions,
    config: &EngineConfig,
    log: &Path,
    report: &mut ParticipantReport,
    progress: &mut dyn FnMut(Progress<'_>),
) -> Result<(), BatchError> {
    let mut worker = None;
    for (index, (scan, outputs, stamp)) in todo.iter().enumerate() {
        if worker.is_none() {
            worker = Some(Worker::new(config)?);
        }
        let Some(w) = worker.as_mut() else { continue };
        let before_wait = Instant::now();
        let prefetched = batch_prefetch::next(reads, index);
        let wait_ms = prefetched
            .ready_at
            .saturating_duration_since(before_wait)
            .as_secs_f64()
            * 1e3;
        let result = process_contained(w, scan, prefetched.read, outputs, options, *stamp);
        let result = result.map(|r| {
            r.map(|(mut summary, mut timings)| {
                timings.wait_ms = wait_ms;
                if let Some(t) = summary.get_mut("timings_ms") {
                    *t = serde_json::json!(timings);
                }
                (summary, timings)
            })
        });
        let result = result.unwrap_or_else(|| {
            // The engine's state after a panic is unknown: the next scan starts a new one.
            worker = None;
            Err(
                "internal error (a panic in the engine) while processing this scan; \
                 please report it with the file"
                    .into(),
            )
        });
        record(scan, outputs, log, &result)?;
        let timings = result.as_ref().map(|(_, t)| *t).unwrap_or_default();
        match &result {
            Ok(_) => report.done += 1,
            Err(_) => report.failed += 1,
        }
        if report.done == 1 && result.is_ok() {
            // The pipelines are all compiled now: the next process (shard, rerun) starts warm.
            // Failing to save the cache costs the next start time only, so it is a note.
            if let Some(Err(e)) = worker.as_ref().map(|w| w.engine.persist_pipeline_cache()) {
                report
                    .notes
                    .push(format!("{e}; the next start compiles its pipelines again"));
            }
        }
        progress(Progress::Scan {
            scan,
            error: result.as_ref().err().map(String::as_str),
            timings: &timings,
        });
    }
    Ok(())
}
