//! Min/max of the finite stored samples (shaders/minmax.wgsl): subgroup reduce, then one shared
//! atomic per subgroup, then one global atomic per workgroup, on order-preserving u32 keys.
//!
//! Decisions: the result lives in a 2-word GPU buffer the pass fills with the identities
//! (0xffffffff, 0) right before the dispatch, so the pass can be recorded again without host
//! writes; the host reads it through a copy into readback memory. A result of (0xffffffff, 0)
//! means "no finite sample".

use super::{LinearDispatch, linear_dispatch, variant};
use crate::gpu::shaders::table;
use crate::gpu::{
    Access, Buffer, ComputePipeline, DescriptorSet, Device, GpuResult, Recording, Resource,
};
use crate::volume::SampleKind;
use ash::vk;
use std::sync::Arc;

/// Push constants of `minmax.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct MinMaxParams {
    /// 16-byte quads in the sample buffer.
    pub quad_count: u32,
    /// Real samples (the rest is padding).
    pub sample_count: u32,
    /// Loop steps per invocation.
    pub iterations: u32,
    /// Quads between an invocation's steps.
    pub stride: u32,
}

/// Samples each invocation reduces, in 16-byte quads: 8 quads = 128 bytes per invocation keeps
/// enough loads in flight without making the last wave long.
const QUADS_PER_INVOCATION: u32 = 8;

/// The min/max pass for one sample kind.
pub struct MinMaxPass {
    pipeline: Arc<ComputePipeline>,
    kind: SampleKind,
}

impl MinMaxPass {
    /// The compiled pipeline (for its statistics and workgroup).
    pub fn pipeline(&self) -> &Arc<ComputePipeline> {
        &self.pipeline
    }

    /// Creates the pipeline variant for `kind`.
    pub fn new(device: &Device, kind: SampleKind, cache: vk::PipelineCache) -> GpuResult<Self> {
        let shader = variant(
            kind,
            &table::MINMAX_U8,
            &table::MINMAX_I8,
            &table::MINMAX_U16,
            &table::MINMAX_I16,
            &table::MINMAX_F32,
        );
        Ok(MinMaxPass {
            pipeline: ComputePipeline::new(device, shader, &[], cache)?,
            kind,
        })
    }

    /// The dispatch shape for `sample_count` samples.
    pub fn dispatch_shape(&self, device: &Device, sample_count: u64) -> LinearDispatch {
        let quads = quads_for(self.kind, sample_count);
        linear_dispatch(
            quads,
            self.pipeline.invocations_per_workgroup(),
            QUADS_PER_INVOCATION,
            device.adapter().max_workgroup_count_x,
        )
    }

    /// Records: fill `result` with the identities, reduce `samples` into it. `samples` must hold
    /// whole 16-byte quads (zero padding after `sample_count`); after this, `result` was last
    /// accessed as `Access::ComputeWriteBuffer`.
    pub fn record(
        &self,
        device: &Device,
        rec: &mut Recording,
        samples: &Arc<Buffer>,
        sample_count: u64,
        result: &Arc<Buffer>,
    ) -> GpuResult<()> {
        let shape = self.dispatch_shape(device, sample_count);
        let params = MinMaxParams {
            quad_count: quads_for(self.kind, sample_count) as u32,
            sample_count: sample_count as u32,
            iterations: shape.iterations,
            stride: shape.stride,
        };
        let set = DescriptorSet::new(
            &self.pipeline,
            0,
            &[
                ("quads", Resource::Buffer(samples.clone())),
                ("result", Resource::Buffer(result.clone())),
            ],
        )?;
        rec.fill_buffer(result, 0, 4, u32::MAX);
        rec.fill_buffer(result, 4, 4, 0);
        // Orders the identity fills before the shader's atomics on the same words.
        rec.barriers(
            &[(result, Access::TransferWrite, Access::ComputeWriteBuffer)],
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

/// Number of 16-byte quads holding `sample_count` samples of `kind`.
pub fn quads_for(kind: SampleKind, sample_count: u64) -> u64 {
    (sample_count * kind.size_bytes() as u64).div_ceil(16)
}

/// Inverse of the shader's order-preserving key: the f32 value (as f64) a key stands for.
pub fn value_of_key(key: u32) -> f64 {
    let bits = if key & 0x8000_0000 != 0 {
        key & 0x7fff_ffff
    } else {
        !key
    };
    f32::from_bits(bits) as f64
}

/// Decodes the two result words: `None` when no finite sample was seen.
pub fn decode_result(min_key: u32, max_key: u32) -> Option<(f64, f64)> {
    if min_key == u32::MAX && max_key == 0 {
        return None;
    }
    Some((value_of_key(min_key), value_of_key(max_key)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key_of(v: f32) -> u32 {
        let bits = v.to_bits();
        if bits & 0x8000_0000 != 0 {
            !bits
        } else {
            bits | 0x8000_0000
        }
    }

    #[test]
    fn keys_preserve_order_and_invert_exactly() {
        let values = [
            f32::MIN,
            -3e38,
            -1.0,
            -f32::MIN_POSITIVE,
            -1e-45,
            -0.0,
            0.0,
            1e-45,
            f32::MIN_POSITIVE,
            1.0,
            3e38,
            f32::MAX,
        ];
        for pair in values.windows(2) {
            assert!(
                key_of(pair[0]) < key_of(pair[1]),
                "{} !< {}",
                pair[0],
                pair[1]
            );
        }
        for v in values {
            assert_eq!(value_of_key(key_of(v)).to_bits(), (v as f64).to_bits());
        }
    }

    #[test]
    fn push_constants_match_the_shader() {
        for shader in [&table::MINMAX_U8, &table::MINMAX_I16, &table::MINMAX_F32] {
            assert_eq!(
                shader.push_constant_bytes as usize,
                std::mem::size_of::<MinMaxParams>()
            );
        }
    }
}
