//! `morphray bench`: what each pass costs on this device, against what it must move.
//!
//! Method: the GPU is warmed up for 0.5 s first (clocks ramp from idle); every pass
//! time is a GPU timestamp median over repeated runs; each pass
//! is compared with its floor (bytes read + written once over the device-copy bandwidth measured
//! in the same run, and texture fetches over the texel rate), and the same counts are projected
//! onto an Intel Xe-LP as a model. The raymarch is timed over an orbit of frames without
//! readback (the per-frame CPU wall minus GPU time, the host overhead, is reported), then again
//! with readback (its overhead reported separately); a last, untimed pass over the same frames
//! counts the samples each frame took.
//! Time to first pixel is measured first, over fresh processes (`ttfp.rs`), before this process
//! opens a device; without a file the input is the phantom written as .nii.gz, so reading and
//! inflating are part of it.

mod derived;

use super::args::BenchArgs;
use super::output::{json, print_line, print_warnings};
use super::progress::say;
use super::session;
use crate::engine::SessionTimings;
use crate::engine::plan::{Layout, Plan};
use crate::error::Error;
use crate::files::write::{OutputKind, check_output, write_file};
use crate::passes::cost::{self, DeviceModel, H100, PassCost, XE_LP};
use crate::scene::{GradientSource, RenderMode};
use ash::vk;
use std::time::Instant;

/// Median, 5th and 95th percentile of a sample.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct Spread {
    /// Median.
    pub median: f64,
    /// 5th percentile.
    pub p5: f64,
    /// 95th percentile.
    pub p95: f64,
    /// Number of values.
    pub n: usize,
}

impl Spread {
    /// Spread of `values` (empty: all zero).
    pub fn of(values: &[f64]) -> Spread {
        let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
        if v.is_empty() {
            return Spread::default();
        }
        v.sort_by(f64::total_cmp);
        let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
        Spread {
            median: at(0.5),
            p5: at(0.05),
            p95: at(0.95),
            n: v.len(),
        }
    }
}

/// One pass's measurement against its floor.
#[derive(Clone, Debug, serde::Serialize)]
struct PassReport {
    name: String,
    gpu_ms: Spread,
    cost: PassCost,
    achieved_gb_per_s: f64,
    fraction_of_measured_copy: Option<f64>,
    achieved_gtexel_per_s: f64,
    fraction_of_documented_texel_rate: Option<f64>,
    xe_lp_model_ms: f64,
    xe_lp_bound: &'static str,
}

/// Host overhead of a frame: CPU wall time (recording, submission, waiting, and the copy out
/// when reading back) minus the raymarch's GPU time, per frame.
#[derive(Clone, Debug, serde::Serialize)]
struct FrameOverhead {
    cpu_wall_ms: Spread,
    gpu_ms: Spread,
    cpu_minus_gpu_ms: Spread,
}

impl FrameOverhead {
    /// `frames`: (CPU wall, GPU time if the queue has timestamps) of each frame.
    fn of(frames: &[(f64, Option<f64>)]) -> FrameOverhead {
        let cpu: Vec<f64> = frames.iter().map(|f| f.0).collect();
        let gpu: Vec<f64> = frames.iter().filter_map(|f| f.1).collect();
        let gap: Vec<f64> = frames
            .iter()
            .filter_map(|(c, g)| g.map(|g| c - g))
            .collect();
        FrameOverhead {
            cpu_wall_ms: Spread::of(&cpu),
            gpu_ms: Spread::of(&gpu),
            cpu_minus_gpu_ms: Spread::of(&gap),
        }
    }
}

#[derive(Clone, Debug, serde::Serialize)]
struct RaymarchReport {
    gpu_ms: Spread,
    cpu_wall_ms: Spread,
    /// Per-frame CPU wall minus GPU time of the timed frames (no readback).
    cpu_minus_gpu_ms: Spread,
    /// The same orbit with each frame copied back to the host, measured separately.
    with_readback: FrameOverhead,
    fps_from_gpu_median: f64,
    samples_per_frame: Spread,
    classified_per_frame: Spread,
    samples_per_second: f64,
    pass: PassReport,
    /// Empty-space skipping of the scene (None when it does not apply: MIP, MinIP, or off).
    skipping: Option<SkippingReport>,
}

/// What empty-space skipping could do for this volume and scene.
#[derive(Clone, Debug, serde::Serialize)]
struct SkippingReport {
    /// Whether the frames skipped (only when few enough bricks can be visible).
    used: bool,
    /// Fraction of the 8^3 bricks a visible tissue window can reach.
    occupied_fraction: f64,
    /// Bricks in the volume.
    bricks: usize,
}

#[derive(serde::Serialize)]
struct BenchReport<'a> {
    engine: String,
    device: String,
    driver: String,
    device_type: &'static str,
    subgroup_size: u32,
    input: &'a str,
    dims: [u32; 3],
    sample_kind: crate::volume::SampleKind,
    image: [u32; 2],
    frames: u32,
    repeat: u32,
    scene: &'a super::args::SceneArgs,
    open_ms: SessionTimings,
    measured_copy_gb_per_s: Option<f64>,
    documented_device: Option<DeviceModel>,
    projection_device: DeviceModel,
    passes: Vec<PassReport>,
    raymarch: RaymarchReport,
    /// The plan that ran (passes, variants, allocations, degradations).
    plan: &'a Plan,
    /// Whether the per-pass study measured every variant (false under a budget or bricking:
    /// then only the planned passes ran, to stay within the plan's memory).
    full_study: bool,
    /// Live allocations after the frames, from the memory ledger.
    held_bytes_while_rendering: u64,
    /// Submissions' command pools, fences, query pools and breadcrumb buffers created and
    /// reused over the whole run (per-queue reuse: `gpu/recycler.rs`).
    recycler: crate::gpu::RecyclerCounts,
    /// The device profile applied, if any.
    device_profile: Option<crate::gpu::DeviceProfile>,
    /// Workgroup and subgroup choices of the tunable kernels.
    tuning: crate::gpu::KernelTuning,
    /// Valid timestamp bits after the profile's clamp.
    timestamp_valid_bits: u32,
    /// How this process's pipeline cache was set up.
    pipeline_cache: crate::gpu::CacheLoad,
    /// Time to first pixel over fresh processes (None with `--trials 0`).
    ttfp: Option<super::ttfp::TtfpReport>,
    /// The loader's repairs and warnings about the input.
    warnings: Vec<String>,
}

fn pass_report(
    name: &str,
    times: &[f64],
    cost: PassCost,
    copy: Option<f64>,
    documented: Option<DeviceModel>,
) -> PassReport {
    let gpu_ms = Spread::of(times);
    let seconds = (gpu_ms.median * 1e-3).max(1e-12);
    let achieved_gb_per_s = cost.bytes() / seconds / 1e9;
    let achieved_gtexel_per_s = cost.texel_units() / seconds / 1e9;
    let (bw_bound, tex_bound) = (
        cost.bytes() / XE_LP.bandwidth,
        cost.texel_units() / XE_LP.texel_rate,
    );
    PassReport {
        name: name.to_string(),
        gpu_ms,
        cost,
        achieved_gb_per_s,
        fraction_of_measured_copy: copy.map(|c| achieved_gb_per_s * 1e9 / c),
        achieved_gtexel_per_s,
        fraction_of_documented_texel_rate: documented
            .map(|d| achieved_gtexel_per_s * 1e9 / d.texel_rate),
        xe_lp_model_ms: bw_bound.max(tex_bound) * 1e3,
        xe_lp_bound: if bw_bound >= tex_bound {
            "bandwidth"
        } else {
            "texel rate"
        },
    }
}

fn times_of(timings: &[crate::gpu::PassTiming], name: &str) -> Option<f64> {
    timings.iter().find(|t| t.name == name).map(|t| t.gpu_ms)
}

/// Removes the bench's temporary input when dropped (also on errors).
struct TemporaryInput(Option<std::path::PathBuf>);

impl Drop for TemporaryInput {
    fn drop(&mut self) {
        if let Some(dir) = &self.0 {
            let _ = std::fs::remove_dir_all(dir);
        }
    }
}

/// The bench's input: the given file, or the phantom written as .nii.gz (libdeflate's default
/// level) into a temporary directory, so reading and inflating are real work as for a user's
/// file.
fn bench_input(args: &BenchArgs) -> Result<(std::path::PathBuf, String, TemporaryInput), Error> {
    if let Some(file) = &args.file {
        let label = file
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| file.display().to_string());
        return Ok((file.clone(), label, TemporaryInput(None)));
    }
    let dir = std::env::temp_dir().join(format!("morphray-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|source| Error::Write {
        path: dir.display().to_string(),
        source,
    })?;
    let guard = TemporaryInput(Some(dir.clone()));
    let path = dir.join("phantom.nii.gz");
    let phantom =
        crate::volume::phantom::generate(&crate::volume::phantom::PhantomSpec::cohort_a())?;
    crate::volume::nifti::write_nifti1(&phantom.volume, &path, true)?;
    Ok((path, "phantom (written as .nii.gz)".into(), guard))
}

/// Runs the command.
pub fn run(args: &BenchArgs, global: &super::GlobalOptions) -> Result<(), Error> {
    if args.ttfp_child {
        return super::ttfp::run_child(args, global);
    }
    let validation = global.validation;
    if args.frames == 0 || args.repeat == 0 {
        return Err(Error::Usage(
            "--frames and --repeat must be at least 1".into(),
        ));
    }
    // The plan is made for the image the bench renders (1920x1080 unless --size says otherwise).
    let (width, height) = args.scene.size.unwrap_or((1920, 1080));
    let mut scene_args = args.scene.clone();
    scene_args.size = Some((width, height));
    // Before the minutes of measuring: a report that cannot be written fails now.
    if let Some(path) = &args.json {
        let inputs: Vec<&std::path::Path> = args.file.iter().map(|p| p.as_path()).collect();
        check_output(path, OutputKind::Json, &inputs, false)?;
    }
    let (input, input_label, _temporary) = bench_input(args)?;
    // Before this process opens a device of its own, so the trials have the machine to
    // themselves.
    let ttfp = if args.trials > 0 {
        say(&format!(
            "bench: time to first pixel, {} cold and {} warm processes",
            args.trials, args.trials
        ));
        Some(super::ttfp::run_trials(args, &input, args.file.is_none())?)
    } else {
        None
    };
    let mut opened = session::open(
        std::slice::from_ref(&input),
        args.frame,
        false,
        global.engine_config(),
        Some(&scene_args),
        true,
    )?;
    print_warnings(&opened.source.volume.warnings);
    let scene = opened.scene;
    let adapter = opened.engine.device().adapter().clone();
    let documented = adapter.name.contains("H100").then_some(H100);
    let volume = &opened.source.volume;
    let voxels = volume.voxel_count() as f64;
    let sample_bytes = volume.samples.as_bytes().len() as f64;
    let raw_f32 = volume.samples.kind() == crate::volume::SampleKind::F32;

    // The ceiling: a device-local copy kernel, sized to the device (CPU devices copy slowly).
    // GPUs idle at low clocks (the H100 showed 390 MHz before a run and 1980 MHz after it), so
    // copies run for at least half a second before anything is measured.
    let probe_bytes: u64 = if adapter.type_name() == "cpu" {
        32 << 20
    } else {
        1 << 30
    };
    let warm_up = Instant::now();
    while warm_up.elapsed().as_secs_f64() < 0.5 {
        opened.engine.copy_bandwidth(probe_bytes, 1)?;
    }
    let copy = opened.engine.copy_bandwidth(probe_bytes, 9)?;

    // The full study repeats every analysis pass and derivative variant, each holding its own
    // outputs for a moment; under a budget or bricking only what the plan runs is measured.
    let bricked = matches!(opened.plan.layout, Layout::Bricked { .. });
    let full_study = global.memory_budget.is_none() && !bricked;
    let normalized_bytes = crate::engine::plan::texel_bytes(opened.plan.normalized_format) as f64;
    let mut passes = Vec::new();
    say(&format!(
        "bench: analysis and derivative passes, {} repeats each",
        args.repeat
    ));
    if !bricked {
        let (mut minmax, mut normalize, mut histogram) = (Vec::new(), Vec::new(), Vec::new());
        let mut record = |timings: &[crate::gpu::PassTiming]| {
            minmax.extend(times_of(timings, "minmax"));
            normalize.extend(times_of(timings, "normalize"));
            histogram.extend(times_of(timings, "histogram"));
        };
        if full_study {
            for _ in 0..args.repeat {
                record(&opened.engine.prepare(volume)?.gpu_timings);
            }
        } else {
            record(&opened.twin.prepared.gpu_timings);
        }
        passes.extend([
            pass_report(
                "minmax",
                &minmax,
                cost::minmax(sample_bytes),
                copy,
                documented,
            ),
            pass_report(
                "normalize",
                &normalize,
                cost::normalize(sample_bytes, voxels, normalized_bytes),
                copy,
                documented,
            ),
            pass_report(
                "histogram",
                &histogram,
                cost::histogram(voxels, normalized_bytes, raw_f32),
                copy,
                documented,
            ),
        ]);
    }
    // --denoise ran once, on the way to the first frame: that one measurement.
    if let Some(ms) = times_of(&opened.twin.prepared.gpu_timings, "denoise") {
        let c = cost::denoise(voxels, normalized_bytes);
        passes.push(pass_report("denoise", &[ms], c, copy, documented));
    }

    // Derived volumes (every derivative variant, or the planned one) and the vesselness.
    let rates = derived::Rates {
        copy,
        documented,
        normalized_bytes,
        repeat: args.repeat,
    };
    passes.extend(derived::reports(
        &mut opened.engine,
        &opened.twin.prepared,
        &scene.effects,
        full_study,
        &rates,
    )?);

    // The brick-bounds pass (issue 17 item 2): it runs when the classification changes, never
    // per frame, so it is timed on its own, `--repeat` times.
    if scene.effects.mode == RenderMode::Dvr && scene.effects.quality.empty_space_skipping {
        let ranges = opened.engine.brick_ranges(&opened.twin.prepared)?;
        let (mut times, mut distance_times) = (Vec::new(), Vec::new());
        for _ in 0..args.repeat {
            let b = opened
                .engine
                .brick_bounds(&ranges, &scene.classification, None, None)?;
            times.extend(times_of(&b.timings, "brick bounds"));
            distance_times.extend(times_of(&b.timings, "brick distance"));
        }
        let bricks = ranges.ranges.len() as f64;
        let c = PassCost {
            bytes_read: 8.0 * bricks,
            bytes_written: 4.0 * bricks + bricks / 8.0,
            ..Default::default()
        };
        passes.push(pass_report("brick bounds", &times, c, copy, documented));
        // Each scan reads at most its whole line per brick (a word of bits or bytes each).
        let line_words: f64 = ranges.grid.iter().map(|&n| f64::from(n)).sum();
        let c = PassCost {
            bytes_read: 4.0 * bricks * line_words,
            bytes_written: 3.0 * bricks,
            ..Default::default()
        };
        passes.push(pass_report(
            "brick distance",
            &distance_times,
            c,
            copy,
            documented,
        ));
    }

    // Raymarch over an orbit: warm-up, timed frames without readback, then counted frames.
    let mut target = opened
        .engine
        .render_target(width, height, vk::Format::R8G8B8A8_UNORM)?;
    target.read_back = false;
    let frame_scene = |i: u32| {
        let mut s = scene;
        s.camera.azimuth_deg = args.scene.azimuth + 360.0 * i as f64 / args.frames as f64;
        s.frame = i;
        s
    };
    say(&format!(
        "bench: orbit of {} frames at {width}x{height}, three times (timed, read back, counted)",
        args.frames
    ));
    for i in 0..3 {
        opened
            .engine
            .render_twin(&mut target, &mut opened.twin, &frame_scene(i))?;
    }
    let mut timed = Vec::new();
    let mut skipped = false;
    for i in 0..args.frames {
        let start = Instant::now();
        let frame = opened
            .engine
            .render_twin(&mut target, &mut opened.twin, &frame_scene(i))?;
        let cpu = start.elapsed().as_secs_f64() * 1e3;
        timed.push((cpu, times_of(&frame.gpu_timings, "raymarch")));
        skipped |= frame.skipped_empty_space;
    }
    let skipping =
        if scene.effects.mode == RenderMode::Dvr && scene.effects.quality.empty_space_skipping {
            let ranges = opened.engine.brick_ranges(&opened.twin.prepared)?;
            // With a brain mask in use the tissues show only where it reaches (render.rs).
            let brain = opened.twin.derived().and_then(|d| d.brain.as_ref());
            let ranges = match brain {
                Some(b) if b.used && !scene.classification.head.visible => b.ranges_inside(&ranges),
                _ => ranges,
            };
            Some(SkippingReport {
                used: skipped,
                occupied_fraction: ranges.occupied_fraction(&scene.classification),
                bricks: ranges.ranges.len(),
            })
        } else {
            None
        };
    let overhead = FrameOverhead::of(&timed);
    let gpu: Vec<f64> = timed.iter().filter_map(|f| f.1).collect();
    // The same frames read back, separately: the copy and the host read are not part of the
    // no-readback gap.
    target.read_back = true;
    let mut read_back = Vec::new();
    for i in 0..args.frames {
        let start = Instant::now();
        let frame = opened
            .engine
            .render_twin(&mut target, &mut opened.twin, &frame_scene(i))?;
        let cpu = start.elapsed().as_secs_f64() * 1e3;
        read_back.push((cpu, times_of(&frame.gpu_timings, "raymarch")));
    }
    target.read_back = false;
    target.count_samples = true;
    let (mut marched, mut classified) = (Vec::new(), Vec::new());
    for i in 0..args.frames {
        let frame = opened
            .engine
            .render_twin(&mut target, &mut opened.twin, &frame_scene(i))?;
        if let Some(s) = frame.samples {
            marched.push(s.marched as f64);
            classified.push(s.classified as f64);
        }
    }
    let gpu_ms = Spread::of(&gpu);
    let samples = Spread::of(&marched);
    let classified_spread = Spread::of(&classified);
    let per_classified = match (scene.effects.mode, scene.effects.gradient_source) {
        (RenderMode::Dvr, GradientSource::Precomputed) => 1.0 + scene.effects.shading as u32 as f64,
        (RenderMode::Dvr, GradientSource::OnTheFly) => {
            if scene.effects.curvature {
                19.0
            } else {
                6.0
            }
        }
        _ => 0.0,
    };
    let raymarch_cost = cost::raymarch(
        width as f64 * height as f64,
        samples.median,
        classified_spread.median,
        per_classified,
    );
    let raymarch_pass = pass_report("raymarch", &gpu, raymarch_cost, copy, documented);
    let raymarch = RaymarchReport {
        gpu_ms,
        cpu_wall_ms: overhead.cpu_wall_ms,
        cpu_minus_gpu_ms: overhead.cpu_minus_gpu_ms,
        with_readback: FrameOverhead::of(&read_back),
        fps_from_gpu_median: 1e3 / gpu_ms.median.max(1e-9),
        samples_per_frame: samples,
        classified_per_frame: classified_spread,
        samples_per_second: samples.median / (gpu_ms.median * 1e-3).max(1e-12),
        pass: raymarch_pass,
        skipping,
    };
    if validation {
        session::check_validation(&opened.engine)?;
    }
    session::persist_pipeline_cache(&opened.engine);
    let report = BenchReport {
        engine: format!("morphray {}", env!("CARGO_PKG_VERSION")),
        device: adapter.name.clone(),
        driver: adapter.driver.clone(),
        device_type: adapter.type_name(),
        subgroup_size: adapter.subgroup_size,
        input: &input_label,
        dims: opened.twin.prepared.dims,
        sample_kind: volume.samples.kind(),
        image: [width, height],
        frames: args.frames,
        repeat: args.repeat,
        scene: &args.scene,
        open_ms: opened.timings.clone(),
        measured_copy_gb_per_s: copy.map(|c| c / 1e9),
        documented_device: documented,
        projection_device: XE_LP,
        passes,
        raymarch,
        plan: &opened.plan,
        full_study,
        held_bytes_while_rendering: opened.engine.device().ledger().total_bytes(),
        recycler: opened.engine.device().recycler_counts(),
        device_profile: opened.engine.device().profile().cloned(),
        tuning: opened.engine.device().tuning().clone(),
        timestamp_valid_bits: adapter.timestamp_valid_bits,
        pipeline_cache: opened.engine.pipeline_cache().load().clone(),
        ttfp,
        warnings: opened.source.volume.warnings.clone(),
    };
    if let Some(path) = &args.json {
        write_file(path, json(&report).as_bytes())?;
    }
    print_text(&report);
    Ok(())
}

fn print_text(r: &BenchReport<'_>) {
    let [x, y, z] = r.dims;
    print_line(&format!(
        "{} on {} ({}, subgroup {})",
        r.engine, r.device, r.driver, r.subgroup_size
    ));
    print_line(&format!(
        "input {} {x}x{y}x{z} {:?}; image {}x{}; {} frames; {} repeats",
        r.input, r.sample_kind, r.image[0], r.image[1], r.frames, r.repeat
    ));
    if let Some(c) = r.measured_copy_gb_per_s {
        print_line(&format!("measured device copy: {c:.1} GB/s (read + write)"));
    }
    let mib = |b: u64| b as f64 / (1u64 << 20) as f64;
    if let Some(p) = &r.device_profile {
        print_line(&format!("device profile {}: {}", p.name, p.description));
    }
    if !r.tuning.workgroups.is_empty() || r.tuning.subgroup_size.is_some() {
        print_line(&format!("kernel tuning: {:?}", r.tuning));
    }
    print_line(&format!(
        "plan: {} layout, I_norm {:?}; planned {:.1} MiB held, {:.1} MiB at the preparation peak; ledger while rendering {:.1} MiB",
        match r.plan.layout {
            Layout::Whole => "whole",
            Layout::Bricked { .. } => "bricked",
        },
        r.plan.normalized_format,
        mib(r.plan.total_bytes),
        mib(r.plan.peak_bytes),
        mib(r.held_bytes_while_rendering)
    ));
    for d in &r.plan.degradations {
        print_line(&format!(
            "degradation: {} (accuracy setting \"{}\": {}; ACCURACY.md)",
            d.what, d.accuracy_setting, d.accuracy_cost
        ));
    }
    if !r.full_study {
        print_line("budget or bricking: only the planned passes were measured");
    }
    print_line(
        "pass                        median ms    p5..p95 ms          MB moved   GB/s   of copy  Gtexel/s  Xe-LP model ms (bound)",
    );
    for p in r.passes.iter().chain(std::iter::once(&r.raymarch.pass)) {
        print_line(&format!(
            "{:<27} {:>10.4}  {:>8.4}..{:<8.4}  {:>9.1}  {:>6.1}  {:>7}  {:>8.1}  {:>8.3} ({})",
            p.name,
            p.gpu_ms.median,
            p.gpu_ms.p5,
            p.gpu_ms.p95,
            p.cost.bytes() / 1e6,
            p.achieved_gb_per_s,
            p.fraction_of_measured_copy
                .map(|f| format!("{:.0}%", f * 100.0))
                .unwrap_or_else(|| "-".into()),
            p.achieved_gtexel_per_s,
            p.xe_lp_model_ms,
            p.xe_lp_bound
        ));
    }
    let rm = &r.raymarch;
    print_line(&format!(
        "raymarch: {:.3} ms GPU median ({:.0} FPS), CPU wall {:.3} ms median; {:.1} M samples/frame ({:.1} M classified), {:.1} G samples/s",
        rm.gpu_ms.median,
        rm.fps_from_gpu_median,
        rm.cpu_wall_ms.median,
        rm.samples_per_frame.median / 1e6,
        rm.classified_per_frame.median / 1e6,
        rm.samples_per_second / 1e9
    ));
    if let Some(k) = &rm.skipping {
        print_line(&format!(
            "empty-space skipping: {}; {:.1} % of the {} 8^3 bricks can hold a visible sample{}",
            if k.used { "used" } else { "not used" },
            100.0 * k.occupied_fraction,
            k.bricks,
            if k.used {
                String::new()
            } else {
                format!(
                    " (skipping is used at or below {:.0} %)",
                    100.0 * crate::engine::MAX_OCCUPANCY_FOR_SKIPPING
                )
            }
        ));
    }
    let rb = &rm.with_readback;
    print_line(&format!(
        "frame overhead (CPU wall - GPU, per frame): {:.3} ms median ({:.3}..{:.3}) without readback; with readback {:.3} ms ({:.3}..{:.3}), CPU wall {:.3} ms",
        rm.cpu_minus_gpu_ms.median,
        rm.cpu_minus_gpu_ms.p5,
        rm.cpu_minus_gpu_ms.p95,
        rb.cpu_minus_gpu_ms.median,
        rb.cpu_minus_gpu_ms.p5,
        rb.cpu_minus_gpu_ms.p95,
        rb.cpu_wall_ms.median
    ));
    if let (Some(d), Some(f)) = (
        &r.documented_device,
        rm.pass.fraction_of_documented_texel_rate,
    ) {
        print_line(&format!(
            "raymarch texel rate: {:.0}% of {}'s documented {:.0} GTexel/s (trilinear = 2 texels)",
            f * 100.0,
            d.name,
            d.texel_rate / 1e9
        ));
    }
    if let Some(t) = &r.ttfp {
        super::ttfp::print_text(t);
    }
    print_line(&format!(
        "first pixel path of this process (host): load {:.1} ms | device {:.1} ms | pipelines {:.1} ms | prepare {:.1} ms | wall {:.1} ms",
        r.open_ms.load.read_ms
            + r.open_ms.load.inflate_ms
            + r.open_ms.load.convert_ms
            + r.open_ms.load.phantom_ms,
        r.open_ms.device_ms,
        r.open_ms.pipelines_ms,
        r.open_ms.prepare_ms,
        r.open_ms.wall_ms
    ));
}
