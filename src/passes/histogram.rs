//! The 256-bin histogram of I_norm over finite voxels (shaders/histogram.wgsl).
//!
//! Decisions: bins are u32 in a GPU buffer zeroed by a fill right before the dispatch; the shader
//! reads the normalized image with `textureLoad` (no filtering, any float-sampleable format) and
//! the raw f32 samples only to skip non-finite voxels. The result is bit-exact with
//! `reference::histogram` given the same normalized values (both bin in f32 with the same rule).

use super::{linear_dispatch, variant};
use crate::gpu::shaders::table;
use crate::gpu::{
    Access, Buffer, ComputePipeline, DescriptorSet, Device, GpuResult, Image, Recording, Resource,
};
use crate::volume::SampleKind;
use ash::vk;
use std::sync::Arc;

/// Number of bins.
pub const BINS: usize = 256;

/// Consecutive voxels an invocation bins per loop step (`RUN` in the shader): one index division
/// and one subgroup vote per run instead of per voxel.
const RUN: u64 = 4;

/// Runs per invocation: 16 voxels each, enough to amortize the 256-bin flush of each workgroup.
const RUNS_PER_INVOCATION: u32 = 4;

/// Push constants of `histogram.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct HistogramParams {
    /// Volume width.
    pub dim_x: u32,
    /// Volume height.
    pub dim_y: u32,
    /// Voxels in the volume.
    pub voxel_count: u32,
    /// Loop steps per invocation.
    pub iterations: u32,
    /// Runs of 4 voxels between an invocation's steps.
    pub stride: u32,
}

/// The histogram pass for one sample kind.
pub struct HistogramPass {
    pipeline: Arc<ComputePipeline>,
}

impl HistogramPass {
    /// The compiled pipeline (for its statistics and workgroup).
    pub fn pipeline(&self) -> &Arc<ComputePipeline> {
        &self.pipeline
    }

    /// Creates the pipeline variant for `kind`.
    pub fn new(device: &Device, kind: SampleKind, cache: vk::PipelineCache) -> GpuResult<Self> {
        let shader = variant(
            kind,
            &table::HISTOGRAM_U8,
            &table::HISTOGRAM_I8,
            &table::HISTOGRAM_U16,
            &table::HISTOGRAM_I16,
            &table::HISTOGRAM_F32,
        );
        Ok(HistogramPass {
            pipeline: ComputePipeline::new(device, shader, &[], cache)?,
        })
    }

    /// Records: zero `bins` (256 u32), accumulate the histogram of `normalized` (which must be in
    /// `Access::ComputeSampled`) into it. Afterwards `bins` was last accessed as
    /// `Access::ComputeWriteBuffer`.
    pub fn record(
        &self,
        device: &Device,
        rec: &mut Recording,
        normalized: &Arc<Image>,
        samples: &Arc<Buffer>,
        bins: &Arc<Buffer>,
    ) -> GpuResult<()> {
        let [x, y, z] = normalized.extent();
        let voxels = x as u64 * y as u64 * z as u64;
        let shape = linear_dispatch(
            voxels.div_ceil(RUN),
            self.pipeline.invocations_per_workgroup(),
            RUNS_PER_INVOCATION,
            device.adapter().max_workgroup_count_x,
        );
        let params = HistogramParams {
            dim_x: x,
            dim_y: y,
            voxel_count: voxels as u32,
            iterations: shape.iterations,
            stride: shape.stride,
        };
        let set = DescriptorSet::new(
            &self.pipeline,
            0,
            &[
                ("normalized", Resource::SampledImage(normalized.clone())),
                ("words", Resource::Buffer(samples.clone())),
                ("bins", Resource::Buffer(bins.clone())),
            ],
        )?;
        rec.fill_buffer(bins, 0, (BINS * 4) as u64, 0);
        // Orders the zero fill before the shader's atomic adds.
        rec.barriers(
            &[(bins, Access::TransferWrite, Access::ComputeWriteBuffer)],
            &[],
        );
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
            table::HISTOGRAM_U16.push_constant_bytes as usize,
            std::mem::size_of::<HistogramParams>()
        );
    }
}
