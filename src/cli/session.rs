//! The common start of every GPU command: load the input on a worker thread while the device is
//! created, then upload, min/max, normalize, histogram, and find the tissue peaks.
//!
//! Decision: loading (read + inflate + convert, or phantom generation) and Vulkan start-up are
//! independent, so they overlap; the timings record both, and the wall time shows the overlap.

use super::source::{self, Source};
use crate::analysis::{TissueReport, analyze};
use crate::engine::{Engine, EngineConfig, PreparedVolume};
use crate::error::Error;
use crate::gpu::{DeviceConfig, DeviceSelector, Validation};
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
    /// Phase times.
    pub timings: OpenTimings,
}

/// Engine configuration from the global options.
pub fn engine_config(device: Option<&str>, validation: bool) -> EngineConfig {
    EngineConfig {
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

/// Loads `file` (or the phantom), creates the engine, and analyses the volume on the GPU.
pub fn open(
    file: Option<&Path>,
    frame: usize,
    want_hash: bool,
    config: EngineConfig,
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
    let prepare_start = Instant::now();
    let prepared = engine.prepare(&source.volume)?;
    let prepare_ms = prepare_start.elapsed().as_secs_f64() * 1e3;
    let peaks_start = Instant::now();
    let (imin, imax) = match (prepared.normalization.imin, prepared.normalization.imax) {
        (Some(lo), Some(hi)) => (lo, hi),
        _ => (0.0, 0.0),
    };
    let report = analyze(
        &prepared.histogram,
        imin,
        imax,
        prepared.voxel_count as usize,
        prepared.nonfinite_voxels() as usize,
    );
    let peaks_ms = peaks_start.elapsed().as_secs_f64() * 1e3;
    let timings = OpenTimings {
        load: source.timings.clone(),
        device_ms,
        pipelines_ms: prepared.timings.pipelines_ms,
        prepare_ms,
        peaks_ms,
        wall_ms: start.elapsed().as_secs_f64() * 1e3,
    };
    Ok(Opened {
        source,
        engine,
        prepared,
        report,
        timings,
    })
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
