//! `morphray peaks`: the paper's Table-1 row from the GPU histogram.
//!
//! Decisions: the modality and the contrast the tissues were labelled for are printed with
//! their basis (metadata, values, histogram, assumed, given) and reason, because every label
//! depends on them; the paper's windows are marked as T1 windows, and on a volume labelled for
//! another order (T2, PD, FLAIR, CT) the "inside?" column says it does not apply rather than
//! reporting its peaks against T1 windows. A foreground shown for want of tissue classes
//! (`analysis::fallback`) is one more line (`fallback` in the JSON).

use super::args::PeaksArgs;
use super::output::{json, ms, print_line, print_warnings};
use super::session;
use crate::analysis::{Contrast, ContrastReport, Peak, TissueWindows};
use crate::error::Error;
use std::collections::BTreeMap;

/// The JSON document of `peaks --json`.
#[derive(serde::Serialize)]
struct PeaksReport<'a> {
    file: &'a str,
    dims: [u32; 3],
    total_voxels: usize,
    used_voxels: u64,
    used_voxels_definition: &'static str,
    nonfinite_voxels: usize,
    imin: Option<f64>,
    imax: Option<f64>,
    /// How the range mapped to I_norm 0..1 was chosen, and eq. 1's data range.
    normalization: crate::analysis::RangeChoice,
    /// The physical range mapped to I_norm 0..1 (the robust range, or imin..imax).
    range: Option<[f64; 2]>,
    /// The paper's Table-1 row: eq. 1's Imin/Imax and its I_norm peaks next to the rendered ones.
    table1: crate::analysis::Table1Row,
    background_threshold: f64,
    peaks: BTreeMap<&'static str, Option<Peak>>,
    paper_windows: &'a TissueWindows,
    /// Always `t1`: the paper's windows describe T1 contrast.
    paper_windows_contrast: Contrast,
    in_paper_window: BTreeMap<&'static str, Option<bool>>,
    windows: &'a TissueWindows,
    /// What the volume is, what the decision rests on, and why.
    modality: &'a crate::analysis::ModalityReport,
    /// Contrast the tissues were labelled for, what the decision rests on, and why.
    contrast: &'a ContrastReport,
    /// The foreground window shown when no tissue class was found (in `windows.wm`).
    fallback: Option<&'a crate::analysis::Fallback>,
    /// Voxels on a mask's edge left out of the tissue analysis (engine/mask_edge.rs).
    mask_edge_voxels: u64,
    /// The look by modality a render would use (`scene::preset`; `--preset` names one).
    preset: String,
    /// The tissue mixture fitted by EM (means, SDs, weights, goodness), beside the Table-1 row.
    fit: Option<&'a crate::analysis::Fit>,
    /// Which path placed `windows`: the fit, the modes or the fallback.
    windows_from: crate::analysis::WindowsFrom,
    /// A fit inside the brain mask that was not sound, shown but not used.
    rejected_fit: Option<&'a crate::analysis::Fit>,
    device: String,
    timings_ms: BTreeMap<String, f64>,
    /// The loader's repairs and warnings about the input.
    warnings: &'a [String],
}

/// One line saying which range became I_norm 0..1 and why.
fn normalization_line(r: &crate::analysis::TissueReport) -> String {
    match (r.range.mode, r.range.robust) {
        (_, _) if r.finite_voxels == 0 => "I_norm: no finite voxel".into(),
        (crate::analysis::NormalizeMode::MinMax, _) => {
            "I_norm: eq. 1 (min/max; --normalize minmax, the paper-literal preset)".into()
        }
        (_, Some(robust)) if robust.fell_back => format!(
            "I_norm: eq. 1 (min/max): the robust percentiles give no range here (the foreground \
             is one value); background threshold {:.6}",
            robust.background
        ),
        (_, Some(robust)) => format!(
            "I_norm: robust range {} .. {} (P{} of the finite voxels .. P{} of the voxels above \
             the background threshold {:.6}; values outside clamped)",
            r.imin,
            r.imax,
            crate::analysis::range::LOW_PERCENTILE,
            crate::analysis::range::HIGH_PERCENTILE,
            robust.background
        ),
        (_, None) => "I_norm: eq. 1 (min/max)".into(),
    }
}

/// The fit's lines: one per tissue class, then the goodness.
fn fit_lines(fit: Option<&crate::analysis::Fit>) -> Vec<String> {
    let mut out = Vec::new();
    if let Some(f) = fit {
        out.push(format!(
            "fit     mean I_norm  mean raw      sd I_norm  sd raw     weight  (EM, {}, {} order)",
            f.domain.words(),
            f.contrast.name()
        ));
        for (name, c) in [("CSF", f.csf), ("GM", f.gm), ("WM", f.wm)] {
            out.push(format!(
                "{name:<7} {:<12.4} {:<13.2} {:<10.4} {:<10.2} {:.3}",
                c.mean, c.mean_raw, c.sd, c.sd_raw, c.weight
            ));
        }
        out.push(format!(
            "fit quality: goodness {:.4} (1 - total variation), partial volume {:.3} + {:.3}, \
             tail {:.3}, {} EM iterations, {:.3} ms{}",
            f.goodness,
            f.partial_volume_weights[0],
            f.partial_volume_weights[1],
            f.tail_weight,
            f.iterations,
            f.fit_ms,
            if f.sound { "" } else { "; not sound, not used" }
        ));
    }
    out
}

/// Runs the command.
pub fn run(args: &PeaksArgs, global: &super::GlobalOptions) -> Result<(), Error> {
    let validation = global.validation;
    // The preset named decides whether a 4-D series is read as its mean frame.
    let recipe = crate::scene::SceneRecipe {
        preset: super::preset_arg::PresetArg::preset(args.preset),
        ..crate::scene::SceneRecipe::default()
    };
    let opened = session::open_recipe(
        args.file.as_slice(),
        args.frame,
        global.engine_config(),
        recipe,
    )?;
    print_warnings(&opened.source.volume.warnings);
    let r = &opened.report;
    let mut timings = BTreeMap::new();
    let t = &opened.timings;
    for (name, value) in [
        ("read", t.load.read_ms),
        ("inflate", t.load.inflate_ms),
        ("convert", t.load.convert_ms),
        ("phantom", t.load.phantom_ms),
        ("device", t.device_ms),
        ("pipelines", t.pipelines_ms),
        ("prepare_wall", t.prepare_ms),
        ("peaks", t.peaks_ms),
        ("total_wall", t.wall_ms),
    ] {
        timings.insert(name.to_string(), ms(value));
    }
    for pass in &opened.twin.prepared.gpu_timings {
        timings.insert(format!("gpu_{}", pass.name), ms(pass.gpu_ms));
    }
    let report = PeaksReport {
        file: &opened.source.label,
        dims: opened.twin.prepared.dims,
        total_voxels: r.total_voxels,
        used_voxels: r.used_voxels,
        used_voxels_definition: "finite voxels whose I_norm bin is at or above the background threshold",
        nonfinite_voxels: r.nonfinite_voxels,
        // null without a finite voxel (the analysis' 0 would read as a real intensity).
        imin: r.range.data_min,
        imax: r.range.data_max,
        normalization: r.range,
        range: (r.finite_voxels > 0).then_some([r.imin, r.imax]),
        table1: r.table1(),
        background_threshold: r.background_threshold,
        peaks: BTreeMap::from([("csf", r.peaks.csf), ("gm", r.peaks.gm), ("wm", r.peaks.wm)]),
        paper_windows: &r.paper_windows,
        paper_windows_contrast: Contrast::T1,
        in_paper_window: BTreeMap::from([
            ("csf", r.in_paper_window.csf),
            ("gm", r.in_paper_window.gm),
            ("wm", r.in_paper_window.wm),
        ]),
        windows: &r.adaptive_windows,
        modality: &r.modality,
        contrast: &r.contrast,
        fallback: r.fallback.as_ref(),
        mask_edge_voxels: opened.twin.prepared.mask_edge_voxels,
        preset: crate::scene::SceneRecipe {
            preset: super::preset_arg::PresetArg::preset(args.preset),
            ..crate::scene::SceneRecipe::default()
        }
        .preset_for(r)
        .label(r),
        fit: r.fit.as_ref(),
        windows_from: r.windows_from,
        rejected_fit: r.rejected_fit.as_ref(),
        device: opened.engine.device().adapter().name.clone(),
        timings_ms: timings,
        warnings: &opened.source.volume.warnings,
    };
    if validation {
        session::check_validation(&opened.engine)?;
    }
    session::persist_pipeline_cache(&opened.engine);
    if args.json {
        print_line(&json(&report));
        return Ok(());
    }
    let [x, y, z] = report.dims;
    print_line(&format!(
        "{}  {x}x{y}x{z}  on {}",
        report.file, report.device
    ));
    print_line(&format!(
        "total voxels {}  used voxels {} (above background I_norm {:.4})  non-finite {}",
        report.total_voxels,
        report.used_voxels,
        report.background_threshold,
        report.nonfinite_voxels
    ));
    match (report.imin, report.imax) {
        (Some(lo), Some(hi)) => print_line(&format!("Imin {lo}  Imax {hi}")),
        _ => print_line("Imin -  Imax -  (no finite voxel)"),
    }
    print_line(&normalization_line(r));
    if report.mask_edge_voxels > 0 {
        print_line(&format!(
            "histogram: a masked volume (its minimum fills much of it): the {} voxels on the \
             mask's edge, tissue averaged with the outside, are left out of the tissue analysis",
            report.mask_edge_voxels
        ));
    }
    print_line(&format!("modality {}", report.modality.summary()));
    print_line(&format!("contrast {}", report.contrast.summary()));
    print_line(&format!("preset: {}", report.preset));
    if let Some(n) = opened.source.header.as_ref().and_then(|h| h.mean_of_frames) {
        print_line(&super::render::epi_mean_line(n));
    }
    if let Some(fallback) = report.fallback {
        print_line(&format!("fallback {}", fallback.reason));
    }
    let t2 = !report.contrast.contrast.is_t1_order();
    let other = report.contrast.contrast.name();
    print_line("tissue  peak I_norm  peak raw      paper window (T1)  inside?");
    let paper = [("csf", "0.05-0.12"), ("gm", "0.12-0.18"), ("wm", "> 0.18")];
    for (name, window) in paper {
        let peak = report.peaks.get(name).copied().flatten();
        let inside = report.in_paper_window.get(name).copied().flatten();
        match peak {
            Some(p) => print_line(&format!(
                "{:<7} {:<12.4} {:<13.2} {:<18} {}",
                name.to_uppercase(),
                p.norm,
                p.raw,
                window,
                match inside {
                    _ if t2 => format!("n/a: T1 window, {other} volume"),
                    Some(true) => "yes".to_string(),
                    _ => "NO: outside the paper's fixed window".to_string(),
                }
            )),
            None => print_line(&format!(
                "{:<7} missing (no distinct mode found)",
                name.to_uppercase()
            )),
        }
    }
    if let Some(f) = report.rejected_fit {
        for line in fit_lines(Some(f)) {
            print_line(&line);
        }
    }
    for line in fit_lines(report.fit) {
        print_line(&line);
    }
    match (report.windows_from, report.fit) {
        (crate::analysis::WindowsFrom::Fit, Some(f)) => print_line(&format!(
            "windows from the fitted tissue mixture ({})",
            f.domain.words()
        )),
        (from, _) => print_line(&format!("windows from {}", from.words())),
    }
    if t2 {
        print_line(&format!(
            "note: the paper's windows are T1 windows (CSF darkest, WM brightest); on this \
             {other} volume they select the wrong tissues: render with the adaptive windows"
        ));
    }
    let gpu: Vec<String> = opened
        .twin
        .prepared
        .gpu_timings
        .iter()
        .map(|p| format!("{} {:.3} ms", p.name, p.gpu_ms))
        .collect();
    print_line(&format!("GPU passes: {}", gpu.join(", ")));
    Ok(())
}
