//! Optional denoising of I_norm before the derivatives (the paper's section 5.3: "in-shader
//! spatial smoothing or median filtering as optional compute passes"): a Gaussian in mm
//! (shaders/gaussian_axis.comp, three axes), the 3x3x3 median and a bilateral filter
//! (shaders/denoise.comp). f64 twins: `reference::denoise`.
//!
//! Decisions:
//! - Off by default (`Denoise::None`): on the phantom at its nominal noise every filter moves
//!   edges or costs contrast (ACCURACY.md measures it); it is for low-SNR scans.
//! - The edge-preserving option is the bilateral filter, not anisotropic diffusion: one dispatch
//!   with no iteration count or time step to choose, and its two parameters are in the units a
//!   user knows (mm and I_norm).
//! - The output has I_norm's own format and replaces it for every later pass (derivatives,
//!   vesselness, raymarch), so nothing downstream changes. The histogram, the range and the
//!   windows stay those of the original (analysis runs before denoising).
//! - Spatial sizes are per index axis from the voxel lengths (exact for orthogonal affines, as
//!   the vesselness Gaussian); the bilateral's radius is ceil(2 s) voxels per axis, at most
//!   [`MAX_BILATERAL_RADIUS`] (11^3 taps).

use crate::gpu::shaders::table;
use crate::gpu::{
    Access, ComputePipeline, DescriptorSet, Device, GpuError, GpuResult, Image, ImageDesc,
    Recording, Resource, Sampler,
};
use crate::passes::vesselness::{GaussianAxis, axis_kernels};
use ash::vk;
use std::sync::Arc;

/// Largest bilateral radius in voxels per axis.
pub const MAX_BILATERAL_RADIUS: u32 = 5;

/// A denoising filter, as `--denoise` names it.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Denoise {
    /// No filter.
    #[default]
    None,
    /// Gaussian of this sigma (mm).
    Gaussian {
        /// Sigma in mm.
        sigma_mm: f32,
    },
    /// 3x3x3 median.
    Median,
    /// Bilateral: spatial sigma (mm) and range sigma (I_norm).
    Bilateral {
        /// Spatial sigma in mm.
        sigma_mm: f32,
        /// Range sigma in I_norm units.
        range: f32,
    },
}

impl std::str::FromStr for Denoise {
    type Err = String;

    /// `none`, `gaussian:SIGMA_MM`, `median` or `bilateral:SIGMA_MM,RANGE`.
    fn from_str(s: &str) -> Result<Self, String> {
        let positive = |v: &str, what: &str| -> Result<f32, String> {
            match v.trim().parse::<f32>() {
                Ok(x) if x.is_finite() && x > 0.0 => Ok(x),
                _ => Err(format!("{what} must be a positive number, got `{v}`")),
            }
        };
        let (kind, args) = s.split_once(':').unwrap_or((s, ""));
        match (kind.trim(), args) {
            ("none", "") => Ok(Denoise::None),
            ("median", "") => Ok(Denoise::Median),
            ("gaussian", a) if !a.is_empty() => Ok(Denoise::Gaussian {
                sigma_mm: positive(a, "the Gaussian's sigma (mm)")?,
            }),
            ("bilateral", a) => {
                let (s, r) = a
                    .split_once(',')
                    .ok_or("bilateral needs SIGMA_MM,RANGE (e.g. bilateral:1,0.1)")?;
                Ok(Denoise::Bilateral {
                    sigma_mm: positive(s, "the bilateral's sigma (mm)")?,
                    range: positive(r, "the bilateral's range sigma")?,
                })
            }
            _ => Err(format!(
                "unknown denoising `{s}`: use none, gaussian:SIGMA_MM, median or bilateral:SIGMA_MM,RANGE"
            )),
        }
    }
}

/// Push constants of `denoise.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct DenoiseParams {
    /// Dimensions (w unused).
    pub dims: [i32; 4],
    /// Bilateral taps per axis (w unused).
    pub radius: [i32; 4],
    /// Voxel length per index axis in mm (w unused).
    pub spacing: [f32; 4],
    /// 0 median, 1 bilateral.
    pub mode: i32,
    /// 1 / (2 s^2).
    pub inv_2s2: f32,
    /// 1 / (2 r^2).
    pub inv_2r2: f32,
}

/// The images a run allocates: the denoised volume (I_norm's format), then for the Gaussian two
/// R32F scratch volumes (freed when the recording completes).
pub fn denoise_descs(denoise: &Denoise, extent: [u32; 3], format: vk::Format) -> Vec<ImageDesc> {
    let mut out = vec![ImageDesc::volume("denoised I_norm", extent, format)];
    if matches!(denoise, Denoise::Gaussian { .. }) {
        for name in ["denoise scratch A", "denoise scratch B"] {
            out.push(ImageDesc::volume(name, extent, vk::Format::R32_SFLOAT));
        }
    }
    out
}

/// Voxel length along each index axis (mm).
pub fn axis_lengths(linear: [[f64; 3]; 3]) -> [f64; 3] {
    [0, 1, 2].map(|c| (0..3).map(|r| linear[r][c].powi(2)).sum::<f64>().sqrt())
}

/// Bilateral taps per axis for a spatial sigma.
pub fn bilateral_radius(linear: [[f64; 3]; 3], sigma_mm: f32) -> [u32; 3] {
    axis_lengths(linear).map(|h| {
        let r = (2.0 * sigma_mm as f64 / h).ceil();
        if r.is_finite() && r > 0.0 {
            (r as u32).min(MAX_BILATERAL_RADIUS)
        } else {
            0
        }
    })
}

/// The two pipelines.
pub struct DenoisePass {
    gaussian: Arc<ComputePipeline>,
    filter: Arc<ComputePipeline>,
}

impl DenoisePass {
    /// Creates both pipelines.
    pub fn new(device: &Device, cache: vk::PipelineCache) -> GpuResult<Self> {
        Ok(DenoisePass {
            gaussian: ComputePipeline::new(device, &table::GAUSSIAN_AXIS, &[], cache)?,
            filter: ComputePipeline::new(device, &table::DENOISE, &[], cache)?,
        })
    }

    /// Records the filter; `normalized` (whole volume) is in `Access::ComputeSampled` and stays
    /// there; the result (None for `Denoise::None`) is left in `Access::ComputeSampled`.
    pub fn record(
        &self,
        device: &Device,
        rec: &mut Recording,
        normalized: &Arc<Image>,
        nearest: &Arc<Sampler>,
        linear_part: [[f64; 3]; 3],
        denoise: &Denoise,
    ) -> GpuResult<Option<Arc<Image>>> {
        if *denoise == Denoise::None {
            return Ok(None);
        }
        let extent = normalized.extent();
        let descs = denoise_descs(denoise, extent, normalized.format());
        let images = descs
            .into_iter()
            .map(|d| Image::new(device, d))
            .collect::<GpuResult<Vec<_>>>()?;
        let out = images[0].clone();
        let dims = [extent[0] as i32, extent[1] as i32, extent[2] as i32, 0];
        let groups = self.filter.workgroups_for(extent);
        match *denoise {
            Denoise::None => {}
            Denoise::Gaussian { sigma_mm } => {
                let kernels = axis_kernels(linear_part, sigma_mm);
                let (a, b) = (&images[1], &images[2]);
                for (axis, (src, dst)) in
                    [(normalized, a), (a, b), (b, &out)].into_iter().enumerate()
                {
                    // Fresh images: nothing to preserve.
                    rec.barriers(&[], &[(dst, Access::Nothing, Access::ComputeWriteImage)]);
                    let axis_pass = GaussianAxis {
                        pipeline: &self.gaussian,
                        nearest,
                        dims,
                        groups,
                    };
                    axis_pass.record(rec, src, dst, axis, kernels[axis])?;
                }
                rec.keep(images[1].clone());
                rec.keep(images[2].clone());
            }
            Denoise::Median | Denoise::Bilateral { .. } => {
                let (mode, s, r) = match *denoise {
                    Denoise::Bilateral { sigma_mm, range } => (1, sigma_mm, range),
                    _ => (0, 1.0, 1.0),
                };
                if !(s.is_finite() && s > 0.0 && r.is_finite() && r > 0.0) {
                    return Err(GpuError::InvalidRequest(format!(
                        "bilateral sigmas must be positive, got {s} mm and {r}"
                    )));
                }
                let radius = bilateral_radius(linear_part, s);
                let h = axis_lengths(linear_part);
                rec.barriers(&[], &[(&out, Access::Nothing, Access::ComputeWriteImage)]);
                let set = DescriptorSet::new(
                    &self.filter,
                    0,
                    &[
                        (
                            "source",
                            Resource::CombinedImageSampler(normalized.clone(), nearest.clone()),
                        ),
                        ("denoised", Resource::StorageImage(out.clone())),
                    ],
                )?;
                let p = DenoiseParams {
                    dims,
                    radius: [radius[0] as i32, radius[1] as i32, radius[2] as i32, 0],
                    spacing: [h[0] as f32, h[1] as f32, h[2] as f32, 0.0],
                    mode,
                    inv_2s2: 1.0 / (2.0 * s * s),
                    inv_2r2: 1.0 / (2.0 * r * r),
                };
                rec.dispatch(&self.filter, &[set], bytemuck::bytes_of(&p), groups)?;
                // Orders the writes before every later pass's fetches.
                rec.barriers(
                    &[],
                    &[(&out, Access::ComputeWriteImage, Access::ComputeSampled)],
                );
            }
        }
        Ok(Some(out))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn push_constants_match_the_shader() {
        assert_eq!(
            table::DENOISE.push_constant_bytes as usize,
            std::mem::size_of::<DenoiseParams>()
        );
    }

    #[test]
    fn parses_every_kind_and_refuses_the_rest() {
        assert_eq!("none".parse::<Denoise>(), Ok(Denoise::None));
        assert_eq!("median".parse::<Denoise>(), Ok(Denoise::Median));
        assert_eq!(
            "gaussian:0.8".parse::<Denoise>(),
            Ok(Denoise::Gaussian { sigma_mm: 0.8 })
        );
        assert_eq!(
            "bilateral:1,0.1".parse::<Denoise>(),
            Ok(Denoise::Bilateral {
                sigma_mm: 1.0,
                range: 0.1
            })
        );
        for bad in [
            "",
            "gaussian",
            "gaussian:-1",
            "gaussian:nan",
            "bilateral:1",
            "bilateral:1,0",
            "median:3",
            "box",
        ] {
            assert!(bad.parse::<Denoise>().is_err(), "{bad}");
        }
    }
}
