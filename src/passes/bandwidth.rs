//! The bandwidth probe (shaders/bandwidth.wgsl): a streaming copy between two storage buffers.

use super::linear_dispatch;
use crate::gpu::shaders::table;
use crate::gpu::{Buffer, ComputePipeline, DescriptorSet, Device, GpuResult, Recording, Resource};
use ash::vk;
use std::sync::Arc;

/// Push constants of `bandwidth.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct CopyParams {
    /// 16-byte quads to copy.
    pub quad_count: u32,
    /// Loop steps per invocation.
    pub iterations: u32,
    /// Quads between an invocation's steps.
    pub stride: u32,
}

/// The copy kernel.
pub struct CopyPass {
    pipeline: Arc<ComputePipeline>,
}

impl CopyPass {
    /// Creates the pipeline.
    pub fn new(device: &Device, cache: vk::PipelineCache) -> GpuResult<Self> {
        Ok(CopyPass {
            pipeline: ComputePipeline::new(device, &table::BANDWIDTH, &[], cache)?,
        })
    }

    /// Records a copy of `source` into `destination` (whole 16-byte quads of the smaller size).
    pub fn record(
        &self,
        device: &Device,
        rec: &mut Recording,
        source: &Arc<Buffer>,
        destination: &Arc<Buffer>,
    ) -> GpuResult<()> {
        let quads = source.size().min(destination.size()) / 16;
        let shape = linear_dispatch(quads, 256, 8, device.adapter().max_workgroup_count_x);
        let params = CopyParams {
            quad_count: quads as u32,
            iterations: shape.iterations,
            stride: shape.stride,
        };
        let set = DescriptorSet::new(
            &self.pipeline,
            0,
            &[
                ("source", Resource::Buffer(source.clone())),
                ("destination", Resource::Buffer(destination.clone())),
            ],
        )?;
        rec.dispatch(
            &self.pipeline,
            &[set],
            bytemuck::bytes_of(&params),
            [shape.workgroups, 1, 1],
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn push_constants_match_the_shader() {
        assert_eq!(
            table::BANDWIDTH.push_constant_bytes as usize,
            std::mem::size_of::<CopyParams>()
        );
    }
}
