//! A test probe for `shaders/include/compositing.glsl` (shaders/probes/compositing_probe.comp):
//! runs the raymarch's own opacity correction and compositing on host-chosen inputs and reads the
//! results back, so tests can compare them with their f64 twins
//! (`reference::raymarch::opacity_correct`, `reference::raymarch::composite`) over parameter
//! grids a render cannot reach.
//!
//! Decisions: the probe is not part of any render path and costs nothing unless a test creates
//! it. Inputs go through a host-visible storage buffer and the results are written straight into
//! host-readable memory (readback buffers are storage buffers too), so one submission and one
//! barrier suffice. Each job also returns the naive formula NUMERICS.md warns against (naive
//! `1 - (1 - a)^r`, an f16 accumulator), computed on the same device, so a test can show that its
//! bound separates the robust form from the naive one.

use crate::gpu::shaders::table;
use crate::gpu::{
    Access, Buffer, BufferDesc, ComputePipeline, DescriptorSet, Device, GpuError, GpuResult,
    Recording, Resource,
};
use ash::vk;
use std::sync::Arc;

/// Push constants of `compositing_probe.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ProbeParams {
    /// Items in the input and output buffers.
    pub count: u32,
    /// [`ProbeJob`] as its shader value.
    pub job: u32,
}

/// What the probe computes per item.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProbeJob {
    /// Item `(a, r)` gives `(opacity_correct(a, r), 1 - pow(1 - a, r))`, both in f32.
    OpacityCorrection = 0,
    /// Item `(a, n)` gives the accumulated alpha after `n` (at most 100000) `composite` steps of
    /// opacity `a` in f32, and the same recurrence with every intermediate rounded to f16.
    Accumulation = 1,
}

/// The probe kernel.
pub struct CompositingProbe {
    pipeline: Arc<ComputePipeline>,
}

impl CompositingProbe {
    /// Creates the pipeline.
    pub fn new(device: &Device, cache: vk::PipelineCache) -> GpuResult<Self> {
        Ok(CompositingProbe {
            pipeline: ComputePipeline::new(device, &table::COMPOSITING_PROBE, &[], cache)?,
        })
    }

    /// Runs `job` over `items`, waits, and returns one result pair per item.
    pub fn run(
        &self,
        device: &Device,
        job: ProbeJob,
        items: &[[f32; 2]],
    ) -> GpuResult<Vec<[f32; 2]>> {
        if items.is_empty() {
            return Ok(Vec::new());
        }
        let count = u32::try_from(items.len()).map_err(|_| {
            GpuError::InvalidRequest(format!("{} probe items exceed 2^32", items.len()))
        })?;
        let bytes = items.len() as u64 * 8;
        let input_bytes: Vec<u8> = items
            .iter()
            .flat_map(|pair| pair.iter().flat_map(|v| v.to_le_bytes()))
            .collect();
        let input = Buffer::new(device, BufferDesc::host_storage("probe inputs", bytes))?;
        input.write(0, &input_bytes)?;
        let output = Buffer::new(device, BufferDesc::readback("probe outputs", bytes))?;
        let set = DescriptorSet::new(
            &self.pipeline,
            0,
            &[
                ("inputs", Resource::Buffer(input.clone())),
                ("outputs", Resource::Buffer(output.clone())),
            ],
        )?;
        let params = ProbeParams {
            count,
            job: job as u32,
        };
        let mut rec = Recording::new(device, "compositing probe")?;
        // Host writes before vkQueueSubmit are visible to the submitted work, so the inputs need
        // no barrier.
        rec.begin_pass("compositing probe");
        rec.dispatch(
            &self.pipeline,
            &[set],
            bytemuck::bytes_of(&params),
            self.pipeline.workgroups_for([count, 1, 1]),
        )?;
        rec.end_pass();
        // Makes the shader's writes visible to the host.
        rec.barriers(
            &[(&output, Access::ComputeWriteBuffer, Access::HostRead)],
            &[],
        );
        rec.submit()?.wait()?;
        let mut out = vec![0u8; bytes as usize];
        output.read(0, &mut out)?;
        Ok(out
            .chunks_exact(8)
            .map(|c| {
                [
                    f32::from_le_bytes([c[0], c[1], c[2], c[3]]),
                    f32::from_le_bytes([c[4], c[5], c[6], c[7]]),
                ]
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn push_constants_match_the_shader() {
        assert_eq!(
            table::COMPOSITING_PROBE.push_constant_bytes as usize,
            std::mem::size_of::<ProbeParams>()
        );
    }
}
