//! Opening a volume: plan the scene within the memory budget, prepare the volume whole on the GPU
//! or bricked from the host, analyse its histogram, and derive what the scene needs.
//!
//! Decisions:
//! - The plan comes first, from the scene's effects and the device's limits; the volume is then
//!   prepared the way the plan says, so what the engine holds is what the plan lists.
//! - A whole volume is normalized and histogrammed on the GPU. A bricked one (over the budget or
//!   the 3D image limit) is normalized in f64 on the host, because the whole-volume sample buffer
//!   the GPU kernels read is exactly what does not fit; the histogram then comes from the host,
//!   the scene decides which bricks are resident (its tissue windows in DVR, the values MIP and
//!   MinIP can show otherwise), and the plan is made again with that occupancy.
//! - The caller gives a [`SceneRecipe`] (adaptive windows need the peaks, so the scene itself
//!   can only be built after the analysis). Its effects are known up front, so a whole volume is
//!   planned exactly once; a bricked one is planned once more when its occupancy is known (the
//!   scene's windows decide which bricks are resident), which is a change of the scene's needs,
//!   not a second guess. [`Engine::open_planned`] takes a plan made earlier (the library's open
//!   path plans before the file is read, to start the right pipelines).
//! - The vessel channel an automatic preset turns on (angiography) is part of the effects
//!   planned: the preset rests on the identity (modality, sequence kind), known before the
//!   analysis (`SceneRecipe::effects_for`), so the vesselness volume is counted against the
//!   budget, or degraded off by the plan with its line, never allocated past the plan. A plan
//!   made by a caller without it is made again with it.

use super::Engine;
use super::bricked::HostPrepared;
use super::denoise::check_denoise_whole;
use super::prepare::{PrepareTimings, PreparedVolume};
use super::twin::Twin;
use crate::analysis::{Identity, TissueReport, analyze_identified, identify};
use crate::engine::plan::{DoesNotFit, Layout, Plan, STORAGE_BRICK, STORAGE_HALO};
use crate::gpu::GpuError;
use crate::scene::{Scene, SceneRecipe};
use crate::volume::Volume;
use ash::vk;
use std::time::Instant;

/// Why a volume could not be opened.
#[derive(Debug, thiserror::Error)]
pub enum OpenError {
    /// Vulkan, device memory or shaders.
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// No plan of the scene fits the memory budget.
    #[error(transparent)]
    DoesNotFit(#[from] DoesNotFit),
}

/// Host times of [`Engine::open_volume`], milliseconds, in the order they ran.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct OpenTimings {
    /// Planning the scene against the budget (once more when bricked, with the occupancy).
    pub plan_ms: f64,
    /// Upload, min/max, normalization and histogram (or the host preparation and brick upload
    /// of a bricked volume), with their own breakdown.
    pub prepare: PrepareTimings,
    /// Denoising I_norm (`recipe.denoise`; 0 without), pipeline creation and dispatch.
    pub denoise_ms: f64,
    /// Histogram analysis: peaks, Table-1 row, tissue windows (CPU).
    pub peaks_ms: f64,
    /// The derived volumes the scene needs (pipeline creation, dispatches, the maximum's
    /// readback); 0 when the scene needs none.
    pub derivatives_ms: f64,
    /// Part of `derivatives_ms`: getting the derivative pipelines (waiting for a worker, or
    /// creating them).
    pub derivatives_pipelines_ms: f64,
    /// Getting pipelines during the whole call (in `prepare.pipelines_ms` and
    /// `derivatives_pipelines_ms`).
    pub pipelines_ms: f64,
    /// The whole call.
    pub wall_ms: f64,
}

/// A volume ready to render: the twin (prepared volume and derived volumes), the histogram
/// analysis, the scene with its planned effects, and the plan.
pub struct OpenedVolume {
    /// Prepared volume and the derived volumes of `scene`'s effects.
    pub twin: Twin,
    /// Peaks, the paper's Table-1 row, tissue windows.
    pub report: TissueReport,
    /// The caller's scene with the planned (possibly degraded) effects.
    pub scene: Scene,
    /// The plan it was prepared for.
    pub plan: Plan,
    /// Where the time went.
    pub timings: OpenTimings,
}

impl Engine {
    /// Plans `recipe`'s effects for `volume` at an `image`-pixel target within the memory
    /// budget, prepares the volume the way the plan says, analyses its histogram, builds the
    /// recipe's scene, and derives what the scene needs.
    pub fn open_volume(
        &mut self,
        volume: &Volume,
        image: [u32; 2],
        recipe: &SceneRecipe,
    ) -> Result<OpenedVolume, OpenError> {
        // The library's open path for a volume in memory, without pipelines ahead of time.
        let options = super::OpenOptions {
            image,
            recipe: recipe.clone(),
            first_frame: false,
            ..Default::default()
        };
        self.open_with(volume, &options)
    }

    /// [`Engine::open_volume`] with the first plan made by the caller: `first` is
    /// `self.plan(recipe.effects, volume, image, 1.0)` (its time is the caller's).
    ///
    /// A MIP or MinIP recipe is normalized with the projection's robust range
    /// (`NormalizeMode::for_projection`: the brightest voxels stay graded).
    pub fn open_planned(
        &mut self,
        volume: &Volume,
        image: [u32; 2],
        recipe: &SceneRecipe,
        first: Result<Plan, DoesNotFit>,
    ) -> Result<OpenedVolume, OpenError> {
        let configured = self.config.normalize;
        let projection = recipe.effects.mode != crate::scene::RenderMode::Dvr;
        self.config.normalize = configured.for_projection(projection);
        let opened = self.open_planned_normalized(volume, image, recipe, first);
        self.config.normalize = configured;
        opened
    }

    /// [`Engine::open_planned`] with the normalization mode already chosen.
    fn open_planned_normalized(
        &mut self,
        volume: &Volume,
        image: [u32; 2],
        recipe: &SceneRecipe,
        first: Result<Plan, DoesNotFit>,
    ) -> Result<OpenedVolume, OpenError> {
        let start = Instant::now();
        let pipelines_before = self.pipeline_times.caller_ms;
        let mut timings = OpenTimings::default();
        let effects = recipe.effects_for(&self.identify(volume));
        let first = self.with_preset_vessels(first, (effects, recipe.denoise), volume, image);
        let (prepared, report, mut scene, plan) = match first {
            Ok(plan) if plan.layout == Layout::Whole => {
                self.set_normalized_format(plan.normalized_format)?;
                let prepared = self.prepare(volume)?;
                timings.prepare = prepared.timings.clone();
                let before_denoise = Instant::now();
                let prepared = self.denoise_opened(prepared, recipe)?;
                timings.denoise_ms = ms(before_denoise);
                let before_peaks = Instant::now();
                let identity = self.identify(volume);
                let mut prepared = prepared;
                if super::mask_edge::wanted_for(&identity) {
                    prepared.leave_out_mask_edge(volume);
                }
                let report = self.analyze_identified(&prepared, &identity);
                prepared.identity = identity;
                let scene = recipe.scene_for(&report);
                timings.peaks_ms = ms(before_peaks);
                (prepared, report, scene, plan)
            }
            first => {
                // Before the host preparation: the filters need the whole volume.
                check_denoise_whole(recipe)?;
                if first.is_err() {
                    // Over the budget (or the bricking limit) with every brick resident: the host
                    // preparation is only worth it if some occupancy could fit. The best case
                    // holds a single brick; when even that does not fit, say so now.
                    self.plan(effects, volume, image, 0.0)?;
                }
                let before_host = Instant::now();
                let mut host = self.prepare_on_host(volume, vk::Format::R16_UNORM)?;
                let before_peaks = Instant::now();
                let identity = self.identify(volume);
                let edge_out = super::mask_edge::wanted_for(&identity);
                if edge_out {
                    host.leave_out_mask_edge(volume);
                }
                let report = self.analyze_host(&host, &identity);
                let scene = recipe.scene_for(&report);
                timings.peaks_ms = ms(before_peaks);
                let fraction = host
                    .brick_ranges(STORAGE_BRICK, STORAGE_HALO)
                    .needed_fraction(&scene);
                let before_plan = Instant::now();
                let plan = self.plan(effects, volume, image, fraction)?;
                timings.plan_ms += ms(before_plan);
                let host = if plan.normalized_format == vk::Format::R8_UNORM {
                    let mut host = self.prepare_on_host(volume, vk::Format::R8_UNORM)?;
                    if edge_out {
                        host.leave_out_mask_edge(volume);
                    }
                    host
                } else {
                    host
                };
                let staging_slots = match plan.layout {
                    Layout::Bricked { staging_slots, .. } => staging_slots,
                    Layout::Whole => 64,
                };
                let prepared = self.upload_bricked(&host, &scene, staging_slots)?;
                timings.prepare = prepared.timings.clone();
                // The host preparation, minus the analysis and the second plan timed above.
                timings.prepare.wall_ms = ms(before_host) - timings.peaks_ms - timings.plan_ms;
                (prepared, report, scene, plan)
            }
        };
        // The plan counted the preset's vessel channel (or degraded it off, and says so).
        scene.effects = plan.effects;
        let mut twin = Twin::new(prepared);
        let before_derivatives = Instant::now();
        let derivative_pipelines_before = self.pipeline_times.caller_ms;
        self.update_twin(&mut twin, &scene.effects)?;
        timings.derivatives_ms = ms(before_derivatives);
        let mut report = report;
        let before_fit = Instant::now();
        if self.refit_in_brain(volume, &twin, &mut report)? {
            // The windows now come from the fit inside the brain mask (engine/brain_fit.rs).
            let effects = scene.effects;
            scene = recipe.scene_for(&report);
            scene.effects = effects;
        }
        timings.peaks_ms += ms(before_fit);
        timings.derivatives_pipelines_ms =
            self.pipeline_times.caller_ms - derivative_pipelines_before;
        timings.pipelines_ms = self.pipeline_times.caller_ms - pipelines_before;
        timings.wall_ms = ms(start);
        Ok(OpenedVolume {
            twin,
            report,
            scene,
            plan,
            timings,
        })
    }
}

impl Engine {
    /// `first` again with `effects` when the caller planned without the vessel channel the
    /// preset turns on (a plan that degraded it off to fit keeps that choice): the vesselness
    /// volume and its scratch are then in the plan, never allocated past it.
    fn with_preset_vessels(
        &self,
        first: Result<Plan, DoesNotFit>,
        (effects, denoise): (crate::scene::Effects, crate::passes::denoise::Denoise),
        volume: &Volume,
        image: [u32; 2],
    ) -> Result<Plan, DoesNotFit> {
        let missing = |plan: &Plan| {
            effects.vessels
                && !plan.effects.vessels
                && !plan
                    .degradations
                    .iter()
                    .any(|d| d.accuracy_setting == "vessels off")
        };
        match first {
            Ok(plan) if missing(&plan) => {
                let mut input = self.plan_input(volume, image, 1.0);
                input.denoise = denoise;
                let sizes = super::DeviceImageSizes(self.device());
                crate::engine::plan::plan(effects, &input, &sizes)
            }
            first => first,
        }
    }
}

/// Milliseconds since `since`.
fn ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

impl Engine {
    /// The histogram analysis of a prepared volume (peaks, Table-1 row, windows) with the
    /// engine's analysis parameters.
    pub fn analyze(&self, prepared: &PreparedVolume) -> TissueReport {
        let params = &self.config.analysis;
        let identity = Identity::from_choices(params.modality, params.contrast);
        self.analyze_identified(prepared, &identity)
    }

    /// What `volume` is (modality, contrast) from its metadata and values, with the engine's
    /// `--modality` / `--contrast` choices (`analysis::modality`).
    pub fn identify(&self, volume: &Volume) -> Identity {
        let params = &self.config.analysis;
        let values = crate::volume::stats::value_summary(volume);
        identify(
            &volume.facts,
            Some(&values),
            params.modality,
            params.contrast,
        )
    }

    /// [`Engine::analyze`] for a volume whose modality and contrast `identity` holds.
    pub fn analyze_identified(
        &self,
        prepared: &PreparedVolume,
        identity: &Identity,
    ) -> TissueReport {
        self.analyze_histogram(
            &prepared.tissue_histogram,
            &prepared.normalization,
            (prepared.range, identity),
            prepared.voxel_count,
            prepared.nonfinite_voxels(),
        )
    }

    fn analyze_host(&self, host: &HostPrepared, identity: &Identity) -> TissueReport {
        self.analyze_histogram(
            &host.tissue_histogram,
            &host.normalization,
            (host.range, identity),
            host.voxel_count,
            host.voxel_count - host.finite_voxels,
        )
    }

    fn analyze_histogram(
        &self,
        histogram: &[u32; crate::passes::histogram::BINS],
        normalization: &crate::passes::normalize::Normalization,
        (range, identity): (crate::analysis::RangeChoice, &Identity),
        voxel_count: u64,
        nonfinite_voxels: u64,
    ) -> TissueReport {
        let (imin, imax) = match (normalization.imin, normalization.imax) {
            (Some(lo), Some(hi)) => (lo, hi),
            _ => (0.0, 0.0),
        };
        let mut report = analyze_identified(
            histogram,
            imin,
            imax,
            voxel_count as usize,
            nonfinite_voxels as usize,
            &self.config.analysis,
            identity,
        );
        report.range = range;
        report
    }
}
