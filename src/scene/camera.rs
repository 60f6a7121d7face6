//! The orbit camera: azimuth, elevation, zoom and pan around the volume's world-space centre,
//! perspective or orthographic.
//!
//! Conventions (world = the NIfTI affine's RAS+ millimetres: +x right, +y anterior, +z superior):
//! - azimuth 0, elevation 0 is the anterior view: the camera sits in front of the face looking
//!   posterior, superior is up, so the patient's left appears on the image's right, as when
//!   facing a person; azimuth 90 puts the camera on the patient's right; elevation 90 looks down
//!   from superior. At exactly +-90 degrees the up vector is the limit of the orbit (no flip
//!   while dragging over the pole): posterior is up for azimuth 0, anterior for azimuth 180.
//! - zoom 1 fits a sphere whose diameter is the largest side of the volume's world bounding box
//!   (not its diagonal: scans pad the head with air, and the diagonal sphere left the brain at a
//!   third of the image); the fit does not depend on the view direction, so a turntable keeps
//!   its scale. Pan moves the look-at point in the image plane, in millimetres.

use glam::DVec3;

/// Perspective or orthographic projection.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Projection {
    /// Pinhole camera with this vertical field of view in degrees.
    Perspective {
        /// Vertical field of view, degrees.
        fov_y_deg: f64,
    },
    /// Parallel rays.
    Orthographic,
}

/// Where the camera is, relative to the volume.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Camera {
    /// Rotation about the superior axis, degrees (0 = anterior view, 90 = from the right).
    pub azimuth_deg: f64,
    /// Angle above the axial plane, degrees (90 = from superior).
    pub elevation_deg: f64,
    /// Magnification (1 fits the whole volume); clamped to [0.001, 1000].
    pub zoom: f64,
    /// Look-at offset in the image plane (right, up), millimetres.
    pub pan_mm: [f64; 2],
    /// Projection.
    pub projection: Projection,
}

impl Default for Camera {
    fn default() -> Self {
        Camera {
            azimuth_deg: 0.0,
            elevation_deg: 0.0,
            zoom: 1.0,
            pan_mm: [0.0, 0.0],
            projection: Projection::Perspective { fov_y_deg: 30.0 },
        }
    }
}

/// A camera resolved against a volume and an image size: everything a ray needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraRays {
    /// Eye position (perspective) or image-plane centre (orthographic), world mm.
    pub origin: DVec3,
    /// Unit vector to the image's right.
    pub right: DVec3,
    /// Unit vector to the image's top.
    pub up: DVec3,
    /// Unit viewing direction.
    pub forward: DVec3,
    /// Half extent of the image plane at unit distance (perspective: tan of the half angles) or
    /// in mm (orthographic), horizontally and vertically.
    pub half_extent: [f64; 2],
    /// True for orthographic projection.
    pub orthographic: bool,
}

impl CameraRays {
    /// Origin and unit direction of the ray through pixel (x, y) (pixel centres at +0.5, y down).
    pub fn ray(&self, x: f64, y: f64, width: u32, height: u32) -> (DVec3, DVec3) {
        let ndc_x = (x + 0.5) / width as f64 * 2.0 - 1.0;
        let ndc_y = 1.0 - (y + 0.5) / height as f64 * 2.0;
        let sx = ndc_x * self.half_extent[0];
        let sy = ndc_y * self.half_extent[1];
        if self.orthographic {
            (self.origin + self.right * sx + self.up * sy, self.forward)
        } else {
            (
                self.origin,
                (self.forward + self.right * sx + self.up * sy).normalize(),
            )
        }
    }
}

impl Camera {
    /// Resolves the camera for a volume whose world bounding box is `(min, max)` and an image of
    /// `width` x `height` pixels.
    pub fn rays(&self, bounds: (DVec3, DVec3), width: u32, height: u32) -> CameraRays {
        let (lo, hi) = bounds;
        let centre = (lo + hi) * 0.5;
        let radius = ((hi - lo).max_element() * 0.5).max(1e-6);
        // Limits keep the eye distance finite (zoom 1e-310 would overflow it).
        let zoom = if self.zoom.is_finite() && self.zoom > 0.0 {
            self.zoom.clamp(1e-3, 1e3)
        } else {
            1.0
        };
        let (el_sin, el_cos) = sin_cos_degrees(self.elevation_deg.clamp(-90.0, 90.0));
        let (az_sin, az_cos) = sin_cos_degrees(self.azimuth_deg);
        // Direction from the centre to the camera.
        let to_camera = DVec3::new(az_sin * el_cos, az_cos * el_cos, el_sin);
        let forward = -to_camera.normalize();
        // Superior is up, except when looking along the superior axis: then the up vector is the
        // limit of the orbit approaching the pole, so orbiting over it never flips the image.
        let world_up = if el_cos.abs() < 1e-6 {
            DVec3::new(az_sin, az_cos, 0.0) * -el_sin.signum()
        } else {
            DVec3::Z
        };
        let right = forward.cross(world_up).normalize();
        let up = right.cross(forward).normalize();
        let aspect = width.max(1) as f64 / height.max(1) as f64;
        let look_at = centre + right * self.pan_mm[0] + up * self.pan_mm[1];
        match self.projection {
            Projection::Perspective { fov_y_deg } => {
                let half = (fov_y_deg.clamp(1.0, 170.0).to_radians() * 0.5).tan();
                // Distance at which the bounding sphere fills the smaller image dimension.
                let fit = half.min(half * aspect);
                let distance = radius / (fit.atan().sin()) / zoom;
                CameraRays {
                    origin: look_at - forward * distance,
                    right,
                    up,
                    forward,
                    half_extent: [half * aspect, half],
                    orthographic: false,
                }
            }
            Projection::Orthographic => {
                let half_h = radius / zoom / aspect.min(1.0);
                CameraRays {
                    origin: look_at - forward * (radius * 4.0),
                    right,
                    up,
                    forward,
                    half_extent: [half_h * aspect, half_h],
                    orthographic: true,
                }
            }
        }
    }
}

/// `(sin, cos)` of an angle in degrees, exact (0, +-1) at multiples of 90 degrees, so views
/// meant to be axis-aligned have exactly zero components (`f64::to_radians` then `cos` gives
/// 6e-17 at 90 degrees, which puts rays meant to lie on a face slightly off it).
pub fn sin_cos_degrees(degrees: f64) -> (f64, f64) {
    if !degrees.is_finite() {
        // A non-finite angle (a typo'd argument) is the front view, never NaN rays.
        return (0.0, 1.0);
    }
    let turns = (degrees / 90.0).round();
    let rest = (degrees - turns * 90.0).to_radians();
    let (s, c) = rest.sin_cos();
    match (turns as i64).rem_euclid(4) {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_box() -> (DVec3, DVec3) {
        (DVec3::splat(-50.0), DVec3::splat(50.0))
    }

    #[test]
    fn anterior_view_puts_patient_left_on_image_right() {
        let rays = Camera::default().rays(unit_box(), 64, 64);
        assert!((rays.forward - DVec3::new(0.0, -1.0, 0.0)).length() < 1e-12);
        assert!((rays.up - DVec3::Z).length() < 1e-12);
        // RAS: patient's left is -x.
        assert!((rays.right - DVec3::new(-1.0, 0.0, 0.0)).length() < 1e-12);
    }

    #[test]
    fn views_from_the_right_and_from_superior() {
        let right = Camera {
            azimuth_deg: 90.0,
            ..Camera::default()
        }
        .rays(unit_box(), 64, 64);
        assert!((right.forward - DVec3::new(-1.0, 0.0, 0.0)).length() < 1e-12);
        let superior = Camera {
            elevation_deg: 90.0,
            ..Camera::default()
        }
        .rays(unit_box(), 64, 64);
        assert!((superior.forward - DVec3::new(0.0, 0.0, -1.0)).length() < 1e-12);
        assert!(
            (superior.up + DVec3::Y).length() < 1e-9,
            "orbit limit: posterior is up"
        );
        let near_pole = Camera {
            elevation_deg: 89.999,
            ..Camera::default()
        }
        .rays(unit_box(), 64, 64);
        assert!(
            (near_pole.up - superior.up).length() < 1e-3,
            "no flip at the pole"
        );
        let from_behind = Camera {
            azimuth_deg: 180.0,
            elevation_deg: 90.0,
            ..Camera::default()
        }
        .rays(unit_box(), 64, 64);
        assert!(
            (from_behind.up - DVec3::Y).length() < 1e-9,
            "anterior up with azimuth 180"
        );
        let inferior = Camera {
            elevation_deg: -90.0,
            ..Camera::default()
        }
        .rays(unit_box(), 64, 64);
        assert!((inferior.forward - DVec3::Z).length() < 1e-12);
        assert!(inferior.right.is_finite() && inferior.up.is_finite());
    }

    #[test]
    fn zoom_one_fits_the_sphere_of_the_largest_side() {
        let rays = Camera::default().rays(unit_box(), 64, 64);
        let radius = 50.0;
        let distance = rays.origin.length();
        // The sphere's silhouette half-angle equals the half field of view.
        assert!(((radius / distance).asin() - 15f64.to_radians()).abs() < 1e-9);
        // Every corner ray hits within the image.
        let (o, d) = rays.ray(-0.5, -0.5, 64, 64);
        assert!(o.is_finite() && (d.length() - 1.0).abs() < 1e-12);
    }
}
