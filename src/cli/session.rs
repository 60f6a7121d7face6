//! The common start of every GPU command: load the input on a worker thread while the device is
//! created, then upload, min/max, normalize, histogram, and find the tissue peaks.
//!
//! Decision: loading (read + inflate + convert, or phantom generation) and Vulkan start-up are
//! independent, so they overlap; the timings record both, and the wall time shows the overlap.

use super::args::SceneArgs;
use super::render::scene_from_args;
use super::source::{self, Source};
use crate::analysis::{TissueReport, analyze};
use crate::engine::{Engine, EngineConfig, OpenedVolume, Twin};
use crate::error::Error;
use crate::gpu::{DeviceConfig, DeviceSelector, Validation};
use crate::scene::Scene;
use crate::scene::plan::Plan;
use std::path::Path;
use std::time::Instant;

/// Host-side phase times of opening a volume, milliseconds.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct OpenTimings {
    /// Read, inflate, convert (or phantom generation), on the worker thread.
    pub load: source::LoadTimings,
    /// Instance + device creation, on the main thread (overlapping the load).
    pub device_ms: f64,
    /// Pipeline creation for this volume's sample kind.
    pub pipelines_ms: f64,
    /// Plan, upload, min/max, normalize, histogram (or host preparation and brick upload), and
    /// the derived volumes the scene needs; host wall time.
    pub prepare_ms: f64,
    /// Peak finding on the CPU.
    pub peaks_ms: f64,
    /// From the start of `open` until the histogram analysis is done.
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
/// bricked from the host, with its histogram analysis.
pub fn open(
    file: Option<&Path>,
    frame: usize,
    want_hash: bool,
    config: EngineConfig,
    scene_args: Option<&SceneArgs>,
) -> Result<Opened, Error> {
    let start = Instant::now();
    let (loaded, engine, device_ms) = std::thread::scope(|scope| {
        let loader = scope.spawn(move || source::load(file, frame, want_hash));
        let device_start = Instant::now();
        let engine = Engine::new(config);
        let device_ms = device_start.elapsed().as_secs_f64() * 1e3;
        let loaded = loader.join().unwrap_or_else(|_| {
            Err(Error::Usage(
                "the loading thread stopped unexpectedly".into(),
            ))
        });
        (loaded, engine, device_ms)
    });
    // A bad file is the more useful message when both fail.
    let source = loaded?;
    let mut engine = engine?;
    let image = scene_args.and_then(|a| a.size).unwrap_or((1024, 1024));
    let image = [image.0, image.1];
    // Validates the scene arguments once; after this, building the scene cannot fail.
    let default_scene = scene_for(scene_args, &analyze(&[0; 256], 0.0, 1.0, 0, 0))?;
    let make_scene = |report: &TissueReport| {
        scene_for(scene_args, report).unwrap_or_else(|_| {
            let mut scene = default_scene;
            scene.classification =
                crate::scene::Classification::from_tissue_windows(&report.adaptive_windows);
            scene
        })
    };
    let prepare_start = Instant::now();
    let opened = engine.open_volume(&source.volume, image, &make_scene)?;
    let OpenedVolume {
        twin,
        report,
        scene,
        plan,
    } = opened;
    let prepare_ms = prepare_start.elapsed().as_secs_f64() * 1e3;
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
        device_ms,
        pipelines_ms: twin.prepared.timings.pipelines_ms,
        prepare_ms,
        peaks_ms: 0.0,
        wall_ms: start.elapsed().as_secs_f64() * 1e3,
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
