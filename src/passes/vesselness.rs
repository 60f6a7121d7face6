//! Multi-scale Frangi vesselness (shaders/gaussian_axis.comp, shaders/vesselness.comp): per
//! scale, three separable Gaussian dispatches (x, y, z) into two f32 scratch volumes, then the
//! scale-normalized Hessian, its eigenvalues and Frangi's measure folded into the running maximum.
//! The f64 twin and the reasons for every constant are in `reference::vesselness`.
//!
//! Decisions:
//! - Storage: the response is R32_SFLOAT, read and written in place across scales. r32f is the one
//!   float format Vulkan guarantees for storage-image reads with a format qualifier; f16 would need
//!   `shaderStorageImageExtendedFormats` or an extra conversion pass. The response is in [0, 1].
//! - Scratch: two R32_SFLOAT volumes (ping-pong of the three axes); f32 because the Hessian of a
//!   smoothed field is a difference of nearly equal samples (f16 would lose it: NUMERICS.md
//!   "curvature"). They are freed when the recording completes; peak memory 12 bytes per voxel.
//! - The Gaussian is per index axis with sigma in voxels of that axis (anisotropic spacing);
//!   exact for orthogonal affines (module doc of the twin). Radius capped at `MAX_RADIUS` voxels.

use crate::gpu::shaders::table;
use crate::gpu::{
    Access, ComputePipeline, DescriptorSet, Device, GpuError, GpuResult, Image, ImageDesc,
    Recording, Resource, Sampler,
};
use crate::passes::derivatives::world_transform;
use ash::vk;
use std::sync::Arc;

/// Largest Gaussian radius in voxels (as `reference::vesselness::MAX_RADIUS`).
pub const MAX_RADIUS: u32 = 64;
/// Most scales one run accepts (each costs four dispatches).
pub const MAX_SCALES: usize = 16;

/// Parameters of the measure (defaults and reasons: `reference::vesselness`).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct VesselnessParams {
    /// Gaussian scales in mm (each > 0, finite; at most [`MAX_SCALES`]).
    pub scales_mm: Vec<f32>,
    /// Frangi's alpha (plate vs line).
    pub alpha: f32,
    /// Frangi's beta (blob vs line).
    pub beta: f32,
    /// Frangi's c (structure vs noise), in scale-normalized I_norm units.
    pub c: f32,
}

impl Default for VesselnessParams {
    fn default() -> Self {
        use crate::reference::vesselness as r;
        VesselnessParams {
            scales_mm: r::DEFAULT_SCALES_MM.iter().map(|&s| s as f32).collect(),
            alpha: r::DEFAULT_ALPHA as f32,
            beta: r::DEFAULT_BETA as f32,
            c: r::DEFAULT_C as f32,
        }
    }
}

impl VesselnessParams {
    /// A typed error for parameters no run can use.
    pub fn validate(&self) -> GpuResult<()> {
        let bad = |what: String| Err(GpuError::InvalidRequest(what));
        if self.scales_mm.is_empty() || self.scales_mm.len() > MAX_SCALES {
            return bad(format!(
                "vesselness needs 1 to {MAX_SCALES} scales, got {}",
                self.scales_mm.len()
            ));
        }
        if let Some(s) = self
            .scales_mm
            .iter()
            .find(|s| !(s.is_finite() && **s > 0.0))
        {
            return bad(format!("vesselness scales must be positive mm, got {s}"));
        }
        for (name, v) in [("alpha", self.alpha), ("beta", self.beta), ("c", self.c)] {
            if !(v.is_finite() && v > 0.0) {
                return bad(format!("vesselness {name} must be positive, got {v}"));
            }
        }
        Ok(())
    }
}

/// Push constants of `gaussian_axis.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GaussianParams {
    /// Dimensions (w unused).
    pub dims: [i32; 4],
    /// Index axis.
    pub axis: i32,
    /// Taps -radius..radius.
    pub radius: i32,
    /// Sigma in voxels of the axis.
    pub sigma: f32,
    /// Unused.
    pub unused: f32,
}

/// Push constants of `vesselness.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct FrangiParams {
    /// Dimensions (w unused).
    pub dims: [i32; 4],
    /// Rows of M = A^-T (w unused).
    pub m_rows: [[f32; 4]; 3],
    /// sigma_mm^2.
    pub sigma2: f32,
    /// Frangi's alpha.
    pub alpha: f32,
    /// Frangi's beta.
    pub beta: f32,
    /// Frangi's c.
    pub c: f32,
    /// 1 for the first scale.
    pub first: i32,
}

/// The images one run allocates for a volume of `extent`: the response, then two scratch
/// volumes (as [`VesselnessPass::record`] creates them and the pass plan declares them).
pub fn vesselness_descs(extent: [u32; 3]) -> [ImageDesc; 3] {
    let f = vk::Format::R32_SFLOAT;
    [
        ImageDesc::volume("vesselness", extent, f),
        ImageDesc::volume("vesselness scratch A", extent, f),
        ImageDesc::volume("vesselness scratch B", extent, f),
    ]
}

/// Gaussian radius and sigma in voxels of each axis for `sigma_mm`.
pub fn axis_kernels(linear: [[f64; 3]; 3], sigma_mm: f32) -> [(u32, f32); 3] {
    crate::reference::vesselness::sigma_voxels(linear, sigma_mm as f64).map(|s| {
        let r = crate::reference::vesselness::radius(s) as u32;
        (r.min(MAX_RADIUS), s as f32)
    })
}

/// The two pipelines.
pub struct VesselnessPass {
    gaussian: Arc<ComputePipeline>,
    frangi: Arc<ComputePipeline>,
}

/// One axis of the separable Gaussian (the vesselness scale space's step, and the Gaussian
/// denoising's): `src` sampled, blurred along an index axis into `dst`.
pub struct GaussianAxis<'a> {
    /// The `gaussian_axis` pipeline.
    pub pipeline: &'a Arc<ComputePipeline>,
    /// The sampler `src` is read through (texel centres only).
    pub nearest: &'a Arc<Sampler>,
    /// Volume dimensions (w unused).
    pub dims: [i32; 4],
    /// Workgroups covering the volume.
    pub groups: [u32; 3],
}

impl GaussianAxis<'_> {
    /// Records the pass along `axis` with `(radius, sigma)` in voxels; `dst` must be in
    /// `Access::ComputeWriteImage` and is left in `Access::ComputeSampled`.
    pub fn record(
        &self,
        rec: &mut Recording,
        src: &Arc<Image>,
        dst: &Arc<Image>,
        axis: usize,
        (radius, sigma): (u32, f32),
    ) -> GpuResult<()> {
        let set = DescriptorSet::new(
            self.pipeline,
            0,
            &[
                (
                    "source",
                    Resource::CombinedImageSampler(src.clone(), self.nearest.clone()),
                ),
                ("blurred", Resource::StorageImage(dst.clone())),
            ],
        )?;
        let p = GaussianParams {
            dims: self.dims,
            axis: axis as i32,
            radius: radius as i32,
            sigma,
            unused: 0.0,
        };
        rec.dispatch(self.pipeline, &[set], bytemuck::bytes_of(&p), self.groups)?;
        // Orders the writes before the next axis's (or every later pass's) fetches.
        rec.barriers(
            &[],
            &[(dst, Access::ComputeWriteImage, Access::ComputeSampled)],
        );
        Ok(())
    }
}

impl VesselnessPass {
    /// Creates both pipelines.
    pub fn new(device: &Device, cache: vk::PipelineCache) -> GpuResult<Self> {
        Ok(VesselnessPass {
            gaussian: ComputePipeline::new(device, &table::GAUSSIAN_AXIS, &[], cache)?,
            frangi: ComputePipeline::new(device, &table::VESSELNESS, &[], cache)?,
        })
    }

    /// Records every scale into `rec`. `normalized` (a whole volume) must be in
    /// `Access::ComputeSampled` and stays there; the returned response is left in
    /// `Access::ComputeSampled`.
    pub fn record(
        &self,
        device: &Device,
        rec: &mut Recording,
        normalized: &Arc<Image>,
        nearest: &Arc<Sampler>,
        linear_part: [[f64; 3]; 3],
        params: &VesselnessParams,
    ) -> GpuResult<Arc<Image>> {
        params.validate()?;
        let extent = normalized.extent();
        let m = world_transform(linear_part)?;
        let [response, a, b] = vesselness_descs(extent).map(|d| Image::new(device, d));
        let (response, a, b) = (response?, a?, b?);
        let dims = [extent[0] as i32, extent[1] as i32, extent[2] as i32, 0];
        let rows = m.transpose().to_cols_array_2d();
        let groups = self.frangi.workgroups_for(extent);
        let mut state_a = Access::Nothing;
        let mut state_b = Access::Nothing;
        for (index, &sigma_mm) in params.scales_mm.iter().enumerate() {
            let kernels = axis_kernels(linear_part, sigma_mm);
            // x: I_norm -> A, y: A -> B, z: B -> A.
            let steps: [(&Arc<Image>, &Arc<Image>); 3] = [(normalized, &a), (&a, &b), (&b, &a)];
            for (axis, (src, dst)) in steps.into_iter().enumerate() {
                let dst_state = if Arc::ptr_eq(dst, &a) {
                    &mut state_a
                } else {
                    &mut state_b
                };
                // Orders the previous reads (or nothing) of dst before its writes.
                rec.barriers(&[], &[(dst, *dst_state, Access::ComputeWriteImage)]);
                *dst_state = Access::ComputeWriteImage;
                let axis_pass = GaussianAxis {
                    pipeline: &self.gaussian,
                    nearest,
                    dims,
                    groups,
                };
                axis_pass.record(rec, src, dst, axis, kernels[axis])?;
                *dst_state = Access::ComputeSampled;
            }
            let before = if index == 0 {
                Access::Nothing
            } else {
                Access::ComputeReadWriteImage
            };
            // The first scale discards the response's contents; later ones order the previous
            // scale's writes before this one's reads.
            rec.barriers(&[], &[(&response, before, Access::ComputeReadWriteImage)]);
            let set = DescriptorSet::new(
                &self.frangi,
                0,
                &[
                    (
                        "smoothed",
                        Resource::CombinedImageSampler(a.clone(), nearest.clone()),
                    ),
                    ("response", Resource::StorageImage(response.clone())),
                ],
            )?;
            let s = sigma_mm;
            let p = FrangiParams {
                dims,
                m_rows: rows.map(|r| [r[0] as f32, r[1] as f32, r[2] as f32, 0.0]),
                sigma2: s * s,
                alpha: params.alpha,
                beta: params.beta,
                c: params.c,
                first: i32::from(index == 0),
            };
            rec.dispatch(&self.frangi, &[set], bytemuck::bytes_of(&p), groups)?;
        }
        // Orders the last scale's writes before every later sampling of the response.
        rec.barriers(
            &[],
            &[(
                &response,
                Access::ComputeReadWriteImage,
                Access::ComputeSampled,
            )],
        );
        // The scratch volumes live until the recording completes.
        rec.keep(a);
        rec.keep(b);
        Ok(response)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn push_constants_match_the_shaders() {
        assert_eq!(
            table::GAUSSIAN_AXIS.push_constant_bytes as usize,
            std::mem::size_of::<GaussianParams>()
        );
        assert_eq!(
            table::VESSELNESS.push_constant_bytes as usize,
            std::mem::size_of::<FrangiParams>()
        );
    }

    #[test]
    fn invalid_parameters_are_refused() {
        let ok = VesselnessParams::default();
        assert!(ok.validate().is_ok());
        for bad in [
            VesselnessParams {
                scales_mm: vec![],
                ..ok.clone()
            },
            VesselnessParams {
                scales_mm: vec![1.0, f32::NAN],
                ..ok.clone()
            },
            VesselnessParams {
                scales_mm: vec![-1.0],
                ..ok.clone()
            },
            VesselnessParams {
                c: 0.0,
                ..ok.clone()
            },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
    }

    #[test]
    fn anisotropic_spacing_gives_per_axis_sigma() {
        let k = axis_kernels([[0.5, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 3.0]], 1.5);
        assert_eq!(k[0], (9, 3.0));
        assert_eq!(k[1], (5, 1.5));
        assert_eq!(k[2], (2, 0.5));
    }
}
