//! The common start of every GPU command: maps the arguments onto the library's open path
//! ([`crate::engine::Session::open`]: the read overlapped with device start-up and pipeline
//! compilation, one plan, whole or bricked preparation, analysis, scene, derived volumes) and
//! says on stderr what the library returns as notes.
//!
//! Decisions:
//! - Nothing here opens anything itself: the viewer and integrators get exactly what the
//!   commands get.
//! - The pipeline cache is saved by the commands after their first frame (or at their end when
//!   they render none), never on the way to the first pixel; failing to save it is a warning.

use super::args::SceneArgs;
use super::render::recipe_from_args;
use crate::engine::plan::Plan;
use crate::engine::{EngineConfig, OpenOptions, Session};
use crate::error::Error;
use crate::gpu::{DeviceConfig, DeviceSelector, Validation};
use crate::scene::SceneRecipe;
use crate::volume::source::VolumeSource;
use std::path::PathBuf;

/// A volume on the GPU with its histogram analysis (the library's session).
pub type Opened = Session;

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

/// [`open`] with the frame of a 4-D file given (`Some`) or not: without one, a 4-D file whose
/// preset is `epi` is opened as the mean of its frames (`EngineConfig::epi_mean_frame`), any
/// other as its frame 0.
pub fn open_frame(
    files: &[PathBuf],
    frame: Option<usize>,
    want_hash: bool,
    config: EngineConfig,
    scene_args: Option<&SceneArgs>,
    first_frame: bool,
) -> Result<Opened, Error> {
    let config = EngineConfig {
        epi_mean_frame: frame.is_none(),
        ..config
    };
    open(
        files,
        frame.unwrap_or(0),
        want_hash,
        config,
        scene_args,
        first_frame,
    )
}

/// [`open_frame`] for an analysis only (no hash, the 1024x1024 default size, no frame to
/// render) with `recipe`, whose preset may be named.
pub fn open_recipe(
    files: &[PathBuf],
    frame: Option<usize>,
    config: EngineConfig,
    recipe: SceneRecipe,
) -> Result<Opened, Error> {
    let config = EngineConfig {
        epi_mean_frame: frame.is_none(),
        ..config
    };
    let options = OpenOptions {
        read: super::source::read_options(frame.unwrap_or(0), false),
        image: [1024, 1024],
        recipe,
        first_frame: false,
    };
    let opened = Session::open(&VolumeSource::from_paths(files), config, &options)?;
    note_rejected_cache(&opened.engine);
    note_degradations(&opened.plan);
    Ok(opened)
}

/// Opens `files` (none: the phantom; several: one DICOM input) through the library with the scene `scene_args` describe (the
/// default scene when None), at the image size they give; prints the plan's degradations and a
/// rejected pipeline cache as notes. `first_frame`: a frame will be rendered, so its pipelines
/// are started ahead of time.
pub fn open(
    files: &[PathBuf],
    frame: usize,
    want_hash: bool,
    config: EngineConfig,
    scene_args: Option<&SceneArgs>,
    first_frame: bool,
) -> Result<Opened, Error> {
    let recipe = match scene_args {
        Some(args) => recipe_from_args(args)?,
        None => SceneRecipe::default(),
    };
    let image = scene_args.and_then(|a| a.size).unwrap_or((1024, 1024));
    // Before the volume is read: a matcap that cannot be loaded fails at once.
    let matcap = scene_args
        .map(SceneArgs::matcap_image)
        .transpose()?
        .flatten();
    let how = OpenHow {
        want_hash,
        first_frame,
        image,
        matcap,
    };
    open_recipe_with(files, frame, config, recipe, how)
}

/// How [`open_recipe_with`] opens a volume besides its recipe.
pub struct OpenHow {
    /// Hash the input (for provenance).
    pub want_hash: bool,
    /// A frame will be rendered: its pipelines are started ahead of time.
    pub first_frame: bool,
    /// The picture's size.
    pub image: (u32, u32),
    /// The matcap image, when the lighting needs one.
    pub matcap: Option<crate::scene::matcap::MatcapImage>,
}

/// [`open`] with a recipe made elsewhere (a scene document's), frame `frame` of `files`.
pub fn open_recipe_with(
    files: &[PathBuf],
    frame: usize,
    config: EngineConfig,
    recipe: SceneRecipe,
    how: OpenHow,
) -> Result<Opened, Error> {
    let OpenHow {
        want_hash,
        first_frame,
        image,
        matcap,
    } = how;
    let options = OpenOptions {
        read: super::source::read_options(frame, want_hash),
        image: [image.0, image.1],
        recipe,
        first_frame,
    };
    let mut opened = Session::open(&VolumeSource::from_paths(files), config, &options)?;
    if let Some(matcap) = matcap {
        opened.engine.set_matcap(matcap);
    }
    note_rejected_cache(&opened.engine);
    note_degradations(&opened.plan);
    Ok(opened)
}

/// One note per degradation the memory budget required.
fn note_degradations(plan: &Plan) {
    for degradation in &plan.degradations {
        eprintln!(
            "morphray: note: to fit {} MiB of GPU memory: {} (saves {:.1} MiB; accuracy cost: {})",
            plan.budget / (1 << 20),
            degradation.what,
            degradation.saved_bytes as f64 / (1u64 << 20) as f64,
            degradation.accuracy_cost
        );
    }
}

/// Says on stderr why a pipeline cache file was not used (the run goes on with an empty cache).
fn note_rejected_cache(engine: &crate::engine::Engine) {
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
pub fn persist_pipeline_cache(
    engine: &crate::engine::Engine,
) -> Option<crate::gpu::PersistOutcome> {
    match engine.persist_pipeline_cache() {
        Ok(outcome) => Some(outcome),
        Err(e) => {
            eprintln!("morphray: warning: {e}; the next start compiles its pipelines again",);
            None
        }
    }
}

/// Fails when the validation layer reported errors (used with `--validation`).
pub fn check_validation(engine: &crate::engine::Engine) -> Result<(), Error> {
    let faults = engine.device().internal_faults();
    if let Some(first) = faults.first() {
        return Err(Error::Gpu(crate::gpu::GpuError::Internal(format!(
            "{} internal fault(s) during the run; first: {first}",
            faults.len()
        ))));
    }
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
