//! The engine's pipelines: created on first use, or ahead of use on worker threads.
//!
//! Decisions:
//! - Every pipeline is found by a [`PipelineKey`] (the sample kind of the analysis passes, a
//!   derivative variant, the brick-range pass, a raymarch variant) and created once per engine,
//!   through the engine's pipeline cache.
//! - [`Engine::start_pipelines`] creates the pipelines a first frame will need on worker threads
//!   while the caller goes on (loading, uploading). Drivers compile one pipeline on one core: on
//!   the H200 (driver 580) the seven pipelines of a first frame took 157 ms one after another
//!   with cold caches, the largest (the raymarch) 44 ms. `vkCreateComputePipelines` may be
//!   called from several threads with one `VkPipelineCache` (it is internally synchronized
//!   unless created externally synchronized, which this engine never does).
//! - The workers leave one core to the caller: at most `available_parallelism - 1` of them (at
//!   least one), each taking its share of the pipelines in order of need (analysis passes
//!   first). On a 16-core host that is one worker per pipeline; on lavapipe's 2 cores one worker
//!   doing them in turn, because seven compiling threads starved the file's inflate, which shares
//!   those cores (the main thread waited 56 ms for the loader instead of 13).
//! - Whoever needs a pipeline waits for that one only (the analysis passes do not wait for the
//!   raymarch); a pipeline nobody started is created inline, as before. An error of a worker
//!   surfaces when its pipeline is used, as it would have when created there; the pipelines of
//!   a guess that turned out wrong (for example effects a memory plan later degraded) are simply
//!   never used.
//! - The time callers spent getting pipelines (waiting or creating inline) and the workers'
//!   compile times are recorded ([`PipelineTimes`]), so a time-to-first-pixel report can say
//!   what the pipelines cost and how much of it was hidden.

use super::{Engine, KindPasses};
use crate::gpu::{Device, GpuError, GpuResult, PipelineCache};
use crate::passes::brain::BrainPass;
use crate::passes::derivatives::{DerivativeOutputs, DerivativePass};
use crate::passes::fine_histogram::FineHistogramPass;
use crate::passes::histogram::HistogramPass;
use crate::passes::minmax::MinMaxPass;
use crate::passes::normalize::NormalizePass;
use crate::passes::occupancy::OccupancyPass;
use crate::passes::raymarch::{RaymarchPass, RaymarchVariant};
use crate::scene::Effects;
use crate::volume::SampleKind;
use std::sync::atomic::Ordering;
use std::sync::mpsc::{Receiver, sync_channel};
use std::time::Instant;

/// One pipeline (or the three analysis pipelines of a sample kind) of the engine.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum PipelineKey {
    /// Min/max, normalization and histogram of a sample kind.
    Kind(SampleKind),
    /// One derivative variant.
    Derivative(DerivativeOutputs),
    /// The brick-range (occupancy) pass.
    Occupancy,
    /// Brain extraction's five pipelines.
    Brain,
    /// One raymarch variant.
    Raymarch(RaymarchVariant),
}

impl PipelineKey {
    /// The pipeline as plans name its variant (traces).
    fn describe(&self) -> String {
        match self {
            PipelineKey::Kind(kind) => format!("analysis passes ({})", kind.name()),
            PipelineKey::Derivative(o) => super::kernels::derivative_variant_name(o),
            PipelineKey::Occupancy => "occupancy".into(),
            PipelineKey::Brain => "brain extraction".into(),
            PipelineKey::Raymarch(v) => v.describe(),
        }
    }
}

/// What a worker built.
enum Built {
    Kind(KindPasses),
    Derivative(DerivativePass),
    Occupancy(OccupancyPass),
    Brain(BrainPass),
    Raymarch(RaymarchPass),
}

type WorkerResult = (GpuResult<Built>, Instant, Instant);

/// A pipeline being created on a worker thread: its result arrives on `result`.
pub(crate) struct Pending {
    key: PipelineKey,
    result: Receiver<WorkerResult>,
}

/// Where the engine's pipeline time went, milliseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct PipelineTimes {
    /// Pipelines created on worker threads (and used).
    pub created_ahead: u32,
    /// Their creation times added up: what creating them one after another would have cost.
    pub ahead_sum_ms: f64,
    /// From the first worker's start to the last used worker's end.
    pub ahead_span_ms: f64,
    /// Time callers spent getting pipelines: waiting for workers, or creating them inline.
    pub caller_ms: f64,
}

/// Threads that may compile at once: all cores but one (left to the caller), at least one.
fn worker_limit() -> usize {
    std::thread::available_parallelism()
        .map(|n| n.get().saturating_sub(1))
        .unwrap_or(1)
        .max(1)
}

/// Creates the pipeline(s) of `key`; `parallel`: the three analysis pipelines of a sample kind
/// on three threads.
fn build(
    device: &Device,
    cache: &PipelineCache,
    key: PipelineKey,
    parallel: bool,
) -> GpuResult<Built> {
    let raw = cache.raw();
    let _span = crate::files::trace::span(format!("pipeline {}", key.describe()), "pipelines");
    Ok(match key {
        PipelineKey::Kind(kind) if !parallel => Built::Kind(KindPasses {
            minmax: MinMaxPass::new(device, kind, raw)?,
            normalize: NormalizePass::new(device, kind, raw)?,
            histogram: HistogramPass::new(device, kind, raw)?,
            fine_histogram: FineHistogramPass::new(device, kind, raw)?,
        }),
        PipelineKey::Kind(kind) => {
            // Four compiles, four threads (each joined before returning).
            let (minmax, normalize, histogram, fine_histogram) = std::thread::scope(|scope| {
                let minmax = scope.spawn(|| MinMaxPass::new(device, kind, raw));
                let normalize = scope.spawn(|| NormalizePass::new(device, kind, raw));
                let fine = scope.spawn(|| FineHistogramPass::new(device, kind, raw));
                let histogram = HistogramPass::new(device, kind, raw);
                let stopped = || GpuError::Internal("a pipeline thread stopped".into());
                (
                    minmax.join().map_err(|_| stopped()).and_then(|r| r),
                    normalize.join().map_err(|_| stopped()).and_then(|r| r),
                    histogram,
                    fine.join().map_err(|_| stopped()).and_then(|r| r),
                )
            });
            Built::Kind(KindPasses {
                minmax: minmax?,
                normalize: normalize?,
                histogram: histogram?,
                fine_histogram: fine_histogram?,
            })
        }
        PipelineKey::Derivative(outputs) => {
            Built::Derivative(DerivativePass::new(device, outputs, raw)?)
        }
        PipelineKey::Occupancy => Built::Occupancy(OccupancyPass::new(device, raw)?),
        PipelineKey::Brain => Built::Brain(BrainPass::new(device, raw)?),
        PipelineKey::Raymarch(variant) => Built::Raymarch(RaymarchPass::new(device, variant, raw)?),
    })
}

/// The pipelines that preparing a volume (of `kind`, when known) and rendering a first frame of
/// `effects` use, analysis passes first; `texel_lookups` as the device prefers
/// (`AdapterInfo::prefers_texel_lookups`), as render.rs sets it.
pub(super) fn first_frame_keys(
    effects: &Effects,
    kind: Option<SampleKind>,
    bricked: bool,
    texel_lookups: bool,
) -> Vec<PipelineKey> {
    let mut keys = Vec::new();
    if let (Some(kind), false) = (kind, bricked) {
        keys.push(PipelineKey::Kind(kind));
    }
    if let Some(outputs) = effects.derivative_outputs() {
        keys.extend(
            super::derive::derivative_variants(outputs)
                .into_iter()
                .map(PipelineKey::Derivative),
        );
        // Brain extraction runs with the derived volumes of a whole volume (on the H200 its
        // five pipelines cost about 100 ms of a cold first pixel when created there).
        if outputs.brain != crate::passes::brain::BrainSwitch::Off && !bricked {
            keys.push(PipelineKey::Brain);
        }
    }
    let raymarch = RaymarchVariant {
        texel_lookups,
        ..RaymarchVariant::of_layout(effects, false, bricked)
    };
    if raymarch.skip_empty {
        keys.push(PipelineKey::Occupancy);
    }
    // With extraction on, the first frame of a head reads the mask (BRAIN=on, as render.rs
    // decides) and that of any other volume does not: both are compiled ahead, so neither is on
    // the main thread's path (on the H200 the main thread waited 182 ms for pipelines with
    // BRAIN=on compiled there, 107 ms without extraction).
    let extracting = raymarch.mode == 0
        && !bricked
        && effects.brain != crate::passes::brain::BrainSwitch::Off
        && effects.derivative_outputs().is_some();
    let mut variants = vec![raymarch];
    if extracting {
        variants.insert(
            0,
            RaymarchVariant {
                brain: true,
                ..raymarch
            },
        );
    }
    for variant in variants {
        // A classified variant's first frame runs its classifier first (engine/classified.rs).
        if variant.classified {
            keys.push(PipelineKey::Raymarch(variant.classifier()));
        }
        keys.push(PipelineKey::Raymarch(variant));
    }
    keys
}

impl Engine {
    fn has_pipeline(&self, key: PipelineKey) -> bool {
        match key {
            PipelineKey::Kind(kind) => self.kind_passes.contains_key(&kind),
            PipelineKey::Derivative(o) => self.derivative_passes.contains_key(&o),
            PipelineKey::Occupancy => self.occupancy_pass.is_some(),
            PipelineKey::Brain => self.brain_pass.is_some(),
            PipelineKey::Raymarch(v) => self.raymarch_passes.contains_key(&v),
        }
    }

    /// Starts creating, on worker threads, every pipeline that preparing a volume (of `kind`,
    /// when already known) and rendering a first frame of `effects` will use, unless it exists
    /// or is being created; returns how many were started. The caller goes on at once; each
    /// pipeline is waited for where it is first used (see the module's decisions). Where no
    /// thread can be started, the pipeline is created on first use. Creating pipelines ahead
    /// only moves their compiles: every result is the same as with creation on first use.
    ///
    /// The raymarch variant assumes empty-space skipping where the effects ask for it; a volume
    /// with nothing to skip (see [`super::MAX_OCCUPANCY_FOR_SKIPPING`]) makes the first frame
    /// create the variant without it.
    pub fn start_pipelines(
        &mut self,
        effects: &Effects,
        kind: Option<SampleKind>,
        bricked: bool,
    ) -> u32 {
        let texel_lookups = self.texel_lookups();
        let keys: Vec<PipelineKey> = first_frame_keys(effects, kind, bricked, texel_lookups)
            .into_iter()
            .filter(|&key| !self.has_pipeline(key) && !self.pending.iter().any(|p| p.key == key))
            .collect();
        let threads = worker_limit().min(keys.len());
        // Worker i takes keys i, i + threads, ...: each worker's first key is among the first
        // needed.
        let mut shares: Vec<Vec<PipelineKey>> = vec![Vec::new(); threads];
        for (i, key) in keys.into_iter().enumerate() {
            shares[i % threads.max(1)].push(key);
        }
        let parallel_kind = worker_limit() >= 3;
        let mut started = 0;
        for share in shares {
            let mut jobs = Vec::new();
            let mut pending = Vec::new();
            for key in share {
                let (send, result) = sync_channel(1);
                jobs.push((key, send));
                pending.push(Pending { key, result });
            }
            let device = self.device.clone();
            let cache = self.pipeline_cache.clone();
            let cancelled = self.workers_cancelled.clone();
            let spawned = std::thread::Builder::new()
                .name("morphray pipelines".into())
                .spawn(move || {
                    for (key, send) in jobs {
                        if cancelled.load(Ordering::Relaxed) {
                            return;
                        }
                        let start = Instant::now();
                        let built = build(&device, &cache, key, parallel_kind);
                        // The engine may be gone (its receiver dropped): nothing to deliver to.
                        let _ = send.send((built, start, Instant::now()));
                    }
                });
            // Where no thread can be started, the share is created on first use.
            if let Ok(handle) = spawned {
                started += pending.len() as u32;
                self.pending.extend(pending);
                self.workers.push(handle);
            }
        }
        started
    }

    /// Where the pipeline time went so far.
    pub fn pipeline_times(&self) -> PipelineTimes {
        let mut times = self.pipeline_times;
        if let Some((first, last)) = self.ahead_window {
            times.ahead_span_ms = (last - first).as_secs_f64() * 1e3;
        }
        times
    }

    /// Makes sure the pipeline(s) of `key` exist: takes a worker's, or creates them inline.
    pub(crate) fn ensure_pipeline(&mut self, key: PipelineKey) -> GpuResult<()> {
        if self.has_pipeline(key) {
            return Ok(());
        }
        let start = Instant::now();
        let built = match self.pending.iter().position(|p| p.key == key) {
            Some(at) => {
                let pending = self.pending.swap_remove(at);
                match pending.result.recv() {
                    Ok((built, from, to)) => {
                        if built.is_ok() {
                            self.pipeline_times.created_ahead += count(key);
                            self.pipeline_times.ahead_sum_ms += (to - from).as_secs_f64() * 1e3;
                            self.ahead_window = Some(match self.ahead_window {
                                Some((a, b)) => (a.min(from), b.max(to)),
                                None => (from, to),
                            });
                        }
                        built
                    }
                    Err(_) => Err(GpuError::Internal(
                        "a pipeline-creation thread stopped unexpectedly".into(),
                    )),
                }
            }
            None => build(&self.device, &self.pipeline_cache, key, false),
        };
        self.pipeline_times.caller_ms += start.elapsed().as_secs_f64() * 1e3;
        match built? {
            Built::Kind(p) => {
                if let PipelineKey::Kind(kind) = key {
                    self.kind_passes.insert(kind, p);
                }
            }
            Built::Derivative(p) => {
                if let PipelineKey::Derivative(o) = key {
                    self.derivative_passes.insert(o, p);
                }
            }
            Built::Occupancy(p) => self.occupancy_pass = Some(p),
            Built::Brain(p) => self.brain_pass = Some(std::sync::Arc::new(p)),
            Built::Raymarch(p) => {
                if let PipelineKey::Raymarch(v) = key {
                    self.raymarch_passes.insert(v, p);
                }
            }
        }
        self.counters.pipelines_created += count(key);
        Ok(())
    }

    /// The analysis passes of `kind`.
    pub(crate) fn kind_passes(&mut self, kind: SampleKind) -> GpuResult<&KindPasses> {
        self.ensure_pipeline(PipelineKey::Kind(kind))?;
        self.kind_passes.get(&kind).ok_or_else(lost)
    }

    /// The derivative pass of `outputs`.
    pub(crate) fn derivative_pass(
        &mut self,
        outputs: DerivativeOutputs,
    ) -> GpuResult<&DerivativePass> {
        self.ensure_pipeline(PipelineKey::Derivative(outputs))?;
        self.derivative_passes.get(&outputs).ok_or_else(lost)
    }

    /// The brick-range pass.
    pub(crate) fn occupancy_pass(&mut self) -> GpuResult<&OccupancyPass> {
        self.ensure_pipeline(PipelineKey::Occupancy)?;
        self.occupancy_pass.as_ref().ok_or_else(lost)
    }

    /// Brain extraction's pipelines (shared, so a recording can use them while the engine is
    /// borrowed for its images).
    pub(crate) fn brain_pass(&mut self) -> GpuResult<std::sync::Arc<BrainPass>> {
        self.ensure_pipeline(PipelineKey::Brain)?;
        self.brain_pass.clone().ok_or_else(lost)
    }

    /// The raymarch pass of `variant`.
    pub(crate) fn raymarch_pass(&mut self, variant: RaymarchVariant) -> GpuResult<&RaymarchPass> {
        self.ensure_pipeline(PipelineKey::Raymarch(variant))?;
        self.raymarch_passes.get(&variant).ok_or_else(lost)
    }

    /// Waits for every worker still running (the engine is going away).
    pub(crate) fn join_pipeline_workers(&mut self) {
        // Pipelines not started yet are not wanted any more.
        self.workers_cancelled.store(true, Ordering::Relaxed);
        self.pending.clear();
        for worker in self.workers.drain(..) {
            // A worker that panicked is a fault to report, not to skip (issue 13 item 6).
            if worker.join().is_err() {
                self.device.shared.faults.record(&GpuError::Internal(
                    "a pipeline-creation thread panicked".into(),
                ));
            }
        }
    }
}

/// Pipelines behind one key.
fn count(key: PipelineKey) -> u32 {
    match key {
        PipelineKey::Kind(_) => 3,
        PipelineKey::Brain => 5,
        _ => 1,
    }
}

fn lost() -> GpuError {
    GpuError::Internal("pass cache lost an entry".into())
}
