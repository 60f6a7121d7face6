//! The status bar: volume, device, per-pass GPU times as coloured segments, frame rate of
//! volume frames, the plan and notes; technical numbers live here, at the bottom, not in the
//! panels a clinician works in.

use super::status::Status;
use egui::{Color32, Pos2, Rect, RichText, Ui, vec2};

/// Colours of the per-pass bar segments, in order.
const PASS_COLOURS: [Color32; 5] = [
    Color32::from_rgb(230, 150, 60),
    Color32::from_rgb(90, 160, 230),
    Color32::from_rgb(120, 200, 120),
    Color32::from_rgb(200, 110, 200),
    Color32::from_rgb(200, 200, 90),
];

pub(super) fn status_bar(ui: &mut Ui, status: &Status) {
    ui.horizontal(|ui| {
        ui.label(RichText::new(status.volume_text()).small());
        if let Some(frame) = &status.frame {
            ui.label(RichText::new(frame.as_str()).small().strong());
        }
    });
    if let Some(identity) = &status.identity {
        ui.label(RichText::new(identity.as_str()).small());
    }
    if let Some(readout) = &status.readout {
        ui.label(RichText::new(readout.as_str()).small().monospace());
    }
    ui.horizontal(|ui| {
        ui.label(RichText::new(status.timing_text()).small());
        let shares = status.pass_shares();
        if !shares.is_empty() {
            let (rect, _) = ui.allocate_exact_size(vec2(120.0, 10.0), egui::Sense::hover());
            let mut x = rect.left();
            for (i, (_, _, share)) in shares.iter().enumerate() {
                let w = rect.width() * *share as f32;
                ui.painter().rect_filled(
                    Rect::from_min_size(Pos2::new(x, rect.top()), vec2(w, rect.height())),
                    0.0,
                    PASS_COLOURS[i % PASS_COLOURS.len()],
                );
                x += w;
            }
            for (i, (name, ms, _)) in shares.iter().enumerate() {
                ui.label(
                    RichText::new(format!("{name} {ms:.2}"))
                        .small()
                        .color(PASS_COLOURS[i % PASS_COLOURS.len()]),
                );
            }
        }
    });
    if let Some(loading) = &status.loading {
        ui.horizontal(|ui| {
            ui.spinner();
            ui.label(
                RichText::new(format!(
                    "Loading {}: {} ({:.1} s)",
                    loading.label,
                    loading.stage,
                    loading.since.elapsed().as_secs_f64()
                ))
                .small(),
            );
        });
    }
    if let Some(deriving) = &status.deriving {
        ui.horizontal(|ui| {
            ui.spinner();
            ui.label(RichText::new(deriving.as_str()).small());
        });
    }
    if let Some(plan) = &status.plan {
        // What the memory plan did (layout, degradations), as `render` says on stderr.
        let colour = if plan.contains("degraded") {
            Color32::from_rgb(255, 200, 90)
        } else {
            Color32::GRAY
        };
        ui.label(RichText::new(format!("Plan: {plan}")).small().color(colour));
    }
    if let Some(note) = &status.note {
        ui.label(
            RichText::new(note.as_str())
                .small()
                .color(Color32::LIGHT_GREEN),
        );
    }
    if let Some(error) = &status.error {
        ui.label(
            RichText::new(error.as_str())
                .small()
                .color(Color32::from_rgb(255, 110, 100)),
        );
    }
}
