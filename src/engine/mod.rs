//! One volume on one device: runs the passes in order and owns their outputs.
//!
//! Decisions:
//! - Passes (pipelines) are created on first use and cached per variant (sample kind, derivative
//!   outputs), so a second volume of the same kind creates no pipeline.
//! - The data flow of DESIGN.md: upload -> min/max -> (CPU, f64) normalization plan ->
//!   normalize -> histogram -> (CPU) peaks; derived volumes only when asked for. The min/max
//!   result makes one host round trip, because the scale and offset are computed in f64.
//! - The engine records what each persistent image was last used for, so readback and later
//!   passes put the right barrier in front of it.

mod derive;
mod occupancy;
mod prepare;
mod probe;
pub mod readback;
mod render;
pub mod upload;

pub use derive::Derived;
pub use prepare::{PrepareTimings, PreparedVolume};
pub use render::{FRAMES_IN_FLIGHT, Frame, RenderTarget, SampleCounts};

use crate::gpu::{
    Access, Buffer, BufferDesc, Device, DeviceConfig, Filter, GpuResult, Image, ImageDesc,
    Recording, Sampler,
};
use crate::passes::derivatives::{DerivativeOutputs, DerivativePass};
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
}

impl Default for EngineConfig {
    fn default() -> Self {
        EngineConfig {
            device: DeviceConfig::default(),
            normalized_format: vk::Format::R16_UNORM,
        }
    }
}

/// The analysis passes of one sample kind.
struct KindPasses {
    minmax: MinMaxPass,
    normalize: NormalizePass,
    histogram: HistogramPass,
}

/// 1-texel stand-ins bound where a shader variant declares an input it does not read.
struct Placeholders {
    gradient: Arc<Image>,
    normal: Arc<Image>,
    occupancy: Arc<Buffer>,
}

/// The GPU engine.
pub struct Engine {
    device: Device,
    config: EngineConfig,
    kind_passes: HashMap<SampleKind, KindPasses>,
    derivative_passes: HashMap<DerivativeOutputs, DerivativePass>,
    raymarch_passes: HashMap<RaymarchVariant, RaymarchPass>,
    occupancy_pass: Option<OccupancyPass>,
    nearest: Arc<Sampler>,
    linear: Arc<Sampler>,
    placeholders: Placeholders,
    pipeline_cache: vk::PipelineCache,
}

impl Engine {
    /// Creates the device and the shared objects; pipelines are created on first use.
    pub fn new(config: EngineConfig) -> GpuResult<Engine> {
        let device = Device::new(&config.device)?;
        Engine::with_device(device, config)
    }

    /// An engine on an existing device (`config.device` is then ignored): the viewer runs one
    /// engine on its interface thread and one on its loader thread, sharing the device, so
    /// volumes prepared by one are rendered by the other.
    pub fn with_device(device: Device, config: EngineConfig) -> GpuResult<Engine> {
        let nearest = Sampler::new(&device, Filter::Nearest)?;
        let linear = Sampler::new(&device, Filter::Linear)?;
        let placeholders = Placeholders {
            gradient: Image::new(
                &device,
                ImageDesc::volume(
                    "placeholder (gradient)",
                    [1, 1, 1],
                    vk::Format::R16G16_SFLOAT,
                ),
            )?,
            normal: Image::new(
                &device,
                ImageDesc::volume(
                    "placeholder (normals)",
                    [1, 1, 1],
                    vk::Format::R8G8B8A8_SNORM,
                ),
            )?,
            occupancy: Buffer::with_data(
                &device,
                BufferDesc::host_storage("placeholder (occupancy)", 16),
                &[0u8; 16],
            )?,
        };
        let mut rec = Recording::new(&device, "placeholder layouts")?;
        // Moves the placeholders once into the layout sampling needs; they are never written.
        rec.barriers(
            &[],
            &[
                (
                    &placeholders.gradient,
                    Access::Nothing,
                    Access::ComputeSampled,
                ),
                (
                    &placeholders.normal,
                    Access::Nothing,
                    Access::ComputeSampled,
                ),
            ],
        );
        rec.submit()?.wait()?;
        Ok(Engine {
            device,
            config,
            kind_passes: HashMap::new(),
            derivative_passes: HashMap::new(),
            raymarch_passes: HashMap::new(),
            occupancy_pass: None,
            nearest,
            linear,
            placeholders,
            pipeline_cache: vk::PipelineCache::null(),
        })
    }

    /// The device.
    pub fn device(&self) -> &Device {
        &self.device
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

    fn kind_passes(&mut self, kind: SampleKind) -> GpuResult<&KindPasses> {
        if !self.kind_passes.contains_key(&kind) {
            let passes = KindPasses {
                minmax: MinMaxPass::new(&self.device, kind, self.pipeline_cache)?,
                normalize: NormalizePass::new(&self.device, kind, self.pipeline_cache)?,
                histogram: HistogramPass::new(&self.device, kind, self.pipeline_cache)?,
            };
            self.kind_passes.insert(kind, passes);
        }
        self.kind_passes
            .get(&kind)
            .ok_or_else(|| crate::gpu::GpuError::InvalidRequest("pass cache lost an entry".into()))
    }

    fn derivative_pass(&mut self, outputs: DerivativeOutputs) -> GpuResult<&DerivativePass> {
        if !self.derivative_passes.contains_key(&outputs) {
            let pass = DerivativePass::new(&self.device, outputs, self.pipeline_cache)?;
            self.derivative_passes.insert(outputs, pass);
        }
        self.derivative_passes
            .get(&outputs)
            .ok_or_else(|| crate::gpu::GpuError::InvalidRequest("pass cache lost an entry".into()))
    }
}
