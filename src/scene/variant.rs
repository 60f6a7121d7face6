//! Which raymarch pipeline a scene's effects need: the mapping from [`Effects`] to the
//! specialization constants of [`RaymarchVariant`].
//!
//! Decision: the mapping lives in the scene layer (an inherent impl of the pass's type, here),
//! so the raymarch pass knows only its constants and never imports the scene; what means nothing
//! in a mode is normalized away, so effects that mean the same shader share one pipeline.

use super::{
    ClassificationLookup, CurvatureMode, Effects, GradientFilter, GradientSource, Interpolation,
    LightModel, OpacityCorrection, RenderMode,
};
use crate::passes::raymarch::RaymarchVariant;

impl RaymarchVariant {
    /// The variant `effects` needs; what means nothing in a mode is normalized away, so such
    /// effects share a pipeline.
    pub fn of(effects: &Effects, count_samples: bool) -> Self {
        Self::of_layout(effects, count_samples, false)
    }

    /// [`RaymarchVariant::of`] for a whole (`bricked` false) or bricked volume.
    pub fn of_layout(effects: &Effects, count_samples: bool, bricked: bool) -> Self {
        let dvr = effects.mode == RenderMode::Dvr;
        let q = &effects.quality;
        RaymarchVariant {
            mode: match effects.mode {
                RenderMode::Dvr => 0,
                RenderMode::Mip => 1,
                RenderMode::MinIp => 2,
            },
            curvature_mode: match effects.curvature_mode() {
                CurvatureMode::Off => 0,
                CurvatureMode::Stored => 1,
                CurvatureMode::OnTheFly => 2,
            },
            shading: dvr && effects.shading,
            gradient_mode: match (dvr, effects.gradient_source, q.gradient_filter) {
                (false, _, _) | (true, GradientSource::Precomputed, _) => 0,
                (true, GradientSource::OnTheFly, GradientFilter::Central) => 1,
                (true, GradientSource::OnTheFly, GradientFilter::Sobel) => 2,
            },
            interpolation: match q.interpolation {
                Interpolation::Nearest => 0,
                Interpolation::Trilinear => 1,
                Interpolation::Tricubic => 2,
            },
            naive_opacity: dvr && q.opacity_correction == OpacityCorrection::Naive,
            // With the vessel channel the engine ORs in the bricks its window can see on the
            // vesselness's own ranges (engine/occupancy.rs), so skipping stays lossless.
            skip_empty: dvr && q.empty_space_skipping,
            count_samples,
            bricked,
            // Set by the engine where a label overlay is attached to the render target.
            labels: false,
            // Set by the engine where intensity layers are attached to the render target.
            layers: 0,
            vessels: dvr && effects.vessels,
            // A classified volume holds the opacity of one step: no longer steps with it.
            long_steps: dvr
                && q.empty_space_skipping
                && q.long_steps.is_on()
                && (q.classification != ClassificationLookup::Volume || bricked),
            // Set by the engine where the derived volumes hold a brain mask in use.
            brain: false,
            // The classified volume is built through the table (the classifier variant).
            classify_table: dvr && q.classification != ClassificationLookup::Exact,
            lighting: match effects.lighting.model {
                LightModel::Studio if dvr && effects.shading => 1,
                LightModel::Matcap if dvr && effects.shading => 2,
                _ => 0,
            },
            depth_cues: dvr && effects.lighting.depth_cues,
            pick: false,
            // A whole volume only (an atlas would need a classified atlas); the engine turns it
            // off for a scene with a cut.
            classified: dvr && q.classification == ClassificationLookup::Volume && !bricked,
            // Set by the engine from the device (`AdapterInfo::prefers_texel_lookups`).
            texel_lookups: false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::shaders::table;
    use crate::scene::uniforms::RaymarchUniforms;
    use crate::scene::{CurvatureSource, Quality};

    #[test]
    fn uniform_block_matches_the_shader() {
        let params = table::RAYMARCH.binding("params").unwrap();
        assert_eq!(
            params.block_bytes as usize,
            std::mem::size_of::<RaymarchUniforms>()
        );
    }

    #[test]
    fn effects_that_mean_the_same_shader_share_a_variant() {
        let mip = Effects {
            mode: RenderMode::Mip,
            ..Effects::default()
        };
        let mip_with_dvr_options = Effects {
            curvature: true,
            shading: true,
            ..mip
        };
        assert_eq!(
            RaymarchVariant::of(&mip, false),
            RaymarchVariant::of(&mip_with_dvr_options, false)
        );
        let on_the_fly = Effects {
            curvature: true,
            gradient_source: GradientSource::OnTheFly,
            quality: Quality {
                curvature_source: CurvatureSource::Stored,
                ..Quality::default()
            },
            ..Effects::default()
        };
        assert_eq!(
            RaymarchVariant::of(&on_the_fly, false).curvature_mode,
            2,
            "no stored k without stored gradients"
        );
    }
}
