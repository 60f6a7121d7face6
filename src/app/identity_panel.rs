//! What the volume on screen is taken to be, changed from the viewer (issue 28, item 5): the
//! modality, the contrast and the preset, each `auto` (what the file says, as the command line
//! decides it) or given, as `--modality`, `--contrast` and `--preset` give them.
//!
//! Decisions:
//! - Three combo boxes under the tissue table; `auto` shows what was decided for this volume
//!   (`auto (T2)`), so the menu also reads as the answer.
//! - A change opens the volume on screen again with the choice, through the same loader and
//!   engine path as the command line's flags (`Loader::set_identity`, the recipe's preset):
//!   no second copy of the analysis or the preset rule. The choice stays for the files opened
//!   after it, as a flag would.
//! - Script steps `modality NAME`, `contrast NAME` and `preset NAME` (each also `auto`) parse
//!   here, so the names have one list.

use crate::analysis::{ContrastChoice, Modality, ModalityChoice, TissueReport};
use crate::scene::Preset;
use egui::{RichText, Ui};

/// The viewer's modality, contrast and preset choices.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct IdentityChoice {
    /// `--modality`.
    pub modality: ModalityChoice,
    /// `--contrast`.
    pub contrast: ContrastChoice,
    /// `--preset` (None: by modality).
    pub preset: Option<Preset>,
}

/// The modalities the menu offers.
const MODALITIES: [Modality; 4] = [Modality::Mr, Modality::Ct, Modality::Pt, Modality::Other];

/// The contrasts the menu offers.
const CONTRASTS: [ContrastChoice; 4] = [
    ContrastChoice::T1,
    ContrastChoice::T2,
    ContrastChoice::Pd,
    ContrastChoice::Flair,
];

/// One script step's change (module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IdentityStep {
    /// `modality auto|mr|ct|pt|other`.
    Modality(ModalityChoice),
    /// `contrast auto|t1|t2|pd|flair`.
    Contrast(ContrastChoice),
    /// `preset auto|NAME`.
    Preset(Option<Preset>),
}

impl IdentityChoice {
    /// This choice with `step` applied.
    pub fn with(self, step: IdentityStep) -> IdentityChoice {
        match step {
            IdentityStep::Modality(modality) => IdentityChoice { modality, ..self },
            IdentityStep::Contrast(contrast) => IdentityChoice { contrast, ..self },
            IdentityStep::Preset(preset) => IdentityChoice { preset, ..self },
        }
    }
}

fn contrast_name(c: ContrastChoice) -> &'static str {
    match c {
        ContrastChoice::Auto => "auto",
        ContrastChoice::T1 => "T1",
        ContrastChoice::T2 => "T2",
        ContrastChoice::Pd => "PD",
        ContrastChoice::Flair => "FLAIR",
    }
}

/// Parses a script step's word and argument (`contrast t2`); None when `word` is not one of
/// these steps.
pub fn parse_step(word: &str, arg: Option<&str>) -> Option<Result<IdentityStep, String>> {
    let arg = arg.map(str::to_ascii_lowercase);
    let arg = arg.as_deref();
    let step = match word {
        "modality" => match arg {
            Some("auto") => Ok(IdentityStep::Modality(ModalityChoice::Auto)),
            Some(name) => MODALITIES
                .into_iter()
                .find(|m| m.name().eq_ignore_ascii_case(name))
                .map(|m| IdentityStep::Modality(ModalityChoice::Given(m)))
                .ok_or_else(|| format!("unknown modality `{name}`; use auto, mr, ct, pt or other")),
            None => Err("expected a modality: auto, mr, ct, pt or other".into()),
        },
        "contrast" => match arg {
            Some("auto") => Ok(IdentityStep::Contrast(ContrastChoice::Auto)),
            Some(name) => CONTRASTS
                .into_iter()
                .find(|c| contrast_name(*c).eq_ignore_ascii_case(name))
                .map(IdentityStep::Contrast)
                .ok_or_else(|| format!("unknown contrast `{name}`; use auto, t1, t2, pd or flair")),
            None => Err("expected a contrast: auto, t1, t2, pd or flair".into()),
        },
        "preset" => match arg {
            Some("auto") => Ok(IdentityStep::Preset(None)),
            Some(name) => Preset::parse(name)
                .map(|p| IdentityStep::Preset(Some(p)))
                .ok_or_else(|| format!("unknown preset `{name}`; use auto, {}", Preset::names())),
            None => Err(format!("expected a preset: auto, {}", Preset::names())),
        },
        _ => return None,
    };
    Some(step)
}

/// The three menus (module doc); true when the choice changed.
pub fn identity_rows(
    ui: &mut Ui,
    choice: &mut IdentityChoice,
    report: Option<&TissueReport>,
) -> bool {
    let before = *choice;
    let decided_modality = report.map_or("-", |r| r.modality.modality.name());
    let decided_contrast = report.map_or("-".to_string(), |r| r.contrast.label());
    let decided_preset = report.map_or("-", |r| Preset::auto(r).name());
    egui::Grid::new("identity").num_columns(2).show(ui, |ui| {
        ui.label(RichText::new("Modality").small())
            .on_hover_text("What the scan is (--modality); auto: from its metadata, then values");
        let shown = match choice.modality {
            ModalityChoice::Auto => format!("auto ({decided_modality})"),
            ModalityChoice::Given(m) => m.name().to_string(),
        };
        egui::ComboBox::from_id_salt("modality")
            .selected_text(shown)
            .show_ui(ui, |ui| {
                ui.selectable_value(&mut choice.modality, ModalityChoice::Auto, "auto");
                for m in MODALITIES {
                    ui.selectable_value(&mut choice.modality, ModalityChoice::Given(m), m.name());
                }
            });
        ui.end_row();
        ui.label(RichText::new("Contrast").small())
            .on_hover_text("Which tissue order the classes follow (--contrast)");
        let shown = match choice.contrast {
            ContrastChoice::Auto => format!("auto ({decided_contrast})"),
            given => contrast_name(given).to_string(),
        };
        egui::ComboBox::from_id_salt("contrast")
            .selected_text(shown)
            .show_ui(ui, |ui| {
                ui.selectable_value(&mut choice.contrast, ContrastChoice::Auto, "auto");
                for c in CONTRASTS {
                    ui.selectable_value(&mut choice.contrast, c, contrast_name(c));
                }
            });
        ui.end_row();
        ui.label(RichText::new("Preset").small())
            .on_hover_text("The look by modality (--preset); auto: chosen from the modality");
        let shown = match choice.preset {
            None => format!("auto ({decided_preset})"),
            Some(p) => p.name().to_string(),
        };
        egui::ComboBox::from_id_salt("preset")
            .selected_text(shown)
            .show_ui(ui, |ui| {
                ui.selectable_value(&mut choice.preset, None, "auto");
                for p in Preset::ALL {
                    ui.selectable_value(&mut choice.preset, Some(p), p.name());
                }
            });
        ui.end_row();
    });
    *choice != before
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_parse_every_name_and_refuse_others_with_the_list() {
        let c = |w: &str, a: &str| parse_step(w, Some(a)).unwrap();
        assert_eq!(
            c("contrast", "T2"),
            Ok(IdentityStep::Contrast(ContrastChoice::T2))
        );
        assert_eq!(
            c("modality", "ct"),
            Ok(IdentityStep::Modality(ModalityChoice::Given(Modality::Ct)))
        );
        assert_eq!(c("preset", "auto"), Ok(IdentityStep::Preset(None)));
        assert_eq!(
            c("preset", "angio"),
            Ok(IdentityStep::Preset(Some(Preset::Angio)))
        );
        let err = c("contrast", "t3").unwrap_err();
        assert!(err.contains("t1, t2, pd or flair"), "{err}");
        assert!(parse_step("contrast", None).unwrap().is_err());
        assert!(parse_step("zoom", Some("2")).is_none());
        let choice = IdentityChoice::default()
            .with(IdentityStep::Contrast(ContrastChoice::Flair))
            .with(IdentityStep::Preset(Some(Preset::Mr)));
        assert_eq!(choice.contrast, ContrastChoice::Flair);
        assert_eq!(choice.preset, Some(Preset::Mr));
        assert_eq!(choice.modality, ModalityChoice::Auto);
    }
}
