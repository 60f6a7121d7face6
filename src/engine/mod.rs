//! One volume on one device: runs the passes in order and owns their outputs.
//!
//! Decisions:
//! - Passes (pipelines) are created on first use and cached per variant (sample kind, derivative
//!   outputs), so a second volume of the same kind creates no pipeline. Every pipeline is created
//!   through the engine's one [`PipelineCache`] (in memory by default; a directory when the
//!   caller asks, saved only when the caller says so, after its first frame). A caller that
//!   knows what its first frame needs can have them compiled ahead on worker threads
//!   (`pipelines.rs`).
//! - The data flow (ARCHITECTURE.md): upload -> min/max -> (CPU, f64) normalization plan ->
//!   normalize -> histogram -> (CPU) peaks; derived volumes only when asked for. The min/max
//!   result makes one host round trip, because the scale and offset are computed in f64.
//! - The engine records what each persistent image was last used for, so readback and later
//!   passes put the right barrier in front of it.

mod brain;
mod brain_extract;
mod brain_fit;
mod bricked;
pub mod classified;
mod denoise;
mod derive;
mod frames;
mod host_slots;
pub mod kernels;
mod labels;
mod layers;
mod maps;
pub mod mask_edge;
pub mod matcap;
mod occupancy;
mod open;
pub mod pick;
mod pipelines;
pub mod plan;
mod prepare;
mod probe;
pub mod readback;
mod render;
mod robust;
pub mod session;
pub mod slice;
mod transfer;
mod twin;
pub mod upload;
mod vessels;

pub use brain::BrainMask;
pub use bricked::HostPrepared;
pub use derive::Derived;
pub use labels::{LabelVolume, label_brick_bits, label_colours};
pub use layers::{LayerUniforms, LayerVolume, layer_brick_bits, layer_colours_desc};
pub use maps::{DerivedMaps, MapRequest};
pub use occupancy::BrickBounds;
pub use open::{OpenError, OpenTimings, OpenedVolume};
pub use pipelines::PipelineTimes;
pub use prepare::{BrickAtlas, PrepareTimings, PreparedVolume, VolumeLayout};
pub use render::{
    FRAMES_IN_FLIGHT, Frame, MAX_OCCUPANCY_FOR_SKIPPING, RecordedFrame, RenderTarget, SampleCounts,
};
pub use session::{OpenOptions, Session, SessionError, SessionTimings};
pub use twin::{Twin, TwinStep, TwinUpdate, twin_step};
pub use vessels::Vesselness;

use crate::gpu::pipeline_cache::PersistError;
use crate::gpu::{
    Access, Buffer, BufferDesc, Device, DeviceConfig, Filter, GpuResult, Image, ImageDesc,
    PersistOutcome, PipelineCache, PipelineCacheConfig, Recording, Sampler,
};
use crate::passes::derivatives::{DerivativeOutputs, DerivativePass};
use crate::passes::fine_histogram::FineHistogramPass;
use crate::passes::histogram::HistogramPass;
use crate::passes::minmax::MinMaxPass;
use crate::passes::normalize::NormalizePass;
use crate::passes::occupancy::OccupancyPass;
use crate::passes::raymarch::{RaymarchPass, RaymarchVariant};
use crate::volume::SampleKind;
use ash::vk;
use std::collections::HashMap;
use std::sync::Arc;

/// How to create an engine.
#[derive(Clone, Debug)]
pub struct EngineConfig {
    /// Device choice and validation.
    pub device: DeviceConfig,
    /// Format of the normalized volume (R16_UNORM by default; R8_UNORM, R16_SFLOAT and
    /// R32_SFLOAT are the accuracy study's alternatives).
    pub normalized_format: vk::Format,
    /// Most GPU memory the engine may hold at once (bytes); None: what the device allows.
    pub memory_budget: Option<u64>,
    /// Brick volumes even when they fit whole (to measure what bricking costs).
    pub force_bricking: bool,
    /// Pipeline cache: off, in memory (the default: no disk I/O unless asked for), or loaded
    /// from and saved into a directory ([`Engine::persist_pipeline_cache`] saves it).
    pub pipeline_cache: PipelineCacheConfig,
    /// Which intensity range maps to I_norm 0..1 (robust percentiles or the paper's min/max).
    pub normalize: crate::analysis::NormalizeMode,
    /// Histogram analysis parameters (peaks, tissue assignment, windows).
    pub analysis: crate::analysis::AnalysisParams,
    /// Open a 4-D NIfTI whose preset is `epi` (BOLD, ASL) as the mean of its frames instead of
    /// the frame asked for (the command line's default when no `--frame` is given; off by
    /// default, so a caller that picks a frame gets that frame).
    pub epi_mean_frame: bool,
    /// Read the raymarch's per-sample tables (occupancy, transfer function) through texel
    /// buffers (`Some(true)`) or storage buffers (`Some(false)`); None: what the device prefers
    /// (`AdapterInfo::prefers_texel_lookups`: texel buffers on CPU devices only). The same
    /// picture either way; tests pin both.
    pub texel_lookups: Option<bool>,
    /// Empty-space skipping jumps across the whole cube of empty bricks the distance map finds
    /// around a sample (true, the default) or one brick at a time (false: the occupancy bits
    /// alone, to measure what the map saves). The same picture either way.
    pub distance_skipping: bool,
}

impl Default for EngineConfig {
    fn default() -> Self {
        EngineConfig {
            device: DeviceConfig::default(),
            normalized_format: vk::Format::R16_UNORM,
            memory_budget: None,
            force_bricking: false,
            pipeline_cache: PipelineCacheConfig::InMemory,
            normalize: crate::analysis::NormalizeMode::default(),
            analysis: crate::analysis::AnalysisParams::default(),
            epi_mean_frame: false,
            texel_lookups: None,
            distance_skipping: true,
        }
    }
}

/// The analysis passes of one sample kind.
pub(crate) struct KindPasses {
    minmax: MinMaxPass,
    normalize: NormalizePass,
    histogram: HistogramPass,
    fine_histogram: FineHistogramPass,
}

/// 1-texel stand-ins bound where a shader variant declares an input it does not read.
struct Placeholders {
    gradient: Arc<Image>,
    normal: Arc<Image>,
    occupancy: Arc<Buffer>,
    /// Bound as the occupancy texels where a variant does not skip.
    uint_texels: Arc<Buffer>,
    /// Bound as the classified volume's storage binding where nothing writes it (kept in
    /// `Access::ComputeWriteImage`).
    storage: Arc<Image>,
}

/// What the engine has done since it was created: how often it compiled a pipeline and ran each
/// kind of compute work. Integrators and tests use it to check that a scene change ran only what
/// it had to (a tissue toggle runs nothing; switching back to a variant compiles nothing).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct EngineCounters {
    /// Compute pipelines created (each variant once; later uses hit the cache).
    pub pipelines_created: u32,
    /// Volumes prepared on the GPU (upload, min/max, normalize, histogram).
    pub prepares: u32,
    /// Derivative dispatches (an 8-bit plan runs two: the maximum, then the stores).
    pub derivative_runs: u32,
    /// Brick-range (occupancy) passes.
    pub occupancy_runs: u32,
    /// Brick-bounds passes (bits and opacity bounds; once per frame slot and classification).
    pub brick_bounds_runs: u32,
    /// Frames rendered.
    pub frames: u32,
    /// Classified-volume builds (a CLASSIFIED variant's rebuild when the classification
    /// changed).
    pub classify_runs: u32,
}

/// Image sizes as this device will allocate them (for plans).
struct DeviceImageSizes<'a>(&'a Device);

impl plan::ImageSizes for DeviceImageSizes<'_> {
    fn image_bytes(&self, desc: &ImageDesc) -> u64 {
        self.0.image_memory_bytes(desc)
    }

    fn buffer_bytes(&self, desc: &BufferDesc) -> u64 {
        self.0.buffer_memory_bytes(desc)
    }
}

/// The GPU engine.
pub struct Engine {
    device: Device,
    config: EngineConfig,
    kind_passes: HashMap<SampleKind, KindPasses>,
    derivative_passes: HashMap<DerivativeOutputs, DerivativePass>,
    raymarch_passes: HashMap<RaymarchVariant, RaymarchPass>,
    occupancy_pass: Option<OccupancyPass>,
    brain_pass: Option<std::sync::Arc<crate::passes::brain::BrainPass>>,
    nearest: Arc<Sampler>,
    linear: Arc<Sampler>,
    placeholders: Placeholders,
    /// The placeholder images are in the layout sampling needs.
    placeholders_ready: bool,
    pipeline_cache: Arc<PipelineCache>,
    counters: EngineCounters,
    /// Pipelines being created on worker threads (`pipelines.rs`), and those threads.
    pending: Vec<pipelines::Pending>,
    workers: Vec<std::thread::JoinHandle<()>>,
    workers_cancelled: Arc<std::sync::atomic::AtomicBool>,
    pipeline_times: PipelineTimes,
    /// First start and last end of the workers' pipelines that were used.
    ahead_window: Option<(std::time::Instant, std::time::Instant)>,
    /// The image a matcap-lit frame looks its normals up in (`matcap.rs`).
    matcap: Arc<crate::scene::matcap::MatcapImage>,
    /// The 1x1 target depth picks render into, after the first (`pick.rs`).
    pick_target: Option<RenderTarget>,
    /// The layers a depth pick sees (`pick.rs`), as the picture's target draws them.
    pick_layers: Vec<(Arc<LayerVolume>, crate::scene::layer::LayerStyle)>,
}

impl Drop for Engine {
    fn drop(&mut self) {
        // Workers hold the device and the cache, so they are safe to outlive the engine; joining
        // them just keeps their work from running on behind its back.
        self.join_pipeline_workers();
    }
}

/// The engine's 1-texel stand-ins, bound where a variant declares an input it never reads (as
/// [`Engine::with_device`] creates them, and as the pass plan declares them).
pub struct PlaceholderDescs {
    /// A gradient image.
    pub gradient: ImageDesc,
    /// A normal image.
    pub normal: ImageDesc,
    /// A storage buffer, also an RGBA32F texel buffer (the transfer-function table's binding).
    pub buffer: BufferDesc,
    /// A storage buffer, also an R32_UINT texel buffer (the occupancy bindings).
    pub uint_texels: BufferDesc,
    /// A storage image (the classified volume's binding).
    pub storage: ImageDesc,
}

/// The stand-ins' descriptions. A texel view's format must match what the shader declares
/// (`samplerBuffer` float, `usamplerBuffer` uint), hence two texel buffers.
pub fn placeholder_descs() -> PlaceholderDescs {
    PlaceholderDescs {
        gradient: ImageDesc::volume(
            "placeholder (gradient)",
            [1, 1, 1],
            vk::Format::R16G16_SFLOAT,
        ),
        normal: ImageDesc::volume(
            "placeholder (normals)",
            [1, 1, 1],
            vk::Format::R8G8B8A8_SNORM,
        ),
        buffer: BufferDesc::host_storage("placeholder (occupancy)", 16)
            .with_texel_view(vk::Format::R32G32B32A32_SFLOAT),
        uint_texels: BufferDesc::host_storage("placeholder (uint texels)", 16)
            .with_texel_view(vk::Format::R32_UINT),
        storage: ImageDesc::volume(
            "placeholder (storage)",
            [1, 1, 1],
            classified::CLASSIFIED_FORMAT,
        ),
    }
}

impl Engine {
    /// Creates the device and the shared objects; pipelines are created on first use.
    pub fn new(config: EngineConfig) -> GpuResult<Engine> {
        let device = Device::new(&config.device)?;
        Self::with_device(device, config)
    }

    /// An engine on a device the caller made (`config.device` is then not used): one adopted
    /// from an integrator's Vulkan handles ([`Device::adopt`]), or a device shared by several
    /// engines, as the viewer shares one between its interface thread and its loader thread
    /// (volumes prepared by one are rendered by the other).
    pub fn with_device(device: Device, config: EngineConfig) -> GpuResult<Engine> {
        let pipeline_cache = Arc::new(PipelineCache::new(&device, &config.pipeline_cache)?);
        let nearest = Sampler::new(&device, Filter::Nearest)?;
        let linear = Sampler::new(&device, Filter::Linear)?;
        let descs = placeholder_descs();
        let placeholders = Placeholders {
            gradient: Image::new(&device, descs.gradient)?,
            normal: Image::new(&device, descs.normal)?,
            occupancy: Buffer::with_data(&device, descs.buffer, &[0u8; 16])?,
            uint_texels: Buffer::with_data(&device, descs.uint_texels, &[0u8; 16])?,
            storage: Image::new(&device, descs.storage)?,
        };
        // Their layout transition waits for the first frame (`ensure_placeholder_layouts`): an
        // engine that only compiles (`morphray kernels`, on a stub device that cannot execute)
        // submits nothing, and no start-up waits for a submission.
        Ok(Engine {
            device,
            config,
            kind_passes: HashMap::new(),
            derivative_passes: HashMap::new(),
            raymarch_passes: HashMap::new(),
            occupancy_pass: None,
            brain_pass: None,
            nearest,
            linear,
            placeholders,
            placeholders_ready: false,
            pipeline_cache,
            counters: EngineCounters::default(),
            pending: Vec::new(),
            workers: Vec::new(),
            workers_cancelled: Arc::default(),
            pipeline_times: PipelineTimes::default(),
            ahead_window: None,
            matcap: Arc::default(),
            pick_target: None,
            pick_layers: Vec::new(),
        })
    }

    /// Moves the placeholder images once into the layout sampling needs (one small submission
    /// before the first frame that may bind them); they are never written.
    pub(crate) fn ensure_placeholder_layouts(&mut self) -> GpuResult<()> {
        if self.placeholders_ready {
            return Ok(());
        }
        let mut rec = Recording::new(&self.device, "placeholder layouts")?;
        // Orders nothing before (fresh images): moves the sampled two to SHADER_READ_ONLY, the
        // storage one to GENERAL.
        rec.barriers(
            &[],
            &[
                (
                    &self.placeholders.storage,
                    Access::Nothing,
                    Access::ComputeWriteImage,
                ),
                (
                    &self.placeholders.gradient,
                    Access::Nothing,
                    Access::ComputeSampled,
                ),
                (
                    &self.placeholders.normal,
                    Access::Nothing,
                    Access::ComputeSampled,
                ),
            ],
        );
        rec.submit()?.wait()?;
        self.placeholders_ready = true;
        Ok(())
    }

    /// What the engine has compiled and run so far.
    pub fn counters(&self) -> EngineCounters {
        self.counters
    }

    /// The pipeline cache every pipeline of this engine is created through (how it was loaded:
    /// [`PipelineCache::load`]).
    pub fn pipeline_cache(&self) -> &PipelineCache {
        &self.pipeline_cache
    }

    /// Saves the pipeline cache when the engine was configured with a cache directory and the
    /// cache changed since it was loaded (see [`PipelineCache::persist`]). Call it after the
    /// first frame: nothing on the way to the first pixel should wait for the disk.
    pub fn persist_pipeline_cache(&self) -> Result<PersistOutcome, PersistError> {
        self.pipeline_cache.persist()
    }

    /// The device.
    pub fn device(&self) -> &Device {
        &self.device
    }

    /// Memory the engine may plan with: the configured budget, capped by what the device can
    /// still give (VK_EXT_memory_budget, or the heap size).
    pub fn memory_budget(&self) -> u64 {
        let device = self.device.device_local_budget();
        self.config.memory_budget.map_or(device, |b| b.min(device))
    }

    /// What the pass plan needs to know about `volume`, an image of `image` pixels and this
    /// device; `occupied_fraction` of the storage bricks a visible tissue can occupy (1 when not
    /// yet known).
    pub fn plan_input(
        &self,
        volume: &crate::volume::Volume,
        image: [u32; 2],
        occupied_fraction: f64,
    ) -> crate::engine::plan::PlanInput {
        let dims = volume.dims.map(|d| u32::try_from(d).unwrap_or(u32::MAX));
        let mut input = self.plan_input_for(dims, volume.samples.kind(), image, occupied_fraction);
        input.spacing_mm = volume.spacing_mm;
        input
    }

    /// [`Engine::plan_input`] from a volume's size and sample kind (a volume that is open).
    pub fn plan_input_for(
        &self,
        dims: [u32; 3],
        sample_kind: crate::volume::SampleKind,
        image: [u32; 2],
        occupied_fraction: f64,
    ) -> crate::engine::plan::PlanInput {
        let a = self.device.adapter();
        crate::engine::plan::PlanInput {
            dims,
            sample_kind,
            image,
            max_image_dimension_3d: a.max_image_dimension_3d,
            max_storage_buffer_range: a.max_storage_buffer_range as u64,
            unified_memory: a.unified_memory,
            budget: self.memory_budget(),
            occupied_fraction,
            force_bricking: self.config.force_bricking,
            robust_range: self.config.normalize != crate::analysis::NormalizeMode::MinMax,
            denoise: crate::passes::denoise::Denoise::None,
            spacing_mm: [1.0; 3],
        }
    }

    /// Plans `effects` for `volume` at an `image`-pixel target on this device within the budget
    /// (`occupied_fraction` as in [`Engine::plan_input`]).
    pub fn plan(
        &self,
        effects: crate::scene::Effects,
        volume: &crate::volume::Volume,
        image: [u32; 2],
        occupied_fraction: f64,
    ) -> Result<crate::engine::plan::Plan, crate::engine::plan::DoesNotFit> {
        crate::engine::plan::plan(
            effects,
            &self.plan_input(volume, image, occupied_fraction),
            &DeviceImageSizes(&self.device),
        )
    }

    /// Chooses how the next volumes opened are normalized and identified (the command line's
    /// `--normalize`, `--contrast` and `--modality`). A client that opens volumes of several
    /// kinds on one engine, as the Python package does, sets them before each open.
    pub fn set_identity(
        &mut self,
        normalize: crate::analysis::NormalizeMode,
        contrast: crate::analysis::ContrastChoice,
        modality: crate::analysis::ModalityChoice,
    ) {
        self.config.normalize = normalize;
        self.config.analysis.contrast = contrast;
        self.config.analysis.modality = modality;
    }

    /// The format the next `prepare` stores I_norm in.
    pub fn normalized_format(&self) -> vk::Format {
        self.config.normalized_format
    }

    /// Chooses the format of I_norm for the next `prepare` (R8_UNORM, R16_UNORM, R16_SFLOAT or
    /// R32_SFLOAT); a format the device cannot sample, filter and store is refused.
    pub fn set_normalized_format(&mut self, format: vk::Format) -> GpuResult<()> {
        let needed = vk::FormatFeatureFlags::SAMPLED_IMAGE
            | vk::FormatFeatureFlags::STORAGE_IMAGE
            | vk::FormatFeatureFlags::SAMPLED_IMAGE_FILTER_LINEAR;
        if !self.device.supports_format(format, needed) {
            return Err(crate::gpu::GpuError::Unsupported(format!(
                "{format:?} 3D images cannot be sampled, filtered and stored on this device"
            )));
        }
        self.config.normalized_format = format;
        Ok(())
    }
}
