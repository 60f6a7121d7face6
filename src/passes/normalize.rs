//! Normalization into a 3D image (shaders/normalize.comp), paper eq. 1.
//!
//! Decisions (NUMERICS.md): scale and offset are computed here in f64 from the GPU's min/max and
//! handed to the shader as `I_norm = clamp((ldexp(s, e) - offset) * scale, 0, 1)`:
//! - the power-of-two pre-scale `e` brings the largest |sample| just below 1, so neither the
//!   subtraction nor the product can overflow for +-3e38 data, and `scale` stays a normal f32
//!   even when 1/(Imax - Imin) would be subnormal;
//! - `offset` is the pre-scaled sample that maps to Imin, exactly representable, so
//!   "1e30 + tiny" ranges subtract exactly (Sterbenz);
//! - a negative scl_slope flips which stored extreme is Imin: `scale` is then negative;
//! - a constant volume (Imax == Imin, or no finite voxel) gets scale 0: I_norm = 0 everywhere;
//! - the range is handled as half-range (`imax/2 - imin/2`), which cannot overflow: float64
//!   data near +-1.7e308 has a range beyond f64 and was once taken for a constant volume.

use crate::gpu::shaders::table;
use crate::gpu::{
    Access, Buffer, ComputePipeline, DescriptorSet, Device, GpuResult, Image, Recording, Resource,
    SpecValue,
};
use crate::volume::{LinearMap, SampleKind};
use ash::vk;
use std::sync::Arc;

/// Push constants of `normalize.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct NormalizeParams {
    /// Volume dimensions.
    pub dims: [u32; 3],
    /// Power-of-two pre-scale applied to every sample.
    pub pre_exponent: i32,
    /// Pre-scaled stored value of Imin.
    pub offset: f32,
    /// `slope * 2^-e / (Imax - Imin)`, or 0 for a constant volume.
    pub scale: f32,
}

/// The physical range and the shader parameters derived from the stored min/max.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Normalization {
    /// Smallest finite physical intensity (None without finite voxels).
    pub imin: Option<f64>,
    /// Largest finite physical intensity.
    pub imax: Option<f64>,
    /// True when every finite voxel has the same intensity (or none is finite): I_norm = 0.
    pub constant: bool,
    /// Shader parameters.
    pub params: NormalizeParams,
}

/// Computes the normalization in f64 from the stored min/max (`None`: no finite sample).
pub fn plan(
    dims: [u32; 3],
    stored_range: Option<(f64, f64)>,
    to_physical: LinearMap,
) -> Normalization {
    let constant_plan = |imin, imax| Normalization {
        imin,
        imax,
        constant: true,
        params: NormalizeParams {
            dims,
            pre_exponent: 0,
            offset: 0.0,
            scale: 0.0,
        },
    };
    let Some((smin, smax)) = stored_range else {
        return constant_plan(None, None);
    };
    let (p1, p2) = (to_physical.apply(smin), to_physical.apply(smax));
    let (imin, imax) = (p1.min(p2), p1.max(p2));
    // Half the range: `imax - imin` itself overflows for float64 data near +-1.7e308.
    let half_range = crate::reference::normalize::half_difference(imax, imin);
    if !(half_range > 0.0 && half_range.is_finite()) {
        return constant_plan(Some(imin), Some(imax));
    }
    // Largest |sample| -> e with |sample| * 2^e in [0.5, 1).
    let largest = smin.abs().max(smax.abs());
    let e = if largest > 0.0 {
        -(largest.log2().floor() as i32 + 1)
    } else {
        0
    };
    let e = e.clamp(-149, 149);
    let reference = if to_physical.slope >= 0.0 { smin } else { smax };
    let offset = reference * 2f64.powi(e);
    // slope / range first: slope * 2^-e alone overflows when the loader folded a large
    // power-of-two scale into the slope (float64 data near 1.7e308).
    let scale = (to_physical.slope / half_range) * 2f64.powi(-e - 1);
    Normalization {
        imin: Some(imin),
        imax: Some(imax),
        constant: false,
        params: NormalizeParams {
            dims,
            pre_exponent: e,
            offset: offset as f32,
            scale: scale as f32,
        },
    }
}

/// Computes the normalization in f64 for a physical range `[lo, hi]` inside the data (the
/// robust range): values outside it are clamped by the shader. The pre-scale comes from the
/// range's own stored ends, so samples far outside (hot voxels) may scale past f32's range:
/// they become +-inf there, and the clamp still sends them to 1 or 0. `lo`'s pre-scaled stored
/// value is rounded to f32 for the shader, and the reported `imin` is the physical value of
/// that rounding, so the mapping the shader applies is exactly the one reported.
pub fn plan_physical(dims: [u32; 3], lo: f64, hi: f64, to_physical: LinearMap) -> Normalization {
    let slope = to_physical.slope;
    let constant = Normalization {
        imin: Some(lo),
        imax: Some(hi),
        constant: true,
        params: NormalizeParams {
            dims,
            pre_exponent: 0,
            offset: 0.0,
            scale: 0.0,
        },
    };
    if !(hi > lo && lo.is_finite() && hi.is_finite() && slope != 0.0 && slope.is_finite()) {
        return constant;
    }
    let stored = |phys: f64| (phys - to_physical.intercept) / slope;
    let (s_lo, s_hi) = (stored(lo), stored(hi));
    let largest = s_lo.abs().max(s_hi.abs());
    let e = if largest > 0.0 && largest.is_finite() {
        -(largest.log2().floor() as i32 + 1)
    } else {
        0
    }
    .clamp(-149, 149);
    let offset = (s_lo * 2f64.powi(e)) as f32;
    let lo_effective = to_physical.apply(offset as f64 * 2f64.powi(-e));
    let half_range = crate::reference::normalize::half_difference(hi, lo_effective);
    if !(half_range > 0.0 && half_range.is_finite()) {
        return constant;
    }
    let scale = (slope / half_range) * 2f64.powi(-e - 1);
    Normalization {
        imin: Some(lo_effective),
        imax: Some(hi),
        constant: false,
        params: NormalizeParams {
            dims,
            pre_exponent: e,
            offset,
            scale: scale as f32,
        },
    }
}

/// The normalization pass for one sample kind.
pub struct NormalizePass {
    pipeline: Arc<ComputePipeline>,
}

impl NormalizePass {
    /// The compiled pipeline (for its statistics and workgroup).
    pub fn pipeline(&self) -> &Arc<ComputePipeline> {
        &self.pipeline
    }

    /// Creates the pipeline specialized for `kind`.
    pub fn new(device: &Device, kind: SampleKind, cache: vk::PipelineCache) -> GpuResult<Self> {
        let pipeline = ComputePipeline::new(
            device,
            &table::NORMALIZE,
            &[("SAMPLE_KIND", SpecValue::U32(kind as u32))],
            cache,
        )?;
        Ok(NormalizePass { pipeline })
    }

    /// [`NormalizePass::record`] as its own pass, then the barrier that orders the writes before
    /// every later read (the histogram, the derivatives, the raymarch; a barrier also orders
    /// work of later submissions to the same queue). Afterwards `target` was last accessed as
    /// `Access::ComputeSampled`.
    pub fn record_for_sampling(
        &self,
        rec: &mut Recording,
        samples: &Arc<Buffer>,
        params: &NormalizeParams,
        target: &Arc<Image>,
    ) -> GpuResult<()> {
        rec.begin_pass("normalize");
        self.record(rec, samples, params, target)?;
        rec.end_pass();
        rec.barriers(
            &[],
            &[(target, Access::ComputeWriteImage, Access::ComputeSampled)],
        );
        Ok(())
    }

    /// Records the normalization of `samples` into `target` (whose previous contents are
    /// discarded). Afterwards `target` was last accessed as `Access::ComputeWriteImage`.
    pub fn record(
        &self,
        rec: &mut Recording,
        samples: &Arc<Buffer>,
        params: &NormalizeParams,
        target: &Arc<Image>,
    ) -> GpuResult<()> {
        let set = DescriptorSet::new(
            &self.pipeline,
            0,
            &[
                ("samples", Resource::Buffer(samples.clone())),
                ("normalized", Resource::StorageImage(target.clone())),
            ],
        )?;
        // Moves the target to GENERAL for storage writes; its old contents are not needed.
        rec.barriers(&[], &[(target, Access::Nothing, Access::ComputeWriteImage)]);
        let groups = self.pipeline.workgroups_for(params.dims);
        rec.dispatch(&self.pipeline, &[set], bytemuck::bytes_of(params), groups)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn apply(p: &NormalizeParams, s: f64) -> f64 {
        ((s * 2f64.powi(p.pre_exponent) - p.offset as f64) * p.scale as f64).clamp(0.0, 1.0)
    }

    #[test]
    fn push_constants_match_the_shader() {
        assert_eq!(
            table::NORMALIZE.push_constant_bytes as usize,
            std::mem::size_of::<NormalizeParams>()
        );
    }

    #[test]
    fn int16_range_maps_to_unit_interval() {
        let n = plan([1, 1, 1], Some((-100.0, 1000.0)), LinearMap::IDENTITY);
        assert_eq!(
            (n.imin, n.imax, n.constant),
            (Some(-100.0), Some(1000.0), false)
        );
        assert!((apply(&n.params, -100.0)).abs() < 1e-7);
        assert!((apply(&n.params, 1000.0) - 1.0).abs() < 1e-6);
        assert!((apply(&n.params, 450.0) - 0.5).abs() < 1e-6);
    }

    #[test]
    fn negative_slope_flips_the_range() {
        let map = LinearMap {
            slope: -2.0,
            intercept: 10.0,
        };
        let n = plan([1, 1, 1], Some((0.0, 5.0)), map);
        assert_eq!((n.imin, n.imax), (Some(0.0), Some(10.0)));
        assert!(
            (apply(&n.params, 5.0)).abs() < 1e-7,
            "stored 5 -> physical 0 = Imin"
        );
        assert!((apply(&n.params, 0.0) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn constant_and_empty_volumes_normalize_to_zero() {
        let n = plan([2, 2, 2], Some((7.0, 7.0)), LinearMap::IDENTITY);
        assert!(n.constant);
        assert_eq!(n.params.scale, 0.0);
        let n = plan([2, 2, 2], None, LinearMap::IDENTITY);
        assert!(n.constant && n.imin.is_none());
    }

    #[test]
    fn extreme_ranges_keep_scale_and_offset_finite_and_normal() {
        for (lo, hi) in [
            (-3e38, 3e38),
            (1e30, 1e30 * (1.0 + 1e-6)),
            (-1e-40, 1e-40),
            (0.0, 1e-44),
        ] {
            let (lo32, hi32) = (lo as f32 as f64, hi as f32 as f64);
            let n = plan([1, 1, 1], Some((lo32, hi32)), LinearMap::IDENTITY);
            assert!(!n.constant, "{lo}..{hi}");
            assert!(
                n.params.scale.is_finite() && n.params.scale.is_normal(),
                "{lo}..{hi}: {:?}",
                n.params
            );
            assert!(n.params.offset.is_finite());
            assert!((apply(&n.params, lo32)).abs() < 1e-6, "{lo}..{hi}");
            assert!(
                (apply(&n.params, hi32) - 1.0).abs() < 1e-5,
                "{lo}..{hi}: {}",
                apply(&n.params, hi32)
            );
        }
    }

    #[test]
    fn float64_ranges_near_the_f64_limit_are_not_taken_for_constant() {
        // float64 data at +-1.7e308 is stored as f32 with a power-of-two scale folded into the
        // map: the physical range (3.4e308) is beyond f64, its half is not.
        let map = LinearMap {
            slope: 2f64.powi(1000),
            intercept: 0.0,
        };
        let (lo, hi) = (-1.6e308 / map.slope, 1.6e308 / map.slope);
        let n = plan([1, 1, 1], Some((lo, hi)), map);
        assert!(!n.constant, "{n:?}");
        assert!(n.params.scale.is_finite() && n.params.scale.is_normal());
        assert!(apply(&n.params, lo).abs() < 1e-6);
        assert!((apply(&n.params, hi) - 1.0).abs() < 1e-5);
        assert!((apply(&n.params, 0.0) - 0.5).abs() < 1e-5);
    }

    #[test]
    fn a_physical_range_inside_the_data_maps_to_the_unit_interval_and_clamps_outside() {
        let map = LinearMap {
            slope: 0.5,
            intercept: -100.0,
        };
        // Physical 0..400 = stored 200..1000; a hot voxel at stored 40 000.
        let n = plan_physical([1, 1, 1], 0.0, 400.0, map);
        assert!(!n.constant);
        assert!(apply(&n.params, 200.0).abs() < 1e-6);
        assert!((apply(&n.params, 600.0) - 0.5).abs() < 1e-6);
        assert_eq!(apply(&n.params, 40_000.0), 1.0);
        assert_eq!(apply(&n.params, -5.0), 0.0);
        let flipped = LinearMap {
            slope: -0.5,
            intercept: 0.0,
        };
        let n = plan_physical([1, 1, 1], -400.0, 0.0, flipped);
        assert!(apply(&n.params, 800.0).abs() < 1e-6, "physical -400 -> 0");
        assert!((apply(&n.params, 0.0) - 1.0).abs() < 1e-6);
        assert!(plan_physical([1, 1, 1], 5.0, 5.0, map).constant);
        assert!(plan_physical([1, 1, 1], 0.0, f64::INFINITY, map).constant);
    }
}
