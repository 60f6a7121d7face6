//! Mouse and keyboard to camera: orbit, pan, zoom, the six standard views, and the orientation
//! letters drawn at the image edges.
//!
//! Decisions:
//! - Pure functions on [`Camera`], no egui or GPU types in the maths, so every mapping is unit
//!   tested; `ui.rs` only decides which function an input event calls ([`drag_kind`],
//!   [`view_for_key`]).
//! - Dragging "grabs" the volume: moving the mouse right turns the face towards the image's
//!   right (the camera orbits towards the patient's right, azimuth grows); moving it down shows
//!   the top of the head (elevation grows). Panning moves the picture with the mouse.
//! - Orientation letters come from the camera's own ray basis ([`Camera::rays`]), the same
//!   vectors the raymarch uses, never from a second derivation of the view: a left-right
//!   swap in the letters would need a swap in the picture too. World is RAS+ (+x = patient's
//!   right, +y = anterior, +z = superior), so the letter of a screen direction is the patient
//!   direction it points to (R/L, A/P, S/I); oblique directions get two letters, strongest first.

use crate::scene::Camera;
use glam::DVec3;

pub use crate::scene::views::StandardView;

/// What a mouse drag does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DragKind {
    /// Rotate around the volume.
    Orbit,
    /// Move the picture in the image plane.
    Pan,
}

/// Mouse buttons, independent of the windowing library.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Button {
    /// Left button.
    Primary,
    /// Right button.
    Secondary,
    /// Wheel button.
    Middle,
}

/// Left-drag orbits; right-drag, middle-drag and shift + left-drag pan.
pub fn drag_kind(button: Button, shift: bool) -> DragKind {
    match (button, shift) {
        (Button::Primary, false) => DragKind::Orbit,
        _ => DragKind::Pan,
    }
}

/// The standard view a key selects (its letter, case-insensitive), if any.
pub fn view_for_key(letter: char) -> Option<StandardView> {
    let upper = letter.to_ascii_uppercase();
    StandardView::ALL.into_iter().find(|v| v.letter() == upper)
}

/// Sensitivities of the mouse mappings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraController {
    /// Orbit degrees per pixel of drag.
    pub degrees_per_pixel: f64,
    /// Zoom factor per wheel step (one notch).
    pub zoom_per_step: f64,
}

impl Default for CameraController {
    fn default() -> Self {
        CameraController {
            degrees_per_pixel: 0.4,
            zoom_per_step: 1.1,
        }
    }
}

/// Smallest and largest zoom the mouse reaches (the camera clamps wider still).
pub const ZOOM_RANGE: (f64, f64) = (0.1, 50.0);

impl CameraController {
    /// Orbits by a drag of `delta` pixels (x right, y down).
    pub fn orbit(&self, camera: &mut Camera, delta: [f64; 2]) {
        camera.azimuth_deg = wrap_degrees(camera.azimuth_deg + delta[0] * self.degrees_per_pixel);
        camera.elevation_deg =
            (camera.elevation_deg + delta[1] * self.degrees_per_pixel).clamp(-90.0, 90.0);
    }

    /// Pans by a drag of `delta` pixels in a view of `view_px` pixels showing a volume whose
    /// largest side is `extent_mm` (zoom 1 fits that side in the smaller view dimension, so one
    /// pixel is `extent_mm / (zoom * min(w, h))` millimetres at the volume's centre).
    pub fn pan(&self, camera: &mut Camera, delta: [f64; 2], view_px: [u32; 2], extent_mm: f64) {
        let side = view_px[0].min(view_px[1]).max(1) as f64;
        let zoom = camera.zoom.clamp(ZOOM_RANGE.0, ZOOM_RANGE.1);
        let mm_per_px = extent_mm / (zoom * side);
        // The picture follows the mouse: the look-at point moves the other way.
        camera.pan_mm[0] -= delta[0] * mm_per_px;
        camera.pan_mm[1] += delta[1] * mm_per_px;
    }

    /// Zooms by `steps` wheel notches (positive = closer).
    pub fn zoom(&self, camera: &mut Camera, steps: f64) {
        camera.zoom =
            (camera.zoom * self.zoom_per_step.powf(steps)).clamp(ZOOM_RANGE.0, ZOOM_RANGE.1);
    }

    /// Back to the anterior view at zoom 1 without pan (double-click).
    pub fn reset(&self, camera: &mut Camera) {
        *camera = Camera {
            projection: camera.projection,
            ..Camera::default()
        };
    }

    /// Looks from one of the six standard directions, keeping zoom and dropping pan.
    pub fn set_view(&self, camera: &mut Camera, view: StandardView) {
        let (azimuth, elevation) = view.angles();
        camera.azimuth_deg = azimuth;
        camera.elevation_deg = elevation;
        camera.pan_mm = [0.0, 0.0];
    }
}

/// An angle in (-180, 180].
fn wrap_degrees(degrees: f64) -> f64 {
    if !degrees.is_finite() {
        return 0.0;
    }
    let wrapped = (degrees + 180.0).rem_euclid(360.0) - 180.0;
    if wrapped == -180.0 { 180.0 } else { wrapped }
}

/// The orientation letters at the four edges of the image.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EdgeLabels {
    /// At the middle of the left edge.
    pub left: String,
    /// At the middle of the right edge.
    pub right: String,
    /// At the middle of the top edge.
    pub top: String,
    /// At the middle of the bottom edge.
    pub bottom: String,
}

/// The letters for `camera` (computed from its ray basis; independent of the volume).
pub fn edge_labels(camera: &Camera) -> EdgeLabels {
    let bounds = (DVec3::splat(-1.0), DVec3::splat(1.0));
    let rays = camera.rays(bounds, 1, 1);
    EdgeLabels {
        left: direction_label(-rays.right),
        right: direction_label(rays.right),
        top: direction_label(rays.up),
        bottom: direction_label(-rays.up),
    }
}

/// The patient direction(s) a world (RAS+) direction points to: the dominant axis's letter,
/// then the second axis's when it is more than tan(22.5 deg) of the first (an oblique view).
pub fn direction_label(v: DVec3) -> String {
    let letters = [('R', 'L'), ('A', 'P'), ('S', 'I')];
    let mut axes: Vec<(f64, char)> = (0..3)
        .map(|i| {
            let (pos, neg) = letters[i];
            (v[i].abs(), if v[i] >= 0.0 { pos } else { neg })
        })
        .collect();
    axes.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut label = axes[0].1.to_string();
    if axes[1].0 > axes[0].0 * 22.5f64.to_radians().tan() {
        label.push(axes[1].1);
    }
    label
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels_of(view: StandardView) -> [String; 4] {
        let mut camera = Camera::default();
        CameraController::default().set_view(&mut camera, view);
        let l = edge_labels(&camera);
        [l.left, l.right, l.top, l.bottom]
    }

    #[test]
    fn orientation_letters_for_the_six_views() {
        // [left edge, right edge, top, bottom]. Anterior: facing the patient, so the patient's
        // left is on the image's right (the radiological convention every viewer must keep).
        assert_eq!(labels_of(StandardView::Anterior), ["R", "L", "S", "I"]);
        // From behind, left and right are as the patient sees them.
        assert_eq!(labels_of(StandardView::Posterior), ["L", "R", "S", "I"]);
        // From the patient's left side the face points to the image's left.
        assert_eq!(labels_of(StandardView::Left), ["A", "P", "S", "I"]);
        assert_eq!(labels_of(StandardView::Right), ["P", "A", "S", "I"]);
        // From above with anterior up (as radiologists expect, issue 16): the patient's right
        // is on the image's right, as when looking down at the top of a head facing away.
        assert_eq!(labels_of(StandardView::Superior), ["L", "R", "A", "P"]);
        // From below: anterior up, and the patient's left stays on the image's right.
        assert_eq!(labels_of(StandardView::Inferior), ["R", "L", "A", "P"]);
    }

    #[test]
    fn oblique_views_get_two_letters_strongest_first() {
        let camera = Camera {
            azimuth_deg: 40.0,
            ..Camera::default()
        };
        let l = edge_labels(&camera);
        // Camera between anterior and right: the image's right points to the patient's left
        // and (less) anterior.
        assert_eq!(l.right, "LA");
        assert_eq!(l.left, "RP");
        assert_eq!(direction_label(DVec3::new(0.0, 0.0, 1.0)), "S");
        assert_eq!(direction_label(DVec3::new(0.1, 0.0, -1.0)), "I");
    }

    #[test]
    fn drags_map_to_azimuth_elevation_and_pan() {
        let c = CameraController::default();
        let mut camera = Camera::default();
        c.orbit(&mut camera, [100.0, 0.0]);
        assert!(
            (camera.azimuth_deg - 40.0).abs() < 1e-12,
            "right drag: azimuth grows"
        );
        c.orbit(&mut camera, [0.0, 50.0]);
        assert!(
            (camera.elevation_deg - 20.0).abs() < 1e-12,
            "down drag: look from above"
        );
        c.orbit(&mut camera, [0.0, 10_000.0]);
        assert_eq!(camera.elevation_deg, 90.0, "elevation clamps at the pole");
        c.orbit(&mut camera, [400.0, 0.0]);
        assert!(
            (camera.azimuth_deg - 200.0 + 360.0).abs() < 1e-9,
            "azimuth wraps"
        );

        let mut camera = Camera::default();
        // 200 mm in a 400-pixel view at zoom 1: half a millimetre per pixel.
        c.pan(&mut camera, [10.0, 0.0], [400, 600], 200.0);
        assert!(
            (camera.pan_mm[0] + 5.0).abs() < 1e-12,
            "picture follows the mouse"
        );
        c.pan(&mut camera, [0.0, 10.0], [400, 600], 200.0);
        assert!((camera.pan_mm[1] - 5.0).abs() < 1e-12);
        camera.zoom = 2.0;
        c.pan(&mut camera, [10.0, 0.0], [400, 600], 200.0);
        assert!(
            (camera.pan_mm[0] + 7.5).abs() < 1e-12,
            "zoomed in, pixels are smaller"
        );
    }

    #[test]
    fn wheel_zooms_within_limits_and_double_click_resets() {
        let c = CameraController::default();
        let mut camera = Camera::default();
        c.zoom(&mut camera, 2.0);
        assert!((camera.zoom - 1.21).abs() < 1e-12);
        c.zoom(&mut camera, -200.0);
        assert_eq!(camera.zoom, ZOOM_RANGE.0);
        camera.azimuth_deg = 33.0;
        camera.pan_mm = [4.0, 5.0];
        c.reset(&mut camera);
        assert_eq!(camera, Camera::default());
    }

    #[test]
    fn buttons_and_keys_select_actions() {
        assert_eq!(drag_kind(Button::Primary, false), DragKind::Orbit);
        assert_eq!(drag_kind(Button::Primary, true), DragKind::Pan);
        assert_eq!(drag_kind(Button::Secondary, false), DragKind::Pan);
        assert_eq!(drag_kind(Button::Middle, false), DragKind::Pan);
        for view in StandardView::ALL {
            assert_eq!(view_for_key(view.letter()), Some(view));
            assert_eq!(view_for_key(view.letter().to_ascii_lowercase()), Some(view));
            assert_eq!(StandardView::parse(view.name()), Some(view));
        }
        assert_eq!(view_for_key('x'), None);
        assert_eq!(StandardView::parse("s"), Some(StandardView::Superior));
    }
}
