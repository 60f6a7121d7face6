//! The library's one way to open a volume: [`Session::open`] (a new engine) and
//! [`Engine::open_source`] (an engine that exists, as the viewer's loader has). Every client
//! uses them: the CLI's commands, the viewer (first file, Open..., drag-and-drop, a switch of
//! files) and the headless example, so a memory budget, `force_bricking` or a device profile
//! means the same everywhere.
//!
//! Decisions:
//! - The source is read on a worker thread while the device and the engine start; the requested
//!   effects' pipelines need no volume, so with `first_frame` they compile on the engine's
//!   workers meanwhile. The timings record both sides, and the wall time shows the overlap.
//! - The plan is made once, as soon as the volume's size and sample kind are known, from the
//!   recipe's effects (given up front, not learnt from a placeholder scene); the pipelines of
//!   the planned (possibly degraded) effects and of the analysis passes start from it, and the
//!   volume is prepared with that same plan ([`Engine::open_planned`]). Only a bricked volume is
//!   planned again, with its occupancy, when the scene's windows are known.
//! - A 4-D BOLD / ASL series whose preset is `epi` is read again as the mean of its frames
//!   (one frame at a time, `volume::nifti::frame_mean`) when the caller allows it
//!   (`EngineConfig::epi_mean_frame`): the preset's foreground window is meant for the mean
//!   frame, and which preset applies is only known once the file has said what it is.
//! - The library prints nothing: notes (a rejected pipeline cache, the plan's degradations) are
//!   in what it returns, and each client says them its way (stderr, the viewer's status bar).
//! - The pipeline cache is saved by the clients after their first frame (never on the way to
//!   it).

use super::open::{OpenError, OpenTimings, OpenedVolume};
use super::{Engine, EngineConfig, PipelineTimes, Twin};
use crate::analysis::TissueReport;
use crate::engine::plan::{Layout, Plan};
use crate::gpu::{Device, DeviceTimings, GpuError};
use crate::scene::{Preset, RecipeError, Scene, SceneRecipe};
use crate::volume::source::{
    self, InputError, LoadTimings, ReadOptions, SourceVolume, VolumeSource,
};
use std::time::Instant;

/// How to open a volume.
#[derive(Clone, Debug, PartialEq)]
pub struct OpenOptions {
    /// Which frame, and whether to hash the input.
    pub read: ReadOptions,
    /// The image size the scene is planned for, pixels.
    pub image: [u32; 2],
    /// How to build the scene (its effects are what the engine plans for).
    pub recipe: SceneRecipe,
    /// A frame will be rendered: start every pipeline it needs ahead of time. Without it only
    /// the passes that run are created, on first use.
    pub first_frame: bool,
}

impl Default for OpenOptions {
    /// Frame 0, no hash, 1024x1024, the default recipe, pipelines ahead of time.
    fn default() -> Self {
        OpenOptions {
            read: ReadOptions::default(),
            image: [1024, 1024],
            recipe: SceneRecipe::default(),
            first_frame: true,
        }
    }
}

/// Why a volume could not be opened.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// The recipe makes no scene (found before any work).
    #[error(transparent)]
    Recipe(#[from] RecipeError),
    /// The source could not be read.
    #[error(transparent)]
    Input(#[from] InputError),
    /// Vulkan start-up.
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// Planning, preparing or deriving.
    #[error(transparent)]
    Open(#[from] OpenError),
}

/// Host-side phase times of opening a volume, milliseconds.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct SessionTimings {
    /// Read, inflate, convert (or phantom generation), on the worker thread.
    pub load: LoadTimings,
    /// Instance, physical-device choice and device creation, on the calling thread (overlapping
    /// the load).
    pub device_parts: DeviceTimings,
    /// Engine setup after the device: pipeline cache (reading its file), samplers, placeholders.
    pub engine_ms: f64,
    /// Instance + device + engine setup: everything Vulkan needs before the first pass.
    pub device_ms: f64,
    /// How long the calling thread then waited for the loader (0 when loading finished first).
    pub load_wait_ms: f64,
    /// Calling-thread time on pipelines: starting the workers of a session that renders, and
    /// waiting for (or creating) pipelines during the preparation (that part is also inside
    /// `prepare_ms`).
    pub pipelines_ms: f64,
    /// The engine's pipeline times when the volume was ready (workers' compile times, waits).
    pub pipeline_times: PipelineTimes,
    /// Plan, upload, min/max, normalize, histogram (or host preparation and brick upload),
    /// peaks, and the derived volumes the scene needs; host wall time.
    pub prepare_ms: f64,
    /// Peak finding on the CPU (inside `prepare_ms`).
    pub peaks_ms: f64,
    /// The breakdown of `prepare_ms`.
    pub volume: OpenTimings,
    /// From the start of the open until the derived volumes are done.
    pub wall_ms: f64,
}

/// An open volume: what renders it, and what was learnt on the way.
pub struct Session {
    /// The source as read (label, volume, header, hash, read times).
    pub source: SourceVolume,
    /// The engine (device, cached pipelines).
    pub engine: Engine,
    /// Normalized volume with its histogram, and the derived volumes of `scene`.
    pub twin: Twin,
    /// Peaks, Table-1 row, windows.
    pub report: TissueReport,
    /// The recipe's scene with the planned (possibly degraded) effects.
    pub scene: Scene,
    /// The pass plan it was prepared for (layout, degradations).
    pub plan: Plan,
    /// Phase times.
    pub timings: SessionTimings,
}

fn ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

impl Session {
    /// Reads `source` on a worker thread while the device and engine start (with `config`),
    /// then plans, prepares (whole or bricked), analyses, builds the scene and derives (see the
    /// module's decisions). A bad source is the error reported when both sides fail.
    pub fn open(
        source: &VolumeSource,
        config: EngineConfig,
        options: &OpenOptions,
    ) -> Result<Session, SessionError> {
        let start = Instant::now();
        options.recipe.check()?;
        let force_bricking = config.force_bricking;
        let mut pipelines_ms = 0.0;
        let (read, engine, load_wait_ms) = std::thread::scope(|scope| {
            let reader = scope.spawn(|| source::read(source, &options.read));
            let engine = Device::new(&config.device).and_then(|device| {
                let engine_start = Instant::now();
                Engine::with_device(device, config).map(|engine| (engine, ms(engine_start)))
            });
            // The requested effects' pipelines need no volume: they compile while it loads (a
            // plan that later degrades the effects leaves them unused).
            let engine = engine.map(|(mut engine, engine_ms)| {
                if options.first_frame {
                    let before = Instant::now();
                    engine.start_pipelines(&options.recipe.effects, None, force_bricking);
                    pipelines_ms += ms(before);
                }
                (engine, engine_ms)
            });
            let wait_start = Instant::now();
            let read = reader.join().unwrap_or(Err(InputError::ReaderStopped));
            (read, engine, ms(wait_start))
        });
        // A bad file is the more useful message when both fail.
        let read = read?;
        let (mut engine, engine_ms) = engine?;
        let read = engine.epi_mean_frame(source, read, options)?;
        let device_parts = engine.device().creation_timings();
        let prepare_start = Instant::now();
        let opened = engine.open_with(&read.volume, options)?;
        let prepare_ms = ms(prepare_start);
        let volume = opened.timings.clone();
        let timings = SessionTimings {
            load: read.timings.clone(),
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
        Ok(Session {
            source: read,
            engine,
            twin: opened.twin,
            report: opened.report,
            scene: opened.scene,
            plan: opened.plan,
            timings,
        })
    }
}

impl Engine {
    /// Reads `source` and opens it on this engine (no overlap: the device exists already). The
    /// viewer's loader opens every file this way.
    pub fn open_source(
        &mut self,
        source: &VolumeSource,
        options: &OpenOptions,
    ) -> Result<(SourceVolume, OpenedVolume), SessionError> {
        options.recipe.check()?;
        let read = source::read(source, &options.read)?;
        let read = self.epi_mean_frame(source, read, options)?;
        let opened = self.open_with(&read.volume, options)?;
        Ok((read, opened))
    }

    /// `read` again as the mean of its frames when the engine is configured for it
    /// (`EngineConfig::epi_mean_frame`), the file has several frames and the scene's preset
    /// (named, or the automatic choice from what the file says it is) is `epi`; `read`
    /// otherwise. The header's `mean_of_frames` says which it is.
    fn epi_mean_frame(
        &self,
        source: &VolumeSource,
        read: SourceVolume,
        options: &OpenOptions,
    ) -> Result<SourceVolume, SessionError> {
        let frames = read.header.as_ref().map_or(1, |h| h.frames);
        if !self.config.epi_mean_frame || frames < 2 {
            return Ok(read);
        }
        let preset = options
            .recipe
            .preset
            .unwrap_or_else(|| Preset::auto_identified(&self.identify(&read.volume)));
        if preset != Preset::Epi {
            return Ok(read);
        }
        Ok(source::read_mean_of_frames(source, &options.read)?.unwrap_or(read))
    }

    /// Opens a volume already in memory the library's way: plans once for
    /// `options.recipe`'s effects, starts the planned pipelines (with `first_frame`; that time
    /// is in `timings.pipelines_ms`), and prepares, analyses and derives with that plan.
    pub fn open_with(
        &mut self,
        volume: &crate::volume::Volume,
        options: &OpenOptions,
    ) -> Result<OpenedVolume, OpenError> {
        let start = Instant::now();
        let mut input = self.plan_input(volume, options.image, 1.0);
        input.denoise = options.recipe.denoise;
        // The preset's vessel channel is planned too (`SceneRecipe::effects_for`).
        let effects = options.recipe.effects_for(&self.identify(volume));
        let plan =
            crate::engine::plan::plan(effects, &input, &super::DeviceImageSizes(self.device()));
        let plan_ms = ms(start);
        let mut ahead_ms = 0.0;
        if options.first_frame {
            let before = Instant::now();
            // A plan that does not fit is left to `open_planned`, which bricks or reports it.
            if let Ok(plan) = &plan {
                let bricked = matches!(plan.layout, Layout::Bricked { .. });
                self.start_pipelines(&plan.effects, Some(volume.samples.kind()), bricked);
            }
            ahead_ms = ms(before);
        }
        let mut opened = self.open_planned(volume, options.image, &options.recipe, plan)?;
        opened.timings.plan_ms += plan_ms;
        opened.timings.pipelines_ms += ahead_ms;
        opened.timings.wall_ms += plan_ms + ahead_ms;
        Ok(opened)
    }

    /// Plans `effects` again for the volume `twin` holds, as its open did (the scene's needs
    /// changed: an effect that needs other derived volumes). `plan` is the plan it was opened
    /// with (its resident fraction when bricked). A client compares the result with `plan`:
    /// the same layout and format mean the new effects (possibly degraded) fit as they are.
    pub fn replan(
        &self,
        twin: &Twin,
        plan: &Plan,
        effects: crate::scene::Effects,
        image: [u32; 2],
    ) -> Result<Plan, crate::engine::plan::DoesNotFit> {
        let fraction = match plan.layout {
            Layout::Whole => 1.0,
            Layout::Bricked { grid, resident, .. } => {
                f64::from(resident)
                    / (f64::from(grid[0]) * f64::from(grid[1]) * f64::from(grid[2])).max(1.0)
            }
        };
        let prepared = &twin.prepared;
        let mut input = self.plan_input_for(prepared.dims, prepared.kind, image, fraction);
        input.spacing_mm = crate::reference::brain_params::spacing_mm(prepared.linear_part);
        crate::engine::plan::plan(effects, &input, &super::DeviceImageSizes(self.device()))
    }
}
