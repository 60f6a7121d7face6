//! Gradient, Hessian and directional curvature of I_norm (shaders/derivatives.comp), paper eqs.
//! 2 and 3, written compactly to 3D images.
//!
//! Decisions:
//! - Outputs on request only ([`DerivativeOutputs`]); what is not requested is neither computed
//!   (specialization constants remove the code) nor stored (no image is allocated for it; a
//!   1-texel placeholder fills the unused binding).
//! - Formats ([`gradient_format`]): by default gradient magnitude alone in R16_SFLOAT, with
//!   curvature in R16G16_SFLOAT (2 or 4 bytes per voxel); f32, or 8-bit SNORM scaled by the
//!   volume's maximum, for the accuracy study; normals in R8G8B8A8_SNORM. Values are in world
//!   units (I_norm per mm and per mm^2): the world transform `M = A^-T` is applied in the shader,
//!   in f32, from the f64 affine.
//! - Curvature and normals are 0 where |g| <= tau (NUMERICS.md "zero gradient").
//! - Every dispatch also reduces max |g| (the normalizer of paper eq. 4) into a slot buffer;
//!   with no output requested that is all it does (the on-the-fly gradient path).

use crate::gpu::shaders::table;
use crate::gpu::{
    Access, Buffer, ComputePipeline, DescriptorSet, Device, GpuError, GpuResult, Image, ImageDesc,
    Recording, Resource, Sampler, SpecValue,
};
use ash::vk;
use glam::DMat3;
use std::sync::Arc;

/// Precision of stored derived volumes (gradient magnitude and curvature).
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "snake_case")]
pub enum DerivedPrecision {
    /// 32-bit float (R32F / RG32F).
    F32,
    /// 16-bit float (R16F / RG16F): the storage default of the derivative pass itself, and the
    /// scene setting for stills at fine steps.
    #[default]
    F16,
    /// 8-bit signed normalized, scaled by the volume's maximum (R8 / RG8 SNORM): the scenes'
    /// interactive default (`scene::Quality::default`).
    Snorm8,
}

/// |g| (I_norm per mm) at or below which the gradient direction is undefined. The f64 twin uses
/// the same value (`reference::derivatives::DEFAULT_TAU`).
pub const DEFAULT_TAU: f32 = 1e-6;

/// Bytes of the gradient-maximum buffer: 256 u32 slots (see derivatives.comp).
pub const STAT_BYTES: u64 = 256 * 4;

/// Which derived volumes to compute.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize)]
pub struct DerivativeOutputs {
    /// |grad I| in world units (paper eq. 4's gradient term).
    pub magnitude: bool,
    /// Directional curvature k = g^T H g (paper eq. 3); stored beside the magnitude.
    pub curvature: bool,
    /// Unit world-space gradient direction, for shading.
    pub normal: bool,
    /// Storage precision of |g| and k.
    pub precision: DerivedPrecision,
    /// The multi-scale vesselness volume (`passes::vesselness`), computed with the derivatives
    /// for the vessel channel; not an output of this pass's shader.
    pub vesselness: bool,
    /// Brain extraction (`passes::brain`), computed with the derivatives when the scene shows
    /// brain tissues; not an output of this pass's shader.
    pub brain: crate::passes::brain::BrainSwitch,
}

/// Push constants of `derivatives.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct DerivativeParams {
    /// Dimensions (w unused).
    pub dims: [i32; 4],
    /// Rows of M = A^-T (w unused).
    pub m_rows: [[f32; 4]; 3],
    /// Zero-gradient threshold.
    pub tau: f32,
    /// Multiplier of |g| before storage.
    pub scale_g: f32,
    /// Multiplier of k before storage.
    pub scale_k: f32,
    /// Side of the atlas slots of a bricked volume, 0 for a whole volume.
    pub slot_side: i32,
    /// Halo of the atlas slots (their brick's own voxels alone count towards max |g|).
    pub slot_halo: i32,
}

/// The derived images one dispatch produced.
pub struct DerivedVolumes {
    /// R16F (|g|) or RG16F (|g|, k); None when neither was requested.
    pub gradient: Option<Arc<Image>>,
    /// RGBA8_SNORM unit gradient; None when not requested.
    pub normal: Option<Arc<Image>>,
    /// What was computed.
    pub outputs: DerivativeOutputs,
    /// Stored values are `|g| * scale[0]` and `k * scale[1]`; readers divide.
    pub store_scale: [f32; 2],
}

impl DerivativeOutputs {
    /// Bytes per texel of the gradient (and curvature) volume in this precision.
    pub fn gradient_texel_bytes(&self) -> u64 {
        let channel = match self.precision {
            DerivedPrecision::F32 => 4,
            DerivedPrecision::F16 => 2,
            DerivedPrecision::Snorm8 => 1,
        };
        channel * if self.curvature { 2 } else { 1 }
    }
}

/// The texel format of the gradient (and curvature) volume.
pub fn gradient_format(precision: DerivedPrecision, curvature: bool) -> vk::Format {
    match (precision, curvature) {
        (DerivedPrecision::F32, false) => vk::Format::R32_SFLOAT,
        (DerivedPrecision::F32, true) => vk::Format::R32G32_SFLOAT,
        (DerivedPrecision::F16, false) => vk::Format::R16_SFLOAT,
        (DerivedPrecision::F16, true) => vk::Format::R16G16_SFLOAT,
        (DerivedPrecision::Snorm8, false) => vk::Format::R8_SNORM,
        (DerivedPrecision::Snorm8, true) => vk::Format::R8G8_SNORM,
    }
}

/// `A^-T` of the affine's linear part, or an error for a singular or non-finite affine.
pub fn world_transform(linear: [[f64; 3]; 3]) -> GpuResult<DMat3> {
    let a = DMat3::from_cols_array_2d(&linear).transpose(); // rows in, glam is column-major
    let det = a.determinant();
    // Singular relative to the axes' lengths (as the f64 twin judges it), so micrometre voxels
    // (det ~ 1e-15 mm^3) are fine and only truly degenerate affines are refused.
    let lengths = a.x_axis.length() * a.y_axis.length() * a.z_axis.length();
    if !det.is_finite()
        || lengths.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)
        || det.abs() < 1e-12 * lengths
    {
        return Err(GpuError::InvalidRequest(format!(
            "the volume's affine is singular (determinant {det:e}); derivatives need an invertible affine"
        )));
    }
    let m = a.inverse().transpose();
    // The shader squares gradients built from M in f32 (max 3.4e38): entries past 1e15 per mm
    // (voxels under 1e-15 mm) would overflow to infinity.
    let largest = m
        .to_cols_array()
        .iter()
        .fold(0.0f64, |acc, v| acc.max(v.abs()));
    if !largest.is_finite() || largest > 1e15 {
        let [x, y, z] = [a.x_axis, a.y_axis, a.z_axis].map(|c| c.length());
        return Err(GpuError::UnusableInput(format!(
            "the voxel spacing ({x:e} x {y:e} x {z:e} mm) is unusable: voxels under 1e-15 mm \
             are too small to differentiate in f32; set the header's pixdim and sform/qform to \
             the real voxel size in mm (nibabel, fslchpixdim)"
        )));
    }
    Ok(m)
}

/// The derivative pass for one combination of outputs.
pub struct DerivativePass {
    pipeline: Arc<ComputePipeline>,
    outputs: DerivativeOutputs,
}

/// The pass's two output images for a volume of `extent` texels, as `record` creates them and
/// as the pass plan declares them: the gradient (|g|, and the curvature channel when asked) and
/// the normals. An output not asked for is a 1-texel image named "(unused placeholder)" (the
/// shader declares both; the engine drops it after the pass).
pub fn output_descs(outputs: &DerivativeOutputs, extent: [u32; 3]) -> [ImageDesc; 2] {
    let image = |name: &str, wanted: bool, format| {
        if wanted {
            ImageDesc::volume(name, extent, format)
        } else {
            ImageDesc::volume(&format!("{name} (unused placeholder)"), [1, 1, 1], format)
        }
    };
    [
        image(
            "gradient magnitude",
            outputs.magnitude || outputs.curvature,
            gradient_format(outputs.precision, outputs.curvature),
        ),
        image("normals", outputs.normal, vk::Format::R8G8B8A8_SNORM),
    ]
}

impl DerivativePass {
    /// The compiled pipeline (for its statistics and workgroup).
    pub fn pipeline(&self) -> &Arc<ComputePipeline> {
        &self.pipeline
    }

    /// Creates the pipeline specialized for `outputs`.
    pub fn new(
        device: &Device,
        outputs: DerivativeOutputs,
        cache: vk::PipelineCache,
    ) -> GpuResult<Self> {
        let pipeline = ComputePipeline::new(
            device,
            &table::DERIVATIVES,
            &[
                ("WANT_MAGNITUDE", SpecValue::Bool(outputs.magnitude)),
                ("WANT_CURVATURE", SpecValue::Bool(outputs.curvature)),
                ("WANT_NORMAL", SpecValue::Bool(outputs.normal)),
            ],
            cache,
        )?;
        Ok(DerivativePass { pipeline, outputs })
    }

    /// Allocates the requested outputs and records the pass. `normalized` must be in
    /// `Access::ComputeSampled`; the outputs are left in `Access::ComputeWriteImage`. `stats`
    /// `slot` = [side, halo] with side > 0 marks `normalized` as a brick atlas of slots of that
    /// shape, and `slot_bounds` holds each slot's box inside the volume (see derivatives.comp);
    /// for a whole volume any small buffer does, unread.
    /// `stats` (STAT_BYTES) receives the bits of max |g| in 256 slots and is left in `Access::ComputeWriteBuffer`.
    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        device: &Device,
        rec: &mut Recording,
        normalized: &Arc<Image>,
        nearest: &Arc<Sampler>,
        linear_part: [[f64; 3]; 3],
        tau: f32,
        store_scale: [f32; 2],
        slot: [i32; 2],
        slot_bounds: &Arc<Buffer>,
        stats: &Arc<Buffer>,
    ) -> GpuResult<DerivedVolumes> {
        let extent = normalized.extent();
        let m = world_transform(linear_part)?;
        let [gradient, normal] = output_descs(&self.outputs, extent);
        let gradient = Image::new(device, gradient)?;
        let normal = Image::new(device, normal)?;
        let set = DescriptorSet::new(
            &self.pipeline,
            0,
            &[
                (
                    "volume",
                    Resource::CombinedImageSampler(normalized.clone(), nearest.clone()),
                ),
                ("gradient_out", Resource::StorageImage(gradient.clone())),
                ("normal_out", Resource::StorageImage(normal.clone())),
                ("stats", Resource::Buffer(stats.clone())),
                ("slot_bounds", Resource::Buffer(slot_bounds.clone())),
            ],
        )?;
        rec.fill_buffer(stats, 0, STAT_BYTES, 0);
        // Orders the zeroing of the maximum before the shader's atomicMax.
        rec.barriers(
            &[(stats, Access::TransferWrite, Access::ComputeWriteBuffer)],
            &[],
        );
        // Moves the fresh outputs to GENERAL for storage writes; nothing to preserve.
        rec.barriers(
            &[],
            &[
                (&gradient, Access::Nothing, Access::ComputeWriteImage),
                (&normal, Access::Nothing, Access::ComputeWriteImage),
            ],
        );
        let rows = m.transpose().to_cols_array_2d(); // rows of M
        let params = DerivativeParams {
            dims: [extent[0] as i32, extent[1] as i32, extent[2] as i32, 0],
            m_rows: rows.map(|r| [r[0] as f32, r[1] as f32, r[2] as f32, 0.0]),
            tau,
            scale_g: store_scale[0],
            scale_k: store_scale[1],
            slot_side: slot[0],
            slot_halo: slot[1],
        };
        let groups = self.pipeline.workgroups_for(extent);
        rec.dispatch(&self.pipeline, &[set], bytemuck::bytes_of(&params), groups)?;
        Ok(DerivedVolumes {
            gradient: (self.outputs.magnitude || self.outputs.curvature).then_some(gradient),
            normal: self.outputs.normal.then_some(normal),
            outputs: self.outputs,
            store_scale,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn push_constants_match_the_shader() {
        assert_eq!(
            table::DERIVATIVES.push_constant_bytes as usize,
            std::mem::size_of::<DerivativeParams>()
        );
    }

    #[test]
    fn world_transform_of_spacing_divides_by_spacing() {
        let m = world_transform([[0.5, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 3.0]]).unwrap();
        let g = m * glam::DVec3::new(1.0, 1.0, 1.0);
        assert!((g - glam::DVec3::new(2.0, 1.0, 1.0 / 3.0)).length() < 1e-12);
    }

    #[test]
    fn singular_affines_are_rejected() {
        assert!(world_transform([[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]]).is_err());
        assert!(world_transform([[f64::NAN, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]).is_err());
    }

    #[test]
    fn tiny_voxels_are_invertible_until_f32_cannot_hold_their_gradients() {
        // 1e-5 mm voxels: det 1e-15, which an absolute 1e-12 threshold wrongly called singular
        // (found by the loader fuzzing, which accepts such pixdim).
        let diag = |h: f64| [[h, 0.0, 0.0], [0.0, h, 0.0], [0.0, 0.0, h]];
        let m = world_transform(diag(1e-5)).unwrap();
        assert!((m.x_axis.x - 1e5).abs() < 1e-6);
        let err = world_transform(diag(1e-20)).unwrap_err().to_string();
        assert!(err.contains("too small to differentiate"), "{err}");
        assert!(err.contains("spacing") && err.contains("unusable"), "{err}");
        assert!(!err.contains("invalid GPU request"), "{err}");
        // Nearly parallel axes stay singular whatever their length.
        let flat = [[1e-5, 1e-5, 0.0], [0.0, 1e-18, 0.0], [0.0, 0.0, 1e-5]];
        assert!(world_transform(flat).is_err());
    }
}
