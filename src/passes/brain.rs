//! Brain extraction's GPU passes (shaders/brain_distance_axis.comp, brain_step.comp,
//! brain_pool.comp, and the Gaussian axis shared with the vesselness): the per-voxel half of
//! the algorithm whose exact text and f64 twin are `reference::brain`. The engine
//! (`engine/brain.rs`) strings them together around the two host steps on the coarse grid
//! (largest connected component, hole filling: `reference::brain::components`).
//!
//! Decisions:
//! - Morphology by Euclidean balls in mm as thresholds of a bounded squared distance transform:
//!   separable (three 1-D passes of 2K+1 taps), exact up to the bound, so anisotropic voxels are
//!   handled in mm with no structuring element to build. Erosion of X by r is
//!   `sqd(not X) > r^2`, dilation `sqd(X) <= r^2`.
//! - A working grid of about [`WORKING_MM`] voxels (`working_factors`: whole blocks of the
//!   volume's voxels, averaged by shaders/brain_downsample.comp): 8x fewer voxels than a 0.9 mm
//!   head and the same Dice against ROBEX (the prototype: 0.958 at 1.76 mm against 0.956 at
//!   0.88 mm). The mask stays on that grid; the raymarch samples it trilinearly through the
//!   block mapping (`brain_grid` in the uniforms), so its edge is soft.
//! - Storage on the working grid: three R32_SFLOAT scratch volumes (the smoothed volume, kept
//!   for the band tests, and a ping-pong pair for the distances), freed when the last recording
//!   completes; the mask is R8_UNORM (0 or 1). Peak memory 13 bytes a working voxel, about 1.6
//!   bytes a voxel of a 0.9 mm volume (`brain_descs`).
//! - Every voxel step is one shader with a uniform mode (`StepMode`): the branch is the same for
//!   a whole dispatch, so it costs nothing, and one pipeline replaces five.
//! - Coarse flags are one u32 a cell in host-visible buffers the shaders read or write in place
//!   (no copies); a cell is `coarse` voxels on an edge.

use crate::gpu::shaders::table;
use crate::gpu::{
    Access, Buffer, BufferDesc, ComputePipeline, DescriptorSet, Device, GpuResult, Image,
    ImageDesc, Recording, Resource, Sampler,
};
use crate::passes::vesselness::GaussianAxis;
use ash::vk;
use std::sync::Arc;

/// Whether a scene's brain tissues are classified inside an extracted brain only.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "snake_case")]
pub enum BrainSwitch {
    /// Never extract.
    #[default]
    Off,
    /// Extract; mask only when the volume is a head (`reference::brain_report::BrainDecision`).
    Auto,
    /// Extract; mask whenever a brain was found, even in a volume that looks skull-stripped.
    On,
}

impl BrainSwitch {
    /// Parses `auto`, `on` or `off`.
    pub fn parse(text: &str) -> Option<BrainSwitch> {
        match text.trim().to_ascii_lowercase().as_str() {
            "auto" => Some(BrainSwitch::Auto),
            "on" => Some(BrainSwitch::On),
            "off" => Some(BrainSwitch::Off),
            _ => None,
        }
    }

    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            BrainSwitch::Off => "off",
            BrainSwitch::Auto => "auto",
            BrainSwitch::On => "on",
        }
    }
}

/// Largest distance-transform bound in voxels (taps -bound..bound), as the twin's.
pub const MAX_BOUND: u32 = 64;

/// The working grid's target voxel size in mm.
pub const WORKING_MM: f64 = 1.75;

/// Block edge per axis of the working grid for voxels of `spacing` mm: `round(WORKING_MM / h)`,
/// 1 to 8 (thick slices keep their resolution along the slice axis).
pub fn working_factors(spacing: [f64; 3]) -> [u32; 3] {
    spacing.map(|h| {
        let f = (WORKING_MM / h).round();
        if f.is_finite() {
            f.clamp(1.0, 8.0) as u32
        } else {
            1
        }
    })
}

/// The working grid's dimensions for a volume of `extent` voxels.
pub fn working_extent(extent: [u32; 3], factors: [u32; 3]) -> [u32; 3] {
    std::array::from_fn(|a| extent[a].div_ceil(factors[a].max(1)))
}

/// What `brain_step.comp` computes (its header lists the formulas).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StepMode {
    /// Sources of the erosion: voxels outside the band.
    BandSources = 0,
    /// Sources of the re-growth: eroded voxels in a selected coarse cell.
    CoreSources = 1,
    /// Sources of the closing: re-grown voxels inside the band.
    GrownSources = 2,
    /// Sources of the closing's erosion: voxels outside the dilation.
    OutsideSources = 3,
    /// The mask: closed voxels or filled cells.
    Final = 4,
    /// Sources of the depth under the head's surface: voxels outside the head's cells.
    HeadSources = 5,
    /// The smoothed volume with the head's outer shell (depth at most `scalp_mm`) set to 0.
    DepthCut = 6,
}

/// What `brain_pool.comp` tests per coarse cell.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PoolMode {
    /// Every voxel has D > t.
    All = 0,
    /// Some voxel has D > t.
    Any = 1,
    /// Some voxel is in the band.
    Band = 2,
    /// Some voxel has S > t (the head's foreground; t is an I_norm, not mm^2).
    Foreground = 3,
}

/// Push constants of `brain_step.comp` and `brain_pool.comp` (one layout).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct BrainStepParams {
    /// Dimensions, w = mode.
    pub dims: [i32; 4],
    /// Coarse grid dimensions, w = cell edge in voxels.
    pub coarse: [i32; 4],
    /// Band: lo < S < hi.
    pub lo: f32,
    /// Upper end of the band.
    pub hi: f32,
    /// Threshold on the squared distance (mm^2).
    pub threshold: f32,
    /// Unused.
    pub unused: f32,
}

/// Push constants of `brain_downsample.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct DownsampleParams {
    /// The volume's dimensions (w unused).
    pub fine: [i32; 4],
    /// The working grid's dimensions (w unused).
    pub working: [i32; 4],
    /// Block edge per axis (w unused).
    pub factors: [i32; 4],
}

/// Push constants of `brain_distance_axis.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct DistanceParams {
    /// Dimensions (w unused).
    pub dims: [i32; 4],
    /// Index axis.
    pub axis: i32,
    /// Taps -bound..bound.
    pub bound: i32,
    /// Voxel length of the axis in mm.
    pub spacing: f32,
    /// Unused.
    pub unused: f32,
}

/// The images one extraction allocates on a working grid of `extent`: the mask, then the
/// smoothed volume and two distance scratch volumes (as `engine/brain.rs` creates them).
pub fn brain_descs(extent: [u32; 3]) -> [ImageDesc; 4] {
    let f = vk::Format::R32_SFLOAT;
    [
        ImageDesc::volume("brain mask", extent, vk::Format::R8_UNORM),
        ImageDesc::volume("brain smoothed", extent, f),
        ImageDesc::volume("brain distance A", extent, f),
        ImageDesc::volume("brain distance B", extent, f),
    ]
}

/// The coarse-flag buffer of a grid of `cells` cells (one u32 each), host-visible both ways.
pub fn cells_desc(name: &str, cells: usize) -> BufferDesc {
    BufferDesc::readback(name, (cells.max(1) * 4) as u64)
}

/// An image and the access it was last left in, so each recording states only where it goes.
pub struct Tracked {
    /// The image.
    pub image: Arc<Image>,
    /// Its last access.
    pub state: Access,
}

impl Tracked {
    /// A new image whose contents may be discarded.
    pub fn new(image: Arc<Image>) -> Self {
        Tracked {
            image,
            state: Access::Nothing,
        }
    }

    /// Orders the previous use before `next` and remembers `next`.
    fn to(&mut self, rec: &mut Recording, next: Access) {
        if self.state != next {
            rec.barriers(&[], &[(&self.image, self.state, next)]);
            self.state = next;
        }
    }
}

/// The pipelines of brain extraction.
pub struct BrainPass {
    downsample: Arc<ComputePipeline>,
    gaussian: Arc<ComputePipeline>,
    distance: Arc<ComputePipeline>,
    step: Arc<ComputePipeline>,
    pool: Arc<ComputePipeline>,
}

/// Per-run geometry every recording needs.
pub struct BrainGrid {
    /// The volume's dimensions.
    pub fine: [u32; 3],
    /// Block edge of the working grid per axis.
    pub factors: [u32; 3],
    /// Working grid dimensions.
    pub extent: [u32; 3],
    /// Working voxel lengths in mm per index axis.
    pub spacing: [f64; 3],
    /// Coarse grid dimensions.
    pub coarse: [u32; 3],
    /// Cell edge in voxels.
    pub cell: u32,
    /// Band in I_norm.
    pub band: (f32, f32),
}

impl BrainGrid {
    fn dims(&self) -> [i32; 4] {
        let e = self.extent;
        [e[0] as i32, e[1] as i32, e[2] as i32, 0]
    }

    fn step_params(&self, mode: i32, threshold: f64) -> BrainStepParams {
        let c = self.coarse;
        let mut dims = self.dims();
        dims[3] = mode;
        BrainStepParams {
            dims,
            coarse: [c[0] as i32, c[1] as i32, c[2] as i32, self.cell as i32],
            lo: self.band.0,
            hi: self.band.1,
            threshold: threshold as f32,
            unused: 0.0,
        }
    }
}

/// Taps per axis for a distance bound of `radius_mm` (`ceil(r / h)`, capped at [`MAX_BOUND`]).
pub fn distance_bounds(spacing: [f64; 3], radius_mm: f64) -> [u32; 3] {
    spacing.map(|h| ((radius_mm / h).ceil().max(0.0) as u32).min(MAX_BOUND))
}

impl BrainPass {
    /// Creates the pipelines.
    pub fn new(device: &Device, cache: vk::PipelineCache) -> GpuResult<Self> {
        Ok(BrainPass {
            downsample: ComputePipeline::new(device, &table::BRAIN_DOWNSAMPLE, &[], cache)?,
            gaussian: ComputePipeline::new(device, &table::GAUSSIAN_AXIS, &[], cache)?,
            distance: ComputePipeline::new(device, &table::BRAIN_DISTANCE_AXIS, &[], cache)?,
            step: ComputePipeline::new(device, &table::BRAIN_STEP, &[], cache)?,
            pool: ComputePipeline::new(device, &table::BRAIN_POOL, &[], cache)?,
        })
    }

    /// The pipelines with the names `morphray kernels` reports.
    pub fn pipelines(&self) -> [(&'static str, &Arc<ComputePipeline>); 5] {
        [
            ("brain_downsample", &self.downsample),
            ("brain gaussian_axis", &self.gaussian),
            ("brain_distance_axis", &self.distance),
            ("brain_step", &self.step),
            ("brain_pool", &self.pool),
        ]
    }

    /// The working grid's block means of `normalized` (in `Access::ComputeSampled`) into `out`.
    pub fn record_downsample(
        &self,
        rec: &mut Recording,
        grid: &BrainGrid,
        nearest: &Arc<Sampler>,
        normalized: &Arc<Image>,
        out: &mut Tracked,
    ) -> GpuResult<()> {
        out.to(rec, Access::ComputeWriteImage);
        let set = DescriptorSet::new(
            &self.downsample,
            0,
            &[
                (
                    "source",
                    Resource::CombinedImageSampler(normalized.clone(), nearest.clone()),
                ),
                ("result", Resource::StorageImage(out.image.clone())),
            ],
        )?;
        let int = |v: [u32; 3]| [v[0] as i32, v[1] as i32, v[2] as i32, 0];
        let p = DownsampleParams {
            fine: int(grid.fine),
            working: int(grid.extent),
            factors: int(grid.factors),
        };
        let groups = self.downsample.workgroups_for(grid.extent);
        rec.dispatch(&self.downsample, &[set], bytemuck::bytes_of(&p), groups)?;
        // Orders the block means before the Gaussian's fetches.
        out.to(rec, Access::ComputeSampled);
        Ok(())
    }

    /// The smoothed volume: the Gaussian along x, y, z (`kernels` per axis, as
    /// `passes::vesselness::axis_kernels`) from `normalized` (left in `Access::ComputeSampled`)
    /// through `a` and `b` into `smoothed`.
    #[allow(clippy::too_many_arguments)]
    pub fn record_smooth(
        &self,
        rec: &mut Recording,
        grid: &BrainGrid,
        nearest: &Arc<Sampler>,
        normalized: &Arc<Image>,
        [smoothed, a, b]: [&mut Tracked; 3],
        kernels: [(u32, f32); 3],
    ) -> GpuResult<()> {
        let axis_pass = GaussianAxis {
            pipeline: &self.gaussian,
            nearest,
            dims: grid.dims(),
            groups: self.gaussian.workgroups_for(grid.extent),
        };
        // x: I_norm -> a, y: a -> b, z: b -> smoothed. Each write is ordered after the target's
        // previous reads; GaussianAxis orders it before the next axis's fetches.
        a.to(rec, Access::ComputeWriteImage);
        axis_pass.record(rec, normalized, &a.image, 0, kernels[0])?;
        a.state = Access::ComputeSampled;
        b.to(rec, Access::ComputeWriteImage);
        axis_pass.record(rec, &a.image, &b.image, 1, kernels[1])?;
        b.state = Access::ComputeSampled;
        smoothed.to(rec, Access::ComputeWriteImage);
        axis_pass.record(rec, &b.image, &smoothed.image, 2, kernels[2])?;
        smoothed.state = Access::ComputeSampled;
        Ok(())
    }

    /// The squared distance to the sources held in `a` (0 at a source, BIG elsewhere), bounded
    /// by `radius_mm`: x a -> b, y b -> a, z a -> b. The result is in `b`.
    pub fn record_distance(
        &self,
        rec: &mut Recording,
        grid: &BrainGrid,
        nearest: &Arc<Sampler>,
        [a, b]: [&mut Tracked; 2],
        radius_mm: f64,
    ) -> GpuResult<()> {
        let bounds = distance_bounds(grid.spacing, radius_mm);
        let groups = self.distance.workgroups_for(grid.extent);
        for (axis, &bound) in bounds.iter().enumerate() {
            let (src, dst) = if axis == 1 {
                (&mut *b, &mut *a)
            } else {
                (&mut *a, &mut *b)
            };
            src.to(rec, Access::ComputeSampled);
            dst.to(rec, Access::ComputeWriteImage);
            let set = DescriptorSet::new(
                &self.distance,
                0,
                &[
                    (
                        "source",
                        Resource::CombinedImageSampler(src.image.clone(), nearest.clone()),
                    ),
                    ("distance", Resource::StorageImage(dst.image.clone())),
                ],
            )?;
            let p = DistanceParams {
                dims: grid.dims(),
                axis: axis as i32,
                bound: bound as i32,
                spacing: grid.spacing[axis] as f32,
                unused: 0.0,
            };
            rec.dispatch(&self.distance, &[set], bytemuck::bytes_of(&p), groups)?;
            // Orders this axis's writes before the next axis's (or the next step's) fetches.
            dst.to(rec, Access::ComputeSampled);
        }
        Ok(())
    }

    /// One voxel step (`mode`) reading the distance `field`, the `smoothed` volume and the
    /// coarse `cells`, writing `out`.
    #[allow(clippy::too_many_arguments)]
    pub fn record_step(
        &self,
        rec: &mut Recording,
        grid: &BrainGrid,
        nearest: &Arc<Sampler>,
        mode: StepMode,
        threshold_mm2: f64,
        [field, smoothed]: [&Tracked; 2],
        cells: &Arc<Buffer>,
        out: &mut Tracked,
    ) -> GpuResult<()> {
        out.to(rec, Access::ComputeWriteImage);
        let set = DescriptorSet::new(
            &self.step,
            0,
            &[
                (
                    "distance_field",
                    Resource::CombinedImageSampler(field.image.clone(), nearest.clone()),
                ),
                (
                    "smoothed",
                    Resource::CombinedImageSampler(smoothed.image.clone(), nearest.clone()),
                ),
                ("cells", Resource::Buffer(cells.clone())),
                ("result", Resource::StorageImage(out.image.clone())),
            ],
        )?;
        let p = grid.step_params(mode as i32, threshold_mm2);
        let groups = self.step.workgroups_for(grid.extent);
        rec.dispatch(&self.step, &[set], bytemuck::bytes_of(&p), groups)?;
        // Orders the step's writes before the next pass's fetches.
        out.to(rec, Access::ComputeSampled);
        Ok(())
    }

    /// The coarse flags (`mode`) of the distance `field` (`threshold` in mm^2), the band or the
    /// foreground (`threshold` in I_norm) into `cells`, left for the host to read once the
    /// recording completes.
    #[allow(clippy::too_many_arguments)]
    pub fn record_pool(
        &self,
        rec: &mut Recording,
        grid: &BrainGrid,
        nearest: &Arc<Sampler>,
        mode: PoolMode,
        threshold: f64,
        [field, smoothed]: [&Tracked; 2],
        cells: &Arc<Buffer>,
    ) -> GpuResult<()> {
        let set = DescriptorSet::new(
            &self.pool,
            0,
            &[
                (
                    "distance_field",
                    Resource::CombinedImageSampler(field.image.clone(), nearest.clone()),
                ),
                (
                    "smoothed",
                    Resource::CombinedImageSampler(smoothed.image.clone(), nearest.clone()),
                ),
                ("cells", Resource::Buffer(cells.clone())),
            ],
        )?;
        let p = grid.step_params(mode as i32, threshold);
        let groups = self.pool.workgroups_for(grid.coarse);
        // Orders the earlier voxel steps' reads of the cells (their binding) before these writes.
        rec.barriers(
            &[(cells, Access::ComputeReadBuffer, Access::ComputeWriteBuffer)],
            &[],
        );
        rec.dispatch(&self.pool, &[set], bytemuck::bytes_of(&p), groups)?;
        // Orders the shader's writes before the host's reads after the fence.
        rec.barriers(
            &[(cells, Access::ComputeWriteBuffer, Access::HostRead)],
            &[],
        );
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn push_constants_match_the_shaders() {
        let step = std::mem::size_of::<BrainStepParams>();
        assert_eq!(table::BRAIN_STEP.push_constant_bytes as usize, step);
        assert_eq!(table::BRAIN_POOL.push_constant_bytes as usize, step);
        assert_eq!(
            table::BRAIN_DISTANCE_AXIS.push_constant_bytes as usize,
            std::mem::size_of::<DistanceParams>()
        );
        assert_eq!(
            table::BRAIN_DOWNSAMPLE.push_constant_bytes as usize,
            std::mem::size_of::<DownsampleParams>()
        );
    }

    #[test]
    fn the_working_grid_is_about_1_75_mm_in_whole_blocks() {
        assert_eq!(working_factors([0.88, 0.88, 0.88]), [2, 2, 2]);
        assert_eq!(working_factors([1.0, 1.0, 2.0]), [2, 2, 1]);
        assert_eq!(working_factors([0.5, 3.0, 0.1]), [4, 1, 8]);
        assert_eq!(working_factors([f64::NAN, 1e-30, 1e30]), [1, 8, 1]);
        assert_eq!(working_extent([189, 256, 7], [2, 2, 1]), [95, 128, 7]);
    }

    #[test]
    fn bounds_cover_the_radius_in_mm_per_axis() {
        assert_eq!(distance_bounds([0.5, 1.0, 3.0], 4.5), [9, 5, 2]);
        assert_eq!(distance_bounds([0.01, 1.0, 1.0], 4.5), [MAX_BOUND, 5, 5]);
    }
}
