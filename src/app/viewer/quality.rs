//! The viewer's side of adaptive quality (`app/adaptive.rs` holds the controller and the
//! design): what counts as interacting, the level of each frame, and the redraw that brings
//! full quality back.
//!
//! Decisions:
//! - Interacting means a continuous gesture that changed the 3D scene this frame: a drag on the
//!   view (orbit, pan), a drag of any widget (a slider, a histogram window edge) or a scroll
//!   (zoom). A click (a toggle, a preset, a standard view) is not: it shows its result at full
//!   quality at once, since one frame of waiting is better than a coarse frame and a pop. A
//!   drag that holds still changes nothing, so full quality comes back while the button is
//!   still down.
//! - A frame that writes a screenshot (the `--screenshot` frame, a `screenshot` step, the
//!   Screenshot button) is always full quality; "Save 3D view" renders on its own at full
//!   quality anyway (`save_view.rs`).

use super::*;
use crate::app::adaptive::Level;

impl Viewer {
    /// Tells the controller about this frame's input: `before` is the scene rendered before the
    /// interface ran.
    pub(super) fn note_input(&mut self, before: Option<Scene>, now: Instant) {
        let gesture = self.controls.dragging
            || self.ctx.dragged_id().is_some()
            || self
                .ctx
                .input(|i| i.smooth_scroll_delta != egui::Vec2::ZERO);
        if gesture && before.is_some() && before != self.rendered_scene() {
            self.adaptive.input(now);
        }
    }

    /// The level of the frame being recorded now.
    pub(super) fn frame_level(&mut self, screenshot: bool) -> Level {
        let level = self.adaptive.level(Instant::now());
        if screenshot { Level::FULL } else { level }
    }

    /// Asks the window for a redraw when the full-quality frame is due (an idle window would
    /// otherwise keep the coarse image until the next input).
    pub(super) fn refine_later(&self, result: &mut FrameResult) {
        if let Some(after) = self.adaptive.refine_after(Instant::now()) {
            let after = after.as_secs_f64();
            result.repaint_after = Some(result.repaint_after.map_or(after, |r| r.min(after)));
        }
    }
}
