//! Samplers for volumes: clamp-to-edge on every axis, never repeat.
//!
//! Decision: repeat would blend the opposite face of the volume into boundary samples, so the only
//! choice offered is the filter (nearest or trilinear).

use super::device::{Device, DeviceShared};
use super::error::{GpuResult, vk_err};
use ash::vk;
use std::sync::Arc;

/// Texture filter.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Filter {
    /// Nearest texel.
    Nearest,
    /// Trilinear (linear in each axis).
    Linear,
}

/// A clamp-to-edge sampler.
pub struct Sampler {
    pub(crate) raw: vk::Sampler,
    device: Arc<DeviceShared>,
}

impl Sampler {
    /// Creates a sampler with the given filter and clamp-to-edge addressing.
    pub fn new(device: &Device, filter: Filter) -> GpuResult<Arc<Sampler>> {
        let f = match filter {
            Filter::Nearest => vk::Filter::NEAREST,
            Filter::Linear => vk::Filter::LINEAR,
        };
        let info = vk::SamplerCreateInfo::default()
            .mag_filter(f)
            .min_filter(f)
            .mipmap_mode(vk::SamplerMipmapMode::NEAREST)
            .address_mode_u(vk::SamplerAddressMode::CLAMP_TO_EDGE)
            .address_mode_v(vk::SamplerAddressMode::CLAMP_TO_EDGE)
            .address_mode_w(vk::SamplerAddressMode::CLAMP_TO_EDGE)
            .max_lod(0.0);
        // SAFETY: valid create info on a live device.
        let raw = unsafe { device.shared.raw.create_sampler(&info, None) }
            .map_err(vk_err("vkCreateSampler"))?;
        Ok(Arc::new(Sampler {
            raw,
            device: device.shared.clone(),
        }))
    }
}

impl Drop for Sampler {
    fn drop(&mut self) {
        // SAFETY: dropped only when no descriptor set or submission holds it.
        unsafe { self.device.raw.destroy_sampler(self.raw, None) };
    }
}
