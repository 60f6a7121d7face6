//! Lighting, depth cues and the cut-away (issue 34 items 2 and 3): what a surface looks like.
//!
//! Decisions:
//! - **Three lighting models, a specialization constant** ([`LightModel`]): the headlight Phong of
//!   the paper's renderer (the interactive default: cheapest, and the accuracy study's reference
//!   look) and a studio model for stills: ambient, a headlight fill, a key light from the upper
//!   left fixed to the camera ([`key_light`]) with a Blinn highlight, and silhouette darkening
//!   (outlines where a surface is seen edge-on). The light follows the camera so a turntable
//!   keeps its look and the shadows fall the same way in every frame. The third is a matcap
//!   (`scene::matcap`): one lookup of the view-space normal in an image of a lit sphere, the
//!   look NiiVue and MRIcroGL users know, with any matcap PNG they have.
//! - **Depth cues once per ray, at the visible surface**: ambient occlusion along the normal and a
//!   soft shadow toward the key light, each integrating the classified opacity f(v) over a short
//!   ray ([`DepthCues`]), evaluated at the sample where the accumulated opacity first reaches 0.05
//!   and multiplying the ray's colour. Per sample they would cost 12 fetches for every
//!   classified sample; per ray they cost 14 per pixel (2 pick the normal's open side), and
//!   they are compiled out when off (free). Tuned by eye on MNI152 and the phantom (lavapipe,
//!   384 and 512 px): at 0.5 the surface point of a ray entering a gentle edge lay millimetres
//!   deep and the cues drew iso-depth rings, at 0.2 a few points still lay inside the tissue
//!   (black pixels on the phantom's gyral crowns); without the back-off and the open-side test
//!   the sulcal walls speckled black. An approximation of global illumination, not a model of it: a cue darkens, it never
//!   brightens, and what lies behind the surface in a translucent ray is darkened with it.
//! - **The cut-away is a clip plane through a point, turned 45 degrees from the view toward the
//!   image's right** ([`Cutaway`]): it removes the near left quarter, so the cut face and the
//!   intact surface are seen side by side. It is added to the scene's planes per frame (it
//!   turns with the camera, so a turntable keeps the brain open toward the viewer), and every
//!   cut face is drawn solid for [`CAP_MM`]: a flat
//!   tissue interior has no gradient, so eq. 4 would show it see-through; the cap gives the cut
//!   the tissue colours (cortex over white matter, ventricles) without shading.
//!
//! The GLSL is `shaders/include/lighting.glsl` and the capping in `raymarch.comp`; the f64 twins
//! are in `reference/raymarch/lighting.rs`.

use super::camera::CameraRays;
use super::clip::{Clip, ClipError, ClipPlane};
use glam::DVec3;

/// How deep behind a cut face (crop box face, clip plane, cut-away) samples are drawn solid, mm.
pub const CAP_MM: f64 = 1.0;

/// The lighting model of shaded DVR.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "snake_case")]
pub enum LightModel {
    /// Ambient + two-sided diffuse + highlight from a light at the eye (the paper's look).
    #[default]
    Headlight,
    /// Ambient, headlight fill, key light from the upper left with a highlight, outlines.
    Studio,
    /// The colour times a matcap image looked up by the view-space normal (`scene::matcap`; the
    /// image is the engine's, `Engine::set_matcap`).
    Matcap,
}

/// The lighting choices that select shader variants (part of `Effects`).
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
pub struct Lighting {
    /// The model of shaded samples (only with shading on).
    pub model: LightModel,
    /// Ambient occlusion and the key light's shadow at each ray's surface (DVR).
    pub depth_cues: bool,
}

impl Lighting {
    /// The stills' lighting: studio model with depth cues.
    pub const STILL: Lighting = Lighting {
        model: LightModel::Studio,
        depth_cues: true,
    };
}

/// The look of a still, stated once for every client (`render`, the viewer's first view,
/// Python's `render()` and thumbnail, batch thumbnails): shaded, studio lighting, depth cues.
/// The command line's `SceneArgs::as_still` fills unset options from it.
pub fn still_effects(mut effects: super::Effects) -> super::Effects {
    effects.shading = true;
    effects.lighting = Lighting::STILL;
    effects
}

/// Strengths and reaches of the studio outline and the depth cues (uniforms only).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DepthCues {
    /// Silhouette darkening at grazing angles, 0..1 (studio model).
    pub silhouette: f32,
    /// How much the occlusion darkens, 0..1.
    pub occlusion: f32,
    /// How much the key light's shadow darkens, 0..1.
    pub shadow: f32,
    /// Length of the occlusion ray along the normal, mm.
    pub occlusion_reach_mm: f32,
    /// Length of the shadow ray toward the key light, mm.
    pub shadow_reach_mm: f32,
}

impl Default for DepthCues {
    /// Outlines at half strength, occlusion 0.6 over 6 mm (a sulcus's width and depth on a 1 mm
    /// brain), shadow 0.4 over 16 mm (a gyrus shadows its neighbour, the brain does not shadow
    /// itself black).
    fn default() -> Self {
        DepthCues {
            silhouette: 0.5,
            occlusion: 0.6,
            shadow: 0.4,
            occlusion_reach_mm: 6.0,
            shadow_reach_mm: 16.0,
        }
    }
}

impl DepthCues {
    /// The values as the shader uses them: strengths in [0, 1], reaches in [0, 1000] mm, 0 where
    /// a value is not finite (the f64 twin reads the same).
    pub fn sanitized(&self) -> DepthCues {
        let unit = |x: f32| {
            if x.is_finite() {
                x.clamp(0.0, 1.0)
            } else {
                0.0
            }
        };
        let reach = |x: f32| {
            if x.is_finite() {
                x.clamp(0.0, 1000.0)
            } else {
                0.0
            }
        };
        DepthCues {
            silhouette: unit(self.silhouette),
            occlusion: unit(self.occlusion),
            shadow: unit(self.shadow),
            occlusion_reach_mm: reach(self.occlusion_reach_mm),
            shadow_reach_mm: reach(self.shadow_reach_mm),
        }
    }

    /// The uniform block's `cues`: occlusion and shadow strengths, then their reaches.
    pub fn uniform(&self) -> [f32; 4] {
        let c = self.sanitized();
        [
            c.occlusion,
            c.shadow,
            c.occlusion_reach_mm,
            c.shadow_reach_mm,
        ]
    }
}

/// The depth cues' unit length: max(1 mm, the finest voxel side `voxel_mm`), so the cue rays'
/// back-off and the normal's side probe step past a voxel's noise on a coarse grid too.
pub fn cue_unit_mm(voxel_mm: f64) -> f64 {
    if voxel_mm.is_finite() {
        voxel_mm.max(1.0)
    } else {
        1.0
    }
}

/// The unit world direction toward the key light: upper left of the image and toward the viewer,
/// fixed to the camera.
pub fn key_light(rays: &CameraRays) -> DVec3 {
    let toward = -0.45 * rays.right + 0.6 * rays.up - 0.66 * rays.forward;
    toward.try_normalize().unwrap_or(-rays.forward)
}

/// The "open the brain" view: a clip plane through `point_mm` (None: the centre of the volume's
/// world box) facing the camera, keeping the far side.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Cutaway {
    /// World point the plane passes through, mm.
    pub point_mm: Option<[f64; 3]>,
}

impl Cutaway {
    /// The plane for the camera `rays` on a volume whose world box is `bounds`: its normal is
    /// halfway between the view direction and the image's right, so the cut removes the near
    /// left quarter of the volume and shows its face at 45 degrees beside the intact surface on
    /// the right (a plane facing the camera would show a flat slice and hide the surface).
    pub fn plane(&self, rays: &CameraRays, bounds: (DVec3, DVec3)) -> ClipPlane {
        let point = self
            .point_mm
            .map(DVec3::from_array)
            .filter(|p| p.is_finite())
            .unwrap_or((bounds.0 + bounds.1) * 0.5);
        let normal = (rays.forward + rays.right)
            .try_normalize()
            .unwrap_or(rays.forward);
        ClipPlane {
            normal: normal.to_array(),
            offset_mm: -normal.dot(point),
        }
    }

    /// `clip` with the cut-away's plane added; fails when all its plane slots are taken.
    pub fn add_to(
        &self,
        clip: &Clip,
        rays: &CameraRays,
        bounds: (DVec3, DVec3),
    ) -> Result<Clip, ClipError> {
        let mut with_cut = *clip;
        with_cut.add_plane(self.plane(rays, bounds))?;
        Ok(with_cut)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Looking along +y with +x to the image's right and +z up.
    fn rays() -> CameraRays {
        CameraRays {
            origin: DVec3::ZERO,
            right: DVec3::X,
            up: DVec3::Z,
            forward: DVec3::Y,
            half_extent: [1.0, 1.0],
            orthographic: false,
        }
    }

    #[test]
    fn the_key_light_is_a_unit_vector_toward_the_viewer_and_up() {
        let rays = rays();
        let l = key_light(&rays);
        assert!((l.length() - 1.0).abs() < 1e-12);
        assert!(l.dot(rays.forward) < 0.0, "toward the viewer");
        assert!(
            l.dot(rays.up) > 0.0 && l.dot(rays.right) < 0.0,
            "upper left"
        );
    }

    #[test]
    fn the_cutaway_removes_the_near_left_quarter_around_its_point() {
        let cut = Cutaway {
            point_mm: Some([1.0, 2.0, 3.0]),
        };
        let plane = cut.plane(&rays(), (DVec3::splat(-10.0), DVec3::splat(10.0)));
        let keeps = |p: DVec3| DVec3::from_array(plane.normal).dot(p) + plane.offset_mm >= 0.0;
        assert!(keeps(DVec3::new(1.0, 5.0, 3.0)), "beyond the point");
        assert!(
            keeps(DVec3::new(6.0, 0.0, 3.0)),
            "near but right of the point"
        );
        assert!(
            !keeps(DVec3::new(-4.0, 0.0, 3.0)),
            "near and left of the point"
        );
        assert!(keeps(DVec3::new(1.0, 2.0, 3.0)), "the point itself");
        let centred = Cutaway::default().plane(&rays(), (DVec3::ZERO, DVec3::splat(4.0)));
        let n = DVec3::from_array(centred.normal);
        assert!((n.dot(DVec3::splat(2.0)) + centred.offset_mm).abs() < 1e-12);
    }

    #[test]
    fn a_cutaway_needs_a_free_plane_slot() {
        let mut full = Clip::default();
        for _ in 0..crate::scene::clip::MAX_CLIP_PLANES {
            full.add_plane(ClipPlane {
                normal: [1.0, 0.0, 0.0],
                offset_mm: 0.0,
            })
            .unwrap();
        }
        let bounds = (DVec3::ZERO, DVec3::ONE);
        assert!(Cutaway::default().add_to(&full, &rays(), bounds).is_err());
        assert!(
            Cutaway::default()
                .add_to(&Clip::default(), &rays(), bounds)
                .is_ok()
        );
    }
}
