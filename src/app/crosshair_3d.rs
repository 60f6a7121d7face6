//! Over the 3D view, for the slices: the layout buttons (top left, clear of the centred
//! orientation letters) and the slices' crosshair marked where the camera sees that world point.
//!
//! Decision: the marker is the world point projected through the same camera the raymarch
//! uses (`Camera::rays`, inverted), drawn over the image; it is not depth-tested (the crosshair
//! is usually inside the head, where no surface would show it).

use super::slices_panel::{Layout, SliceControls};
use crate::scene::camera::Camera;
use crate::scene::slice::Plane;
use egui::{Color32, Pos2, Rect, Ui, vec2};
use glam::DVec3;

/// Over the 3D view: the layout buttons, and the crosshair when slices are shown.
pub fn decorate_view(
    ui: &mut Ui,
    view: Rect,
    controls: &mut super::ui::Controls,
    has_volume: bool,
) {
    if !has_volume {
        return;
    }
    layout_buttons(ui, view, &mut controls.slices);
    mark_in_3d(ui, view, &controls.slices, &controls.scene.camera);
    if let Some(geometry) = &controls.slices.geometry {
        let (camera, bounds) = (&controls.scene.camera, geometry.world_bounds());
        super::measure_panel::draw_marks(
            &ui.painter_at(view),
            &controls.slices.measures,
            |w| project(camera, bounds, view, w).map(|(x, y)| Pos2::new(x, y)),
            |_| true,
        );
    }
}

/// The layout buttons, floating at the top right of the 3D view.
pub fn layout_buttons(ui: &mut Ui, view: Rect, slices: &mut SliceControls) {
    let ctx = ui.ctx().clone();
    egui::Area::new(egui::Id::new("morphray layouts"))
        .fixed_pos(Pos2::new(view.left() + 4.0, view.top() + 4.0))
        .show(&ctx, |ui| {
            // A column at the top left: clear of the centred top and bottom letters.
            ui.vertical(|ui| {
                for layout in [
                    Layout::ThreeD,
                    Layout::ThreeDAndSlices,
                    Layout::One(Plane::Axial),
                    Layout::One(Plane::Coronal),
                    Layout::One(Plane::Sagittal),
                ] {
                    ui.selectable_value(&mut slices.layout, layout, layout.name());
                }
            });
        });
}

/// The crosshair marked in the 3D view: the world point projected through the camera.
pub fn mark_in_3d(ui: &Ui, view: Rect, slices: &SliceControls, camera: &Camera) {
    let (Some(geometry), Some(cross)) = (&slices.geometry, slices.crosshair) else {
        return;
    };
    if slices.layout == Layout::ThreeD || view.width() < 2.0 || view.height() < 2.0 {
        return;
    }
    let Some((x, y)) = project(camera, geometry.world_bounds(), view, cross) else {
        return;
    };
    let p = Pos2::new(x, y);
    let stroke = egui::Stroke::new(1.5, Color32::from_rgb(0, 200, 255));
    let painter = ui.painter_at(view);
    painter.line_segment([p - vec2(8.0, 0.0), p + vec2(8.0, 0.0)], stroke);
    painter.line_segment([p - vec2(0.0, 8.0), p + vec2(0.0, 8.0)], stroke);
}

/// Screen position (points) of world point `p` in the 3D view `view`, None behind the eye.
pub fn project(
    camera: &Camera,
    bounds: (DVec3, DVec3),
    view: Rect,
    p: DVec3,
) -> Option<(f32, f32)> {
    let w = view.width().round().max(1.0) as u32;
    let h = view.height().round().max(1.0) as u32;
    let rays = camera.rays(bounds, w, h);
    let d = p - rays.origin;
    let (sx, sy) = if rays.orthographic {
        (d.dot(rays.right), d.dot(rays.up))
    } else {
        let z = d.dot(rays.forward);
        if z <= 1e-9 {
            return None;
        }
        (d.dot(rays.right) / z, d.dot(rays.up) / z)
    };
    let ndc_x = sx / rays.half_extent[0];
    let ndc_y = sy / rays.half_extent[1];
    let x = view.left() + ((ndc_x + 1.0) / 2.0) as f32 * view.width();
    let y = view.top() + ((1.0 - ndc_y) / 2.0) as f32 * view.height();
    Some((x, y))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_projection_puts_the_volume_centre_at_the_view_centre() {
        let camera = Camera::default();
        let bounds = (DVec3::splat(-10.0), DVec3::splat(10.0));
        let view = Rect::from_min_size(Pos2::new(100.0, 50.0), vec2(200.0, 100.0));
        let (x, y) = project(&camera, bounds, view, DVec3::ZERO).unwrap();
        assert!(
            (x - 200.0).abs() < 0.5 && (y - 100.0).abs() < 0.5,
            "{x}, {y}"
        );
        // A ray through a pixel projects back onto that pixel.
        let rays = camera.rays(bounds, 200, 100);
        let (o, d) = rays.ray(30.0, 70.0, 200, 100);
        let (x, y) = project(&camera, bounds, view, o + d * 40.0).unwrap();
        assert!(
            (x - 130.5).abs() < 1e-3 && (y - 120.5).abs() < 1e-3,
            "{x}, {y}"
        );
    }
}
