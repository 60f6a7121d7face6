//! Time to first pixel, measured over fresh processes: `morphray bench --trials K`.
//!
//! Decisions:
//! - One fresh process per trial, because what a user waits for at start-up (loading the Vulkan
//!   driver, creating the device, compiling pipelines) happens once per process. The bench
//!   re-executes its own binary (`std::env::current_exe`) with the hidden flag `--ttfp-child`;
//!   each child opens the volume, renders the bench's first frame at the bench's size and scene,
//!   waits for its fence, then saves the pipeline cache and prints its phases as one JSON line.
//! - "Process start" is the parent's wall clock (nanoseconds since the UNIX epoch, passed in
//!   `MORPHRAY_TTFP_SPAWN_NS`) just before it spawns the child, so the total includes exec, the
//!   dynamic loader and Rust's start-up; the child's own clock from the top of `main` is reported
//!   beside it (`in_process_ms`), and the difference as the `exec` phase. Wall clocks can step
//!   (NTP); over the fraction of a second measured here that is negligible.
//! - Cold and warm are separate sets of K trials. A cold trial gets an empty temporary cache
//!   directory; the warm trials share one that a first, untimed trial filled. The drivers' own
//!   shader caches are pointed into the same directory (`XDG_CACHE_HOME`,
//!   `MESA_SHADER_CACHE_DIR`, `__GL_SHADER_DISK_CACHE_PATH`), because a cold start with the
//!   driver's cache warm from an earlier run is not cold. The input file and the binary stay in
//!   the operating system's page cache after the first trial (reads are from memory).
//! - Phases are host wall times on the thread that does them: read, inflate and convert on the
//!   loader thread, overlapped with instance, adapter, device and engine on the main thread; the
//!   main thread then waits for the loader (`load_wait`) and runs the passes. Pipelines compile
//!   on worker threads from the moment the engine exists (`Engine::start_pipelines`); the
//!   `pipelines` phase is the main thread's time on them (starting the workers, waiting where a
//!   pass needed one still compiling), taken out of the phase it happened in. Its sub-phases
//!   `pipelines.ahead_span` (first worker's start to last worker's end) and
//!   `pipelines.ahead_sum` (the workers' compile times added up) say what the compiles cost
//!   and how much was hidden. The main-thread phases plus `startup`, `exec` and `other` (what
//!   no phase covers) add up to the total. GPU times of the passes come from timestamp queries
//!   (on lavapipe they include the shader compile, which it does at the first dispatch).

use super::args::BenchArgs;
use super::bench::Spread;
use super::output::print_line;
use super::session;
use crate::engine::plan::Layout;
use crate::error::Error;
use crate::passes::raymarch::RaymarchVariant;
use ash::vk;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::{Instant, SystemTime, UNIX_EPOCH};

/// Environment variable carrying the parent's wall clock at spawn (ns since the UNIX epoch).
pub const SPAWN_ENV: &str = "MORPHRAY_TTFP_SPAWN_NS";

/// Phases of the loader thread, in order.
pub const WORKER_PHASES: [&str; 3] = ["read", "inflate", "convert"];

/// Phases of the main thread, in order (each follows the previous one).
pub const MAIN_PHASES: [&str; 15] = [
    "instance",
    "adapter",
    "device",
    "engine",
    "load_wait",
    "pipelines",
    "plan",
    "upload",
    "minmax",
    "normalize",
    "histogram",
    "peaks",
    "derivatives",
    "occupancy",
    "raymarch",
];

/// Parts of main-thread phases (`phase.part`), reported beside them, not added again.
pub const SUB_PHASES: [&str; 4] = [
    "instance.loader",
    "device.allocator",
    "pipelines.ahead_span",
    "pipelines.ahead_sum",
];

/// Passes with GPU timestamps, in order.
pub const GPU_PHASES: [&str; 8] = [
    "upload",
    "minmax",
    "normalize",
    "histogram",
    "denoise",
    "derivatives",
    "occupancy",
    "raymarch",
];

/// The targets on the H100 (milliseconds), printed for context, never asserted.
pub const TARGET_COLD_MS: f64 = 150.0;
/// See [`TARGET_COLD_MS`].
pub const TARGET_WARM_MS: f64 = 100.0;

static PROCESS_START: OnceLock<(Instant, u128)> = OnceLock::new();

fn unix_ns() -> u128 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0)
}

/// Records the process's start (call first thing in `main`; later calls keep the first time).
pub fn mark_process_start() {
    PROCESS_START.get_or_init(|| (Instant::now(), unix_ns()));
}

/// The process's start as an `Instant` (traces count from it).
pub fn process_start_instant() -> Instant {
    process_start().0
}

fn process_start() -> (Instant, u128) {
    *PROCESS_START.get_or_init(|| (Instant::now(), unix_ns()))
}

fn ms_since(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

/// One trial's measurements: the JSON line a child prints.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct ChildReport {
    /// Host wall time per phase, milliseconds (see the module's decisions).
    pub phases_ms: BTreeMap<String, f64>,
    /// GPU time per pass from timestamps, milliseconds.
    pub gpu_ms: BTreeMap<String, f64>,
    /// Parent's spawn to the first frame's fence (None when started without the parent).
    pub total_ms: Option<f64>,
    /// Top of `main` to the first frame's fence.
    pub in_process_ms: f64,
    /// Bytes of pipeline-cache data the child loaded (0: started empty).
    pub cache_loaded_bytes: u64,
    /// Why an existing cache file was not used.
    pub cache_rejected: Option<String>,
    /// Bytes of pipeline-cache data written after the first frame (0: unchanged or not saved).
    pub cache_written_bytes: u64,
    /// Host time of saving the cache after the first frame (not part of the total).
    pub cache_save_ms: f64,
    /// Pipelines created ahead of use on worker threads.
    pub pipelines_created_ahead: u32,
    /// Pipelines created by the first frame itself (a raymarch variant the plan did not
    /// predict, such as one without empty-space skipping for a volume with nothing to skip).
    pub pipelines_created_by_frame: u32,
    /// How the volume came in: threads, gzip members, the upload path.
    #[serde(default)]
    pub load_path: LoadPath,
}

/// How a trial's volume was read and uploaded (the streamed load's shape, next to its phases).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LoadPath {
    /// Threads for the large read, inflation and staging copy.
    pub io_threads: usize,
    /// gzip members (0: not compressed, 1: one thread inflates, more: in parallel).
    pub gzip_members: usize,
    /// `direct`, `staged` or `rebar` (engine/upload.rs).
    pub upload: String,
}

/// Runs one trial (`bench --ttfp-child`) and prints its [`ChildReport`] as one JSON line.
pub fn run_child(args: &BenchArgs, global: &super::GlobalOptions) -> Result<(), Error> {
    let (main_start, main_wall) = process_start();
    let spawned = std::env::var(SPAWN_ENV)
        .ok()
        .and_then(|v| v.trim().parse::<u128>().ok());
    let (width, height) = args.scene.size.unwrap_or((1920, 1080));
    let mut scene_args = args.scene.clone();
    scene_args.size = Some((width, height));
    let open_start = Instant::now();
    let startup_ms = (open_start - main_start).as_secs_f64() * 1e3;
    let mut opened = session::open(
        args.file.as_slice(),
        args.frame,
        false,
        global.engine_config(),
        Some(&scene_args),
        true,
    )?;
    let t = opened.timings.clone();
    let created_before_frame = opened.engine.counters().pipelines_created;

    // The brick ranges the first frame's empty-space skipping needs (what `render` would do
    // inside the frame), timed on their own.
    let pipelines_before = opened.engine.pipeline_times().caller_ms;
    let before = Instant::now();
    let bricked = matches!(opened.plan.layout, Layout::Bricked { .. });
    let variant = RaymarchVariant::of_layout(&opened.scene.effects, false, bricked);
    let occupancy_gpu = if variant.skip_empty {
        opened.engine.brick_ranges_timed(&opened.twin.prepared)?.1
    } else {
        Vec::new()
    };
    let occupancy_ms = ms_since(before);
    let occupancy_pipelines_ms = opened.engine.pipeline_times().caller_ms - pipelines_before;
    let pipelines_before = opened.engine.pipeline_times().caller_ms;

    // The first frame: the bench's scene at the bench's size, no readback (the pixels are on
    // the GPU when the fence signals, as a presenter would find them).
    let before = Instant::now();
    let mut target = opened
        .engine
        .render_target(width, height, vk::Format::R8G8B8A8_UNORM)?;
    target.read_back = false;
    let scene = opened.scene;
    let frame = opened
        .engine
        .render_twin(&mut target, &mut opened.twin, &scene)?;
    let fence_wall = unix_ns();
    let raymarch_ms = ms_since(before);
    let in_process_ms = ms_since(main_start);
    let created_by_frame = opened.engine.counters().pipelines_created - created_before_frame;
    let pipeline_times = opened.engine.pipeline_times();
    let raymarch_pipelines_ms = pipeline_times.caller_ms - pipelines_before;

    // Everything the first frame did not need runs after it.
    let before = Instant::now();
    let written = match session::persist_pipeline_cache(&opened.engine) {
        Some(crate::gpu::PersistOutcome::Written { bytes, .. }) => bytes,
        _ => 0,
    };
    let cache_save_ms = ms_since(before);
    if global.validation {
        session::check_validation(&opened.engine)?;
    }

    let v = &t.volume;
    let p = &v.prepare;
    let mut phases: BTreeMap<String, f64> = [
        ("startup", startup_ms),
        ("read", t.load.read_ms),
        ("inflate", t.load.inflate_ms),
        ("convert", t.load.convert_ms + t.load.phantom_ms),
        ("instance", t.device_parts.instance_ms),
        ("instance.loader", t.device_parts.loader_ms),
        ("device.allocator", t.device_parts.allocator_ms),
        ("adapter", t.device_parts.adapter_ms),
        ("device", t.device_parts.device_ms),
        ("engine", t.engine_ms),
        ("load_wait", t.load_wait_ms),
        // Waits for pipelines are taken out of the phases they happened in and shown here.
        (
            "pipelines",
            t.pipelines_ms + occupancy_pipelines_ms + raymarch_pipelines_ms,
        ),
        ("pipelines.ahead_span", pipeline_times.ahead_span_ms),
        ("pipelines.ahead_sum", pipeline_times.ahead_sum_ms),
        ("plan", v.plan_ms),
        ("upload", p.upload_ms),
        ("minmax", p.minmax_ms),
        ("normalize", p.normalize_ms),
        ("histogram", p.histogram_ms),
        ("peaks", v.peaks_ms),
        ("derivatives", v.derivatives_ms - v.derivatives_pipelines_ms),
        ("occupancy", occupancy_ms - occupancy_pipelines_ms),
        ("raymarch", raymarch_ms - raymarch_pipelines_ms),
    ]
    .into_iter()
    .map(|(name, value)| (name.to_string(), value))
    .collect();
    let exec_ms = spawned.map(|s| main_wall.saturating_sub(s) as f64 / 1e6);
    if let Some(exec) = exec_ms {
        phases.insert("exec".into(), exec);
    }
    let accounted: f64 = MAIN_PHASES
        .iter()
        .chain(["startup"].iter())
        .filter_map(|name| phases.get(*name))
        .sum();
    phases.insert("other".into(), in_process_ms - accounted);

    let mut gpu: BTreeMap<String, f64> = BTreeMap::new();
    let timings = opened
        .twin
        .prepared
        .gpu_timings
        .iter()
        .chain(
            opened
                .twin
                .derived()
                .into_iter()
                .flat_map(|d| &d.gpu_timings),
        )
        .chain(&occupancy_gpu)
        .chain(&frame.gpu_timings);
    for timing in timings {
        let name = if timing.name.starts_with("derivatives") {
            "derivatives"
        } else {
            timing.name.as_str()
        };
        *gpu.entry(name.to_string()).or_default() += timing.gpu_ms;
    }

    let upload = serde_json::to_value(opened.twin.prepared.upload_path)
        .ok()
        .and_then(|v| v.as_str().map(str::to_string))
        .unwrap_or_default();
    let load_path = LoadPath {
        io_threads: t.load.io_threads,
        gzip_members: t.load.gzip_members,
        upload,
    };
    let load = opened.engine.pipeline_cache().load();
    let report = ChildReport {
        load_path,
        phases_ms: phases,
        gpu_ms: gpu,
        total_ms: spawned.map(|s| fence_wall.saturating_sub(s) as f64 / 1e6),
        in_process_ms,
        cache_loaded_bytes: load.loaded_bytes,
        cache_rejected: load.rejected.clone(),
        cache_written_bytes: written,
        cache_save_ms,
        pipelines_created_ahead: pipeline_times.created_ahead,
        pipelines_created_by_frame: created_by_frame,
    };
    let line = serde_json::to_string(&report)
        .map_err(|e| Error::Usage(format!("cannot encode the trial's report: {e}")))?;
    print_line(&line);
    Ok(())
}

/// Medians and spreads of one cache state's trials.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct TtfpSide {
    /// Parent's spawn to the first frame's fence.
    pub total_ms: Spread,
    /// Top of the child's `main` to the first frame's fence.
    pub in_process_ms: Spread,
    /// Host wall time per phase.
    pub phases: BTreeMap<String, Spread>,
    /// GPU time per pass.
    pub gpu_ms: BTreeMap<String, Spread>,
    /// Pipeline-cache bytes each trial loaded.
    pub cache_loaded_bytes: Vec<u64>,
    /// Pipeline-cache bytes each trial wrote after its first frame (0: unchanged).
    pub cache_written_bytes: Vec<u64>,
    /// Why a trial's cache file was rejected, if one was.
    pub cache_rejected: Vec<String>,
    /// Saving the cache after the first frame (not in the total).
    pub cache_save_ms: Spread,
    /// Pipelines each trial's first frame created itself (beyond those created ahead).
    pub pipelines_created_by_frame: Vec<u32>,
    /// How the volume came in (the same for every trial of a run; the first trial's).
    pub load_path: LoadPath,
}

impl TtfpSide {
    fn of(trials: &[ChildReport]) -> TtfpSide {
        let spread_of = |f: &dyn Fn(&ChildReport) -> Option<f64>| {
            Spread::of(&trials.iter().filter_map(f).collect::<Vec<_>>())
        };
        let names = |f: &dyn Fn(&ChildReport) -> Vec<String>| {
            let mut all: Vec<String> = trials.iter().flat_map(f).collect();
            all.sort();
            all.dedup();
            all
        };
        let phases = names(&|c| c.phases_ms.keys().cloned().collect())
            .into_iter()
            .map(|n| {
                let s = spread_of(&|c| c.phases_ms.get(&n).copied());
                (n, s)
            })
            .collect();
        let gpu_ms = names(&|c| c.gpu_ms.keys().cloned().collect())
            .into_iter()
            .map(|n| {
                let s = spread_of(&|c| c.gpu_ms.get(&n).copied());
                (n, s)
            })
            .collect();
        TtfpSide {
            total_ms: spread_of(&|c| c.total_ms),
            in_process_ms: spread_of(&|c| Some(c.in_process_ms)),
            phases,
            gpu_ms,
            cache_loaded_bytes: trials.iter().map(|c| c.cache_loaded_bytes).collect(),
            cache_written_bytes: trials.iter().map(|c| c.cache_written_bytes).collect(),
            cache_rejected: trials
                .iter()
                .filter_map(|c| c.cache_rejected.clone())
                .collect(),
            cache_save_ms: spread_of(&|c| Some(c.cache_save_ms)),
            pipelines_created_by_frame: trials
                .iter()
                .map(|c| c.pipelines_created_by_frame)
                .collect(),
            load_path: trials
                .first()
                .map(|c| c.load_path.clone())
                .unwrap_or_default(),
        }
    }
}

/// The targets, for context.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Targets {
    /// Median with a cold cache, ms.
    pub cold_ms: f64,
    /// Median with a warm cache, ms.
    pub warm_ms: f64,
    /// Where they apply.
    pub applies_to: &'static str,
}

/// The time-to-first-pixel section of the bench report.
#[derive(Clone, Debug, serde::Serialize)]
pub struct TtfpReport {
    /// Trials per cache state.
    pub trials: u32,
    /// How it was measured.
    pub method: &'static str,
    /// Empty pipeline and driver caches.
    pub cold: TtfpSide,
    /// Caches filled by an earlier, untimed process.
    pub warm: TtfpSide,
    /// The targets (not asserted).
    pub targets: Targets,
}

const METHOD: &str = "one fresh process per trial (the bench re-executes itself); total = parent's \
    wall clock just before spawn to the child's first-frame fence (includes exec and dynamic \
    loading), in_process = top of main to that fence; cold: empty pipeline cache and driver shader \
    caches (XDG_CACHE_HOME, MESA_SHADER_CACHE_DIR, __GL_SHADER_DISK_CACHE_PATH per trial), warm: \
    caches filled by one untimed process; input and binary in the OS page cache";

/// Removes a directory tree when dropped (also on errors).
struct RemoveOnDrop(PathBuf);

impl Drop for RemoveOnDrop {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The parent's command line for the children: its own arguments without `--pipeline-cache`
/// (each child gets its own), plus `input` when the parent generated it.
fn child_arguments(input: Option<&Path>) -> Vec<std::ffi::OsString> {
    let mut out = Vec::new();
    let mut args = std::env::args_os().skip(1);
    while let Some(arg) = args.next() {
        let text = arg.to_string_lossy();
        if text == "--pipeline-cache" {
            args.next();
            continue;
        }
        if text.starts_with("--pipeline-cache=") {
            continue;
        }
        out.push(arg);
    }
    if let Some(input) = input {
        out.push(input.as_os_str().to_owned());
    }
    out
}

fn spawn_trial(
    exe: &Path,
    arguments: &[std::ffi::OsString],
    cache: &Path,
) -> Result<ChildReport, Error> {
    let io = |what: &str, e: std::io::Error| {
        Error::Usage(format!("time to first pixel: cannot {what}: {e}"))
    };
    let drivers = cache.join("driver");
    std::fs::create_dir_all(&drivers).map_err(|e| io("create a cache directory", e))?;
    let mut command = std::process::Command::new(exe);
    command
        .args(arguments)
        .arg("--pipeline-cache")
        .arg(cache)
        .arg("--ttfp-child")
        .env("XDG_CACHE_HOME", &drivers)
        .env("MESA_SHADER_CACHE_DIR", &drivers)
        .env("__GL_SHADER_DISK_CACHE_PATH", &drivers)
        .stdin(std::process::Stdio::null())
        .stderr(std::process::Stdio::inherit());
    // Taken last, just before the spawn: the child's total starts here.
    command.env(SPAWN_ENV, unix_ns().to_string());
    let output = command.output().map_err(|e| io("start a trial", e))?;
    if !output.status.success() {
        return Err(Error::Usage(format!(
            "a time-to-first-pixel trial failed ({}); its message is above",
            output.status
        )));
    }
    let stdout = String::from_utf8_lossy(&output.stdout);
    let line = stdout
        .lines()
        .rev()
        .find(|l| !l.trim().is_empty())
        .unwrap_or("");
    serde_json::from_str(line).map_err(|e| {
        Error::Usage(format!(
            "a time-to-first-pixel trial printed no report ({e}): `{line}`"
        ))
    })
}

/// Runs `args.trials` cold and warm trials on `input` (`generated`: the parent wrote it, so the
/// children are handed its path).
pub fn run_trials(args: &BenchArgs, input: &Path, generated: bool) -> Result<TtfpReport, Error> {
    let exe = std::env::current_exe().map_err(|e| {
        Error::Usage(format!(
            "time to first pixel: cannot find morphray's own executable: {e}"
        ))
    })?;
    let root = std::env::temp_dir().join(format!("morphray-ttfp-{}", std::process::id()));
    let _remove = RemoveOnDrop(root.clone());
    let arguments = child_arguments(generated.then_some(input));
    let mut cold = Vec::new();
    for trial in 0..args.trials {
        cold.push(spawn_trial(
            &exe,
            &arguments,
            &root.join(format!("cold-{trial}")),
        )?);
    }
    let warm_dir = root.join("warm");
    // Untimed: fills the pipeline cache and the driver's cache.
    spawn_trial(&exe, &arguments, &warm_dir)?;
    let mut warm = Vec::new();
    for _ in 0..args.trials {
        warm.push(spawn_trial(&exe, &arguments, &warm_dir)?);
    }
    Ok(TtfpReport {
        trials: args.trials,
        method: METHOD,
        cold: TtfpSide::of(&cold),
        warm: TtfpSide::of(&warm),
        targets: Targets {
            cold_ms: TARGET_COLD_MS,
            warm_ms: TARGET_WARM_MS,
            applies_to: "issue 5, NVIDIA H100: phantom 256x256x192 int16 as .nii.gz, 1920x1080, \
                         step 0.5, all tissues, curvature on (context, not asserted)",
        },
    })
}

/// Prints the time-to-first-pixel table.
pub fn print_text(r: &TtfpReport) {
    let cell = |s: Option<&Spread>| match s {
        Some(s) if s.n > 0 => format!("{:>9.2} ({:>8.2}..{:<8.2})", s.median, s.p5, s.p95),
        _ => format!("{:>9} {:>20}", "-", ""),
    };
    print_line(&format!(
        "time to first pixel: {} fresh processes per cache state; median (p5..p95) ms",
        r.trials
    ));
    print_line(&format!(
        "  {:<26} {:<31} {:<31}",
        "phase (host wall)", "cold", "warm"
    ));
    let row = |label: &str, cold: Option<&Spread>, warm: Option<&Spread>| {
        print_line(&format!("  {label:<26} {} {}", cell(cold), cell(warm)));
    };
    for name in WORKER_PHASES {
        row(
            &format!("{name} (loader thread)"),
            r.cold.phases.get(name),
            r.warm.phases.get(name),
        );
    }
    for name in ["exec", "startup"]
        .into_iter()
        .chain(MAIN_PHASES)
        .chain(["other"])
    {
        row(name, r.cold.phases.get(name), r.warm.phases.get(name));
        // Sub-phases, already inside the row above.
        for part in SUB_PHASES
            .iter()
            .filter(|p| p.starts_with(&format!("{name}.")))
        {
            row(
                &format!("  {part}"),
                r.cold.phases.get(*part),
                r.warm.phases.get(*part),
            );
        }
    }
    row(
        "total (spawn -> fence)",
        Some(&r.cold.total_ms),
        Some(&r.warm.total_ms),
    );
    row(
        "in process (main -> fence)",
        Some(&r.cold.in_process_ms),
        Some(&r.warm.in_process_ms),
    );
    let gpu: Vec<String> = GPU_PHASES
        .iter()
        .filter_map(|name| {
            let c = r.cold.gpu_ms.get(*name)?;
            let w = r.warm.gpu_ms.get(*name)?;
            Some(format!("{name} {:.3}/{:.3}", c.median, w.median))
        })
        .collect();
    print_line(&format!(
        "  GPU ms (timestamps, median cold/warm): {}",
        gpu.join(", ")
    ));
    let path = &r.cold.load_path;
    print_line(&format!(
        "  load path: {} I/O threads, {} gzip member(s), upload {}",
        path.io_threads, path.gzip_members, path.upload
    ));
    let bytes = |v: &[u64]| {
        v.iter()
            .map(|b| b.to_string())
            .collect::<Vec<_>>()
            .join(",")
    };
    print_line(&format!(
        "  pipeline cache: cold trials wrote [{}] bytes after their first frame; warm trials loaded [{}] bytes",
        bytes(&r.cold.cache_written_bytes),
        bytes(&r.warm.cache_loaded_bytes)
    ));
    for reason in r.cold.cache_rejected.iter().chain(&r.warm.cache_rejected) {
        print_line(&format!("  pipeline cache rejected: {reason}"));
    }
    print_line(&format!(
        "  targets ({}): <= {:.0} ms cold, <= {:.0} ms warm",
        r.targets.applies_to, r.targets.cold_ms, r.targets.warm_ms
    ));
}
