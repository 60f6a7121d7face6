//! Compute pipelines built from the reflection table, specialized by name.
//!
//! Decisions: set layouts and the push-constant range come from [`ShaderInfo`] only. Specialization
//! constants are set by name and type-checked against the reflection, so a renamed or retyped
//! constant fails pipeline creation with a message instead of silently keeping its default.
//! Pipelines can be created through a `VkPipelineCache` (persisted by the engine).

use super::device::{Device, DeviceShared};
use super::error::{GpuError, GpuResult, vk_err};
use super::shaders::{BindingKind, ShaderInfo, SpecKind};
use ash::vk;
use std::sync::Arc;

/// Value of one specialization constant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SpecValue {
    /// A boolean constant.
    Bool(bool),
    /// An unsigned constant.
    U32(u32),
    /// A signed constant.
    I32(i32),
    /// A float constant.
    F32(f32),
}

impl SpecValue {
    fn kind(self) -> SpecKind {
        match self {
            SpecValue::Bool(_) => SpecKind::Bool,
            SpecValue::U32(_) => SpecKind::U32,
            SpecValue::I32(_) => SpecKind::I32,
            SpecValue::F32(_) => SpecKind::F32,
        }
    }

    fn bits(self) -> u32 {
        match self {
            SpecValue::Bool(b) => b as u32,
            SpecValue::U32(v) => v,
            SpecValue::I32(v) => v as u32,
            SpecValue::F32(v) => v.to_bits(),
        }
    }
}

/// A compute pipeline with its layouts.
pub struct ComputePipeline {
    pub(crate) raw: vk::Pipeline,
    pub(crate) layout: vk::PipelineLayout,
    pub(crate) set_layouts: Vec<vk::DescriptorSetLayout>,
    shader: &'static ShaderInfo,
    device: Arc<DeviceShared>,
}

pub(crate) fn descriptor_type(kind: BindingKind) -> vk::DescriptorType {
    match kind {
        BindingKind::UniformBuffer => vk::DescriptorType::UNIFORM_BUFFER,
        BindingKind::StorageBuffer { .. } => vk::DescriptorType::STORAGE_BUFFER,
        BindingKind::StorageImage { .. } => vk::DescriptorType::STORAGE_IMAGE,
        BindingKind::CombinedImageSampler => vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
        BindingKind::SampledImage => vk::DescriptorType::SAMPLED_IMAGE,
        BindingKind::Sampler => vk::DescriptorType::SAMPLER,
    }
}

impl ComputePipeline {
    /// Creates the pipeline for `shader` with the given specialization constants.
    pub fn new(
        device: &Device,
        shader: &'static ShaderInfo,
        specialization: &[(&str, SpecValue)],
        cache: vk::PipelineCache,
    ) -> GpuResult<Arc<ComputePipeline>> {
        let shared = &device.shared;
        let raw_device = &shared.raw;
        let mut entries = Vec::with_capacity(specialization.len());
        let mut data = Vec::with_capacity(specialization.len() * 4);
        for (name, value) in specialization {
            let info = shader
                .spec_constants
                .iter()
                .find(|c| c.name == *name)
                .ok_or_else(|| {
                    GpuError::InvalidRequest(format!(
                        "shader {} has no specialization constant `{name}`",
                        shader.name
                    ))
                })?;
            if info.kind != value.kind() {
                return Err(GpuError::InvalidRequest(format!(
                    "specialization constant `{name}` of {} is {:?}, got {:?}",
                    shader.name, info.kind, value
                )));
            }
            entries.push(vk::SpecializationMapEntry {
                constant_id: info.id,
                offset: data.len() as u32 * 4,
                size: 4,
            });
            data.push(value.bits());
        }
        let data_bytes: Vec<u8> = data.iter().flat_map(|w| w.to_le_bytes()).collect();

        let mut pipeline = ComputePipeline {
            raw: vk::Pipeline::null(),
            layout: vk::PipelineLayout::null(),
            set_layouts: Vec::new(),
            shader,
            device: shared.clone(),
        };
        let set_count = shader.bindings.iter().map(|b| b.set + 1).max().unwrap_or(0);
        for set in 0..set_count {
            let bindings: Vec<vk::DescriptorSetLayoutBinding> = shader
                .bindings
                .iter()
                .filter(|b| b.set == set)
                .map(|b| {
                    vk::DescriptorSetLayoutBinding::default()
                        .binding(b.binding)
                        .descriptor_type(descriptor_type(b.kind))
                        .descriptor_count(b.count)
                        .stage_flags(vk::ShaderStageFlags::COMPUTE)
                })
                .collect();
            let info = vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings);
            // SAFETY: valid create info on a live device. On error, Drop destroys what exists.
            let layout = unsafe { raw_device.create_descriptor_set_layout(&info, None) }
                .map_err(vk_err("vkCreateDescriptorSetLayout"))?;
            pipeline.set_layouts.push(layout);
        }
        let ranges = [vk::PushConstantRange {
            stage_flags: vk::ShaderStageFlags::COMPUTE,
            offset: 0,
            size: shader.push_constant_bytes,
        }];
        let layout_info = vk::PipelineLayoutCreateInfo::default()
            .set_layouts(&pipeline.set_layouts)
            .push_constant_ranges(if shader.push_constant_bytes > 0 {
                &ranges
            } else {
                &[]
            });
        // SAFETY: as above.
        pipeline.layout = unsafe { raw_device.create_pipeline_layout(&layout_info, None) }
            .map_err(vk_err("vkCreatePipelineLayout"))?;

        let words = shader.spirv_words();
        let module_info = vk::ShaderModuleCreateInfo::default().code(&words);
        // SAFETY: SPIR-V validated at build time.
        let module = unsafe { raw_device.create_shader_module(&module_info, None) }
            .map_err(vk_err("vkCreateShaderModule"))?;
        let entry = std::ffi::CString::new(shader.entry_point).map_err(|_| {
            GpuError::InvalidRequest(format!("entry point of {} contains NUL", shader.name))
        })?;
        let spec_info = vk::SpecializationInfo::default()
            .map_entries(&entries)
            .data(&data_bytes);
        let stage = vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::COMPUTE)
            .module(module)
            .name(&entry)
            .specialization_info(&spec_info);
        let create = [vk::ComputePipelineCreateInfo::default()
            .stage(stage)
            .layout(pipeline.layout)];
        // SAFETY: module, layout and cache belong to this device.
        let result = unsafe { raw_device.create_compute_pipelines(cache, &create, None) };
        // SAFETY: the module is no longer needed once the pipeline exists (or failed).
        unsafe { raw_device.destroy_shader_module(module, None) };
        pipeline.raw = match result {
            Ok(p) => p.into_iter().next().unwrap_or(vk::Pipeline::null()),
            Err((_, e)) => return Err(GpuError::from_vk("vkCreateComputePipelines", e)),
        };
        if pipeline.raw == vk::Pipeline::null() {
            return Err(GpuError::Vulkan {
                call: "vkCreateComputePipelines",
                result: vk::Result::ERROR_UNKNOWN,
            });
        }
        Ok(Arc::new(pipeline))
    }

    /// The reflection this pipeline was built from.
    pub fn shader(&self) -> &'static ShaderInfo {
        self.shader
    }

    /// Workgroups needed to cover `extent` invocations along each axis.
    pub fn workgroups_for(&self, extent: [u32; 3]) -> [u32; 3] {
        let w = self.shader.workgroup_size;
        [
            extent[0].div_ceil(w[0]),
            extent[1].div_ceil(w[1]),
            extent[2].div_ceil(w[2]),
        ]
    }
}

impl Drop for ComputePipeline {
    fn drop(&mut self) {
        // SAFETY: dropped only when no recording or submission holds it.
        unsafe {
            if self.raw != vk::Pipeline::null() {
                self.device.raw.destroy_pipeline(self.raw, None);
            }
            if self.layout != vk::PipelineLayout::null() {
                self.device.raw.destroy_pipeline_layout(self.layout, None);
            }
            for layout in self.set_layouts.drain(..) {
                self.device.raw.destroy_descriptor_set_layout(layout, None);
            }
        }
    }
}

impl ComputePipeline {
    pub(crate) fn device_shared(&self) -> Arc<DeviceShared> {
        self.device.clone()
    }
}
