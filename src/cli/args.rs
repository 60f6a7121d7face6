//! Command-line arguments (clap), with help text that explains each option.
//!
//! Decision: every scene option of `render` lives in [`SceneArgs`], flattened into each command
//! that renders or plans, so `render`, `view`, `bench` and `plan` accept the same spelling.

use clap::{Args, Parser, Subcommand};
use std::path::PathBuf;

pub use super::scene_args::{
    ClassificationArg, GradientArg, ModeArg, PrecisionArg, ProjectionArg, SceneArgs, Switch,
    WindowsArg,
};

/// morphray: GPU volume rendering of MRI scans (NIfTI) on Vulkan.
#[derive(Debug, Parser)]
#[command(name = "morphray", version, about, long_about = None, propagate_version = true)]
pub struct Cli {
    /// Vulkan device to use: an index from the device list, or part of its name (case-insensitive).
    ///
    /// Default: the best suitable device (or $MORPHRAY_DEVICE).
    #[arg(
        long,
        global = true,
        help_heading = "Device and profiling",
        value_name = "INDEX|NAME"
    )]
    pub device: Option<String>,

    /// Load the Khronos validation layer (core + synchronization) and fail on any error it reports.
    ///
    /// Slow; for debugging and tests.
    #[arg(
        long,
        global = true,
        help_heading = "Device and profiling",
        hide_short_help = true
    )]
    pub validation: bool,

    /// Most GPU memory morphray may hold, in bytes (suffixes K, M, G and decimals allowed: 512M,
    /// 1.5G).
    ///
    /// Over it, the plan degrades, cheapest accuracy first (8-bit derived volumes, R8 intensities,
    /// bricking, then gradients on the fly; `morphray plan` shows which and what each costs) or the
    /// command stops with a message naming what did not fit. Default: what the device reports
    /// available (VK_EXT_memory_budget, or the heap size).
    #[arg(long, global = true, help_heading = "Device and profiling", hide_short_help = true, value_name = "BYTES", value_parser = crate::gpu::profile::parse_bytes)]
    pub memory_budget: Option<u64>,

    /// Brick the volume even when it fits whole (32^3 bricks with a 3-voxel halo, read through a
    /// brick table), to measure what bricking costs.
    ///
    /// Bricking is otherwise automatic: over the budget, or over the device's 3D image limit.
    #[arg(
        long,
        global = true,
        help_heading = "Device and profiling",
        hide_short_help = true
    )]
    pub bricked: bool,

    /// How far empty-space skipping jumps: across the whole cube of empty 8^3 bricks around a
    /// sample, from a Chebyshev distance map rebuilt on the GPU when the classification changes
    /// (`distance`), or one brick at a time from the occupancy bits alone (`bricks`, to measure
    /// what the map saves). The picture is the same either way.
    #[arg(
        long,
        global = true,
        help_heading = "Device and profiling",
        hide_short_help = true,
        value_enum,
        default_value = "distance"
    )]
    pub empty_skip: EmptySkip,

    /// Run under a device profile: `gen12` (Intel Xe-LP: 2048-texel 3D images, unified memory
    /// without staging, a 12 GiB budget from 16 GiB of RAM, subgroup sizes 8/16/32, no float
    /// atomics, 36-bit timestamps) or the path of a .toml profile with the same keys.
    ///
    /// A profile only clamps what the real device offers, so the constrained paths really run.
    #[arg(
        long,
        global = true,
        help_heading = "Device and profiling",
        hide_short_help = true,
        value_name = "gen12|FILE.toml"
    )]
    pub profile: Option<String>,

    /// Workgroup size of the tunable kernels, for profiling: `8x8` for all of them (z = 1), or
    /// `raymarch=16x8`, `normalize=8x8x4`, `derivatives=8x8x2` for one (repeatable; later wins).
    ///
    /// The WGSL reductions (minmax, histogram) keep their 256 invocations.
    #[arg(
        long,
        global = true,
        help_heading = "Device and profiling",
        hide_short_help = true,
        value_name = "[PASS=]XxY[xZ]"
    )]
    pub wg: Vec<String>,

    /// Pin the subgroup size of every kernel (requiredSubgroupSize), for profiling SIMD8/16/32 on
    /// devices with subgroup size control; an unsupported size is an error naming the range.
    #[arg(
        long,
        global = true,
        help_heading = "Device and profiling",
        hide_short_help = true,
        value_name = "N"
    )]
    pub subgroup: Option<u32>,

    /// Where compiled GPU pipelines are kept between runs, so later starts skip the driver's shader
    /// compiler: a directory, `memory` (this run only) or `off` (no pipeline cache).
    ///
    /// Default: $MORPHRAY_CACHE_DIR, else $XDG_CACHE_HOME/morphray, else ~/.cache/morphray. One
    /// file per GPU and driver (pipelines-VENDOR-DEVICE-DRIVER-UUID.bin); a damaged file, or one
    /// from another GPU or driver, is ignored with a note and replaced. The file is written after
    /// the first frame, only when it changed; failing to write it is a warning, not an error.
    #[arg(
        long,
        global = true,
        help_heading = "Device and profiling",
        hide_short_help = true,
        value_name = "DIR|memory|off"
    )]
    pub pipeline_cache: Option<String>,

    /// Which intensity range becomes I_norm 0..1 (the scale of the tissue windows)
    ///
    /// `robust` = from percentiles of the finite voxels, so a few hot voxels (fat, vessels,
    /// spikes) cannot squeeze every tissue into the darkest bins; values outside are clamped.
    ///
    /// `minmax` = the paper's eq. 1, the finite minimum and maximum (paper-literal preset;
    /// `morphray peaks` reports both).
    #[arg(long, global = true, help_heading = "Input", value_enum, default_value_t = NormalizeArg::Robust)]
    pub normalize: NormalizeArg,

    /// Which MR contrast the tissues are labelled for.
    ///
    /// T1 = CSF < GM < WM, T2 and PD = WM < GM < CSF (PD with less contrast), FLAIR = CSF
    /// (suppressed) < WM < GM.
    ///
    /// `auto` = from what the file says first: a BIDS suffix (`_T1w`, `_T2w`, `_PDw`, `_FLAIR`,
    /// `_angio`, ...) or its JSON sidecar, DICOM's SeriesDescription / ProtocolName words (T1,
    /// MPRAGE, T2, TSE, FLAIR, PD, TOF, ...), the timing (TR, TE, TI), the NIfTI `descrip`, the
    /// file name's words; only when all are silent from the histogram (T2 when the largest tissue
    /// mode is dark and sharp and a broad mode is more than twice as bright; T1 when the tissue
    /// bulk is at the bright end; T1 assumed when it cannot tell). `info` and `peaks` say what
    /// was decided and from what. `t1` / `t2` / `pd` / `flair` = take it as given. A CT is
    /// labelled in density order (see --modality). `--windows paper` uses T1 windows.
    /// For `phantom`, the contrast to make (t1, t2, pd, flair or ct; auto makes t1).
    #[arg(long, global = true, help_heading = "Input", value_enum, default_value_t = ContrastArg::Auto)]
    pub contrast: ContrastArg,

    /// What the scan is (`pt` = PET).
    ///
    /// `auto` = from DICOM's Modality tag or the sidecar's, the BIDS suffix (`_ct`, `_pet`, MR
    /// suffixes), words of the description and the file name (CT, CTA, PET, MR sequence names),
    /// then the values (Hounsfield units: air at -1000 and soft tissue near 0); MR when nothing
    /// tells. A CT's tissues are labelled in density order (CSF < WM < GM).
    #[arg(long, global = true, help_heading = "Input", value_enum, default_value_t = ModalityArg::Auto, hide_short_help = true)]
    pub modality: ModalityArg,

    /// Write a trace of the run (Chrome trace JSON; opens in ui.perfetto.dev and
    /// chrome://tracing): host phases (read, inflate, instance, device, pipelines, prepare,
    /// frames) on their threads and every GPU pass, from timestamps, on a "GPU queue" track.
    #[arg(
        long,
        global = true,
        help_heading = "Device and profiling",
        hide_short_help = true,
        value_name = "OUT.json"
    )]
    pub trace: Option<std::path::PathBuf>,

    /// Which series of a DICOM input (a folder, a DICOMDIR or a .dcm file): a SeriesInstanceUID, or
    /// the index `morphray info PATH` lists.
    ///
    /// Default: the largest 3-D image series (localizers and derived images are never the default).
    #[arg(long, global = true, help_heading = "Input", value_name = "UID|INDEX", value_parser = parse_series)]
    pub series: Option<crate::volume::source::dicom::SeriesChoice>,

    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

pub use super::identity_args::{ContrastArg, ModalityArg};
pub use super::value_args::{EmptySkip, NormalizeArg};

/// The commands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Describe a NIfTI file: header, geometry, intensity range, repairs and warnings (CPU only).
    Info(InfoArgs),
    /// Find the CSF / GM / WM histogram peaks on the GPU and print the paper's Table-1 row.
    Peaks(PeaksArgs),
    /// Render a volume to a PNG (with provenance), or a turntable of PNGs.
    Render(RenderArgs),
    /// Open the interactive viewer: tissue windows on the histogram, toggles, camera, status;
    /// scriptable (--frames, --script, --screenshot) for tests and demos.
    #[cfg(feature = "viewer")]
    View(ViewArgs),
    /// What accuracy costs in time: every quality knob against the f64 reference, with the
    /// Pareto frontier, an SVG plot and recommended defaults.
    Accuracy(AccuracyArgs),
    /// Measure: per-pass GPU times with bytes moved and bandwidth, raymarch frame times and
    /// samples over an orbit, a projection onto an Intel Xe-LP; JSON for tools.
    Bench(BenchArgs),
    /// List the Vulkan devices and why any of them cannot run morphray.
    Devices,
    /// Write the built-in digital phantom as a NIfTI-1 file (.nii or .nii.gz).
    Phantom(PhantomArgs),
    /// Write the volume a command would open (a DICOM series, or a NIfTI frame) as NIfTI-1.
    Convert(ConvertArgs),
    /// Write the derived maps the scene computes (I_norm, gradient magnitude, curvature,
    /// vesselness, denoised I_norm) as NIfTI-1 files `<name>_<map>.nii.gz` in a folder.
    Derive(super::derive::DeriveArgs),
    /// Show the pass plan of a scene: passes, pipeline variants, every allocation (name, bytes,
    /// format, memory type), the total, predicted per-pass costs and the degradations the memory
    /// budget forced; then set the volume up and print what the engine actually holds.
    Plan(PlanArgs),
    /// Process a BIDS dataset (BIDS-App conventions): `participant` writes each scan's Table-1
    /// row, peaks and three thumbnails as BIDS Derivatives; `group` writes a TSV and an HTML
    /// report from them.
    Batch(super::batch::BatchArgs),
    /// Compile the kernels a scene's plan uses (or every variant, --all) on the chosen device
    /// without running anything, and print the driver compiler's statistics per kernel (SIMD
    /// width, instructions, cycles, spills, sends, registers, ... where the driver reports them
    /// through VK_KHR_pipeline_executable_properties; Intel's ANV does, also on the stub Tiger
    /// Lake of tools/gen12).
    Kernels(KernelsArgs),
    /// Write one axial, coronal or sagittal slice (world-oriented, the affine honoured) as a
    /// greyscale PNG; prints the convention used (radiological by default).
    Slice(super::slice::SliceArgs),
}

/// Options of `kernels`.
#[derive(Debug, Args)]
pub struct KernelsArgs {
    /// Input: a NIfTI-1/2 file (.nii, .nii.gz, .hdr/.img), or DICOM (an exam's folder, a
    /// DICOMDIR, a .dcm file, or several files of one series); without one, the built-in
    /// digital phantom (256x256x192, 1 mm). DICOM series are listed by `morphray info`.
    #[arg(value_name = "FILE")]
    pub file: Vec<PathBuf>,
    /// Every variant the engine can build, not only the plan's.
    #[arg(long)]
    pub all: bool,
    /// Compile the plan's kernels for every workgroup shape of the tunable passes (default,
    /// 8x8, 16x16, 4x4x4, 8x8x4), required subgroup size (driver's, 8, 16, 32) and derived
    /// precision (8-bit, f16, f32), and report the compiler's choices (SIMD width, spills,
    /// instructions, cycles) beside the Xe-LP model's time bound of each pass.
    #[arg(long, conflicts_with = "all")]
    pub sweep: bool,
    /// Print JSON: {"device", "kernels": [{"name", "variant", "workgroup", "subgroup",
    /// "statistics": {...}}]}.
    #[arg(long)]
    pub json: bool,
    /// Frame of a 4-D file (0-based).
    #[arg(long, default_value_t = 0)]
    pub frame: usize,
    /// Scene whose plan to compile (the render options; --size defaults to 1024x1024).
    #[command(flatten)]
    pub scene: SceneArgs,
}

/// Options of `plan`.
#[derive(Debug, Args)]
pub struct PlanArgs {
    /// Input: a NIfTI-1/2 file (.nii, .nii.gz, .hdr/.img), or DICOM (an exam's folder, a
    /// DICOMDIR, a .dcm file, or several files of one series); without one, the built-in
    /// digital phantom (256x256x192, 1 mm). DICOM series are listed by `morphray info`.
    #[arg(value_name = "FILE")]
    pub file: Vec<PathBuf>,
    /// Print JSON instead of text (keys: passes, variants, allocations, total_bytes,
    /// peak_bytes, degradations, held, ...).
    #[arg(long)]
    pub json: bool,
    /// Frame of a 4-D file (0-based).
    #[arg(long, default_value_t = 0)]
    pub frame: usize,
    /// Scene to plan (the render options; --size defaults to 1024x1024).
    #[command(flatten)]
    pub scene: SceneArgs,
}

/// Options of `info`.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// Input: a NIfTI-1/2 file (.nii or .nii.gz; gzip is detected from the content, not the
    /// name), or DICOM (an exam's folder, a DICOMDIR, a .dcm file, or several files of one
    /// series: each series is listed).
    #[arg(value_name = "FILE", required = true)]
    pub file: Vec<PathBuf>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Frame of a 4-D file to analyse (0-based).
    #[arg(long, default_value_t = 0)]
    pub frame: usize,
}

/// Options of `peaks`.
#[derive(Debug, Args)]
pub struct PeaksArgs {
    /// Input: a NIfTI-1/2 file (.nii, .nii.gz, .hdr/.img), or DICOM (an exam's folder, a
    /// DICOMDIR, a .dcm file, or several files of one series); without one, the built-in
    /// digital phantom (256x256x192, 1 mm). DICOM series are listed by `morphray info`.
    #[arg(value_name = "FILE")]
    pub file: Vec<PathBuf>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Frame of a 4-D file to analyse (0-based)
    ///
    /// Default: frame 0, or the mean of all frames when the preset is epi (a BOLD or ASL
    /// series).
    #[arg(long)]
    pub frame: Option<usize>,
    /// Look by modality to report (mr, ct, angio, post-contrast, epi; `list` names them).
    #[arg(long, value_name = "NAME", value_parser = super::preset_arg::parse_preset)]
    pub preset: Option<super::preset_arg::PresetArg>,
}

/// Options of `render`.
#[derive(Debug, Args)]
#[command(next_help_heading = "Output")]
pub struct RenderArgs {
    /// Input: a NIfTI-1/2 file (.nii, .nii.gz, .hdr/.img), or DICOM (an exam's folder, a
    /// DICOMDIR, a .dcm file, or several files of one series); without one, the built-in
    /// digital phantom (256x256x192, 1 mm). DICOM series are listed by `morphray info`.
    #[arg(value_name = "FILE", help_heading = "Input")]
    pub file: Vec<PathBuf>,
    /// Output PNG [default: the input's name with .png, here]
    ///
    /// With --turntable N: frames are written as NAME-000.png, NAME-001.png, .... Without -o:
    /// the input's name with .png in the current directory (`scan.nii.gz` -> `scan.png`;
    /// `phantom.png` without an input), never over an existing file unless --force is given.
    #[arg(short, long, value_name = "PNG")]
    pub output: Option<PathBuf>,
    /// Replace the default output (`<input>.png`) when it exists already; a file named with
    /// -o is always replaced.
    #[arg(long, hide_short_help = true)]
    pub force: bool,
    /// Render N frames (1 to 10000) of a full orbit, azimuth advancing 360/N degrees a frame
    ///
    /// Every frame's file name is checked before the render starts.
    /// Progress shows on stderr when it is a terminal (MORPHRAY_PROGRESS=always: also in logs,
    /// as plain lines; =never: not at all).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=10_000))]
    pub turntable: Option<u32>,
    /// Turntable movie (src/cli/movie.rs).
    #[command(flatten)]
    pub movie: super::movie::MovieArgs,
    /// Frame of a 4-D file to render (0-based)
    ///
    /// Default: frame 0, or the mean of all frames when the preset is epi (a BOLD or ASL
    /// series: its foreground on the mean frame).
    #[arg(long)]
    pub frame: Option<usize>,
    /// Scene.
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Label overlay, drawn in 3D (DVR).
    #[command(flatten)]
    pub overlay: super::overlay::OverlayArgs,
    /// Intensity layers, drawn in 3D (DVR).
    #[command(flatten)]
    pub layer: super::layer_args::LayerArgs,
    /// Scene documents: `--scene`, `--scene-from`, `--save-scene`.
    #[command(flatten)]
    pub scene_file: super::scene_file::SceneFileArgs,
}

/// Options of `view`.
#[derive(Debug, Args)]
pub struct ViewArgs {
    /// Input: a NIfTI-1/2 file, or DICOM (an exam's folder, a DICOMDIR, a .dcm file, or several
    /// files of one series; --series picks a series, the window's series menu switches); without
    /// one, the built-in digital phantom. More can be opened from the window (Open..., or drop
    /// files or a folder on it).
    #[arg(value_name = "FILE")]
    pub file: Vec<PathBuf>,
    /// Render at least this many frames showing the volume, and on until the script (if any)
    /// has finished, then exit; logs each frame's GPU passes and each action's latency.
    #[arg(long, value_name = "N")]
    pub frames: Option<u32>,
    /// Save the last frame (the whole window) as PNG with provenance before exiting.
    #[arg(long, value_name = "PNG")]
    pub screenshot: Option<PathBuf>,
    /// Replay interface actions from this file, one per line (`toggle wm`, `orbit 30 0`,
    /// `set window wm 0.7 0.9`, `view superior`, `mode mip`, `curvature on`, `wait 10`, ...).
    #[arg(long, value_name = "FILE")]
    pub script: Option<PathBuf>,
    /// Present without waiting for vertical sync (for measuring frame rates).
    #[arg(long)]
    pub no_vsync: bool,
    /// Render into an offscreen image instead of a window (no display needed; needs --frames
    /// or --script).
    #[arg(long)]
    pub offscreen: bool,
    /// Label overlay on the slices.
    #[command(flatten)]
    pub overlay: super::overlay::OverlayArgs,
    /// Intensity layers over the volume (slices and 3D).
    #[command(flatten)]
    pub layer: super::layer_args::LayerArgs,
    /// Frame of a 4-D file to show (0-based), as `render --frame`.
    #[arg(long, default_value_t = 0)]
    pub frame: usize,
    /// Play a 4-D file's frames from the start (Play/Pause in the 4-D panel; looping).
    #[arg(long)]
    pub play: bool,
    /// Playback rate of a 4-D file, frames per second (0.1 to 60); a frame that takes longer to
    /// prepare is skipped, never queued.
    // The range is app::cine_panel::FPS_RANGE (app exists only with the viewer feature).
    #[arg(long, value_name = "F", default_value_t = 4.0, value_parser = parse_fps)]
    pub fps: f64,
    /// Raymarch time budget while you drag, scroll or move a slider, in ms of GPU time (default:
    /// one frame at 60 Hz). A scene that would miss it is drawn with a coarser step (then a
    /// smaller image) until 0.25 s after the last input, then once at full quality; 0 keeps
    /// full quality always. Screenshots are always full quality.
    // The literal is app::adaptive::DEFAULT_BUDGET_MS (app exists only with the viewer feature).
    #[arg(long, value_name = "MS", default_value_t = 16.7, value_parser = parse_budget)]
    pub frame_budget: f64,
    /// The first layout: slices (3D + axial, coronal and sagittal slices with the crosshair's
    /// readout), 3d (the 3D view alone), or one slice large (axial, coronal, sagittal).
    ///
    /// `V` or the buttons at the view's top left switch it later.
    #[arg(long, default_value = "slices", value_parser = ["slices", "3d", "axial", "coronal", "sagittal"])]
    pub layout: String,
    /// Scene documents: `--scene`, `--scene-from` (`--save-scene` is render's).
    #[command(flatten)]
    pub scene_file: super::scene_file::SceneFileArgs,
    /// Initial scene (--size is the window size, default 1280x800).
    #[command(flatten)]
    pub scene: SceneArgs,
}

/// Options of `phantom`.
#[derive(Debug, Args)]
pub struct PhantomArgs {
    /// Output file, .nii or .nii.gz (gzip-compressed).
    ///
    /// An existing file is not replaced unless --force is given (it may be a scan).
    #[arg(short, long, value_name = "NII")]
    pub output: PathBuf,
    /// Replace an existing output file (atomically: the old file stays whole until the new one
    /// is complete).
    #[arg(long)]
    pub force: bool,
    /// Dimensions X x Y x Z at 1 mm (the paper's cohort-A size by default).
    #[arg(long, default_value = "256x256x192", value_parser = parse_dims)]
    pub dims: [usize; 3],
    /// Also write the phantom's ground-truth tissue labels here (an integer label map for
    /// `slice --overlay`: 1 skull/scalp shell, 2 CSF, 3 GM, 4 WM, 5 lesion, 6 vessels, 7 edema;
    /// with --head: 8 skin, 9 fat, 10 muscle, 11 bone, 12 marrow, 13 eye, 14 spinal cord).
    #[arg(long, value_name = "NII")]
    pub labels: Option<PathBuf>,
    /// Make a whole head: skin, fat, muscle, a three-layer skull, eyes, a face and a neck with
    /// the spinal cord joining the brainstem, instead of the plain dark shell (for brain
    /// extraction).
    ///
    /// The image contrast is the global --contrast: t1 (also for auto, the default), t2, pd,
    /// flair or ct (Hounsfield units), for the plain phantom and --head alike. The output name is
    /// yours; BIDS-style names say the contrast, e.g. sub-01_T1w.nii.gz, sub-01_T2w.nii.gz,
    /// sub-01_PDw.nii.gz, sub-01_FLAIR.nii.gz or sub-01_ct.nii.gz.
    #[arg(long)]
    pub head: bool,
}

/// Options of `convert`.
#[derive(Debug, Args)]
pub struct ConvertArgs {
    /// DICOM folder, DICOMDIR, .dcm file or several files of one series (or a NIfTI file).
    #[arg(value_name = "INPUT", required = true)]
    pub input: Vec<PathBuf>,
    /// Output file, .nii or .nii.gz; never the input, and an existing file is replaced only
    /// with --force.
    #[arg(short, long, value_name = "NII")]
    pub output: PathBuf,
    /// Replace an existing output file (atomically).
    #[arg(long)]
    pub force: bool,
    /// Frame of a 4-D NIfTI input (0-based).
    #[arg(long, default_value_t = 0)]
    pub frame: usize,
}

fn parse_budget(text: &str) -> Result<f64, String> {
    text.parse::<f64>()
        .ok()
        .filter(|ms| ms.is_finite() && *ms >= 0.0)
        .ok_or_else(|| "give milliseconds >= 0 (0 switches adaptive quality off)".into())
}

fn parse_fps(text: &str) -> Result<f64, String> {
    text.parse::<f64>()
        .ok()
        .filter(|fps| (0.1..=60.0).contains(fps))
        .ok_or_else(|| "give 0.1 to 60 frames per second".into())
}

fn parse_series(text: &str) -> Result<crate::volume::source::dicom::SeriesChoice, String> {
    crate::volume::source::dicom::SeriesChoice::parse(text)
}

fn parse_dims(text: &str) -> Result<[usize; 3], String> {
    let parts: Vec<_> = text
        .split(['x', 'X'])
        .map(|p| p.trim().parse::<usize>())
        .collect();
    match parts.as_slice() {
        [Ok(x), Ok(y), Ok(z)] if [*x, *y, *z].iter().all(|&d| (4..=2048).contains(&d)) => {
            Ok([*x, *y, *z])
        }
        _ => Err(format!(
            "`{text}` is not XxYxZ with each side from 4 to 2048"
        )),
    }
}

/// Options of `accuracy`.
#[derive(Debug, Args)]
pub struct AccuracyArgs {
    /// Input: a NIfTI-1/2 file (.nii, .nii.gz, .hdr/.img), or DICOM (an exam's folder, a
    /// DICOMDIR, a .dcm file, or several files of one series); without one, the built-in
    /// digital phantom (256x256x192, 1 mm). DICOM series are listed by `morphray info`.
    #[arg(value_name = "FILE")]
    pub file: Vec<PathBuf>,
    /// Frames per view for the GPU time median.
    #[arg(long, default_value_t = 5)]
    pub frames: u32,
    /// Number of fixed views (1 to 3).
    #[arg(long, default_value_t = 3)]
    pub views: usize,
    /// Write the full report as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Write an SVG plot of error vs time with the Pareto frontier.
    #[arg(long, value_name = "SVG")]
    pub plot: Option<PathBuf>,
    /// Image size of the timing renders, WIDTHxHEIGHT (RGBA8, as `render` draws); errors are
    /// measured at --size, where the f64 reference is affordable.
    ///
    /// Default: --size.
    #[arg(long, value_parser = parse_size)]
    pub time_size: Option<(u32, u32)>,
    /// Frame of a 4-D file (0-based).
    #[arg(long, default_value_t = 0)]
    pub frame: usize,
    /// Instead: the vesselness and denoising knobs (number of scales, filter kind) on the shape
    /// phantoms, error next to GPU time (src/study/vessels.rs; --frames = repeats).
    #[arg(long)]
    pub vessels: bool,
    /// Base scene (its defaults are the render defaults; --size defaults to 256x256).
    #[command(flatten)]
    pub scene: SceneArgs,
}

/// Options of `bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// NIfTI-1/2 file; without one, the built-in digital phantom, written to a temporary
    /// .nii.gz first (and removed afterwards), so reading and inflating are real work.
    pub file: Option<PathBuf>,
    /// Time to first pixel: run this many fresh processes of morphray with an empty pipeline
    /// cache (cold) and as many with a cache a first untimed process filled (warm), each
    /// timing its phases from process start to the first frame's fence; medians and p5..p95
    /// are reported. 0 skips it.
    #[arg(long, default_value_t = 5, value_name = "K")]
    pub trials: u32,
    /// Internal: run as one time-to-first-pixel trial (open, first frame, one JSON line).
    #[arg(long, hide = true)]
    pub ttfp_child: bool,
    /// Frames of the orbit (azimuth advancing 360/N degrees per frame).
    #[arg(long, default_value_t = 200)]
    pub frames: u32,
    /// Repetitions of each analysis and derivative pass (medians are reported).
    #[arg(long, default_value_t = 10)]
    pub repeat: u32,
    /// Also write the full report as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Frame of a 4-D file (0-based).
    #[arg(long, default_value_t = 0)]
    pub frame: usize,
    /// Scene.
    #[command(flatten)]
    pub scene: SceneArgs,
}

pub(super) fn parse_size(text: &str) -> Result<(u32, u32), String> {
    let (w, h) = text
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("`{text}` is not WIDTHxHEIGHT (for example 1024x768)"))?;
    let parse = |s: &str| {
        s.trim()
            .parse::<u32>()
            .ok()
            .filter(|&v| (1..=16384).contains(&v))
    };
    match (parse(w), parse(h)) {
        (Some(w), Some(h)) => Ok((w, h)),
        _ => Err(format!(
            "`{text}`: width and height must be whole numbers from 1 to 16384"
        )),
    }
}

/// A finite number: NaN and infinities are usage errors naming the flag (clap adds the name),
/// instead of a camera at NaN degrees rendered as 0 with `null` in the provenance.
pub(super) fn parse_finite(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(format!("`{text}` is not a finite number")),
        Err(_) => Err(format!("`{text}` is not a number")),
    }
}

pub(super) fn parse_pair(text: &str) -> Result<(f64, f64), String> {
    let (a, b) = text
        .split_once(',')
        .ok_or_else(|| format!("`{text}` is not X,Y"))?;
    match (a.trim().parse::<f64>(), b.trim().parse::<f64>()) {
        (Ok(a), Ok(b)) if a.is_finite() && b.is_finite() => Ok((a, b)),
        _ => Err(format!("`{text}` is not two finite numbers X,Y")),
    }
}

pub(super) fn parse_colour(text: &str) -> Result<[f32; 3], String> {
    let text = text.trim();
    if let Some(hex) = text.strip_prefix('#') {
        if let Some(v) = (hex.len() == 6)
            .then(|| u32::from_str_radix(hex, 16).ok())
            .flatten()
        {
            return Ok([
                (v >> 16) as f32 / 255.0,
                ((v >> 8) & 0xff) as f32 / 255.0,
                (v & 0xff) as f32 / 255.0,
            ]);
        }
        return Err(format!("`{text}` is not a #RRGGBB colour"));
    }
    let parts: Vec<_> = text.split(',').map(|p| p.trim().parse::<u8>()).collect();
    match parts.as_slice() {
        [Ok(r), Ok(g), Ok(b)] => Ok([*r as f32 / 255.0, *g as f32 / 255.0, *b as f32 / 255.0]),
        _ => Err(format!(
            "`{text}` is neither #RRGGBB nor R,G,B with values 0..255"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_pairs_and_colours_parse_or_explain() {
        assert_eq!(parse_size("1920x1080"), Ok((1920, 1080)));
        assert!(
            parse_size("0x10").is_err()
                && parse_size("big").is_err()
                && parse_size("99999x2").is_err()
        );
        assert_eq!(parse_pair("-3,4.5"), Ok((-3.0, 4.5)));
        assert!(parse_pair("nan,1").is_err());
        assert_eq!(parse_finite("-30.5"), Ok(-30.5));
        for bad in ["NaN", "nan", "inf", "-inf", "infinity", "ten"] {
            assert!(parse_finite(bad).is_err(), "{bad}");
        }
        assert_eq!(parse_colour("#ff0000"), Ok([1.0, 0.0, 0.0]));
        assert_eq!(parse_colour("0,255,0"), Ok([0.0, 1.0, 0.0]));
        assert!(parse_colour("#12345").is_err() && parse_colour("1,2").is_err());
    }

    #[test]
    fn the_command_line_definition_is_consistent() {
        use clap::CommandFactory;
        Cli::command().debug_assert();
    }
}
