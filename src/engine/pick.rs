//! Depth picking (issue 31 item 2): where the picture shows something at one pixel of a view,
//! as a world point, so a click on the 3D view can move the crosshair there.
//!
//! Decisions:
//! - **The pixel's own ray on the GPU**, not a readback of the frame: the raymarch's PICK variant
//!   marches view pixel (x, y) of a `view`-sized picture exactly as the picture does (camera,
//!   jitter, step, classification, brain mask, clip and cut-away, long steps) in one invocation
//!   and writes one ray parameter; a 16-byte readback. The f64 twin is
//!   `ReferenceRaymarch::pick`.
//! - **What counts as visible**: DVR, the first sample at which the accumulated opacity reaches
//!   `threshold` ([`DEFAULT_PICK_THRESHOLD`] 0.5: half of the pixel's colour lies in front of
//!   the point, so the pick lands on the surface the eye sees, not on faint CSF in front of it);
//!   MIP/MinIP, the first sample holding the ray's extreme (the voxel the pixel shows).
//! - **One 1x1 RGBA32F target, kept** by the engine after the first pick (a click allocates
//!   nothing after the first).

use super::{Derived, Engine, PreparedVolume};
use crate::gpu::{GpuError, GpuResult};
use crate::scene::Scene;
use crate::scene::geometry::VolumeGeometry;
use crate::scene::uniforms::PixelPick;
use ash::vk;
use glam::DVec3;
use std::sync::Arc;

/// The accumulated opacity at which a DVR ray counts as having met what the pixel shows.
pub const DEFAULT_PICK_THRESHOLD: f32 = 0.5;

/// What a pick found at a pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PickHit {
    /// The point, world millimetres (the volume's RAS+ frame).
    pub world_mm: DVec3,
    /// Its distance along the pixel's ray from the ray's origin, mm.
    pub ray_mm: f64,
}

impl Engine {
    /// The intensity layers later picks see (those the picture's target draws; empty: none), so
    /// a click on a blob that shows finds it.
    pub fn set_pick_layers(
        &mut self,
        layers: Vec<(Arc<super::LayerVolume>, crate::scene::layer::LayerStyle)>,
    ) {
        self.pick_layers = layers;
    }

    /// Where `scene`, drawn `view[0]` x `view[1]` pixels, first shows something at `pixel`
    /// (module doc): None where the ray meets nothing visible. `threshold` in (0, 1] (DVR).
    pub fn pick(
        &mut self,
        prepared: &PreparedVolume,
        derived: Option<&Derived>,
        scene: &Scene,
        view: [u32; 2],
        pixel: [u32; 2],
        threshold: f32,
    ) -> GpuResult<Option<PickHit>> {
        if pixel[0] >= view[0] || pixel[1] >= view[1] {
            return Err(GpuError::InvalidRequest(format!(
                "pixel ({}, {}) lies outside the {}x{} view",
                pixel[0], pixel[1], view[0], view[1]
            )));
        }
        if threshold.is_nan() || threshold <= 0.0 || threshold > 1.0 {
            return Err(GpuError::InvalidRequest(format!(
                "a pick threshold is an opacity in (0, 1], not {threshold}"
            )));
        }
        let mut target = match self.pick_target.take() {
            Some(target) => target,
            None => self.render_target(1, 1, vk::Format::R32G32B32A32_SFLOAT)?,
        };
        target.pick = Some((PixelPick { pixel, threshold }, view));
        // What the picture shows is what the pick meets: its layers too.
        target.set_layers(self.pick_layers.clone())?;
        let frame = self.render(&mut target, prepared, derived, scene);
        self.pick_target = Some(target);
        let ray_mm = f64::from(frame?.values.first().copied().unwrap_or(-1.0));
        // -1 where the ray met nothing (NaN cannot come from the shader, and is not a hit).
        if ray_mm.is_nan() || ray_mm < 0.0 {
            return Ok(None);
        }
        let geometry = VolumeGeometry::new(prepared.dims, prepared.affine)
            .map_err(|e| GpuError::InvalidRequest(e.to_string()))?;
        let rays = scene.camera.rays(geometry.world_bounds(), view[0], view[1]);
        let (origin, direction) =
            rays.ray(f64::from(pixel[0]), f64::from(pixel[1]), view[0], view[1]);
        Ok(Some(PickHit {
            world_mm: origin + direction * ray_mm,
            ray_mm,
        }))
    }
}
