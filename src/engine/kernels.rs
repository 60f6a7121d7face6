//! The kernels a plan uses (or every variant the engine can build), compiled on the engine's
//! device with no dispatch at all, with the driver compiler's own statistics
//! (`gpu::pipeline_stats`): what `morphray kernels` reports, and what works on a stub device
//! whose submissions never execute (the Gen12 stub of `tools/gen12`).
//!
//! Decisions:
//! - A plan's kernels are exactly the pipelines its first frame needs (the engine's
//!   `first_frame_keys`, the list its workers compile ahead of time), so the report and the
//!   engine cannot disagree about what runs.
//! - "Every variant" is every variant a scene can select: each combination of the scene's
//!   effects and quality knobs that changes a specialization constant, whole and bricked,
//!   de-duplicated (the raymarch's benchmark counters are left out: only `bench` builds them).
//! - Variants are named as the plan names them (`minmax_i16`, `derivatives (...)`,
//!   `raymarch (...)`), so a report line can be found in `morphray plan`.

use super::Engine;
use super::pipelines::{PipelineKey, first_frame_keys};
use crate::gpu::pipeline::ComputePipeline;
use crate::gpu::pipeline_stats::Executable;
use crate::gpu::{GpuError, GpuResult};
use crate::passes::derivatives::{DerivativeOutputs, DerivedPrecision};
use crate::scene::{
    CurvatureSource, Effects, GradientFilter, GradientSource, Interpolation, OpacityCorrection,
    Quality, RenderMode,
};
use crate::volume::SampleKind;
use std::collections::HashSet;
use std::sync::Arc;

/// Which kernels to report.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum KernelSet {
    /// The pipelines a first frame of `effects` needs on a volume of `kind` samples, whole or
    /// bricked as planned.
    Plan {
        /// The planned effects.
        effects: Effects,
        /// The volume's sample kind.
        kind: SampleKind,
        /// The plan bricks the volume.
        bricked: bool,
    },
    /// Every variant the engine can build.
    All,
}

/// One compiled kernel.
#[derive(Clone, Debug, serde::Serialize)]
pub struct KernelReport {
    /// The shader's name.
    pub name: String,
    /// The variant, named as plans name it.
    pub variant: String,
    /// Workgroup size the pipeline was built with.
    pub workgroup: [u32; 3],
    /// The required subgroup size, when the device tuning pins one.
    pub subgroup: Option<u32>,
    /// The driver's executables with their statistics (None: the driver reports none).
    pub executables: Option<Vec<Executable>>,
}

const KINDS: [SampleKind; 5] = [
    SampleKind::U8,
    SampleKind::I8,
    SampleKind::U16,
    SampleKind::I16,
    SampleKind::F32,
];

/// Every pipeline key a scene can select on a device that does (or does not) prefer texel
/// lookups, analysis passes first.
fn all_keys(texel_lookups: bool) -> Vec<PipelineKey> {
    let mut keys: Vec<PipelineKey> = KINDS.into_iter().map(PipelineKey::Kind).collect();
    let mut seen: HashSet<PipelineKey> = keys.iter().copied().collect();
    for effects in every_effects() {
        for bricked in [false, true] {
            for key in first_frame_keys(&effects, None, bricked, texel_lookups) {
                if seen.insert(key) {
                    keys.push(key);
                }
            }
        }
    }
    keys
}

/// Every combination of effects and quality knobs (many select the same variants; the caller
/// de-duplicates).
fn every_effects() -> Vec<Effects> {
    let mut all = Vec::new();
    for mode in [RenderMode::Dvr, RenderMode::Mip, RenderMode::MinIp] {
        for (curvature, shading) in [(false, false), (true, false), (false, true), (true, true)] {
            for gradient_source in [GradientSource::Precomputed, GradientSource::OnTheFly] {
                for quality in every_quality() {
                    all.push(Effects {
                        mode,
                        curvature,
                        shading,
                        gradient_source,
                        quality,
                        // The vessel channel adds one texture fetch per sample; the sweep
                        // keeps to the tissue variants it was made for.
                        vessels: false,
                        // The brain mask adds one fetch per classified sample, as the vessels.
                        brain: crate::passes::brain::BrainSwitch::Off,
                        lighting: crate::scene::Lighting::default(),
                    });
                }
            }
        }
    }
    // The stills' lighting (studio, depth cues) and the matcap with cues on the shaded default
    // variants: their cost is the lighting's, not another axis of every quality knob.
    let matcap = crate::scene::Lighting {
        model: crate::scene::LightModel::Matcap,
        depth_cues: true,
    };
    for lighting in [crate::scene::Lighting::STILL, matcap] {
        for curvature in [false, true] {
            all.push(Effects {
                curvature,
                shading: true,
                lighting,
                ..Effects::default()
            });
        }
    }
    all
}

fn every_quality() -> Vec<Quality> {
    let mut all = Vec::new();
    for interpolation in [
        Interpolation::Nearest,
        Interpolation::Trilinear,
        Interpolation::Tricubic,
    ] {
        for gradient_filter in [GradientFilter::Central, GradientFilter::Sobel] {
            for curvature_source in [CurvatureSource::Stored, CurvatureSource::OnTheFly] {
                for derived_precision in [
                    DerivedPrecision::F32,
                    DerivedPrecision::F16,
                    DerivedPrecision::Snorm8,
                ] {
                    for opacity_correction in [OpacityCorrection::Exact, OpacityCorrection::Naive] {
                        for empty_space_skipping in [false, true] {
                            all.push(Quality {
                                interpolation,
                                gradient_filter,
                                curvature_source,
                                derived_precision,
                                opacity_correction,
                                empty_space_skipping,
                                long_steps: crate::scene::occupancy::LongSteps::OFF,
                                classification: crate::scene::ClassificationLookup::Table,
                            });
                        }
                    }
                }
            }
        }
    }
    all
}

/// The derivative variant as plans name it.
pub fn derivative_variant_name(o: &DerivativeOutputs) -> String {
    format!(
        "derivatives (WANT_MAGNITUDE={}, WANT_CURVATURE={}, WANT_NORMAL={}, {:?})",
        o.magnitude, o.curvature, o.normal, o.precision
    )
}

fn report(pipeline: &Arc<ComputePipeline>, variant: String) -> GpuResult<KernelReport> {
    Ok(KernelReport {
        name: pipeline.shader().name.to_string(),
        variant,
        workgroup: pipeline.workgroup_size(),
        subgroup: pipeline.subgroup_size(),
        executables: pipeline.executables()?,
    })
}

impl Engine {
    /// Compiles `set`'s kernels (through the engine's pipeline cache; nothing is dispatched)
    /// and reports each with the driver's statistics.
    pub fn kernels(&mut self, set: KernelSet) -> GpuResult<Vec<KernelReport>> {
        let texel_lookups = self.texel_lookups();
        let keys = match set {
            KernelSet::Plan {
                effects,
                kind,
                bricked,
            } => first_frame_keys(&effects, Some(kind), bricked, texel_lookups),
            KernelSet::All => all_keys(texel_lookups),
        };
        let mut reports = Vec::new();
        for key in keys {
            reports.extend(self.key_reports(key)?);
        }
        Ok(reports)
    }

    fn key_reports(&mut self, key: PipelineKey) -> GpuResult<Vec<KernelReport>> {
        Ok(match key {
            PipelineKey::Kind(kind) => {
                let k = kind.name();
                let passes = self.kind_passes(kind)?;
                vec![
                    report(passes.minmax.pipeline(), format!("minmax_{k}"))?,
                    report(
                        passes.fine_histogram.pipeline(),
                        format!("fine_histogram_{k}"),
                    )?,
                    report(
                        passes.normalize.pipeline(),
                        format!("normalize (SAMPLE_KIND={k})"),
                    )?,
                    report(passes.histogram.pipeline(), format!("histogram_{k}"))?,
                ]
            }
            PipelineKey::Derivative(outputs) => {
                let pass = self.derivative_pass(outputs)?;
                vec![report(pass.pipeline(), derivative_variant_name(&outputs))?]
            }
            PipelineKey::Occupancy => {
                let pass = self.occupancy_pass()?;
                vec![
                    report(pass.pipeline(), "occupancy".into())?,
                    report(pass.bounds().pipeline(), "brick bounds".into())?,
                    report(pass.distance().pipeline(), "brick distance".into())?,
                ]
            }
            PipelineKey::Brain => {
                let pass = self.brain_pass()?;
                let mut reports = Vec::new();
                for (name, pipeline) in pass.pipelines() {
                    reports.push(report(pipeline, name.into())?);
                }
                reports
            }
            PipelineKey::Raymarch(variant) => {
                let pass = self.raymarch_pass(variant)?;
                vec![report(pass.pipeline(), variant.describe())?]
            }
        })
    }
}

/// Checks that `reports` came from a device that captures statistics.
pub fn require_statistics(reports: &[KernelReport]) -> GpuResult<()> {
    match reports.iter().find(|r| r.executables.is_none()) {
        Some(r) => Err(GpuError::Unsupported(format!(
            "the driver reports no compiler statistics for {} (no \
             VK_KHR_pipeline_executable_properties)",
            r.variant
        ))),
        None => Ok(()),
    }
}
