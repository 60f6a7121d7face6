//! The empty-space distance map (shaders/brick_distance.comp, issue 33 item 3): per brick the
//! Chebyshev distance in bricks to the nearest occupied brick, from the brick-bounds pass's bits,
//! so the raymarch jumps across the whole empty cube around a sample.
//!
//! Decisions:
//! - Three dispatches of one pipeline (the separable L-infinity transform, one axis each) in the
//!   brick-bounds pass's own buffer ([`BrickBoundsLayout`]: a distance region and a scratch
//!   region of one byte per brick after the count), recorded right behind that pass in its
//!   submission: it runs when the classification changes, never per frame, and needs no
//!   allocation of its own.
//! - Bytes capped at 255 bricks (2040 voxels): beyond that a jump ends early and the next one
//!   continues, so the cap costs a step, never a sample.

use super::brick_bounds::BrickBoundsLayout;
use crate::gpu::shaders::table;
use crate::gpu::{
    Access, Buffer, ComputePipeline, DescriptorSet, Device, GpuResult, Recording, Resource,
};
use ash::vk;
use std::sync::Arc;

/// Invocations per workgroup (one per word of four bricks).
const WORKGROUP: u32 = 64;

/// Push constants of `brick_distance.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct BrickDistanceParams {
    /// Brick grid (xyz) and the axis this dispatch scans (w).
    pub grid: [u32; 4],
    /// First word of the bits, of the source bytes and of the destination bytes; w unused.
    pub offsets: [u32; 4],
}

/// The distance-map pass.
pub struct BrickDistancePass {
    pipeline: Arc<ComputePipeline>,
}

impl BrickDistancePass {
    /// Creates the pipeline.
    pub fn new(device: &Device, cache: vk::PipelineCache) -> GpuResult<Self> {
        Ok(BrickDistancePass {
            pipeline: ComputePipeline::new(device, &table::BRICK_DISTANCE, &[], cache)?,
        })
    }

    /// The compiled pipeline.
    pub fn pipeline(&self) -> &Arc<ComputePipeline> {
        &self.pipeline
    }

    /// Records the three scans over `data`, whose bits the brick-bounds pass has just written
    /// (left in `Access::ComputeWriteBuffer`) for a brick grid `grid`; afterwards the distance
    /// region was last written by a compute shader.
    pub fn record(&self, rec: &mut Recording, data: &Arc<Buffer>, grid: [u32; 3]) -> GpuResult<()> {
        let bricks = grid.iter().map(|&g| u64::from(g)).product();
        let layout = BrickBoundsLayout::new(bricks);
        let set = DescriptorSet::new(
            &self.pipeline,
            0,
            &[("data", Resource::Buffer(data.clone()))],
        )?;
        let groups = (layout.distance_words() as u32).div_ceil(WORKGROUP);
        let (distances, scratch) = (layout.distances() as u32, layout.distance_scratch() as u32);
        // x: bits -> distances; y: distances -> scratch; z: scratch -> distances.
        let scans = [(0, distances), (distances, scratch), (scratch, distances)];
        for (axis, (source, destination)) in scans.into_iter().enumerate() {
            // Orders the previous pass's writes (the bits, or the last scan's bytes) before this
            // scan reads them and overwrites the region it read two scans ago.
            rec.barriers(
                &[(data, Access::ComputeWriteBuffer, Access::ComputeWriteBuffer)],
                &[],
            );
            let params = BrickDistanceParams {
                grid: [grid[0], grid[1], grid[2], axis as u32],
                offsets: [0, source, destination, 0],
            };
            rec.dispatch(
                &self.pipeline,
                std::slice::from_ref(&set),
                bytemuck::bytes_of(&params),
                [groups, 1, 1],
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn push_constants_match_the_shader() {
        assert_eq!(
            table::BRICK_DISTANCE.push_constant_bytes as usize,
            std::mem::size_of::<BrickDistanceParams>()
        );
    }
}
