//! Brain extraction's rows in the tissue panel (issue 27 item 3): the switch (Auto, On, Off),
//! a line saying what extraction decided, and the head layer's row (show, colour, opacity).
//!
//! Decisions:
//! - The switch is `Effects::brain`. Auto and On extract alike (`Effects::derivative_outputs`
//!   asks for the same mask), so moving between them only changes which outcomes mask
//!   (`BrainMask::use_for`): no recomputation. Off drops the mask and Off -> Auto computes it,
//!   both through the twin's rule like the vessel channel (the loader thread computes, the
//!   previous picture stays meanwhile).
//! - The head row is uniforms only (`Classification::head`); it draws only where a mask is in
//!   use, so it is greyed out while none is, with the reason on hover.
//! - The decision line is the engine's own words (`BrainDecision::describe`) with the brain's
//!   volume, so the panel, `morphray render` and `morphray derive` say the same thing. In MIP
//!   and MinIP the rows are greyed out: the mask classifies DVR samples only.

use crate::passes::brain::BrainSwitch;
use crate::reference::brain_report::{BrainDecision, BrainReport};
use crate::scene::{RenderMode, Scene};
use egui::{RichText, Ui};

/// What the viewer knows of the current volume's brain extraction.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BrainShown {
    /// The held extraction's report (None: no mask held for this volume).
    pub report: Option<BrainReport>,
    /// The mask is in use in the picture now (a head with Auto, any brain found with On).
    pub in_use: bool,
    /// An extraction is being computed.
    pub computing: bool,
}

/// The decision line for `shown` under `switch`.
pub fn decision_text(shown: &BrainShown, switch: BrainSwitch) -> String {
    if switch == BrainSwitch::Off {
        return "Off: every voxel is classified (a head scan shows its face)".into();
    }
    if shown.computing {
        return "Extracting the brain...".into();
    }
    let Some(report) = &shown.report else {
        return "Not extracted (DVR of a whole volume extracts it)".into();
    };
    let size = format!("{:.0} cm^3", report.brain_cm3);
    match (report.decision, shown.in_use) {
        (BrainDecision::NotFound | BrainDecision::NotAHeadScan, _) => {
            report.decision.describe().to_string()
        }
        (_, true) if report.decision == BrainDecision::Head => {
            format!("{} ({size})", report.decision.describe())
        }
        (_, true) => format!("Masked by On: {} ({size})", report.decision.describe()),
        (_, false) => format!(
            "{} ({size}); On masks it anyway",
            report.decision.describe()
        ),
    }
}

/// Draws the rows; true when something changed.
pub fn brain_rows(ui: &mut Ui, scene: &mut Scene, shown: &BrainShown) -> bool {
    let dvr = scene.effects.mode == RenderMode::Dvr;
    let mut changed = false;
    ui.add_enabled_ui(dvr, |ui| {
        ui.horizontal(|ui| {
            ui.label("Brain").on_hover_text(
                "Brain extraction: tissues are classified inside the brain only, the rest is \
                 the head layer",
            );
            let brain = &mut scene.effects.brain;
            for (value, name, hover) in [
                (
                    BrainSwitch::Auto,
                    "Auto",
                    "Mask a head scan; leave a skull-stripped one alone",
                ),
                (BrainSwitch::On, "On", "Mask whenever a brain is found"),
                (
                    BrainSwitch::Off,
                    "Off",
                    "Classify every voxel (frees the mask)",
                ),
            ] {
                changed |= ui
                    .selectable_value(brain, value, name)
                    .on_hover_text(hover)
                    .changed();
            }
        });
        ui.label(RichText::new(decision_text(shown, scene.effects.brain)).small());
        ui.add_enabled_ui(shown.in_use, |ui| {
            ui.horizontal(|ui| {
                let head = &mut scene.classification.head;
                changed |= ui
                    .checkbox(&mut head.visible, "Head")
                    .on_hover_text("Skin, fat, muscle and bone around the brain, translucent")
                    .on_disabled_hover_text("Drawn only around an extracted brain in use")
                    .changed();
                changed |= ui.color_edit_button_rgb(&mut head.colour).changed();
                changed |= ui
                    .add(egui::Slider::new(&mut head.opacity, 0.0..=1.0).show_value(false))
                    .on_hover_text("Opacity per millimetre of ray")
                    .changed();
            });
        });
    });
    changed
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::brain_params::BrainParams;

    fn report(decision: BrainDecision, cm3: f64) -> BrainReport {
        BrainReport {
            brain_cm3: cm3,
            decision,
            ..BrainReport::not_found(&BrainParams::default(), std::time::Duration::ZERO)
        }
    }

    #[test]
    fn the_decision_line_says_what_extraction_decided_and_whether_it_masks() {
        let head = BrainShown {
            report: Some(report(BrainDecision::Head, 1234.4)),
            in_use: true,
            computing: false,
        };
        let text = decision_text(&head, BrainSwitch::Auto);
        assert!(text.starts_with("head: the brain is extracted"), "{text}");
        assert!(text.ends_with("(1234 cm^3)"), "{text}");
        let stripped = BrainShown {
            report: Some(report(BrainDecision::SkullStripped, 1100.0)),
            in_use: false,
            computing: false,
        };
        let text = decision_text(&stripped, BrainSwitch::Auto);
        assert!(text.contains("already skull-stripped") && text.contains("On masks it"));
        let forced = BrainShown {
            in_use: true,
            ..stripped.clone()
        };
        assert!(decision_text(&forced, BrainSwitch::On).starts_with("Masked by On"));
        assert!(decision_text(&head, BrainSwitch::Off).starts_with("Off"));
        let computing = BrainShown {
            computing: true,
            ..Default::default()
        };
        assert_eq!(
            decision_text(&computing, BrainSwitch::Auto),
            "Extracting the brain..."
        );
        let none = BrainShown {
            report: Some(report(BrainDecision::NotFound, 0.0)),
            ..Default::default()
        };
        assert!(decision_text(&none, BrainSwitch::On).starts_with("no brain-like region"));
    }
}
