//! Occupancy bits and per-brick opacity bounds (shaders/brick_bounds.comp), from the brick
//! ranges under one classification (issue 17 item 2).
//!
//! Decisions:
//! - It runs when the classification changes, never per frame, and replaces the host's
//!   classification of every brick (a few ms per frame of change at 266 k bricks on one core).
//! - One buffer holds the pass's inputs and outputs ([`BrickBoundsLayout`]): the raymarch reads
//!   the bits and bounds from the same buffer, one per frame in flight, so no other allocation
//!   exists for it. The ranges are copied in by the host when the volume (or vesselness or
//!   labels) changes, not when the classification does.
//! - The channel values arrive as push constants (128 bytes: the minimum every device offers);
//!   the supports are rounded outward on the host so the f32 test equals the f64 twin's
//!   (`scene::occupancy::bound_channels`).

use crate::gpu::shaders::table;
use crate::gpu::{Buffer, ComputePipeline, DescriptorSet, Device, GpuResult, Recording, Resource};
use ash::vk;
use std::sync::Arc;

/// Invocations per workgroup (one per word of 32 bricks).
const WORKGROUP: u32 = 64;

/// Flag: the vessel channel's ranges are present.
pub const VESSEL_BIT: u32 = 1;
/// Flag: the label bits are present.
pub const LABEL_BIT: u32 = 2;

/// The support of a channel that is off: no f32 range meets it.
pub const EMPTY_SUPPORT: [f32; 2] = [3.0e38, -3.0e38];

/// Push constants of `brick_bounds.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct BrickBoundsParams {
    /// Tissues 0-3 and the vessel channel: lo, hi, edge, opacity (0: off).
    pub windows: [[f32; 4]; 5],
    /// Open supports, rounded outward ([`EMPTY_SUPPORT`] when off).
    pub supports: [[f32; 2]; 5],
    /// Bricks.
    pub bricks: u32,
    /// [`VESSEL_BIT`] | [`LABEL_BIT`].
    pub flags: u32,
}

/// Word offsets of the pass's buffer for `bricks` bricks (see the shader's header).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BrickBoundsLayout {
    /// Bricks.
    pub bricks: u64,
    /// Words of bits (32 bricks each, at least 1).
    pub words: u64,
}

impl BrickBoundsLayout {
    /// The layout for `bricks` bricks.
    pub fn new(bricks: u64) -> Self {
        BrickBoundsLayout {
            bricks,
            words: bricks.div_ceil(32).max(1),
        }
    }

    /// First word of the bounds (after the bits).
    pub fn bounds(&self) -> u64 {
        self.words
    }

    /// First word of the I_norm ranges.
    pub fn ranges(&self) -> u64 {
        self.words + self.bricks
    }

    /// First word of the vesselness ranges.
    pub fn vessel_ranges(&self) -> u64 {
        self.words + 3 * self.bricks
    }

    /// First word of the label bits.
    pub fn label_bits(&self) -> u64 {
        self.words + 5 * self.bricks
    }

    /// The word counting occupied bricks.
    pub fn count(&self) -> u64 {
        2 * self.words + 5 * self.bricks
    }

    /// Words of one distance-map region (four bricks' bytes each, at least 1).
    pub fn distance_words(&self) -> u64 {
        self.bricks.div_ceil(4).max(1)
    }

    /// First word of the empty-space distance map (`passes::brick_distance`), after the count:
    /// the raymarch reads it here.
    pub fn distances(&self) -> u64 {
        self.count() + 1
    }

    /// First word of the distance map's scratch region (the y scan's output).
    pub fn distance_scratch(&self) -> u64 {
        self.distances() + self.distance_words()
    }

    /// Size of the buffer in bytes.
    pub fn bytes(&self) -> u64 {
        4 * (self.distance_scratch() + self.distance_words())
    }
}

/// The brick-bounds pass.
pub struct BrickBoundsPass {
    pipeline: Arc<ComputePipeline>,
}

impl BrickBoundsPass {
    /// Creates the pipeline.
    pub fn new(device: &Device, cache: vk::PipelineCache) -> GpuResult<Self> {
        Ok(BrickBoundsPass {
            pipeline: ComputePipeline::new(device, &table::BRICK_BOUNDS, &[], cache)?,
        })
    }

    /// The compiled pipeline.
    pub fn pipeline(&self) -> &Arc<ComputePipeline> {
        &self.pipeline
    }

    /// Records the pass over `data` (laid out as [`BrickBoundsLayout`] for `params.bricks`,
    /// inputs written and the count word zeroed, both visible to compute shaders); afterwards
    /// its bits, bounds and count were last written by a compute shader.
    pub fn record(
        &self,
        rec: &mut Recording,
        data: &Arc<Buffer>,
        params: &BrickBoundsParams,
    ) -> GpuResult<()> {
        let set = DescriptorSet::new(
            &self.pipeline,
            0,
            &[("data", Resource::Buffer(data.clone()))],
        )?;
        let words = BrickBoundsLayout::new(u64::from(params.bricks)).words;
        let groups = (words as u32).div_ceil(WORKGROUP);
        rec.dispatch(
            &self.pipeline,
            &[set],
            bytemuck::bytes_of(params),
            [groups, 1, 1],
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn push_constants_match_the_shader() {
        assert_eq!(
            table::BRICK_BOUNDS.push_constant_bytes as usize,
            std::mem::size_of::<BrickBoundsParams>()
        );
        assert!(std::mem::size_of::<BrickBoundsParams>() <= 128);
    }

    #[test]
    fn the_layout_leaves_no_gaps_and_no_overlaps() {
        let l = BrickBoundsLayout::new(33);
        assert_eq!(l.words, 2);
        assert_eq!(l.bounds(), 2);
        assert_eq!(l.ranges(), 2 + 33);
        assert_eq!(l.vessel_ranges(), 2 + 33 + 66);
        assert_eq!(l.label_bits(), 2 + 33 + 132);
        assert_eq!(l.count(), 2 + 33 + 132 + 2);
        assert_eq!(l.distances(), l.count() + 1);
        assert_eq!(l.distance_words(), 9);
        assert_eq!(l.distance_scratch(), l.count() + 1 + 9);
        assert_eq!(l.bytes(), 4 * (l.count() + 1 + 18));
        assert_eq!(BrickBoundsLayout::new(0).words, 1);
    }
}
