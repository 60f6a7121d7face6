//! `morphray plan`: the passes, pipeline variants and memory a scene needs, planned within the
//! budget, next to what the engine then actually holds.
//!
//! Decisions: the command sets the volume up exactly as `render` would (same plan, same
//! degradations, derived volumes, render target) but renders nothing, so the printed plan is the
//! one that runs, and the memory ledger's live allocations after set-up are printed beside the
//! planned ones. Predicted per-pass costs are bytes and fetches (the floors `bench` measures
//! against) with the Xe-LP model's time bound.

use super::args::PlanArgs;
use super::output::{json, print_line, print_warnings};
use super::session;
use crate::engine::plan::{Layout, Plan};
use crate::error::Error;
use crate::gpu::{AllocationRecord, DeviceProfile, KernelTuning};
use crate::passes::cost::{DeviceModel, XE_LP};
use ash::vk;

/// One pass with its predicted time bound on the Xe-LP model.
#[derive(serde::Serialize)]
struct PassPrediction {
    name: String,
    xe_lp_model_ms: f64,
}

/// The JSON document of `plan --json`: the plan's own fields, then what was measured.
#[derive(serde::Serialize)]
struct PlanReport<'a> {
    input: &'a str,
    dims: [u32; 3],
    device: &'a str,
    image: [u32; 2],
    #[serde(flatten)]
    plan: &'a Plan,
    predicted: Vec<PassPrediction>,
    projection_device: DeviceModel,
    accuracy_study: &'static str,
    held: Vec<AllocationRecord>,
    held_bytes: u64,
    device_profile: Option<&'a DeviceProfile>,
    tuning: &'a KernelTuning,
    /// The loader's repairs and warnings about the input.
    warnings: &'a [String],
}

/// Runs the command.
pub fn run(args: &PlanArgs, global: &super::GlobalOptions) -> Result<(), Error> {
    let opened = session::open(
        args.file.as_slice(),
        args.frame,
        false,
        global.engine_config(),
        Some(&args.scene),
        false,
    )?;
    print_warnings(&opened.source.volume.warnings);
    let (width, height) = args.scene.size.unwrap_or((1024, 1024));
    let engine = opened.engine;
    let twin = opened.twin;
    let target = engine.render_target(width, height, vk::Format::R8G8B8A8_UNORM)?;
    let held = engine.device().ledger().live();
    let held_bytes = held.iter().map(|a| a.bytes).sum();
    if global.validation {
        session::check_validation(&engine)?;
    }
    session::persist_pipeline_cache(&engine);
    let plan = &opened.plan;
    let report = PlanReport {
        input: &opened.source.label,
        dims: twin.prepared.dims,
        device: &engine.device().adapter().name,
        image: [target.width, target.height],
        plan,
        predicted: plan
            .passes
            .iter()
            .map(|p| PassPrediction {
                name: p.name.clone(),
                xe_lp_model_ms: p.cost.bound_seconds(XE_LP.bandwidth, XE_LP.texel_rate) * 1e3,
            })
            .collect(),
        projection_device: XE_LP,
        accuracy_study: "ACCURACY.md (morphray accuracy measures each degradation's error)",
        held,
        held_bytes,
        device_profile: engine.device().profile(),
        tuning: engine.device().tuning(),
        warnings: &opened.source.volume.warnings,
    };
    if args.json {
        print_line(&json(&report));
    } else {
        print_text(&report);
    }
    Ok(())
}

fn mib(bytes: u64) -> f64 {
    bytes as f64 / (1u64 << 20) as f64
}

fn print_text(r: &PlanReport<'_>) {
    let p = r.plan;
    let [x, y, z] = r.dims;
    print_line(&format!(
        "plan for {} ({x}x{y}x{z}) on {}, image {}x{}, budget {:.1} MiB",
        r.input,
        r.device,
        r.image[0],
        r.image[1],
        mib(p.budget)
    ));
    if let Some(profile) = r.device_profile {
        print_line(&format!(
            "device profile {}: {}",
            profile.name, profile.description
        ));
    }
    let t = r.tuning;
    if !t.workgroups.is_empty() || t.subgroup_size.is_some() {
        let groups: Vec<String> = t
            .workgroups
            .iter()
            .map(|(pass, [x, y, z])| format!("{}={x}x{y}x{z}", pass.as_deref().unwrap_or("all")))
            .collect();
        print_line(&format!(
            "kernel tuning: workgroups [{}], subgroup size {}",
            groups.join(", "),
            t.subgroup_size
                .map(|s| s.to_string())
                .unwrap_or_else(|| "device default".into())
        ));
    }
    let layout = match p.layout {
        Layout::Whole => "whole volume".to_string(),
        Layout::Bricked {
            brick,
            halo,
            grid,
            resident,
            staging_slots,
        } => format!(
            "bricked: {resident} of {} bricks of {brick}^3 (+{halo} halo) resident, uploaded {staging_slots} at a time",
            grid.iter().map(|&g| g as u64).product::<u64>()
        ),
    };
    print_line(&format!(
        "effects: {:?}, curvature {}, shading {}, gradient {:?}; I_norm {:?}; {layout}",
        p.effects.mode,
        on_off(p.effects.curvature),
        on_off(p.effects.shading),
        p.effects.gradient_source,
        p.normalized_format
    ));
    print_line("");
    print_line(&format!(
        "{:<13} {:<18} {:>10} {:>14}  {:>13}  variant",
        "pass", "runs", "MB moved", "texel units", "Xe-LP ms"
    ));
    for (pass, predicted) in p.passes.iter().zip(&r.predicted) {
        print_line(&format!(
            "{:<13} {:<18} {:>10.1} {:>14.3e}  {:>13.3}  {}",
            pass.name,
            pass.runs,
            pass.cost.bytes() / 1e6,
            pass.cost.texel_units(),
            predicted.xe_lp_model_ms,
            pass.variant
        ));
    }
    print_line("");
    print_line(&format!(
        "{:<34} {:>12}  {:<16} {:<24} when",
        "allocation", "bytes", "format", "memory"
    ));
    for a in &p.allocations {
        print_line(&format!(
            "{:<34} {:>12}  {:<16} {:<24} {}",
            a.name,
            a.bytes,
            a.format_label(),
            a.memory_type,
            if a.transient {
                "while preparing"
            } else {
                "held"
            }
        ));
    }
    print_line(&format!(
        "planned: {:.1} MiB held while rendering, {:.1} MiB at the preparation peak",
        mib(p.total_bytes),
        mib(p.peak_bytes)
    ));
    print_line(&format!(
        "measured: {:.1} MiB in {} live allocations after set-up (memory ledger, incl. driver rounding and the engine's small buffers)",
        mib(r.held_bytes),
        r.held.len()
    ));
    if p.degradations.is_empty() {
        print_line("degradations: none (the full plan fits)");
    } else {
        print_line(
            "degradations, in the order applied (their error: ACCURACY.md, `morphray accuracy`):",
        );
        for d in &p.degradations {
            print_line(&format!(
                "  - {} (saves {:.1} MiB; accuracy setting \"{}\": {})",
                d.what,
                mib(d.saved_bytes),
                d.accuracy_setting,
                d.accuracy_cost
            ));
        }
    }
}

fn on_off(value: bool) -> &'static str {
    if value { "on" } else { "off" }
}
