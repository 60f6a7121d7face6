//! The fine histogram of one physical interval (shaders/fine_histogram.comp): the robust range's
//! percentiles are read from it (src/analysis/range.rs).
//!
//! Decisions: the interval is handed over as a [`NormalizeParams`] mapping (planned in f64 by
//! `normalize::plan` or `plan_physical`), so the kernel shares the normalization's arithmetic
//! and its safety for extreme data; the counts live in a GPU buffer the pass zeroes with a fill
//! right before the dispatch, so the pass records again without host writes.

use super::linear_dispatch;
use super::normalize::NormalizeParams;
use crate::gpu::shaders::table;
use crate::gpu::{
    Access, Buffer, ComputePipeline, DescriptorSet, Device, GpuResult, Recording, Resource,
    SpecValue,
};
use crate::reference::fine_histogram::{FINE_BINS, RangeHistogram};
use crate::reference::normalize::half_difference;
use crate::volume::SampleKind;
use ash::vk;
use std::sync::Arc;

/// Words in the result buffer: the bins, under, over, then the smallest and largest `x` inside
/// the interval as f32 bits (`u32::MAX`, 0 when none is inside).
pub const COUNTERS: usize = FINE_BINS + 4;

/// Bytes of the result buffer.
pub const RESULT_BYTES: u64 = (COUNTERS * 4) as u64;

/// Voxels each invocation counts: 16 amortizes the 2050-counter flush of each workgroup.
const VOXELS_PER_INVOCATION: u32 = 16;

/// Push constants of `fine_histogram.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct FineHistogramParams {
    /// Voxels in the volume.
    pub voxel_count: u32,
    /// Loop steps per invocation.
    pub iterations: u32,
    /// Voxels between an invocation's steps.
    pub stride: u32,
    /// Power-of-two pre-scale of every sample.
    pub pre_exponent: i32,
    /// Pre-scaled stored value of the interval's low end.
    pub offset: f32,
    /// Maps the interval onto [0, 1].
    pub scale: f32,
}

/// The fine-histogram pass for one sample kind.
pub struct FineHistogramPass {
    pipeline: Arc<ComputePipeline>,
}

impl FineHistogramPass {
    /// The compiled pipeline (for its statistics and workgroup).
    pub fn pipeline(&self) -> &Arc<ComputePipeline> {
        &self.pipeline
    }

    /// Creates the pipeline specialized for `kind`.
    pub fn new(device: &Device, kind: SampleKind, cache: vk::PipelineCache) -> GpuResult<Self> {
        let pipeline = ComputePipeline::new(
            device,
            &table::FINE_HISTOGRAM,
            &[("SAMPLE_KIND", SpecValue::U32(kind as u32))],
            cache,
        )?;
        Ok(FineHistogramPass { pipeline })
    }

    /// Records: zero `counts` ([`RESULT_BYTES`]), count `samples` over the interval `mapping`
    /// maps onto [0, 1]. Afterwards `counts` was last accessed as `Access::ComputeWriteBuffer`.
    pub fn record(
        &self,
        device: &Device,
        rec: &mut Recording,
        samples: &Arc<Buffer>,
        voxel_count: u64,
        mapping: &NormalizeParams,
        counts: &Arc<Buffer>,
    ) -> GpuResult<()> {
        let shape = linear_dispatch(
            voxel_count,
            self.pipeline.invocations_per_workgroup(),
            VOXELS_PER_INVOCATION,
            device.adapter().max_workgroup_count_x,
        );
        let params = FineHistogramParams {
            voxel_count: voxel_count as u32,
            iterations: shape.iterations,
            stride: shape.stride,
            pre_exponent: mapping.pre_exponent,
            offset: mapping.offset,
            scale: mapping.scale,
        };
        let set = DescriptorSet::new(
            &self.pipeline,
            0,
            &[
                ("samples", Resource::Buffer(samples.clone())),
                ("result", Resource::Buffer(counts.clone())),
            ],
        )?;
        // Disjoint fills (overlapping ones would need a barrier between them).
        let min_word = (FINE_BINS as u64 + 2) * 4;
        rec.fill_buffer(counts, 0, min_word, 0);
        rec.fill_buffer(counts, min_word, 4, u32::MAX);
        rec.fill_buffer(counts, min_word + 4, 4, 0);
        // Orders the fills (zero counts, the minimum's identity) before the shader's atomics.
        rec.barriers(
            &[(counts, Access::TransferWrite, Access::ComputeWriteBuffer)],
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

/// The counts read back from the result buffer, as the histogram of `[lo, hi]` (the interval
/// the pass's mapping sends to [0, 1]).
pub fn decode(bytes: &[u8], lo: f64, hi: f64) -> RangeHistogram {
    let word = |i: usize| {
        bytes
            .get(i * 4..i * 4 + 4)
            .map_or(0, |b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    let (min_key, max_key) = (word(FINE_BINS + 2), word(FINE_BINS + 3));
    let inside = (min_key != u32::MAX).then(|| {
        let x = |key: u32| f64::from(f32::from_bits(key));
        let at = |x: f64| lo + 2.0 * half_difference(hi, lo) * x;
        (at(x(min_key)).clamp(lo, hi), at(x(max_key)).clamp(lo, hi))
    });
    RangeHistogram {
        lo,
        hi,
        bins: (0..FINE_BINS).map(|i| u64::from(word(i))).collect(),
        under: u64::from(word(FINE_BINS)),
        over: u64::from(word(FINE_BINS + 1)),
        inside,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn push_constants_match_the_shader() {
        assert_eq!(
            table::FINE_HISTOGRAM.push_constant_bytes as usize,
            std::mem::size_of::<FineHistogramParams>()
        );
    }
}
