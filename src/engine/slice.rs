//! World-oriented slices of a prepared volume (`morphray slice`, the viewer's slice panels).
//!
//! Decisions:
//! - A [`Slicer`] owns the slice pipeline beside the engine rather than inside it: slices are an
//!   optional client of the prepared volume (no plan, no twin, no derived volume), and the
//!   engine's pipeline bookkeeping stays about the raymarch's first frame.
//! - Only a whole volume can be sliced: a bricked atlas (`--memory-budget` too small for the
//!   volume) is refused with a message; sampling through the brick table is future work.
//! - [`Slicer::render`] is one submission with its own readback (the CLI, tests);
//!   [`Slicer::record`] records into a caller's submission (the viewer's frame).

use super::Engine;
use super::prepare::{PreparedVolume, VolumeLayout};
use super::readback::read_image_bytes;
use crate::gpu::{Access, GpuError, GpuResult, Image, Recording};
use crate::passes::slice::{SlicePass, output_desc};
use crate::scene::VolumeGeometry;
use crate::scene::slice::SliceGrid;
use std::sync::Arc;

/// One slice read back to the host.
#[derive(Clone, Debug)]
pub struct SliceImage {
    /// The grid it shows.
    pub grid: SliceGrid,
    /// `width * height` RGBA8 pixels, row-major; alpha 0 outside the volume.
    pub rgba8: Vec<u8>,
    /// GPU time of the slice pass (ms).
    pub gpu_ms: f64,
}

/// The slice pipeline of one engine's device.
pub struct Slicer {
    pass: SlicePass,
}

/// The geometry of a prepared volume, or an error for an affine the slicer cannot invert.
pub fn geometry_of(prepared: &PreparedVolume) -> GpuResult<VolumeGeometry> {
    VolumeGeometry::new(prepared.dims, prepared.affine)
        .map_err(|e| GpuError::UnusableInput(e.to_string()))
}

impl Slicer {
    /// Compiles the slice pipeline through the engine's pipeline cache.
    pub fn new(engine: &Engine) -> GpuResult<Slicer> {
        Ok(Slicer {
            pass: SlicePass::new(&engine.device, engine.pipeline_cache.raw())?,
        })
    }

    /// Records `grid` of `prepared` with `window` (I_norm black, white) into `target` (last
    /// accessed as `before`; left in `Access::ComputeWriteImage`).
    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        engine: &Engine,
        rec: &mut Recording,
        prepared: &PreparedVolume,
        grid: &SliceGrid,
        window: (f64, f64),
        target: &Arc<Image>,
        before: Access,
    ) -> GpuResult<()> {
        if let VolumeLayout::Bricked(_) = prepared.layout {
            return Err(GpuError::Unsupported(
                "slices of a bricked volume are not supported yet; raise --memory-budget so the \
                 volume fits whole"
                    .into(),
            ));
        }
        let geometry = geometry_of(prepared)?;
        let index = grid.in_index_space(&geometry);
        self.pass.record(
            rec,
            &prepared.normalized,
            &engine.nearest,
            &index,
            window,
            target,
            before,
        )
    }

    /// Renders `grid` of `prepared` in one submission and reads it back.
    pub fn render(
        &self,
        engine: &Engine,
        prepared: &PreparedVolume,
        grid: &SliceGrid,
        window: (f64, f64),
    ) -> GpuResult<SliceImage> {
        let target = Image::new(&engine.device, output_desc(grid.width, grid.height))?;
        let mut rec = Recording::new(&engine.device, "slice")?;
        rec.begin_pass("slice");
        self.record(
            engine,
            &mut rec,
            prepared,
            grid,
            window,
            &target,
            Access::Nothing,
        )?;
        rec.end_pass();
        let timings = rec.submit()?.wait()?;
        let rgba8 = read_image_bytes(&engine.device, &target, Access::ComputeWriteImage)?;
        Ok(SliceImage {
            grid: *grid,
            rgba8,
            gpu_ms: timings.iter().map(|t| t.gpu_ms).sum(),
        })
    }
}
