//! What the viewer shows of brain extraction: the tissue panel's decision line
//! (`app/brain_panel.rs`), the session log's `brain:` lines, and the slices' outline of the mask
//! in use (`app/brain_outline.rs`).
//!
//! Decision: the state is read once per frame from the twin on screen and the effects rendered
//! now (`Viewer::active_effects`), exactly as the raymarch decides whether it masks
//! (`engine/render.rs`: DVR, the switch not Off, a mask the switch uses), so the panel, the
//! outline and the picture agree; a change marks the slices for a new rendering.

use super::Viewer;
use crate::app::brain_panel::BrainShown;
use crate::passes::brain::BrainSwitch;
use crate::scene::RenderMode;

impl Viewer {
    /// Brings the panel's brain state and the slices' outline up to date (before the interface).
    pub(super) fn sync_brain(&mut self) {
        let effects = self.active_effects;
        let computing = self
            .pending_derive
            .is_some_and(|o| o.brain != BrainSwitch::Off);
        let (shown, outline) = match &self.current {
            None => (BrainShown::default(), None),
            Some(current) => {
                let mask = current.loaded.twin.derived().and_then(|d| d.brain.as_ref());
                let in_use = effects.mode == RenderMode::Dvr
                    && mask.is_some_and(|m| m.use_for(effects.brain));
                let shown = BrainShown {
                    report: mask.map(|m| m.report.clone()),
                    in_use,
                    computing,
                };
                let outline = current.loaded.brain_outline.clone().filter(|_| in_use);
                (shown, outline)
            }
        };
        if shown != self.controls.brain {
            self.log_brain(&shown);
            self.controls.brain = shown;
        }
        let slices = &mut self.controls.slices;
        let same = match (&slices.brain, &outline) {
            (Some(a), Some(b)) => std::sync::Arc::ptr_eq(a, b),
            (None, None) => true,
            _ => false,
        };
        if !same {
            slices.brain = outline;
            slices.dirty = true;
        }
    }

    /// The session log's line for a new brain state (scripted runs and tests read it).
    fn log_brain(&mut self, shown: &BrainShown) {
        let before = &self.controls.brain;
        if shown.report != before.report
            && let Some(report) = &shown.report
        {
            self.log.say(&format!(
                "brain: {} ({:.0} cm^3, {:.1} % of the tissue band outside it, {:.0} ms)",
                report.decision.describe(),
                report.brain_cm3,
                report.outside_fraction * 100.0,
                report.total_ms
            ));
        }
        if shown.in_use != before.in_use {
            self.log.say(if shown.in_use {
                "brain mask in use: tissues inside the brain, the rest is the head layer"
            } else {
                "brain mask not in use: every voxel is classified"
            });
        }
    }
}
