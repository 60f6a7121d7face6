//! Descriptor sets, written from named resources and checked against the reflection.
//!
//! Decisions: each set has its own one-set pool, taken from its pipeline's reusable pools
//! (`descriptor_pools.rs`: sized once from the reflection, reset and reused when the set drops,
//! which is after every submission that bound it completed). A set keeps the resources written
//! into it alive. Binding is by the shader's variable name; a missing, unknown or mistyped
//! binding is an error naming it.

use super::buffer::Buffer;
use super::descriptor_pools::DescriptorPools;
use super::error::{GpuError, GpuResult, vk_err};
use super::image::Image;
use super::pipeline::{ComputePipeline, descriptor_type};
use super::sampler::Sampler;
use super::shaders::BindingKind;
use ash::vk;
use std::any::Any;
use std::sync::Arc;

/// A resource to write into one binding.
#[derive(Clone)]
pub enum Resource {
    /// A storage or uniform buffer (whole buffer).
    Buffer(Arc<Buffer>),
    /// A storage image (layout GENERAL).
    StorageImage(Arc<Image>),
    /// A sampled image without sampler (layout SHADER_READ_ONLY_OPTIMAL).
    SampledImage(Arc<Image>),
    /// A combined image sampler (layout SHADER_READ_ONLY_OPTIMAL).
    CombinedImageSampler(Arc<Image>, Arc<Sampler>),
    /// A uniform texel buffer: the buffer's own view (`BufferDesc::with_texel_view`).
    TexelBuffer(Arc<Buffer>),
}

impl Resource {
    fn matches(&self, kind: BindingKind) -> bool {
        matches!(
            (self, kind),
            (
                Resource::Buffer(_),
                BindingKind::StorageBuffer { .. } | BindingKind::UniformBuffer
            ) | (Resource::StorageImage(_), BindingKind::StorageImage { .. })
                | (Resource::SampledImage(_), BindingKind::SampledImage)
                | (
                    Resource::CombinedImageSampler(..),
                    BindingKind::CombinedImageSampler
                )
                | (Resource::TexelBuffer(_), BindingKind::UniformTexelBuffer)
        )
    }

    fn keep_alive(&self) -> Vec<Arc<dyn Any + Send + Sync>> {
        match self {
            Resource::Buffer(b) | Resource::TexelBuffer(b) => vec![b.clone()],
            Resource::StorageImage(i) | Resource::SampledImage(i) => vec![i.clone()],
            Resource::CombinedImageSampler(i, s) => vec![i.clone(), s.clone()],
        }
    }
}

/// Which array of a write's descriptor infos an entry indexes.
#[derive(Clone, Copy)]
enum Info {
    Buffer,
    Image,
    TexelView,
}

/// A written descriptor set and the resources it refers to.
pub struct DescriptorSet {
    pub(crate) raw: vk::DescriptorSet,
    pub(crate) set_index: u32,
    pool: vk::DescriptorPool,
    pools: Arc<DescriptorPools>,
    _resources: Vec<Arc<dyn Any + Send + Sync>>,
}

impl DescriptorSet {
    /// Allocates set `set_index` of `pipeline` and writes `resources` by binding name.
    pub fn new(
        pipeline: &ComputePipeline,
        set_index: u32,
        resources: &[(&str, Resource)],
    ) -> GpuResult<Arc<DescriptorSet>> {
        let shader = pipeline.shader();
        let device = pipeline.device_shared();
        let wanted: Vec<_> = shader
            .bindings
            .iter()
            .filter(|b| b.set == set_index)
            .collect();
        let no_set = || {
            GpuError::InvalidRequest(format!(
                "shader {} has no descriptor set {set_index}",
                shader.name
            ))
        };
        let layout = *pipeline
            .set_layouts
            .get(set_index as usize)
            .ok_or_else(no_set)?;
        let pools = pipeline
            .descriptor_pools
            .get(set_index as usize)
            .ok_or_else(no_set)?
            .clone();
        for (name, _) in resources {
            if !wanted.iter().any(|b| b.name == *name) {
                return Err(GpuError::InvalidRequest(format!(
                    "shader {} does not use a binding `{name}` in set {set_index}",
                    shader.name
                )));
            }
        }
        let pool = pools.take()?;
        // From here the set owns the pool: any error below drops it, which gives the pool back.
        let mut set = DescriptorSet {
            raw: vk::DescriptorSet::null(),
            set_index,
            pool,
            pools,
            _resources: Vec::new(),
        };
        let layouts = [layout];
        let alloc_info = vk::DescriptorSetAllocateInfo::default()
            .descriptor_pool(pool)
            .set_layouts(&layouts);
        // SAFETY: pool and layout belong to this device; the pool has room for exactly this set
        // (sized for this layout, and reset when it came back).
        set.raw = unsafe { device.raw.allocate_descriptor_sets(&alloc_info) }
            .map_err(vk_err("vkAllocateDescriptorSets"))?
            .first()
            .copied()
            .ok_or_else(|| GpuError::Internal("vkAllocateDescriptorSets returned no set".into()))?;
        device.name_object(set.raw, &format!("{} set {set_index}", shader.name));

        let mut buffer_infos = Vec::new();
        let mut image_infos = Vec::new();
        let mut texel_views = Vec::new();
        let mut targets = Vec::new();
        for binding in &wanted {
            let (_, resource) = resources
                .iter()
                .find(|(n, _)| *n == binding.name)
                .ok_or_else(|| {
                    GpuError::InvalidRequest(format!(
                        "binding `{}` of shader {} was not given a resource",
                        binding.name, shader.name
                    ))
                })?;
            if !resource.matches(binding.kind) {
                return Err(GpuError::InvalidRequest(format!(
                    "binding `{}` of shader {} is {:?}; the resource given does not fit it",
                    binding.name, shader.name, binding.kind
                )));
            }
            set._resources.extend(resource.keep_alive());
            match resource {
                Resource::Buffer(b) => {
                    buffer_infos.push(vk::DescriptorBufferInfo {
                        buffer: b.raw,
                        offset: 0,
                        range: vk::WHOLE_SIZE,
                    });
                    targets.push((
                        binding.binding,
                        descriptor_type(binding.kind),
                        Info::Buffer,
                        buffer_infos.len() - 1,
                    ));
                }
                Resource::StorageImage(i) => {
                    image_infos.push(vk::DescriptorImageInfo {
                        sampler: vk::Sampler::null(),
                        image_view: i.view,
                        image_layout: vk::ImageLayout::GENERAL,
                    });
                    targets.push((
                        binding.binding,
                        descriptor_type(binding.kind),
                        Info::Image,
                        image_infos.len() - 1,
                    ));
                }
                Resource::SampledImage(i) => {
                    image_infos.push(vk::DescriptorImageInfo {
                        sampler: vk::Sampler::null(),
                        image_view: i.view,
                        image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
                    });
                    targets.push((
                        binding.binding,
                        descriptor_type(binding.kind),
                        Info::Image,
                        image_infos.len() - 1,
                    ));
                }
                Resource::TexelBuffer(b) => {
                    if b.texel_view == vk::BufferView::null() {
                        return Err(GpuError::InvalidRequest(format!(
                            "binding `{}` of shader {} is a texel buffer; buffer `{}` has no \
                             texel view",
                            binding.name,
                            shader.name,
                            b.name()
                        )));
                    }
                    texel_views.push(b.texel_view);
                    targets.push((
                        binding.binding,
                        descriptor_type(binding.kind),
                        Info::TexelView,
                        texel_views.len() - 1,
                    ));
                }
                Resource::CombinedImageSampler(i, s) => {
                    image_infos.push(vk::DescriptorImageInfo {
                        sampler: s.raw,
                        image_view: i.view,
                        image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
                    });
                    targets.push((
                        binding.binding,
                        descriptor_type(binding.kind),
                        Info::Image,
                        image_infos.len() - 1,
                    ));
                }
            }
        }
        let writes: Vec<vk::WriteDescriptorSet> = targets
            .iter()
            .map(|&(binding, ty, info, index)| {
                let write = vk::WriteDescriptorSet::default()
                    .dst_set(set.raw)
                    .dst_binding(binding)
                    .descriptor_type(ty);
                match info {
                    Info::Buffer => write.buffer_info(std::slice::from_ref(&buffer_infos[index])),
                    Info::Image => write.image_info(std::slice::from_ref(&image_infos[index])),
                    Info::TexelView => {
                        write.texel_buffer_view(std::slice::from_ref(&texel_views[index]))
                    }
                }
            })
            .collect();
        // SAFETY: every handle in `writes` is alive (kept by `set._resources`).
        unsafe { device.raw.update_descriptor_sets(&writes, &[]) };
        Ok(Arc::new(set))
    }
}

impl DescriptorSet {
    /// Descriptor pools this set's pipeline set has created so far (tests of reuse).
    #[cfg(test)]
    pub(crate) fn pools_created(&self) -> u64 {
        self.pools.created()
    }
}

impl Drop for DescriptorSet {
    fn drop(&mut self) {
        // Dropped only when no submission uses the set (they keep it until their fence
        // signals): the pool is reset and reused.
        self.pools.give_back(self.pool);
    }
}
