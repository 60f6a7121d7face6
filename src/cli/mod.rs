//! The command-line layer: argument parsing, commands, output. No Vulkan calls of its own.
//!
//! Decisions: every command returns `Result<(), Error>`; `main` prints an error as exactly one
//! line on stderr (`morphray: ...`) and exits with status 1 (clap's usage errors exit with 2).
//! A panic, which would be a bug, is also reported as one line.

mod accuracy;
mod accuracy_report;
mod accuracy_settings;
pub mod args;
mod batch;
mod bench;
mod clip;
mod convert;
mod derive;
mod devices;
mod glyphs;
mod identity_args;
mod info;
mod kernels;
pub mod layer_args;
mod movie;
pub mod output;
mod overlay;
mod peaks;
mod phantom;
mod plan;
pub mod preset_arg;
mod progress;
pub mod render;
pub mod scene_args;
pub mod scene_file;
pub mod scene_options;
pub mod session;
mod slice;
pub mod source;
mod ttfp;
mod value_args;
#[cfg(feature = "viewer")]
mod view;
mod view_preset;

use crate::error::Error;
use args::{Cli, Command};
use clap::Parser;
use std::process::ExitCode;

/// Runs the command line and returns the process exit status.
pub fn main() -> ExitCode {
    // First: the time-to-first-pixel trials measure from here (and from before the exec).
    ttfp::mark_process_start();
    // Before any thread starts: the environment is changed only while nothing else can read it.
    if let Some(note) = crate::files::cache_dir::guard_mesa_cache() {
        eprintln!("morphray: note: {note}");
    }
    // Before any thread starts, so every thread inherits the blocked signals (files::unfinished).
    crate::files::unfinished::install_interrupt_cleanup();
    std::panic::set_hook(Box::new(|info| {
        // A DICOM file that makes the parser panic is reported as a skipped file.
        if crate::volume::source::dicom::panic_is_contained() {
            return;
        }
        let message = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown".into());
        let place = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        eprintln!("morphray: internal error (a bug, please report it): {message}{place}");
    }));
    if preset_arg::asks_for_list(&std::env::args().collect::<Vec<_>>()) {
        output::print_line(&preset_arg::list_text());
        return ExitCode::SUCCESS;
    }
    let cli = Cli::parse();
    match run(&cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("morphray: {}", one_line(&e.to_string()));
            match &e {
                CommandError::Library(e) => ExitCode::from(e.exit_code()),
                #[cfg(feature = "viewer")]
                CommandError::Viewer(_) => ExitCode::FAILURE,
            }
        }
    }
}

fn one_line(text: &str) -> String {
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// Options every GPU command shares.
#[derive(Clone, Debug, Default)]
pub struct GlobalOptions {
    /// Device index or name fragment.
    pub device: Option<String>,
    /// Validation layer required, errors fail the command.
    pub validation: bool,
    /// Most GPU memory to hold, bytes.
    pub memory_budget: Option<u64>,
    /// Brick even when the volume fits whole.
    pub bricked: bool,
    /// How far one empty-space jump reaches (the distance map's cube by default).
    pub empty_skip: args::EmptySkip,
    /// Device profile to apply.
    pub profile: Option<crate::gpu::DeviceProfile>,
    /// Workgroup and subgroup choices.
    pub tuning: crate::gpu::KernelTuning,
    /// Pipeline cache (the user's cache directory unless `--pipeline-cache` says otherwise).
    pub pipeline_cache: crate::gpu::PipelineCacheConfig,
    /// Which range maps to I_norm 0..1.
    pub normalize: crate::analysis::NormalizeMode,
    /// Which contrast tissues are labelled for (auto-detected unless given).
    pub contrast: crate::analysis::ContrastChoice,
    /// Which modality the volume is (auto-detected unless given).
    pub modality: crate::analysis::ModalityChoice,
}

impl GlobalOptions {
    /// The engine configuration these options describe.
    pub fn engine_config(&self) -> crate::engine::EngineConfig {
        let mut config =
            session::engine_config(self.device.as_deref(), self.validation, self.memory_budget);
        config.force_bricking = self.bricked;
        config.distance_skipping = self.empty_skip == args::EmptySkip::Distance;
        config.device.profile = self.profile.clone();
        config.device.tuning = self.tuning.clone();
        config.pipeline_cache = self.pipeline_cache.clone();
        config.normalize = self.normalize;
        config.analysis.contrast = self.contrast;
        config.analysis.modality = self.modality;
        config
    }
}

/// `--pipeline-cache`: `off`, `memory`, a directory, or (absent) the user's cache directory
/// (in memory when no home or cache directory is known).
fn pipeline_cache_config(option: Option<&str>) -> crate::gpu::PipelineCacheConfig {
    use crate::gpu::PipelineCacheConfig as Config;
    let config = match option.map(str::trim) {
        Some("off") => Config::Off,
        Some("memory") => Config::InMemory,
        Some(dir) => Config::Directory(dir.into()),
        None => crate::gpu::pipeline_cache::default_dir()
            .map(Config::Directory)
            .unwrap_or(Config::InMemory),
    };
    // A folder that cannot take the file (a file in its place, read-only, full): the cache is
    // only a speed-up, so it is kept in memory with one line, not a load note and a save warning.
    if let Config::Directory(dir) = &config
        && let Some(why) = crate::files::cache_dir::unusable(dir)
    {
        eprintln!(
            "morphray: note: the pipeline cache is kept in memory for this run: {why}; pass \
             --pipeline-cache with a writable folder (or off) to choose another"
        );
        return Config::InMemory;
    }
    config
}

/// What a command fails with: the library's errors, or (for `view`) the viewer's. The library's
/// own [`Error`] knows nothing of the viewer, so the engine builds without it.
#[derive(Debug, thiserror::Error)]
pub enum CommandError {
    /// Loading, the GPU, the plan, outputs, arguments.
    #[error(transparent)]
    Library(#[from] Error),
    /// The interactive viewer (window system, script, interface).
    #[cfg(feature = "viewer")]
    #[error(transparent)]
    Viewer(#[from] crate::app::AppError),
}

/// Dispatches a parsed command line.
pub fn run(cli: &Cli) -> Result<(), CommandError> {
    let mut tuning = crate::gpu::KernelTuning {
        subgroup_size: cli.subgroup,
        ..Default::default()
    };
    for wg in &cli.wg {
        tuning
            .add_workgroup(wg)
            .map_err(|e| Error::Usage(format!("--wg: {e}")))?;
    }
    let global = GlobalOptions {
        device: cli.device.clone(),
        validation: cli.validation,
        memory_budget: cli.memory_budget,
        bricked: cli.bricked,
        empty_skip: cli.empty_skip,
        profile: cli
            .profile
            .as_deref()
            .map(crate::gpu::DeviceProfile::load)
            .transpose()
            .map_err(Error::from)?,
        tuning,
        pipeline_cache: pipeline_cache_config(cli.pipeline_cache.as_deref()),
        normalize: cli.normalize.into(),
        contrast: match (&cli.command, cli.contrast.analysis()) {
            // The phantom reads --contrast itself (below); it analyses nothing.
            (Command::Phantom(_), _) => crate::analysis::ContrastChoice::Auto,
            (_, choice) => choice.map_err(Error::Usage)?,
        },
        modality: cli.modality.into(),
    };
    let global = &global;
    if let Some(path) = &cli.trace {
        // Before the work: a trace that cannot be written fails now, not after it.
        use crate::files::write::{OutputKind, check_output};
        check_output(path, OutputKind::Json, &[], false).map_err(Error::from)?;
        crate::files::trace::enable(ttfp::process_start_instant());
    }
    source::set_series(cli.series.clone());
    let result = match &cli.command {
        #[cfg(feature = "viewer")]
        Command::View(args) => view::run(args, global),
        Command::Phantom(args) => {
            phantom::run(args, cli.contrast.phantom()).map_err(CommandError::from)
        }
        other => run_engine_command(other, global).map_err(CommandError::from),
    };
    if let Some(path) = &cli.trace {
        // Written whatever the outcome: a trace of a failing run is as useful.
        let document = output::json(&crate::files::trace::document());
        if let Err(e) = crate::files::write::write_file(path, document.as_bytes()) {
            output::print_warnings(&[format!("the trace was not written: {e}")]);
        }
    }
    result
}

/// Every command but `view`: they fail only with the library's errors.
fn run_engine_command(command: &Command, global: &GlobalOptions) -> Result<(), Error> {
    match command {
        Command::Info(args) => info::run(args, global),
        Command::Peaks(args) => peaks::run(args, global),
        Command::Render(args) => render::run(args, global),
        #[cfg(feature = "viewer")]
        Command::View(_) => Ok(()),
        Command::Bench(args) => bench::run(args, global),
        Command::Accuracy(args) => accuracy::run(args, global),
        Command::Devices => devices::run(),
        Command::Plan(args) => plan::run(args, global),
        Command::Batch(args) => batch::run(args, global),
        Command::Kernels(args) => kernels::run(args, global),
        Command::Convert(args) => convert::run(args),
        Command::Derive(args) => derive::run(args, global),
        Command::Slice(args) => slice::run(args, global),
        // In `run`: it reads the global --contrast.
        Command::Phantom(_) => Ok(()),
    }
}
