//! The vessel channel's row in the tissue panel (issue 15 item 3): a switch, its colour and
//! opacity like a tissue's, and its own band, a window on the vesselness (0..1) rather than on
//! the I_norm histogram, as two sliders.
//!
//! Decisions: the switch is `Effects::vessels`, not a uniform: turning it on computes the
//! multi-scale vesselness (the viewer's derived-volume update runs it on the loader thread, the
//! previous picture stays meanwhile) and selects the raymarch variant that reads it; turning it
//! off frees it. The window, colour and opacity are uniforms and cost nothing to change. In
//! MIP/MinIP the row is greyed out: the channel classifies DVR samples only.

use crate::scene::{RenderMode, Scene};
use egui::{RichText, Ui};

/// Draws the row; true when something changed.
pub fn vessel_row(ui: &mut Ui, scene: &mut Scene) -> bool {
    let dvr = scene.effects.mode == RenderMode::Dvr;
    let mut changed = false;
    ui.add_enabled_ui(dvr, |ui| {
        ui.horizontal(|ui| {
            changed |= ui
                .checkbox(&mut scene.effects.vessels, "Vessels")
                .on_hover_text(
                    "The vessel channel: classified on the multi-scale vesselness (Frangi, \
                     0.6-3 mm), computed when switched on; with the tissues hidden it unmasks \
                     the vessels",
                )
                .changed();
            let style = &mut scene.classification.vessels;
            changed |= ui.color_edit_button_rgb(&mut style.colour).changed();
            changed |= ui
                .add(egui::Slider::new(&mut style.opacity, 0.0..=1.0).show_value(false))
                .on_hover_text("Opacity per millimetre of ray")
                .changed();
        });
        let window = &mut scene.classification.vessels.window;
        let mut lo = window.lo;
        let mut hi = window.hi.min(1.0);
        ui.horizontal(|ui| {
            ui.label(RichText::new("vesselness").small());
            changed |= ui
                .add(egui::Slider::new(&mut lo, 0.0..=1.0).text("from"))
                .changed();
        });
        ui.horizontal(|ui| {
            ui.label(RichText::new("vesselness").small());
            changed |= ui
                .add(egui::Slider::new(&mut hi, 0.0..=1.0).text("to"))
                .changed();
        });
        if changed {
            window.lo = lo.min(hi);
            // The top at 1 keeps the strongest tubes (the default reaches beyond 1 for that).
            window.hi = if hi >= 1.0 {
                window.hi.max(1.0)
            } else {
                hi.max(lo)
            };
        }
    });
    changed
}
