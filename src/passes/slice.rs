//! One world-oriented slice of I_norm as a greyscale RGBA8 image (shaders/slice.comp).
//!
//! Decisions:
//! - It binds the prepared volume's own normalized image (no second upload, no copy) with the
//!   engine's nearest sampler: the shader fetches texels and interpolates itself.
//! - The plane arrives in index space ([`IndexGrid`]), mapped from world millimetres in f64 on
//!   the CPU; the f32 push constants then only carry one origin and two steps.
//! - The window is `[lo, hi]` in I_norm units (`hi > lo`; anything else is refused), so the
//!   viewer's window/level drag and the CLI's `--window` mean the same numbers.

use crate::gpu::shaders::table;
use crate::gpu::{
    Access, ComputePipeline, DescriptorSet, Device, GpuError, GpuResult, Image, ImageDesc,
    Recording, Resource, Sampler,
};
use ash::vk;
use std::sync::Arc;

/// A slice's pixel grid in the volume's index space (voxel centres at integers), what this pass
/// and its f64 twin sample: pixel (x, y) is at `origin + x * du + y * dv`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IndexGrid {
    /// Index position of pixel (0, 0)'s centre.
    pub origin: [f64; 3],
    /// Index step per column.
    pub du: [f64; 3],
    /// Index step per row.
    pub dv: [f64; 3],
    /// Pixels per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
}

/// Push constants of `slice.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SliceParams {
    /// Index position of pixel (0, 0)'s centre (w unused).
    pub origin: [f32; 4],
    /// Index step per column (w unused).
    pub du: [f32; 4],
    /// Index step per row (w unused).
    pub dv: [f32; 4],
    /// Volume dimensions (w unused).
    pub dims: [i32; 4],
    /// I_norm at black, 1 / (white - black) (zw unused).
    pub window: [f32; 4],
    /// Image width and height (zw unused).
    pub size: [i32; 4],
}

/// The RGBA8 image one slice of `width` x `height` pixels is written into (as
/// [`SlicePass::record`] creates it).
pub fn output_desc(width: u32, height: u32) -> ImageDesc {
    ImageDesc::render_target("slice", width, height, vk::Format::R8G8B8A8_UNORM)
}

/// The push constants of one slice, or an error for an empty or non-finite window.
pub fn params(grid: &IndexGrid, dims: [u32; 3], window: (f64, f64)) -> GpuResult<SliceParams> {
    let width = window.1 - window.0;
    if !(width > 0.0 && width.is_finite() && window.0.is_finite()) {
        return Err(GpuError::InvalidRequest(format!(
            "the slice window [{}, {}] must have its white end above its black end",
            window.0, window.1
        )));
    }
    let v = |a: [f64; 3]| [a[0] as f32, a[1] as f32, a[2] as f32, 0.0];
    Ok(SliceParams {
        origin: v(grid.origin),
        du: v(grid.du),
        dv: v(grid.dv),
        dims: [dims[0] as i32, dims[1] as i32, dims[2] as i32, 0],
        window: [window.0 as f32, (1.0 / width) as f32, 0.0, 0.0],
        size: [grid.width as i32, grid.height as i32, 0, 0],
    })
}

/// The slice pass.
pub struct SlicePass {
    pipeline: Arc<ComputePipeline>,
}

impl SlicePass {
    /// Creates the pipeline.
    pub fn new(device: &Device, cache: vk::PipelineCache) -> GpuResult<Self> {
        Ok(SlicePass {
            pipeline: ComputePipeline::new(device, &table::SLICE, &[], cache)?,
        })
    }

    /// The compiled pipeline.
    pub fn pipeline(&self) -> &Arc<ComputePipeline> {
        &self.pipeline
    }

    /// Records the slice `grid` of `normalized` (in `Access::ComputeSampled`, a whole volume)
    /// into `target` (an [`output_desc`] image of the grid's size, last accessed as `before`);
    /// `target` is left in `Access::ComputeWriteImage`.
    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        rec: &mut Recording,
        normalized: &Arc<Image>,
        nearest: &Arc<Sampler>,
        grid: &IndexGrid,
        window: (f64, f64),
        target: &Arc<Image>,
        before: Access,
    ) -> GpuResult<()> {
        let extent = target.extent();
        if extent[0] != grid.width || extent[1] != grid.height {
            return Err(GpuError::InvalidRequest(format!(
                "slice target {}x{} does not match the slice's {}x{} pixels",
                extent[0], extent[1], grid.width, grid.height
            )));
        }
        let params = params(grid, normalized.extent(), window)?;
        let set = DescriptorSet::new(
            &self.pipeline,
            0,
            &[
                (
                    "volume",
                    Resource::CombinedImageSampler(normalized.clone(), nearest.clone()),
                ),
                ("target", Resource::StorageImage(target.clone())),
            ],
        )?;
        // Orders the target's last use (a readback or a composition) before the writes.
        rec.barriers(&[], &[(target, before, Access::ComputeWriteImage)]);
        let groups = self.pipeline.workgroups_for([grid.width, grid.height, 1]);
        rec.dispatch(&self.pipeline, &[set], bytemuck::bytes_of(&params), groups)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn push_constants_match_the_shader() {
        assert_eq!(
            table::SLICE.push_constant_bytes as usize,
            std::mem::size_of::<SliceParams>()
        );
    }

    #[test]
    fn empty_windows_are_refused() {
        let grid = IndexGrid {
            origin: [0.0; 3],
            du: [1.0, 0.0, 0.0],
            dv: [0.0, 1.0, 0.0],
            width: 2,
            height: 2,
        };
        assert!(params(&grid, [2, 2, 2], (0.5, 0.5)).is_err());
        assert!(params(&grid, [2, 2, 2], (0.0, f64::NAN)).is_err());
        let p = params(&grid, [2, 2, 2], (0.25, 0.75)).unwrap();
        assert_eq!(p.window[..2], [0.25, 2.0]);
    }
}
