//! `morphray accuracy`: what accuracy costs in time. Every quality knob is rendered on a fixed
//! set of views and compared with the f64 CPU reference; each setting gets its GPU time per frame
//! and its error, the Pareto frontier is marked, and defaults are recommended per device class.
//!
//! Method:
//! - Truth is the f64 pipeline end to end: I_norm from the normalization twin, derivatives from
//!   the derivative twin, the reference raymarcher at a step of 0.125 voxel with trilinear
//!   sampling, exact opacity correction and no early termination. One reference image per view
//!   and scene definition (curvature off; on; the stills' studio lighting with depth cues),
//!   computed once and reused by every setting.
//! - Each setting changes one knob from the render/view default within a group
//!   (`accuracy_settings::Group`): the curvature knobs are compared with the curvature-on
//!   reference, the lighting settings with the lit one, everything else with the curvature-off
//!   one, and the frontier is computed within each group, counting differences below the
//!   measurement resolution as ties: 1 % in error; in time 5 %, or the two settings' spreads
//!   (half their rounds' 10th..90th percentile range) together when that is larger.
//! - Time is the median over `--frames` rounds of the mean GPU raymarch time (timestamps) of the
//!   views, rendered as RGBA8 at `--time-size` (errors are measured at `--size`),
//!   after two warm-up frames (lavapipe compiles a pipeline at its first dispatch); each round
//!   renders every setting once, so load from other processes falls on all settings alike; jitter
//!   advances per round like real rendering; the error is measured on frame 0, whose
//!   jitter pattern the reference shares. Precomputation (derived volumes) is reported apart.
//! - Stability: the images cannot show the naive opacity correction's failure (per-sample
//!   opacities below about 1e-6), so the study also runs the compositing probe over NUMERICS.md's
//!   (a, r) grid on the device; a setting whose formula is off by more than 0.1 % there is kept
//!   off the frontier, with the measured reason.
//! - Interpolation other than trilinear is compared with the trilinear reference: for the cubic
//!   B-spline the error includes its intended smoothing.
//! - Devices measured are one class each; the integrated class is projected from the counted
//!   samples onto an Intel Xe-LP (passes/cost.rs), labelled as a model.

use super::accuracy_report::{AccuracyReport, Recommendation, SettingResult, print_table};
use super::accuracy_settings::{Group, settings};
use super::args::AccuracyArgs;
use super::output::{json, print_line, print_warnings};
use super::session;
use crate::error::Error;
use crate::files::write::{OutputKind, check_output, write_file};
use crate::passes::cost::XE_LP;
use crate::passes::raymarch::RaymarchVariant;
use crate::reference::derivatives::{DEFAULT_TAU, IndexToWorld, voxel_derivatives};
use crate::reference::raymarch::{ReferenceDerived, ReferenceRaymarch, ReferenceVolume};
use crate::scene::uniforms::GradientStats;
use crate::scene::{OpacityCorrection, Scene, VolumeGeometry};
use crate::study::metrics::{ImageError, compare};
use crate::study::pareto::{frontier_with_spread, frontier_within};
use crate::study::plot::{PlotError, PlotPoint, write_svg};
use crate::study::stability::{UNSTABLE_RELATIVE_ERROR, opacity_grid, worst_errors};
use ash::vk;

/// The views every setting is rendered from: (azimuth, elevation) in degrees.
const VIEWS: [(f64, f64); 3] = [(30.0, 20.0), (120.0, -10.0), (250.0, 60.0)];

/// Time differences below 5 % are within the spread of repeated GPU timings (bench's p5..p95 on
/// the H100 spans about 3 %) and count as ties on the frontier; so do error differences below 1 %.
const TIME_TOLERANCE: f64 = 0.05;
/// See [`TIME_TOLERANCE`].
const ERROR_TOLERANCE: f64 = 0.01;

/// The interaction recommendation is the fastest frontier setting at or above this PSNR: about
/// where differences stop being visible on an 8-bit display (whose own quantization is ~48 dB).
const INTERACTION_PSNR_DB: f64 = 40.0;

/// Untimed frames per setting before timing: lavapipe compiles a pipeline at its first dispatch.
const WARM_UP_FRAMES: u32 = 2;

/// The reference's step in voxels.
const REFERENCE_STEP: f64 = 0.125;

/// The f64 derived volumes of the whole pipeline's truth: |g|, k and unit normals per voxel.
fn reference_derived(
    norm: &[f64],
    dims: [usize; 3],
    to_world: &IndexToWorld,
) -> (Vec<f64>, Vec<f64>, Vec<[f64; 3]>, f64) {
    let n = norm.len();
    let threads = std::thread::available_parallelism()
        .map(|t| t.get())
        .unwrap_or(1)
        .max(1);
    let slab = n.div_ceil(threads).max(1);
    let mut magnitude = vec![0.0; n];
    let mut curvature = vec![0.0; n];
    let mut normals = vec![[0.0; 3]; n];
    std::thread::scope(|scope| {
        for ((m, k), (nrm, start)) in magnitude
            .chunks_mut(slab)
            .zip(curvature.chunks_mut(slab))
            .zip(normals.chunks_mut(slab).zip((0..n).step_by(slab)))
        {
            scope.spawn(move || {
                for i in 0..m.len() {
                    let index = start + i;
                    let p = [
                        index % dims[0],
                        (index / dims[0]) % dims[1],
                        index / (dims[0] * dims[1]),
                    ];
                    if let Ok(d) = voxel_derivatives(norm, dims, to_world, p, DEFAULT_TAU) {
                        m[i] = d.gradient_magnitude;
                        k[i] = d.curvature;
                        if d.gradient_magnitude > DEFAULT_TAU {
                            nrm[i] = d.gradient.map(|c| c / d.gradient_magnitude);
                        }
                    }
                }
            });
        }
    });
    let max = magnitude.iter().cloned().fold(0.0, f64::max);
    (magnitude, curvature, normals, max)
}

/// Renders the reference image of one view on every core.
fn reference_image(r: &ReferenceRaymarch<'_>, width: u32, height: u32) -> Vec<[f64; 4]> {
    let threads = std::thread::available_parallelism()
        .map(|t| t.get())
        .unwrap_or(1)
        .max(1) as u32;
    let mut rows: Vec<Vec<[f64; 4]>> = vec![Vec::new(); height as usize];
    std::thread::scope(|scope| {
        let chunks: Vec<_> = rows
            .chunks_mut((height.div_ceil(threads)).max(1) as usize)
            .collect();
        let mut first = 0u32;
        for chunk in chunks {
            let start = first;
            first += chunk.len() as u32;
            scope.spawn(move || {
                for (i, row) in chunk.iter_mut().enumerate() {
                    let y = start + i as u32;
                    *row = (0..width).map(|x| r.pixel(x, y)).collect();
                }
            });
        }
    });
    rows.into_iter().flatten().collect()
}

/// A typical round-to-round time spread above this means the timings measured contention, not
/// the settings (a quiet H100 shows about 1 %, a quiet lavapipe under 10 %).
pub(super) const NOISY_TIME_SPREAD: f64 = 0.15;

/// Median and relative half-width of the 10th..90th percentile range of `values`.
fn median_and_spread(values: &mut [f64]) -> (f64, f64) {
    if values.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    values.sort_by(f64::total_cmp);
    let at = |q: f64| values[((values.len() - 1) as f64 * q).round() as usize];
    let median = at(0.5);
    (median, (at(0.9) - at(0.1)) / (2.0 * median.max(1e-12)))
}

/// `accuracy --vessels`: the vesselness and denoising knobs (`study::vessels`).
fn vessel_study(args: &AccuracyArgs, global: &super::GlobalOptions) -> Result<(), Error> {
    let mut engine = crate::engine::Engine::new(global.engine_config())?;
    let study = crate::study::vessels::run(&mut engine, args.frames as usize)?;
    if global.validation {
        session::check_validation(&engine)?;
    }
    print_line(&crate::study::vessels::table(&study));
    Ok(())
}

/// Runs the command.
pub fn run(args: &AccuracyArgs, global: &super::GlobalOptions) -> Result<(), Error> {
    let validation = global.validation;
    if args.frames == 0 || args.views == 0 || args.views > VIEWS.len() {
        return Err(Error::Usage(format!(
            "--frames must be >= 1 and --views 1..={}",
            VIEWS.len()
        )));
    }
    if args.vessels {
        return vessel_study(args, global);
    }
    if args.scene.denoise != crate::passes::denoise::Denoise::None {
        // The f64 reference renders the volume as read: the error would be the filter's.
        return Err(Error::Usage(
            "accuracy measures the pipeline against its f64 twin on the volume as read: run it \
             without --denoise (the filters' own accuracy: accuracy --vessels)"
                .into(),
        ));
    }
    let (width, height) = args.scene.size.unwrap_or((256, 256));
    let time_size = args.time_size.unwrap_or((width, height));
    let mut scene_args = args.scene.clone();
    scene_args.size = Some((width, height));
    // Before the study: outputs that cannot be written fail now, not after it.
    let inputs: Vec<&std::path::Path> = args.file.iter().map(|p| p.as_path()).collect();
    if let Some(path) = &args.json {
        check_output(path, OutputKind::Json, &inputs, false)?;
    }
    if let Some(path) = &args.plot {
        check_output(path, OutputKind::Svg, &inputs, false)?;
    }
    let mut opened = session::open(
        args.file.as_slice(),
        args.frame,
        false,
        global.engine_config(),
        Some(&scene_args),
        true,
    )?;
    print_warnings(&opened.source.volume.warnings);
    let base = opened.scene;
    let views = &VIEWS[..args.views];
    let volume = opened.source.volume.clone();
    let dims = opened.twin.prepared.dims;
    let dims_usize = volume.dims;
    let geometry = VolumeGeometry::new(dims, volume.orientation.affine)
        .map_err(|e| Error::Usage(e.to_string()))?;
    eprintln!(
        "accuracy: computing the f64 reference (normalization, derivatives, {} views x {} definitions)",
        views.len(),
        Group::ALL.len()
    );

    // Truth: f64 end to end.
    let (imin, imax) = (opened.report.imin, opened.report.imax);
    let norm =
        crate::reference::normalize::normalize(&volume.samples, volume.to_physical, imin, imax);
    let to_world = IndexToWorld::new(volume.orientation.linear_part())
        .map_err(|e| Error::Usage(e.to_string()))?;
    let (magnitude, curvature, normals, gmax) = reference_derived(&norm, dims_usize, &to_world);
    let ref_volume = ReferenceVolume::new(dims, &norm).map_err(|e| Error::Usage(e.to_string()))?;
    let ref_derived = ReferenceDerived {
        gradient_magnitude: Some(&magnitude),
        curvature: Some(&curvature),
        normals: Some(&normals),
    };
    let stats = GradientStats {
        max_magnitude: gmax,
        tau: DEFAULT_TAU,
    };
    let mut references: [Vec<Vec<[f64; 4]>>; Group::ALL.len()] = Default::default();
    for (group, definition) in Group::ALL.into_iter().enumerate() {
        for &(azimuth, elevation) in views {
            let mut scene = base;
            definition.define(&mut scene);
            scene.camera.azimuth_deg = azimuth;
            scene.camera.elevation_deg = elevation;
            scene.step_voxels = REFERENCE_STEP;
            scene.early_termination = 2.0;
            scene.frame = 0;
            let r = ReferenceRaymarch::new(
                &scene,
                &geometry,
                &stats,
                &ref_volume,
                &ref_derived,
                width,
                height,
            )
            .map_err(|e| Error::Usage(e.to_string()))?;
            references[group].push(reference_image(&r, width, height));
        }
    }

    // Every setting on the GPU. Phase 1: resources, error on frame 0, sample counts, warm-up.
    let all = settings();
    let mut prepared_by_format: Vec<(vk::Format, crate::engine::PreparedVolume)> = Vec::new();
    struct Live {
        scene: Scene,
        format: usize,
        derived: Option<crate::engine::Derived>,
        target: crate::engine::RenderTarget,
        times: Vec<f64>,
    }
    let mut live: Vec<Option<Live>> = Vec::new();
    let mut results = Vec::new();
    for (index, setting) in all.iter().enumerate() {
        eprintln!("accuracy: [{}/{}] {}", index + 1, all.len(), setting.name);
        let group = setting.group as usize;
        let group_name = setting.group.name();
        let mut scene = base;
        setting.group.define(&mut scene);
        (setting.edit)(&mut scene);
        let mut result = SettingResult {
            name: setting.name,
            knob: setting.knob,
            group: group_name,
            gpu_ms: f64::NAN,
            time_spread: f64::NAN,
            precompute_ms: f64::NAN,
            error: ImageError::default(),
            samples_per_frame: f64::NAN,
            xe_lp_model_ms: f64::NAN,
            frontier: false,
            xe_lp_frontier: false,
            default: setting.name == "default",
            skipped: None,
            unstable: None,
            naive_opacity: scene.effects.quality.opacity_correction == OpacityCorrection::Naive,
        };
        let format = match prepared_by_format
            .iter()
            .position(|(f, _)| *f == setting.format)
        {
            Some(k) => k,
            None => {
                if let Err(e) = opened.engine.set_normalized_format(setting.format) {
                    result.skipped = Some(e.to_string());
                    results.push(result);
                    live.push(None);
                    continue;
                }
                let prepared = opened.engine.prepare(&volume)?;
                prepared_by_format.push((setting.format, prepared));
                prepared_by_format.len() - 1
            }
        };
        let prepared = &prepared_by_format[format].1;
        let derived = match scene.effects.derivative_outputs() {
            Some(outputs) => Some(opened.engine.derive(prepared, outputs)?),
            None => None,
        };
        result.precompute_ms = derived
            .as_ref()
            .map_or(0.0, |d| d.gpu_timings.iter().map(|t| t.gpu_ms).sum());
        let mut target =
            opened
                .engine
                .render_target(width, height, vk::Format::R32G32B32A32_SFLOAT)?;
        let mut timing =
            opened
                .engine
                .render_target(time_size.0, time_size.1, vk::Format::R8G8B8A8_UNORM)?;
        timing.read_back = false;
        timing.count_samples = true;
        let (mut sq_sum, mut max_abs, mut ssim, mut samples) = (0.0, 0.0f64, 0.0, Vec::new());
        for (v, &(azimuth, elevation)) in views.iter().enumerate() {
            let mut view = scene;
            view.camera.azimuth_deg = azimuth;
            view.camera.elevation_deg = elevation;
            view.frame = 0;
            target.read_back = true;
            target.count_samples = false;
            let frame = opened
                .engine
                .render(&mut target, prepared, derived.as_ref(), &view)?;
            let image: Vec<[f64; 4]> = frame
                .values
                .chunks_exact(4)
                .map(|c| [c[0] as f64, c[1] as f64, c[2] as f64, 1.0])
                .collect();
            let e = compare(
                &image,
                &references[group][v],
                width as usize,
                height as usize,
            );
            sq_sum += e.rmse * e.rmse;
            max_abs = max_abs.max(e.max_abs);
            ssim += e.ssim;
            // Time and count samples where the timing happens: an RGBA8 target at --time-size.
            let counted = opened
                .engine
                .render(&mut timing, prepared, derived.as_ref(), &view)?;
            if let Some(c) = counted.samples {
                let variant = RaymarchVariant::of(&view.effects, false);
                let (per_marched, per_classified) = variant.fetches();
                samples.push((
                    c.marched as f64,
                    per_marched * c.marched as f64 + per_classified * c.classified as f64,
                ));
            }
        }
        timing.count_samples = false;
        for f in 0..WARM_UP_FRAMES {
            let mut warm = scene;
            warm.frame = f;
            opened
                .engine
                .render(&mut timing, prepared, derived.as_ref(), &warm)?;
        }
        let nviews = views.len() as f64;
        let rmse = (sq_sum / nviews).sqrt();
        let fetches = samples.iter().map(|s| s.1).sum::<f64>() / samples.len().max(1) as f64;
        result.error = ImageError {
            max_abs,
            rmse,
            psnr_db: if rmse > 0.0 {
                (20.0 * (1.0 / rmse).log10()).min(200.0)
            } else {
                200.0
            },
            ssim: ssim / nviews,
        };
        result.samples_per_frame =
            samples.iter().map(|s| s.0).sum::<f64>() / samples.len().max(1) as f64;
        result.xe_lp_model_ms = 2.0 * fetches / XE_LP.texel_rate * 1e3;
        results.push(result);
        live.push(Some(Live {
            scene,
            format,
            derived,
            target: timing,
            times: Vec::new(),
        }));
    }

    // Phase 2: timing rounds, every setting once per round, so load spikes from other
    // processes (this machine is shared) fall on all settings alike. GPUs idle at low clocks
    // (the H100 showed 345 MHz before a run), so the first setting renders for half a second
    // before anything is timed.
    if let Some(first) = live.iter_mut().flatten().next() {
        let prepared = &prepared_by_format[first.format].1;
        let warm_up = std::time::Instant::now();
        while warm_up.elapsed().as_secs_f64() < 0.5 {
            opened.engine.render(
                &mut first.target,
                prepared,
                first.derived.as_ref(),
                &first.scene,
            )?;
        }
    }
    eprintln!(
        "accuracy: timing {} rounds at {}x{}",
        args.frames, time_size.0, time_size.1
    );
    let mut progress = super::progress::Progress::new(u64::from(args.frames), "rounds");
    for round in 0..args.frames {
        progress.step();
        for slot in live.iter_mut().flatten() {
            let mut round_ms = 0.0;
            for &(azimuth, elevation) in views {
                let mut view = slot.scene;
                view.camera.azimuth_deg = azimuth;
                view.camera.elevation_deg = elevation;
                view.frame = round + 1;
                let prepared = &prepared_by_format[slot.format].1;
                let frame = opened.engine.render(
                    &mut slot.target,
                    prepared,
                    slot.derived.as_ref(),
                    &view,
                )?;
                round_ms += frame
                    .gpu_timings
                    .iter()
                    .filter(|t| t.name == "raymarch")
                    .map(|t| t.gpu_ms)
                    .sum::<f64>();
            }
            slot.times.push(round_ms / views.len() as f64);
        }
    }
    progress.finish();
    for (result, slot) in results.iter_mut().zip(live.iter_mut()) {
        if let Some(slot) = slot {
            (result.gpu_ms, result.time_spread) = median_and_spread(&mut slot.times);
        }
    }
    drop(live);
    drop(prepared_by_format);
    if opened.engine.normalized_format() != vk::Format::R16_UNORM {
        opened.engine.set_normalized_format(vk::Format::R16_UNORM)?;
    }

    // Numerical stability of the opacity-correction knob, on this device (see study/stability.rs):
    // a setting that fails it stays off the frontier, whatever its images show.
    let probe = crate::passes::compositing_probe::CompositingProbe::new(
        opened.engine.device(),
        opened.engine.pipeline_cache().raw(),
    )?;
    let grid = opacity_grid();
    let probed = probe.run(
        opened.engine.device(),
        crate::passes::compositing_probe::ProbeJob::OpacityCorrection,
        &grid,
    )?;
    let stability = worst_errors(&grid, &probed);
    for result in results.iter_mut() {
        let worst = if result.naive_opacity {
            stability.naive
        } else {
            stability.exact
        };
        if worst.relative > UNSTABLE_RELATIVE_ERROR {
            result.unstable = Some(format!(
                "opacity correction off by {:.0} % at a = {:e}, r = {} on this device (NUMERICS.md)",
                worst.relative * 100.0,
                worst.alpha,
                worst.ratio
            ));
        }
    }

    // Frontiers within each group, on measured and on projected time.
    for group in Group::ALL.map(Group::name) {
        let members: Vec<usize> = (0..results.len())
            .filter(|&i| {
                results[i].group == group
                    && results[i].skipped.is_none()
                    && results[i].unstable.is_none()
            })
            .collect();
        let measured: Vec<(f64, f64, f64)> = members
            .iter()
            .map(|&i| {
                let r = &results[i];
                (r.gpu_ms, r.time_spread, r.error.rmse)
            })
            .collect();
        for j in frontier_with_spread(&measured, TIME_TOLERANCE, ERROR_TOLERANCE) {
            results[members[j]].frontier = true;
        }
        let projected: Vec<(f64, f64)> = members
            .iter()
            .map(|&i| (results[i].xe_lp_model_ms, results[i].error.rmse))
            .collect();
        for j in frontier_within(&projected, TIME_TOLERANCE, ERROR_TOLERANCE) {
            results[members[j]].xe_lp_frontier = true;
        }
    }
    let default_on_frontier = results.iter().any(|r| r.default && r.frontier);
    let mut spreads: Vec<f64> = results
        .iter()
        .map(|r| r.time_spread)
        .filter(|s| s.is_finite())
        .collect();
    let (typical_time_spread, _) = median_and_spread(&mut spreads);
    let adapter = opened.engine.device().adapter().clone();
    let recommend = |class: String,
                     on_frontier: &dyn Fn(&SettingResult) -> bool,
                     time: &dyn Fn(&SettingResult) -> f64| {
        let candidates: Vec<&SettingResult> = results
            .iter()
            .filter(|r| r.group == "curvature off" && on_frontier(r))
            .collect();
        let interaction = candidates
            .iter()
            .filter(|r| r.error.psnr_db >= INTERACTION_PSNR_DB)
            .min_by(|a, b| time(a).total_cmp(&time(b)))
            .map(|r| r.name);
        let diagnosis = candidates
            .iter()
            .min_by(|a, b| a.error.rmse.total_cmp(&b.error.rmse))
            .map(|r| r.name);
        Recommendation {
            device_class: class,
            interaction,
            diagnosis,
            rule: "interaction: the fastest frontier setting with PSNR >= 40 dB; diagnosis: the frontier setting with the lowest error",
        }
    };
    let recommendations = vec![
        recommend(
            format!("{} ({}), measured", adapter.type_name(), adapter.name),
            &|r| r.frontier,
            &|r| r.gpu_ms,
        ),
        recommend(
            "integrated (Intel Xe-LP), model from counted samples".into(),
            &|r| r.xe_lp_frontier,
            &|r| r.xe_lp_model_ms,
        ),
    ];
    let report = AccuracyReport {
        engine: format!("morphray {}", env!("CARGO_PKG_VERSION")),
        device: adapter.name.clone(),
        device_type: adapter.type_name(),
        input: &opened.source.label,
        dims,
        image: [width, height],
        time_image: [time_size.0, time_size.1],
        views: views.to_vec(),
        frames: args.frames,
        reference: "f64 pipeline: normalization and derivative twins, reference raymarcher at step 0.125, trilinear, exact opacity correction, no early termination",
        settings: results,
        default_on_frontier,
        typical_time_spread,
        opacity_stability: stability,
        recommendations,
        warnings: opened.source.volume.warnings.clone(),
    };
    if let Some(path) = &args.json {
        write_file(path, json(&report).as_bytes())?;
    }
    if let Some(path) = &args.plot {
        let points: Vec<PlotPoint> = report
            .settings
            .iter()
            .filter(|r| r.group == "curvature off" && r.skipped.is_none())
            .map(|r| PlotPoint {
                label: r.name.to_string(),
                time_ms: r.gpu_ms,
                error: r.error.rmse,
                frontier: r.frontier,
                default: r.default,
            })
            .collect();
        let title = format!(
            "{} on {}: error at {}x{}, time at {}x{} (curvature off)",
            report.input, report.device, width, height, time_size.0, time_size.1
        );
        write_svg(path, &title, &points).map_err(|e| match e {
            PlotError::Write(e) => Error::Output(e),
            other => Error::Usage(other.to_string()),
        })?;
    }
    if validation {
        session::check_validation(&opened.engine)?;
    }
    session::persist_pipeline_cache(&opened.engine);
    print_table(&report);
    Ok(())
}
