//! The 3D view's own input and overlays: orbit, pan and zoom from egui's response on the view
//! (so egui decides who owns a drag: a slider drag never orbits the volume), a click (no drag)
//! asks for a depth pick (`Controls::pick`, run by viewer/pick.rs), keys only when no
//! text field has focus, and the orientation letters, the colour map's bar, the empty-view message,
//! load progress and errors drawn over the raymarched image.

use super::camera_control::{Button, DragKind, drag_kind, edge_labels, view_for_key};
use super::ui::{Controls, Shown, empty_view_message};
use egui::{Color32, Pos2, Rect, Ui, vec2};

pub(super) fn view_input(ui: &mut Ui, rect: Rect, controls: &mut Controls) {
    let response = ui.interact(rect, ui.id().with("3d view"), egui::Sense::click_and_drag());
    let shift = ui.input(|i| i.modifiers.shift);
    let pixels = ui.ctx().pixels_per_point();
    let view_px = [
        (rect.width() * pixels).round().max(1.0) as u32,
        (rect.height() * pixels).round().max(1.0) as u32,
    ];
    let buttons = [
        (egui::PointerButton::Primary, Button::Primary),
        (egui::PointerButton::Secondary, Button::Secondary),
        (egui::PointerButton::Middle, Button::Middle),
    ];
    controls.dragging = false;
    for (egui_button, button) in buttons {
        if response.dragged_by(egui_button) {
            controls.dragging = true;
            let d = response.drag_delta() * pixels;
            let delta = [d.x as f64, d.y as f64];
            match drag_kind(button, shift) {
                DragKind::Orbit => controls.camera.orbit(&mut controls.scene.camera, delta),
                DragKind::Pan => controls.camera.pan(
                    &mut controls.scene.camera,
                    delta,
                    view_px,
                    controls.extent_mm,
                ),
            }
        }
    }
    if response.double_clicked() {
        controls.camera.reset(&mut controls.scene.camera);
    } else if response.clicked_by(egui::PointerButton::Primary)
        && let Some(at) = response.interact_pointer_pos()
    {
        // A click without a drag: the crosshair goes where the picture shows something.
        let at = at - rect.min;
        controls.pick = Some([at.x / rect.width(), at.y / rect.height()]);
        // With Shift the picked point is a measurement point instead of the crosshair.
        controls.pick_measures = ui.input(|i| i.modifiers.shift);
    }
    if response.hovered() {
        let scroll = ui.input(|i| i.smooth_scroll_delta.y);
        if scroll != 0.0 {
            // egui-winit turns one wheel notch into 50 points of scroll.
            controls
                .camera
                .zoom(&mut controls.scene.camera, scroll as f64 / 50.0);
        }
    }
    if !ui.ctx().egui_wants_keyboard_input() {
        let keys: Vec<egui::Key> = ui.input(|i| {
            i.events
                .iter()
                .filter_map(|e| match e {
                    egui::Event::Key {
                        key,
                        pressed: true,
                        repeat: false,
                        modifiers,
                        ..
                    } if modifiers.is_none() || modifiers.shift_only() => Some(*key),
                    _ => None,
                })
                .collect()
        });
        for key in keys {
            let name = key.name();
            if name.len() == 1
                && let Some(view) = name.chars().next().and_then(view_for_key)
            {
                controls.view(view);
            }
            if key == egui::Key::Home {
                controls.camera.reset(&mut controls.scene.camera);
            }
        }
    }
}

/// Where each orientation letter is drawn, in points (for tests and the scripted log).
pub fn letter_positions(rect: Rect) -> [(Pos2, egui::Align2); 4] {
    let m = 6.0;
    [
        (
            Pos2::new(rect.left() + m, rect.center().y),
            egui::Align2::LEFT_CENTER,
        ),
        (
            Pos2::new(rect.right() - m, rect.center().y),
            egui::Align2::RIGHT_CENTER,
        ),
        (
            Pos2::new(rect.center().x, rect.top() + m),
            egui::Align2::CENTER_TOP,
        ),
        (
            Pos2::new(rect.center().x, rect.bottom() - m),
            egui::Align2::CENTER_BOTTOM,
        ),
    ]
}

pub(super) fn view_overlays(ui: &mut Ui, rect: Rect, controls: &Controls, shown: &Shown) {
    let painter = ui.painter_at(rect);
    if shown.has_volume
        && let Some(message) = empty_view_message(&controls.scene, shown.constant_volume)
    {
        // Wrapped to the view, centred: the reason is a sentence, longer than a narrow view.
        let colour = Color32::from_rgb(255, 220, 0);
        let galley = painter.layout(
            message,
            egui::FontId::proportional(15.0),
            colour,
            (rect.width() - 24.0).max(40.0),
        );
        painter.galley(rect.center() - galley.size() / 2.0, galley, colour);
    }
    if shown.has_volume {
        super::colour_bar::draw(&painter, rect, &controls.scene, controls.slices.units);
        let labels = edge_labels(&controls.scene.camera);
        let texts = [labels.left, labels.right, labels.top, labels.bottom];
        for ((pos, align), text) in letter_positions(rect).into_iter().zip(texts) {
            painter.text(
                pos,
                align,
                text,
                egui::FontId::proportional(18.0),
                Color32::from_rgb(255, 220, 0),
            );
        }
    } else if shown.status.loading.is_none() {
        painter.text(
            rect.center(),
            egui::Align2::CENTER_CENTER,
            "Open a NIfTI file (Open..., or drop it here)",
            egui::FontId::proportional(16.0),
            Color32::GRAY,
        );
    }
    if let Some(loading) = &shown.status.loading {
        let spinner = Rect::from_center_size(rect.center(), vec2(32.0, 32.0));
        ui.put(spinner, egui::Spinner::new().size(32.0));
        painter.text(
            rect.center() + vec2(0.0, 30.0),
            egui::Align2::CENTER_TOP,
            format!("Loading {}: {}", loading.label, loading.stage),
            egui::FontId::proportional(14.0),
            Color32::WHITE,
        );
    }
    if let Some(error) = &shown.status.error {
        painter.text(
            rect.left_top() + vec2(8.0, 28.0),
            egui::Align2::LEFT_TOP,
            error,
            egui::FontId::proportional(13.0),
            Color32::from_rgb(255, 110, 100),
        );
    }
}
