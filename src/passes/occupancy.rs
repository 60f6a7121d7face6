//! Brick min/max for empty-space skipping (shaders/occupancy.comp): one workgroup per 8^3 brick,
//! the range over the brick plus a 2-voxel halo (the footprint of trilinear and cubic samples).

use crate::gpu::shaders::table;
use crate::gpu::{
    Buffer, ComputePipeline, DescriptorSet, Device, GpuResult, Image, Recording, Resource, Sampler,
};
use ash::vk;
use std::sync::Arc;

/// Side of a brick in voxels: 8^3 bricks keep the grid small (24,576 bricks and 3 KB of
/// occupancy bits for the 256x256x192 phantom) while skipping most of the air around a head.
pub const BRICK_SIDE: u32 = 8;

/// Voxels each side of a brick that its range covers (occupancy.comp's halo: the footprint of
/// trilinear and cubic samples).
pub const OCCUPANCY_HALO: u32 = 2;

/// Push constants of `occupancy.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct OccupancyParams {
    /// Volume dimensions (w unused).
    pub dims: [i32; 4],
    /// Brick grid (xyz) and brick side (w).
    pub bricks: [i32; 4],
}

/// Bricks along each axis for a volume of `dims`.
pub fn brick_grid(dims: [u32; 3]) -> [u32; 3] {
    dims.map(|d| d.div_ceil(BRICK_SIDE))
}

/// The brick-range pass, with the brick-bounds pass that classifies its ranges and the distance
/// map made from its bits (one pipeline key for the three: whoever skips empty space needs them).
pub struct OccupancyPass {
    pipeline: Arc<ComputePipeline>,
    bounds: super::brick_bounds::BrickBoundsPass,
    distance: super::brick_distance::BrickDistancePass,
}

impl OccupancyPass {
    /// The compiled pipeline (for its statistics and workgroup).
    pub fn pipeline(&self) -> &Arc<ComputePipeline> {
        &self.pipeline
    }

    /// Creates the pipeline.
    pub fn new(device: &Device, cache: vk::PipelineCache) -> GpuResult<Self> {
        Ok(OccupancyPass {
            pipeline: ComputePipeline::new(device, &table::OCCUPANCY, &[], cache)?,
            bounds: super::brick_bounds::BrickBoundsPass::new(device, cache)?,
            distance: super::brick_distance::BrickDistancePass::new(device, cache)?,
        })
    }

    /// The brick-bounds pass (bits and opacity bounds from the ranges).
    pub fn bounds(&self) -> &super::brick_bounds::BrickBoundsPass {
        &self.bounds
    }

    /// The distance-map pass (Chebyshev distances from the bits).
    pub fn distance(&self) -> &super::brick_distance::BrickDistancePass {
        &self.distance
    }

    /// Records the ranges of `volume` (in `Access::ComputeSampled`) into `ranges` (2 u32 per
    /// brick: the bits of min and max); afterwards `ranges` was last written by a compute shader.
    pub fn record(
        &self,
        rec: &mut Recording,
        volume: &Arc<Image>,
        nearest: &Arc<Sampler>,
        ranges: &Arc<Buffer>,
    ) -> GpuResult<()> {
        let extent = volume.extent();
        let grid = brick_grid(extent);
        let set = DescriptorSet::new(
            &self.pipeline,
            0,
            &[
                (
                    "volume",
                    Resource::CombinedImageSampler(volume.clone(), nearest.clone()),
                ),
                ("ranges", Resource::Buffer(ranges.clone())),
            ],
        )?;
        let params = OccupancyParams {
            dims: [extent[0] as i32, extent[1] as i32, extent[2] as i32, 0],
            bricks: [
                grid[0] as i32,
                grid[1] as i32,
                grid[2] as i32,
                BRICK_SIDE as i32,
            ],
        };
        rec.dispatch(&self.pipeline, &[set], bytemuck::bytes_of(&params), grid)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn push_constants_match_the_shader() {
        assert_eq!(
            table::OCCUPANCY.push_constant_bytes as usize,
            std::mem::size_of::<OccupancyParams>()
        );
    }

    #[test]
    fn the_grid_covers_every_voxel() {
        assert_eq!(brick_grid([256, 256, 192]), [32, 32, 24]);
        assert_eq!(brick_grid([1, 9, 17]), [1, 2, 3]);
    }
}
