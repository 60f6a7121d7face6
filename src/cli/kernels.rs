//! `morphray kernels`: the kernels a scene's plan uses (or every variant), compiled on the chosen
//! device with the driver compiler's statistics, and nothing dispatched.
//!
//! Decisions:
//! - The volume is read on the host only (its size and sample kind choose the plan), and the
//!   engine compiles pipelines without preparing the volume, so the command works on a device
//!   whose submissions never execute (the stub Tiger Lake of `tools/gen12`).
//! - The JSON keeps each driver's own statistic names; the text shows them as `name=value`.
//!   A driver without VK_KHR_pipeline_executable_properties gets one line saying so, and the
//!   kernels are still listed (they compiled).

use super::args::KernelsArgs;
use super::output::{json, print_line, print_warnings};
use super::render::recipe_from_args;
use super::source;
use crate::engine::Engine;
use crate::engine::kernels::{KernelReport, KernelSet};
use crate::engine::plan::Layout;
use crate::error::Error;
use crate::gpu::pipeline_stats::{Executable, StatValue};
use crate::study::kernel_sweep::{SweepRow, SweepSpace, sweep};
use serde_json::{Map, Value};

/// Runs the command.
pub fn run(args: &KernelsArgs, global: &super::GlobalOptions) -> Result<(), Error> {
    let source = source::load(&args.file, args.frame, false)?;
    print_warnings(&source.volume.warnings);
    let recipe = recipe_from_args(&args.scene)?;
    let mut config = global.engine_config();
    config.device.pipeline_statistics = true;
    let mut engine = Engine::new(config)?;
    let (width, height) = args.scene.size.unwrap_or((1024, 1024));
    if args.sweep {
        drop(engine);
        let space = SweepSpace::default();
        let rows = sweep(
            &global.engine_config(),
            &source.volume,
            recipe.effects,
            [width, height],
            &space,
        );
        print_sweep(&rows, args.json);
        return Ok(());
    }
    let set = if args.all {
        KernelSet::All
    } else {
        let plan = engine.plan(recipe.effects, &source.volume, [width, height], 1.0)?;
        KernelSet::Plan {
            effects: plan.effects,
            kind: source.volume.samples.kind(),
            bricked: matches!(plan.layout, Layout::Bricked { .. }),
        }
    };
    let reports = engine.kernels(set)?;
    if global.validation {
        super::session::check_validation(&engine)?;
    }
    let adapter = engine.device().adapter();
    let device = format!("{} ({})", adapter.name, adapter.driver);
    if args.json {
        let kernels: Vec<Value> = reports.iter().map(kernel_json).collect();
        print_line(&json(&serde_json::json!({
            "device": device,
            // The device's own limits (clamped by --profile when one is given), for checking a
            // profile against what a driver reports.
            "limits": {
                "max_image_dimension_3d": adapter.max_image_dimension_3d,
                "subgroup_size": adapter.subgroup_size,
                "subgroup_size_range": adapter.subgroup_size_range,
                "max_workgroup_invocations": adapter.max_workgroup_invocations,
                "timestamp_valid_bits": adapter.timestamp_valid_bits,
                "unified_memory": adapter.unified_memory,
                "float_atomics": adapter.float_atomics,
            },
            "statistics_available": reports.iter().all(|r| r.executables.is_some()),
            "kernels": kernels,
        })));
    } else {
        print_text(&device, &reports);
    }
    Ok(())
}

fn value_json(v: StatValue) -> Value {
    serde_json::to_value(v).unwrap_or(Value::Null)
}

/// One kernel: the first executable's statistics as a name -> value map (a compute pipeline
/// has one executable on the drivers seen so far), and every executable in full.
fn kernel_json(r: &KernelReport) -> Value {
    let statistics = r.executables.as_ref().and_then(|e| e.first()).map(|e| {
        e.statistics
            .iter()
            .map(|s| (s.name.clone(), value_json(s.value)))
            .collect::<Map<String, Value>>()
    });
    serde_json::json!({
        "name": r.name,
        "variant": r.variant,
        "workgroup": r.workgroup,
        "subgroup": r.subgroup,
        "statistics": statistics,
        "executables": r.executables,
    })
}

fn stat_text(e: &Executable) -> String {
    e.statistics
        .iter()
        .map(|s| {
            let v = match s.value {
                StatValue::Bool(b) => b.to_string(),
                StatValue::Int(v) => v.to_string(),
                StatValue::Uint(v) => v.to_string(),
                StatValue::Float(v) => format!("{v:.3}"),
            };
            format!("{}={v}", s.name.replace(' ', "_"))
        })
        .collect::<Vec<_>>()
        .join(" ")
}

fn print_text(device: &str, reports: &[KernelReport]) {
    print_line(&format!("{} kernels on {device}", reports.len()));
    if reports.iter().any(|r| r.executables.is_none()) {
        print_line(
            "this driver reports no compiler statistics (it lacks \
             VK_KHR_pipeline_executable_properties); the kernels below compiled",
        );
    }
    for r in reports {
        let [x, y, z] = r.workgroup;
        let subgroup = r
            .subgroup
            .map(|s| format!(", subgroup {s}"))
            .unwrap_or_default();
        print_line(&format!(
            "{}  [{}, workgroup {x}x{y}x{z}{subgroup}]",
            r.variant, r.name
        ));
        for e in r.executables.iter().flatten() {
            print_line(&format!(
                "    {} (SIMD{}): {}",
                e.name,
                e.subgroup_size,
                stat_text(e)
            ));
        }
    }
}

/// The sweep as JSON rows, or as a table with the findings first: spills, SIMD8 choices, and
/// per kernel the range of instructions and cycles over the configurations.
fn print_sweep(rows: &[SweepRow], as_json: bool) {
    if as_json {
        print_line(&json(&serde_json::json!({ "rows": rows })));
        return;
    }
    let compiled: Vec<&SweepRow> = rows.iter().filter(|r| r.kernel.is_some()).collect();
    let refused: Vec<&SweepRow> = rows.iter().filter(|r| r.error.is_some()).collect();
    print_line(&format!(
        "{} kernel compiles, {} configurations refused",
        compiled.len(),
        refused.len()
    ));
    let config = |r: &SweepRow| {
        let wg = r
            .workgroup_asked
            .map(|[x, y, z]| format!("{x}x{y}x{z}"))
            .unwrap_or_else(|| "default".into());
        let sg = r
            .subgroup_asked
            .map(|s| s.to_string())
            .unwrap_or_else(|| "driver".into());
        format!("wg {wg}, subgroup {sg}, {:?}", r.precision)
    };
    let spilled: Vec<String> = compiled
        .iter()
        .filter(|r| r.stat("Spill Count").unwrap_or(0.0) > 0.0)
        .map(|r| format!("  {} ({})", variant(r), config(r)))
        .collect();
    print_line(&format!(
        "spills: {}",
        if spilled.is_empty() {
            "none".into()
        } else {
            spilled.len().to_string()
        }
    ));
    spilled.iter().for_each(|l| print_line(l));
    let mut said = std::collections::HashSet::new();
    for r in &refused {
        // One line per configuration, whatever the precision.
        let line = format!(
            "refused (wg {}, subgroup {}): {}",
            r.workgroup_asked
                .map(|[x, y, z]| format!("{x}x{y}x{z}"))
                .unwrap_or_else(|| "default".into()),
            r.subgroup_asked
                .map(|s| s.to_string())
                .unwrap_or_else(|| "driver".into()),
            r.error.as_deref().unwrap_or("")
        );
        if said.insert(line.clone()) {
            print_line(&line);
        }
    }
    print_line("");
    print_line(
        "| subgroup asked | workgroup asked | precision | kernel | SIMD | instructions | cycles | spills:fills | sends | Xe-LP model ms |",
    );
    print_line("|---|---|---|---|---|---|---|---|---|---|");
    for r in compiled {
        let num = |name: &str| {
            r.stat(name)
                .map(|v| format!("{v:.0}"))
                .unwrap_or_else(|| "-".into())
        };
        print_line(&format!(
            "| {} | {} | {:?} | {} | {} | {} | {} | {}:{} | {} | {} |",
            r.subgroup_asked
                .map(|s| s.to_string())
                .unwrap_or_else(|| "driver".into()),
            r.workgroup_asked
                .map(|[x, y, z]| format!("{x}x{y}x{z}"))
                .unwrap_or_else(|| "default".into()),
            r.precision,
            variant(r),
            r.simd()
                .map(|s| s.to_string())
                .unwrap_or_else(|| "-".into()),
            num("Instruction Count"),
            num("Cycle Count"),
            num("Spill Count"),
            num("Fill Count"),
            num("SEND Count"),
            r.xe_lp_model_ms
                .map(|m| format!("{m:.3}"))
                .unwrap_or_else(|| "-".into()),
        ));
    }
}

/// A short name for a kernel row (the shader and its variant's parameters).
fn variant(r: &SweepRow) -> String {
    r.kernel
        .as_ref()
        .map(|k| k.variant.clone())
        .unwrap_or_default()
}
