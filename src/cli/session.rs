//! The common start of every GPU command: load the input on a worker thread while the device is
//! created, then upload, min/max, normalize, histogram, and find the tissue peaks.
//!
//! Decisions:
//! - Loading (read + inflate + convert, or phantom generation) and Vulkan start-up are
//!   independent, so they overlap; the timings record both, and the wall time shows the overlap.
//! - A command that renders creates every pipeline of its plan before the upload, so the compiles
//!   are one timed phase instead of being spread over the passes.
//! - The pipeline cache is saved by the commands after their first frame (or at their end when
//!   they render none), never on the way to the first pixel; failing to save it is a warning.

use super::args::SceneArgs;
use super::render::scene_from_args;
use super::source::{self, Source};
use crate::analysis::{TissueReport, analyze};
use crate::engine::{Engine, EngineConfig, OpenTimings as VolumeTimings, OpenedVolume, Twin};
use crate::error::Error;
use crate::gpu::{Device, DeviceConfig, DeviceSelector, DeviceTimings, Validation};
use crate::scene::Scene;
use crate::scene::plan::Plan;
use std::path::Path;
use std::time::Instant;

/// Host-side phase times of opening a volume, milliseconds.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct OpenTimings {
    /// Read, inflate, convert (or phantom generation), on the worker thread.
    pub load: source::LoadTimings,
    /// Instance, physical-device choice and device creation, on the main thread (overlapping
    /// the load).
    pub device_parts: DeviceTimings,
    /// Engine setup after the device: pipeline cache (reading its file), samplers, placeholders.
    pub engine_ms: f64,
    /// Instance + device + engine setup: everything Vulkan needs before the first pass.
    pub device_ms: f64,
    /// How long the main thread then waited for the loader (0 when loading finished first).
    pub load_wait_ms: f64,
    /// Main-thread time on pipelines: starting the workers of a command that renders, and
    /// waiting for (or creating) pipelines during the preparation (that part is also inside
    /// `prepare_ms`).
    pub pipelines_ms: f64,
    /// The engine's pipeline times when the volume was ready (workers' compile times, waits).
    pub pipeline_times: crate::engine::PipelineTimes,
    /// Plan, upload, min/max, normalize, histogram (or host preparation and brick upload),
    /// peaks, and the derived volumes the scene needs; host wall time.
    pub prepare_ms: f64,
    /// Peak finding on the CPU (inside `prepare_ms`).
    pub peaks_ms: f64,
    /// The breakdown of `prepare_ms`.
    pub volume: VolumeTimings,
    /// From the start of `open` until the derived volumes are done.
    pub wall_ms: f64,
}

/// A volume on the GPU with its histogram analysis.
pub struct Opened {
    /// The input.
    pub source: Source,
    /// The engine (device, cached pipelines).
    pub engine: Engine,
    /// Normalized volume with its histogram, and the derived volumes of `scene`.
    pub twin: Twin,
    /// Peaks, Table-1 row, windows.
    pub report: TissueReport,
    /// The scene the arguments describe, with the planned (possibly degraded) effects.
    pub scene: Scene,
    /// The pass plan it was prepared for.
    pub plan: Plan,
    /// Phase times.
    pub timings: OpenTimings,
}

/// Engine configuration from the global options.
pub fn engine_config(
    device: Option<&str>,
    validation: bool,
    memory_budget: Option<u64>,
) -> EngineConfig {
    EngineConfig {
        memory_budget,
        device: DeviceConfig {
            selector: device.map(DeviceSelector::parse).unwrap_or_default(),
            validation: if validation {
                Validation::Required
            } else {
                Validation::from_build_and_env()
            },
            ..DeviceConfig::default()
        },
        ..EngineConfig::default()
    }
}

/// Loads `file` (or the phantom), creates the engine, plans the scene `scene_args` describes (the
/// default scene when None) within the memory budget, and prepares the volume whole on the GPU or
/// bricked from the host, with its histogram analysis. With `first_frame`, every pipeline the
/// first frame needs is started on worker threads as soon as the device exists (those of the
/// requested effects while the file still loads, the analysis passes once its sample kind is
/// known), and waited for where first used; without it (no frame will be rendered) only the
/// passes that run are created, on first use.
pub fn open(
    file: Option<&Path>,
    frame: usize,
    want_hash: bool,
    config: EngineConfig,
    scene_args: Option<&SceneArgs>,
    first_frame: bool,
) -> Result<Opened, Error> {
    let start = Instant::now();
    let ms = |since: Instant| since.elapsed().as_secs_f64() * 1e3;
    // Validates the scene arguments once; after this, building the scene cannot fail.
    let default_scene = scene_for(scene_args, &analyze(&[0; 256], 0.0, 1.0, 0, 0))?;
    let force_bricking = config.force_bricking;
    let mut pipelines_ms = 0.0;
    let (loaded, engine, engine_ms, load_wait_ms) = std::thread::scope(|scope| {
        let loader = scope.spawn(move || source::load(file, frame, want_hash));
        // Device timings are kept by the device; the engine's own setup is timed here.
        let engine = Device::new(&config.device).and_then(|device| {
            let engine_start = Instant::now();
            Engine::with_device(device, config).map(|engine| (engine, ms(engine_start)))
        });
        // The requested effects' pipelines need no volume: they compile while it loads (a
        // memory plan that later degrades the effects leaves them unused).
        let engine = engine.map(|(mut engine, engine_ms)| {
            if first_frame {
                let before = Instant::now();
                engine.start_pipelines(&default_scene.effects, None, force_bricking);
                pipelines_ms += ms(before);
            }
            (engine, engine_ms)
        });
        let wait_start = Instant::now();
        let loaded = loader.join().unwrap_or_else(|_| {
            Err(Error::Usage(
                "the loading thread stopped unexpectedly".into(),
            ))
        });
        let (engine, engine_ms) = match engine {
            Ok((engine, engine_ms)) => (Ok(engine), engine_ms),
            Err(e) => (Err(e), 0.0),
        };
        (loaded, engine, engine_ms, ms(wait_start))
    });
    // A bad file is the more useful message when both fail.
    let source = loaded?;
    let mut engine = engine?;
    note_rejected_cache(&engine);
    let device_parts = engine.device().creation_timings();
    let image = scene_args.and_then(|a| a.size).unwrap_or((1024, 1024));
    let image = [image.0, image.1];
    let make_scene = |report: &TissueReport| {
        scene_for(scene_args, report).unwrap_or_else(|_| {
            let mut scene = default_scene;
            scene.classification =
                crate::scene::Classification::from_tissue_windows(&report.adaptive_windows);
            scene
        })
    };
    if first_frame {
        let before = Instant::now();
        // The plan `open_volume` makes first (it plans again: the same inputs give the same
        // plan), with the sample kind now known. A plan that does not fit is left to
        // `open_volume`, which bricks or reports it.
        if let Ok(plan) = engine.plan(default_scene.effects, &source.volume, image, 1.0) {
            let bricked = matches!(plan.layout, crate::scene::plan::Layout::Bricked { .. });
            engine.start_pipelines(&plan.effects, Some(source.volume.samples.kind()), bricked);
        }
        pipelines_ms += ms(before);
    }
    let prepare_start = Instant::now();
    let opened = engine.open_volume(&source.volume, image, &make_scene)?;
    let OpenedVolume {
        twin,
        report,
        scene,
        plan,
        timings: volume,
    } = opened;
    let prepare_ms = ms(prepare_start);
    for degradation in &plan.degradations {
        eprintln!(
            "morphray: note: to fit {} MiB of GPU memory: {} (saves {:.1} MiB; accuracy cost: {})",
            plan.budget / (1 << 20),
            degradation.what,
            degradation.saved_bytes as f64 / (1u64 << 20) as f64,
            degradation.accuracy_cost
        );
    }
    let timings = OpenTimings {
        load: source.timings.clone(),
        device_parts,
        engine_ms,
        device_ms: device_parts.instance_ms
            + device_parts.adapter_ms
            + device_parts.device_ms
            + engine_ms,
        load_wait_ms,
        pipelines_ms: pipelines_ms + volume.pipelines_ms,
        pipeline_times: engine.pipeline_times(),
        prepare_ms,
        peaks_ms: volume.peaks_ms,
        volume,
        wall_ms: ms(start),
    };
    Ok(Opened {
        source,
        engine,
        twin,
        report,
        scene,
        plan,
        timings,
    })
}

/// Says on stderr why a pipeline cache file was not used (the run goes on with an empty cache).
fn note_rejected_cache(engine: &Engine) {
    let load = engine.pipeline_cache().load();
    if let (Some(reason), Some(path)) = (&load.rejected, &load.path) {
        eprintln!(
            "morphray: note: pipeline cache {} not used: {reason}; pipelines are compiled afresh",
            path.display()
        );
    }
}

/// Saves the pipeline cache if it is kept in a directory and changed; a failure is a warning on
/// stderr (the command's own work succeeded). Returns what happened, for reports.
pub fn persist_pipeline_cache(engine: &Engine) -> Option<crate::gpu::PersistOutcome> {
    match engine.persist_pipeline_cache() {
        Ok(outcome) => Some(outcome),
        Err(e) => {
            eprintln!("morphray: warning: {e}; the next start compiles its pipelines again",);
            None
        }
    }
}

/// The scene the arguments describe around a histogram analysis (the defaults without
/// arguments).
fn scene_for(args: Option<&SceneArgs>, report: &TissueReport) -> Result<Scene, Error> {
    match args {
        Some(a) => scene_from_args(a, report),
        None => Ok(Scene::new(
            crate::scene::Classification::from_tissue_windows(&report.adaptive_windows),
        )),
    }
}

/// Fails when the validation layer reported errors (used with `--validation`).
pub fn check_validation(engine: &Engine) -> Result<(), Error> {
    let errors = engine.device().validation_log().errors();
    if errors.is_empty() {
        return Ok(());
    }
    Err(Error::Usage(format!(
        "the Vulkan validation layer reported {} error(s); first: {}",
        errors.len(),
        errors[0].lines().next().unwrap_or("")
    )))
}
