//! Compute pipelines built from the reflection table, specialized by name.
//!
//! Decisions: set layouts and the push-constant range come from [`ShaderInfo`] only. Specialization
//! constants are set by name and type-checked against the reflection, so a renamed or retyped
//! constant fails pipeline creation with a message instead of silently keeping its default.
//! Pipelines can be created through a `VkPipelineCache` (persisted by the engine).

use super::descriptor_pools::DescriptorPools;
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
    /// Reusable descriptor pools, one list per set, sized once here (`descriptor_pools.rs`).
    pub(crate) descriptor_pools: Vec<Arc<DescriptorPools>>,
    shader: &'static ShaderInfo,
    workgroup_size: [u32; 3],
    subgroup_size: Option<u32>,
    pub(crate) device: Arc<DeviceShared>,
}

pub(crate) fn descriptor_type(kind: BindingKind) -> vk::DescriptorType {
    match kind {
        BindingKind::UniformBuffer => vk::DescriptorType::UNIFORM_BUFFER,
        BindingKind::StorageBuffer { .. } => vk::DescriptorType::STORAGE_BUFFER,
        BindingKind::StorageImage { .. } => vk::DescriptorType::STORAGE_IMAGE,
        BindingKind::CombinedImageSampler => vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
        BindingKind::SampledImage => vk::DescriptorType::SAMPLED_IMAGE,
        BindingKind::Sampler => vk::DescriptorType::SAMPLER,
        BindingKind::UniformTexelBuffer => vk::DescriptorType::UNIFORM_TEXEL_BUFFER,
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
        // The device's tuning: a chosen workgroup for kernels that declare one specializable,
        // and a pinned subgroup size (checked against the device when it was created).
        let mut workgroup_size = shader.workgroup_size;
        if let (Some(ids), Some(size)) = (
            shader.workgroup_spec_ids,
            shared.tuning.workgroup_for(shader.source),
        ) {
            super::profile::check_workgroup(
                &shared.adapter,
                shader.name,
                shader.workgroup_size,
                size,
            )?;
            for (id, value) in ids.into_iter().zip(size) {
                entries.push(vk::SpecializationMapEntry {
                    constant_id: id,
                    offset: data.len() as u32 * 4,
                    size: 4,
                });
                data.push(value);
            }
            workgroup_size = size;
        }
        let subgroup_size = shared.tuning.subgroup_size;
        if let Some(size) = subgroup_size {
            let subgroups = workgroup_size.iter().product::<u32>().div_ceil(size);
            if subgroups > shared.adapter.max_workgroup_subgroups {
                return Err(GpuError::Unsupported(format!(
                    "{}: {subgroups} subgroups of {size} per workgroup exceed the device's {}",
                    shader.name, shared.adapter.max_workgroup_subgroups
                )));
            }
        }
        if !shared.adapter.float_atomics && uses_float_atomics(&shader.spirv_words()) {
            return Err(GpuError::Unsupported(format!(
                "{} uses float atomics, which the {} profile does not have",
                shader.name,
                shared.adapter.profile.as_deref().unwrap_or("device's")
            )));
        }
        let data_bytes: Vec<u8> = data.iter().flat_map(|w| w.to_le_bytes()).collect();

        let mut pipeline = ComputePipeline {
            raw: vk::Pipeline::null(),
            layout: vk::PipelineLayout::null(),
            set_layouts: Vec::new(),
            descriptor_pools: Vec::new(),
            shader,
            workgroup_size,
            subgroup_size,
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
            pipeline
                .descriptor_pools
                .push(Arc::new(DescriptorPools::new(shared, shader, set)));
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
        let mut required = vk::PipelineShaderStageRequiredSubgroupSizeCreateInfo::default()
            .required_subgroup_size(subgroup_size.unwrap_or(0));
        let mut stage = vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::COMPUTE)
            .module(module)
            .name(&entry)
            .specialization_info(&spec_info);
        if subgroup_size.is_some() {
            stage = stage.push_next(&mut required);
        }
        // Statistics are captured only when asked for (drivers may keep more per pipeline).
        let flags = if shared.executable_properties.is_some() {
            vk::PipelineCreateFlags::CAPTURE_STATISTICS_KHR
        } else {
            vk::PipelineCreateFlags::empty()
        };
        let create = [vk::ComputePipelineCreateInfo::default()
            .flags(flags)
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
        shared.name_object(pipeline.raw, shader.name);
        shared.name_object(pipeline.layout, &format!("{} (layout)", shader.name));
        Ok(Arc::new(pipeline))
    }

    /// The reflection this pipeline was built from.
    pub fn shader(&self) -> &'static ShaderInfo {
        self.shader
    }

    /// The workgroup size this pipeline runs with (the shader's, or the tuning's choice).
    pub fn workgroup_size(&self) -> [u32; 3] {
        self.workgroup_size
    }

    /// Invocations per workgroup.
    pub fn invocations_per_workgroup(&self) -> u32 {
        self.workgroup_size.iter().product()
    }

    /// The pinned subgroup size, if any.
    pub fn subgroup_size(&self) -> Option<u32> {
        self.subgroup_size
    }

    /// Workgroups needed to cover `extent` invocations along each axis.
    pub fn workgroups_for(&self, extent: [u32; 3]) -> [u32; 3] {
        let w = self.workgroup_size;
        [
            extent[0].div_ceil(w[0]),
            extent[1].div_ceil(w[1]),
            extent[2].div_ceil(w[2]),
        ]
    }
}

/// True when the module declares a float-atomic capability (SPV_EXT_shader_atomic_float_add and
/// _min_max): `OpCapability AtomicFloat{16,32,64}{Add,MinMax}EXT`.
fn uses_float_atomics(words: &[u32]) -> bool {
    const OP_CAPABILITY: u32 = 17;
    const FLOAT_ATOMICS: [u32; 6] = [5612, 5613, 5616, 6033, 6034, 6095];
    let mut at = 5;
    while at < words.len() {
        let count = (words[at] >> 16) as usize;
        if count == 0 {
            return false;
        }
        if words[at] & 0xffff == OP_CAPABILITY
            && words.get(at + 1).is_some_and(|c| FLOAT_ATOMICS.contains(c))
        {
            return true;
        }
        at += count;
    }
    false
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

#[cfg(test)]
mod tests {
    use super::uses_float_atomics;

    /// A module header plus the given instructions.
    fn module(instructions: &[&[u32]]) -> Vec<u32> {
        let mut words = vec![0x0723_0203, 0x0001_0300, 0, 100, 0];
        for i in instructions {
            words.push(((i.len() as u32) << 16) | i[0]);
            words.extend_from_slice(&i[1..]);
        }
        words
    }

    #[test]
    fn float_atomic_capabilities_are_found() {
        // OpCapability Shader (1), OpCapability AtomicFloat32AddEXT (6033).
        let plain = module(&[&[17, 1]]);
        let float_add = module(&[&[17, 1], &[17, 6033]]);
        assert!(!uses_float_atomics(&plain));
        assert!(uses_float_atomics(&float_add));
        // A malformed zero-length instruction ends the scan instead of looping.
        assert!(!uses_float_atomics(&[0x0723_0203, 0, 0, 0, 0, 0]));
        // No shipped shader needs them (Xe-LP has none).
        for shader in crate::gpu::shaders::table::ALL {
            assert!(
                !uses_float_atomics(&shader.spirv_words()),
                "{}",
                shader.name
            );
        }
    }
}
