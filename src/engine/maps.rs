//! The derived maps of a prepared volume as f32 arrays in world units, for export
//! (`morphray derive`, the Python package): I_norm, |grad I_norm| (per mm), the directional
//! curvature k (per mm^2), the multi-scale vesselness and the denoised I_norm.
//!
//! Decisions: derivatives are computed in f32 storage for export (not the render's 8-bit or f16
//! default) and divided by their store scale, so the maps are in the units of paper eqs. 2-3.
//! With denoising on, every other map is computed from the denoised I_norm (as a scene with that
//! denoising renders), and `normalized` stays the original I_norm. Whole volumes only.

use super::Engine;
use super::prepare::{PreparedVolume, VolumeLayout};
use super::readback::read_image;
use crate::gpu::{Access, GpuError, GpuResult};
use crate::passes::denoise::Denoise;
use crate::passes::derivatives::DerivativeOutputs;
use crate::passes::vesselness::VesselnessParams;
use crate::scene::DerivedPrecision;

/// Which maps to compute.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MapRequest {
    /// |grad I_norm|.
    pub gradient: bool,
    /// k = g^T H g.
    pub curvature: bool,
    /// Multi-scale vesselness with these parameters.
    pub vesselness: Option<VesselnessParams>,
    /// Denoising applied before the other maps (its result is a map too unless `None`).
    pub denoise: Denoise,
    /// The brain mask (`Engine::extract_brain`, any brain found: `BrainSwitch::On`).
    pub brain: bool,
}

/// The maps, x fastest, one f32 per voxel; None where not requested.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DerivedMaps {
    /// I_norm (always).
    pub normalized: Vec<f32>,
    /// |grad I_norm| per mm.
    pub gradient: Option<Vec<f32>>,
    /// k per mm^2.
    pub curvature: Option<Vec<f32>>,
    /// Vesselness in [0, 1].
    pub vesselness: Option<Vec<f32>>,
    /// Denoised I_norm.
    pub denoised: Option<Vec<f32>>,
    /// The brain mask (0 or 1) when one was found, with the extraction's report (also when none
    /// was found: it says why).
    pub brain: Option<Vec<u8>>,
    /// What brain extraction decided, when requested.
    pub brain_report: Option<crate::reference::brain_report::BrainReport>,
}

impl MapRequest {
    /// The request for the maps named (`normalized`, `gradient`, `curvature`, `vesselness`,
    /// `brain`; `morphray derive --maps` and the Python `derive()` take the same names), with
    /// `denoise` applied first and the vesselness at `vessel_scales` mm (empty: the default
    /// scales). Returns the names to export in order, each once, `denoised` last when
    /// denoising is on. Fails on an unknown name or unusable vessel scales.
    pub fn named(
        names: &[String],
        denoise: Denoise,
        vessel_scales: &[f32],
    ) -> GpuResult<(MapRequest, Vec<&'static str>)> {
        let mut request = MapRequest {
            denoise,
            ..Default::default()
        };
        let mut wanted: Vec<&'static str> = Vec::new();
        for name in names {
            let name = match name.trim() {
                "normalized" => "normalized",
                "gradient" => {
                    request.gradient = true;
                    "gradient"
                }
                "curvature" => {
                    request.curvature = true;
                    "curvature"
                }
                "brain" => {
                    request.brain = true;
                    "brain"
                }
                "vesselness" => {
                    let mut params = VesselnessParams::default();
                    if !vessel_scales.is_empty() {
                        params.scales_mm = vessel_scales.to_vec();
                    }
                    params.validate()?;
                    request.vesselness = Some(params);
                    "vesselness"
                }
                other => {
                    return Err(GpuError::InvalidRequest(format!(
                        "unknown map `{other}`: use normalized, gradient, curvature, vesselness \
                         or brain"
                    )));
                }
            };
            if !wanted.contains(&name) {
                wanted.push(name);
            }
        }
        if denoise != Denoise::None {
            wanted.push("denoised");
        }
        Ok((request, wanted))
    }
}

impl Engine {
    /// Computes the requested maps of `prepared` (module decisions).
    pub fn derived_maps(
        &mut self,
        prepared: &PreparedVolume,
        request: &MapRequest,
    ) -> GpuResult<DerivedMaps> {
        if matches!(prepared.layout, VolumeLayout::Bricked(_)) {
            return Err(GpuError::InvalidRequest(
                "derived maps need the whole volume on the GPU; this one is bricked (raise --memory-budget)".into(),
            ));
        }
        let mut maps = DerivedMaps {
            normalized: read(self, &prepared.normalized)?,
            ..Default::default()
        };
        let denoised = self.denoise(prepared, &request.denoise)?;
        if let Some(d) = &denoised {
            maps.denoised = Some(read(self, &d.normalized)?);
        }
        let source = denoised.as_ref().unwrap_or(prepared);
        if request.gradient || request.curvature {
            let outputs = DerivativeOutputs {
                magnitude: true,
                curvature: request.curvature,
                normal: false,
                precision: DerivedPrecision::F32,
                vesselness: false,
                brain: crate::passes::brain::BrainSwitch::Off,
            };
            let derived = self.derive(source, outputs)?;
            let image = derived.volumes.gradient.as_ref().ok_or_else(|| {
                GpuError::Internal("the derivative pass returned no gradient volume".into())
            })?;
            let data = read_image(self.device(), image, Access::ComputeSampled)?;
            let scale = derived.volumes.store_scale;
            let channel = |c: usize| -> Vec<f32> {
                data.values
                    .iter()
                    .skip(c)
                    .step_by(data.channels.max(1))
                    .map(|v| v / scale[c])
                    .collect()
            };
            if request.gradient {
                maps.gradient = Some(channel(0));
            }
            if request.curvature {
                maps.curvature = Some(channel(1));
            }
        }
        if let Some(params) = &request.vesselness {
            let v = self.vesselness(source, params)?;
            maps.vesselness = Some(read(self, &v.image)?);
        }
        if request.brain {
            // From the volume as it is (not the denoised one): extraction smooths on its own.
            let brain = self.extract_brain(prepared, crate::passes::brain::BrainSwitch::On)?;
            if let (true, Some(image)) = (brain.used, &brain.image) {
                let values: Vec<f64> = read(self, image)?.iter().map(|&v| f64::from(v)).collect();
                let mask = crate::reference::brain_mask::WorkingMask {
                    values: &values,
                    dims: image.extent().map(|d| d as usize),
                    factors: brain.factors,
                };
                maps.brain = Some(mask.export(prepared.dims.map(|d| d as usize)));
            }
            maps.brain_report = Some(brain.report.clone());
        }
        Ok(maps)
    }
}

/// The f32 values of a sampled image.
fn read(engine: &Engine, image: &std::sync::Arc<crate::gpu::Image>) -> GpuResult<Vec<f32>> {
    Ok(read_image(engine.device(), image, Access::ComputeSampled)?.values)
}
