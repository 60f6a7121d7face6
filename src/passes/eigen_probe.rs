//! A test probe for `shaders/include/eigen3.glsl` (shaders/probes/eigen_probe.comp): runs the
//! vesselness pass's own symmetric 3x3 eigenvalue routine on host-chosen matrices and reads the
//! results back, so tests can compare them with the f64 twin (`reference::eigen`) on the hard
//! cases of NUMERICS.md, and with the naive closed form computed on the same device.
//!
//! Decisions: as `compositing_probe.rs` (not on any render path; host-visible input, results
//! written straight into host-readable memory, one submission).

use crate::gpu::shaders::table;
use crate::gpu::{
    Access, Buffer, BufferDesc, ComputePipeline, DescriptorSet, Device, GpuError, GpuResult,
    Recording, Resource,
};
use ash::vk;
use std::sync::Arc;

/// Push constants of `eigen_probe.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct EigenProbeParams {
    /// Matrices in the buffers.
    pub count: u32,
}

/// One matrix's results.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EigenProbeResult {
    /// `sym3_eigenvalues` (Jacobi), ascending.
    pub jacobi: [f32; 3],
    /// The naive closed form, ascending.
    pub naive: [f32; 3],
}

/// The probe kernel.
pub struct EigenProbe {
    pipeline: Arc<ComputePipeline>,
}

impl EigenProbe {
    /// Creates the pipeline.
    pub fn new(device: &Device, cache: vk::PipelineCache) -> GpuResult<Self> {
        Ok(EigenProbe {
            pipeline: ComputePipeline::new(device, &table::EIGEN_PROBE, &[], cache)?,
        })
    }

    /// Runs the probe on `matrices`, each `[a00, a11, a22, a01, a02, a12]`, and waits.
    pub fn run(&self, device: &Device, matrices: &[[f32; 6]]) -> GpuResult<Vec<EigenProbeResult>> {
        if matrices.is_empty() {
            return Ok(Vec::new());
        }
        let count = u32::try_from(matrices.len()).map_err(|_| {
            GpuError::InvalidRequest(format!("{} probe matrices exceed 2^32", matrices.len()))
        })?;
        let bytes = matrices.len() as u64 * 32;
        let input_bytes: Vec<u8> = matrices
            .iter()
            .flat_map(|m| [m[0], m[1], m[2], m[3], m[4], m[5], 0.0, 0.0])
            .flat_map(f32::to_le_bytes)
            .collect();
        let input = Buffer::new(
            device,
            BufferDesc::host_storage("eigen probe inputs", bytes),
        )?;
        input.write(0, &input_bytes)?;
        let output = Buffer::new(device, BufferDesc::readback("eigen probe outputs", bytes))?;
        let set = DescriptorSet::new(
            &self.pipeline,
            0,
            &[
                ("inputs", Resource::Buffer(input.clone())),
                ("outputs", Resource::Buffer(output.clone())),
            ],
        )?;
        let mut rec = Recording::new(device, "eigen probe")?;
        // Host writes before vkQueueSubmit are visible to the submitted work.
        rec.begin_pass("eigen probe");
        rec.dispatch(
            &self.pipeline,
            &[set],
            bytemuck::bytes_of(&EigenProbeParams { count }),
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
        let floats: Vec<f32> = out
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        Ok(floats
            .chunks_exact(8)
            .map(|c| EigenProbeResult {
                jacobi: [c[0], c[1], c[2]],
                naive: [c[4], c[5], c[6]],
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
            table::EIGEN_PROBE.push_constant_bytes as usize,
            std::mem::size_of::<EigenProbeParams>()
        );
    }
}
