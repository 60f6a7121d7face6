//! The common start of every GPU command: load the input on a worker thread while the device is
//! created, then upload, min/max, normalize, histogram, and find the tissue peaks.
//!
//! Decision: loading (read + inflate + convert, or phantom generation) and Vulkan start-up are
//! independent, so they overlap; the timings record both, and the wall time shows the overlap.

use super::args::SceneArgs;
use super::render::scene_from_args;
use super::source::{self, Source};
use crate::analysis::{TissueReport, analyze};
use crate::engine::{Engine, EngineConfig, HostPrepared, PreparedVolume};
use crate::error::Error;
use crate::gpu::{DeviceConfig, DeviceSelector, Validation};
use crate::scene::Scene;
use crate::scene::plan::{Layout, Plan, STORAGE_BRICK, STORAGE_HALO, plan};
use ash::vk;
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
    /// Upload, min/max, normalize and histogram, host wall time.
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
    /// Normalized volume and histogram.
    pub prepared: PreparedVolume,
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
    let effects = effects_from_args(scene_args)?;
    let volume = &source.volume;
    let prepare_start = Instant::now();
    let first = plan(effects, &engine.plan_input(volume, image, 1.0));
    let whole = matches!(
        first,
        Ok(Plan {
            layout: Layout::Whole,
            ..
        })
    );
    let (prepared, report, scene, plan) = if let (true, Ok(plan)) = (whole, first.clone()) {
        let format = if plan.normalized_format == "R8_UNORM" {
            vk::Format::R8_UNORM
        } else {
            vk::Format::R16_UNORM
        };
        engine.set_normalized_format(format)?;
        let prepared = engine.prepare(volume)?;
        let report = report_of(&prepared.histogram, &prepared, prepared.nonfinite_voxels());
        let scene = scene_for(scene_args, &report, plan.effects)?;
        (prepared, report, scene, plan)
    } else {
        // Bricked: the histogram and windows come from the host; residency then follows what the
        // scene's tissues can see, and the plan is made again with that occupancy.
        let host = engine.prepare_on_host(volume, vk::Format::R16_UNORM)?;
        let report = report_of_host(&host);
        let scene = scene_for(scene_args, &report, effects)?;
        let fraction = host
            .brick_ranges(STORAGE_BRICK, STORAGE_HALO)
            .occupied_fraction(&scene.classification);
        let plan = plan(effects, &engine.plan_input(volume, image, fraction))?;
        let host = if plan.normalized_format == "R8_UNORM" {
            engine.prepare_on_host(volume, vk::Format::R8_UNORM)?
        } else {
            host
        };
        let mut scene = scene;
        scene.effects = plan.effects;
        let prepared = engine.upload_bricked(&host, &scene.classification)?;
        (prepared, report, scene, plan)
    };
    let prepare_ms = prepare_start.elapsed().as_secs_f64() * 1e3;
    for degradation in &plan.degradations {
        eprintln!(
            "morphray: note: to fit {} MiB of GPU memory: {} (saves {:.1} MiB; accuracy setting \"{}\")",
            plan.budget / (1 << 20),
            degradation.what,
            degradation.saved_bytes as f64 / (1u64 << 20) as f64,
            degradation.accuracy_setting
        );
    }
    let timings = OpenTimings {
        load: source.timings.clone(),
        device_ms,
        pipelines_ms: prepared.timings.pipelines_ms,
        prepare_ms,
        peaks_ms: 0.0,
        wall_ms: start.elapsed().as_secs_f64() * 1e3,
    };
    Ok(Opened {
        source,
        engine,
        prepared,
        report,
        scene,
        plan,
        timings,
    })
}

/// The effects the arguments ask for (the defaults without arguments).
fn effects_from_args(args: Option<&SceneArgs>) -> Result<crate::scene::Effects, Error> {
    let report = crate::analysis::analyze(&[0; 256], 0.0, 1.0, 0, 0);
    Ok(match args {
        Some(a) => scene_from_args(a, &report)?.effects,
        None => crate::scene::Effects::default(),
    })
}

/// The scene for the arguments around a histogram analysis, with the planned effects.
fn scene_for(
    args: Option<&SceneArgs>,
    report: &TissueReport,
    effects: crate::scene::Effects,
) -> Result<Scene, Error> {
    let mut scene = match args {
        Some(a) => scene_from_args(a, report)?,
        None => Scene::new(crate::scene::Classification::from_tissue_windows(
            &report.adaptive_windows,
        )),
    };
    scene.effects = effects;
    Ok(scene)
}

fn report_of(histogram: &[u32; 256], prepared: &PreparedVolume, nonfinite: u64) -> TissueReport {
    let (imin, imax) = match (prepared.normalization.imin, prepared.normalization.imax) {
        (Some(lo), Some(hi)) => (lo, hi),
        _ => (0.0, 0.0),
    };
    analyze(
        histogram,
        imin,
        imax,
        prepared.voxel_count as usize,
        nonfinite as usize,
    )
}

fn report_of_host(host: &HostPrepared) -> TissueReport {
    let (imin, imax) = match (host.normalization.imin, host.normalization.imax) {
        (Some(lo), Some(hi)) => (lo, hi),
        _ => (0.0, 0.0),
    };
    analyze(
        &host.histogram,
        imin,
        imax,
        host.voxel_count as usize,
        (host.voxel_count - host.finite_voxels) as usize,
    )
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
