//! The kernel sweep behind `morphray kernels --sweep`: every kernel of a scene's plan compiled
//! for each workgroup shape of the tunable passes, each required subgroup size the device
//! allows, and each derived-volume precision, with the driver compiler's statistics (on the
//! stub Tiger Lake of `tools/gen12`: Intel's own SIMD choice, instructions, cycles, spills,
//! fills, sends) beside the Xe-LP bandwidth/texel model's time bound of the same pass.
//!
//! Decisions:
//! - One engine per (subgroup, workgroup) pair, since both are fixed when a device's pipelines
//!   are made (`KernelTuning`); the precisions share it. Nothing is dispatched.
//! - A configuration the device refuses (a subgroup size it lacks, a workgroup over its
//!   limits) is a row with the error, not a failure of the sweep: that too is what the sweep
//!   is for.
//! - The model's bound comes from the plan's own pass costs (`passes::cost`), matched by
//!   variant name; the 8-bit path's max-only derivative dispatch has no plan pass of its own
//!   and no bound.

use crate::engine::kernels::{KernelReport, KernelSet};
use crate::engine::plan::Layout;
use crate::engine::{Engine, EngineConfig};
use crate::gpu::GpuError;
use crate::passes::cost::XE_LP;
use crate::passes::derivatives::DerivedPrecision;
use crate::scene::Effects;
use crate::volume::Volume;

/// What to sweep.
#[derive(Clone, Debug)]
pub struct SweepSpace {
    /// Workgroup shapes of the tunable passes (None: the engine's default or the profile's); a
    /// shape with z > 1 applies to the 3-D kernels (normalize, derivatives) only.
    pub workgroups: Vec<Option<[u32; 3]>>,
    /// Required subgroup sizes (None: the driver's choice).
    pub subgroups: Vec<Option<u32>>,
    /// Derived-volume precisions.
    pub precisions: Vec<DerivedPrecision>,
}

impl Default for SweepSpace {
    /// The shapes Intel's guide discusses (8x8, and 16x16 = 256 invocations), a 3-D 4x4x4 and
    /// a deep 8x8x4; subgroups 8, 16, 32 and the driver's choice; all three precisions.
    fn default() -> Self {
        SweepSpace {
            workgroups: vec![
                None,
                Some([8, 8, 1]),
                Some([16, 16, 1]),
                Some([4, 4, 4]),
                Some([8, 8, 4]),
            ],
            subgroups: vec![None, Some(8), Some(16), Some(32)],
            precisions: vec![
                DerivedPrecision::Snorm8,
                DerivedPrecision::F16,
                DerivedPrecision::F32,
            ],
        }
    }
}

/// One kernel under one configuration.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SweepRow {
    /// Workgroup asked for the tunable passes (None: default).
    pub workgroup_asked: Option<[u32; 3]>,
    /// Subgroup size asked for (None: the driver's choice).
    pub subgroup_asked: Option<u32>,
    /// Derived-volume precision of the scene.
    pub precision: DerivedPrecision,
    /// The kernel (None when the configuration was refused).
    pub kernel: Option<KernelReport>,
    /// The Xe-LP model's time bound of the kernel's pass, ms.
    pub xe_lp_model_ms: Option<f64>,
    /// Why the configuration was refused.
    pub error: Option<String>,
}

impl SweepRow {
    /// The first executable's statistic `name`, as a number.
    pub fn stat(&self, name: &str) -> Option<f64> {
        let executables = self.kernel.as_ref()?.executables.as_ref()?;
        executables.first()?.value(name).map(|v| v.as_f64())
    }

    /// The SIMD width the compiler chose (the executable's subgroup size).
    pub fn simd(&self) -> Option<u32> {
        let executables = self.kernel.as_ref()?.executables.as_ref()?;
        executables.first().map(|e| e.subgroup_size)
    }
}

/// Sweeps `space` for the plan of `effects` on `volume` at `image` pixels, on engines made from
/// `base` (its device selection, profile and validation).
pub fn sweep(
    base: &EngineConfig,
    volume: &Volume,
    effects: Effects,
    image: [u32; 2],
    space: &SweepSpace,
) -> Vec<SweepRow> {
    let mut rows = Vec::new();
    for &subgroup in &space.subgroups {
        for &workgroup in &space.workgroups {
            let mut config = base.clone();
            config.device.pipeline_statistics = true;
            config.device.tuning.subgroup_size = subgroup;
            match workgroup {
                // A 3-D shape goes to the 3-D kernels only (the raymarch is 2-D).
                Some(size) if size[2] > 1 => {
                    for pass in ["normalize", "derivatives"] {
                        config
                            .device
                            .tuning
                            .workgroups
                            .push((Some(pass.into()), size));
                    }
                }
                Some(size) => config.device.tuning.workgroups.push((None, size)),
                None => {}
            }
            let refused = |precision, e: String| SweepRow {
                workgroup_asked: workgroup,
                subgroup_asked: subgroup,
                precision,
                kernel: None,
                xe_lp_model_ms: None,
                error: Some(e),
            };
            let mut engine = match Engine::new(config) {
                Ok(e) => e,
                Err(e) => {
                    rows.extend(space.precisions.iter().map(|&p| refused(p, e.to_string())));
                    continue;
                }
            };
            for &precision in &space.precisions {
                let mut effects = effects;
                effects.quality.derived_precision = precision;
                match configuration(&mut engine, volume, effects, image) {
                    Ok(kernels) => {
                        rows.extend(kernels.into_iter().map(|(kernel, model)| SweepRow {
                            workgroup_asked: workgroup,
                            subgroup_asked: subgroup,
                            precision,
                            kernel: Some(kernel),
                            xe_lp_model_ms: model,
                            error: None,
                        }))
                    }
                    Err(e) => rows.push(refused(precision, e)),
                }
            }
        }
    }
    rows
}

/// The plan's kernels on `engine` with each one's modelled bound.
fn configuration(
    engine: &mut Engine,
    volume: &Volume,
    effects: Effects,
    image: [u32; 2],
) -> Result<Vec<(KernelReport, Option<f64>)>, String> {
    let plan = engine
        .plan(effects, volume, image, 1.0)
        .map_err(|e| e.to_string())?;
    let kernels = engine
        .kernels(KernelSet::Plan {
            effects: plan.effects,
            kind: volume.samples.kind(),
            bricked: matches!(plan.layout, Layout::Bricked { .. }),
        })
        .map_err(|e: GpuError| e.to_string())?;
    Ok(kernels
        .into_iter()
        .map(|k| {
            let model = plan
                .passes
                .iter()
                .find(|p| p.variant == k.variant)
                .map(|p| p.cost.bound_seconds(XE_LP.bandwidth, XE_LP.texel_rate) * 1e3);
            (k, model)
        })
        .collect())
}
