//! f64 twins of `shaders/include/lighting.glsl` (studio lighting, the matcap, the surface's depth
//! cues) and of the raymarch's cut-face capping (issue 34; `scene::lighting` and `scene::matcap`
//! document the choices).
//!
//! The formulas are the shader's term for term: the normal turned to the viewer, ambient 0.3,
//! headlight fill 0.3 |n . v|, key light 0.55 max(n . l, 0), Blinn highlight 0.2 (n . h)^32,
//! outline 1 - s (1 - |n . v|)^2, clamped to 1; the cues' transmittance
//! exp(-CUE_EXTINCTION sum f dl) over samples at (j + 0.5) dl, j < count, from a point
//! CUE_BACKOFF units back along the ray, the occlusion halfway between the viewer and the normal's
//! side with less matter
//! (probed CUE_SIDE_PROBE units away; a unit is max(1 mm, the finest voxel side)).

use super::ReferenceRaymarch;
use crate::scene::LightModel;
use crate::scene::lighting::DepthCues;
use crate::scene::matcap::MatcapImage;
use glam::DVec3;
use std::sync::Arc;

/// Samples of the occlusion ray (OCCLUSION_SAMPLES in lighting.glsl).
pub const OCCLUSION_SAMPLES: u32 = 4;
/// Samples of the shadow ray (SHADOW_SAMPLES in lighting.glsl).
pub const SHADOW_SAMPLES: u32 = 8;
/// How far back along the ray the cue rays start, in cue units (CUE_BACKOFF).
pub const CUE_BACKOFF: f64 = 1.5;
/// How far the normal's two sides are probed, in cue units (CUE_SIDE_PROBE).
pub const CUE_SIDE_PROBE: f64 = 1.5;
/// The density's scale in the cues' transmittance (CUE_EXTINCTION).
pub const CUE_EXTINCTION: f64 = 0.5;
/// The accumulated opacity at which a ray's surface is taken (CUE_SURFACE_ALPHA).
pub const CUE_SURFACE_ALPHA: f64 = 0.05;

/// The studio model of one sample: `key_light` is the unit world direction toward the key light,
/// `silhouette` the outline strength, `view_direction` the unit ray direction.
pub fn shade_studio(
    colour: [f64; 3],
    normal: DVec3,
    view_direction: DVec3,
    key_light: DVec3,
    silhouette: f64,
) -> [f64; 3] {
    let len = normal.length();
    if len < 1e-3 {
        return colour;
    }
    let mut n = normal / len;
    let ndv = n.dot(view_direction);
    if ndv > 0.0 {
        n = -n;
    }
    let facing = ndv.abs();
    let key = n.dot(key_light).max(0.0);
    let halfway = (key_light - view_direction).normalize_or_zero();
    let highlight = 0.2 * n.dot(halfway).max(0.0).powi(32);
    let rim = 1.0 - facing;
    let outline = 1.0 - silhouette * rim * rim;
    colour.map(|c| ((c * (0.3 + 0.3 * facing + 0.55 * key) + highlight) * outline).min(1.0))
}

/// The matcap model of one sample (`shade_matcap` in lighting.glsl): the colour times the matcap
/// at the normal turned to the viewer, in camera coordinates (`right`, `up` unit world vectors).
pub fn shade_matcap(
    colour: [f64; 3],
    normal: DVec3,
    view_direction: DVec3,
    right: DVec3,
    up: DVec3,
    matcap: &MatcapImage,
) -> [f64; 3] {
    if normal.length_squared() < 1e-6 {
        return colour;
    }
    let mut n = normal.normalize();
    if n.dot(view_direction) > 0.0 {
        n = -n;
    }
    let m = matcap.sample(n.dot(right), n.dot(up));
    std::array::from_fn(|i| (colour[i] * m[i]).min(1.0))
}

/// What the twin needs of the scene's lighting, resolved once.
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceLighting {
    /// The model of shaded samples (the headlight Phong of `formulas::shade`, studio, matcap).
    pub model: LightModel,
    /// The matcap of the matcap model (the engine's: `with_matcap`; the built-in `clay` until
    /// given).
    pub matcap: Option<Arc<MatcapImage>>,
    /// The camera's unit right and up vectors (world), the matcap's axes.
    pub camera_axes: [DVec3; 2],
    /// Depth cues at each ray's surface.
    pub depth_cues: bool,
    /// Unit world direction toward the key light.
    pub key_light: DVec3,
    /// The strengths and reaches as the shader reads them (f32 values, sanitized).
    pub cues: DepthCues,
}

impl ReferenceRaymarch<'_> {
    /// Lit by `matcap` (the image the engine was given by `Engine::set_matcap`) when the scene's
    /// model is the matcap.
    pub fn with_matcap(mut self, matcap: Arc<MatcapImage>) -> Self {
        if self.lighting.model == LightModel::Matcap {
            self.lighting.matcap = Some(matcap);
        }
        self
    }

    /// The cues' occluder density at index position `p`: f(v), 0 where nothing is kept.
    fn cue_density(&self, p: DVec3) -> f64 {
        if !self.clip.keeps(p, self.volume.dims) {
            return 0.0;
        }
        self.classify_at(p, self.value(p)).0
    }

    /// exp(-CUE_EXTINCTION sum f dl) along `step_index` (index space per mm) from `p`, the
    /// samples at (j + 0.5) dl.
    fn cue_transmittance(&self, p: DVec3, step_index: DVec3, reach_mm: f64, count: u32) -> f64 {
        let dl = reach_mm / f64::from(count);
        let sum: f64 = (0..count)
            .map(|j| self.cue_density(p + step_index * (dl * (f64::from(j) + 0.5))))
            .sum();
        (-CUE_EXTINCTION * sum * dl).exp()
    }

    /// The factor a ray's colour is multiplied by at its surface `p` (index space) with shading
    /// normal `normal` (world, any length; zero: the occlusion looks back along the ray), as
    /// `surface_cues` in lighting.glsl.
    pub(super) fn surface_cues(&self, p: DVec3, normal: DVec3, view_direction: DVec3) -> f64 {
        let light = &self.lighting;
        let to_index = glam::DMat3::from_mat4(self.geometry.world_to_index);
        // The shader's unit is the f32 uniform of `cue_unit_mm`.
        let unit = f64::from(crate::scene::lighting::cue_unit_mm(self.geometry.voxel_mm) as f32);
        let origin = p - to_index * view_direction * (CUE_BACKOFF * unit);
        let mut outward = -view_direction;
        if normal.length_squared() >= 1e-6 {
            let n = normal.normalize();
            let n_index = to_index * n * (CUE_SIDE_PROBE * unit);
            outward = if self.cue_density(p + n_index) <= self.cue_density(p - n_index) {
                n
            } else {
                -n
            };
        }
        let cues = light.cues;
        // Halfway between the open side and the viewer, as the shader.
        let halfway_open = outward - view_direction;
        let occlusion_direction = if halfway_open.length_squared() > 1e-6 {
            halfway_open.normalize()
        } else {
            -view_direction
        };
        let occlusion = self.cue_transmittance(
            origin,
            to_index * occlusion_direction,
            f64::from(cues.occlusion_reach_mm),
            OCCLUSION_SAMPLES,
        );
        let shadow = self.cue_transmittance(
            origin,
            to_index * light.key_light,
            f64::from(cues.shadow_reach_mm),
            SHADOW_SAMPLES,
        );
        let mix = |t: f64, strength: f32| 1.0 + (t - 1.0) * f64::from(strength);
        mix(occlusion, cues.occlusion) * mix(shadow, cues.shadow)
    }

    /// The scene's lighting model applied to one sample's colour.
    pub(super) fn lit(&self, colour: [f64; 3], normal: DVec3, view_direction: DVec3) -> [f64; 3] {
        let light = &self.lighting;
        match (light.model, &light.matcap) {
            (LightModel::Studio, _) => shade_studio(
                colour,
                normal,
                view_direction,
                light.key_light,
                f64::from(light.cues.silhouette),
            ),
            (LightModel::Matcap, Some(matcap)) => {
                let [right, up] = light.camera_axes;
                shade_matcap(colour, normal, view_direction, right, up, matcap)
            }
            _ => super::formulas::shade(colour, normal, view_direction),
        }
    }
}
