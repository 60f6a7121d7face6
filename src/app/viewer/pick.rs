//! Depth picking in the viewer (issue 31 item 2): a click without a drag on the 3D view (or the
//! script's `pick X Y`) moves the crosshair to the point the picture shows there, and the slices
//! follow (the crosshair is theirs).
//!
//! Decisions: the pick marches the ray of the picture on screen (`Engine::pick`): the scene and
//! quality level it was drawn at, in the target size it was drawn in (an interactive level draws
//! a smaller target, stretched), so the point is under the cursor in what the user sees. It runs
//! at once, on the interface thread: one ray and a 16-byte readback. A click on empty background
//! moves nothing and says so.

use super::Viewer;
use crate::engine::pick::DEFAULT_PICK_THRESHOLD;

impl Viewer {
    /// Runs the pick the interface or the script asked for (`Controls::pick`), if any.
    pub(super) fn run_pick(&mut self) {
        let Some(at) = self.controls.pick.take() else {
            return;
        };
        let (Some(gpu), Some(current), Some(last)) = (&mut self.gpu, &self.current, &self.last)
        else {
            self.log.say("pick: no picture yet");
            return;
        };
        let size = last.size;
        let pixel = [0, 1].map(|a| {
            let p = (at[a] * size[a] as f32).floor();
            (p.max(0.0) as u32).min(size[a].saturating_sub(1))
        });
        let scene = last.level.apply(&last.scene);
        let twin = &current.loaded.twin;
        // The layers drawn are met by the pick too (a failed upload is the frame's error).
        let layers =
            self.controls
                .layers
                .attached(&mut gpu.engine, &twin.prepared, current.loaded.id);
        gpu.engine.set_pick_layers(layers.unwrap_or_default());
        let picked = gpu.engine.pick(
            &twin.prepared,
            twin.derived(),
            &scene,
            size,
            pixel,
            DEFAULT_PICK_THRESHOLD,
        );
        let at_text = format!("{:.3},{:.3} of the view", at[0], at[1]);
        match picked {
            Ok(Some(hit)) => {
                let [x, y, z] = hit.world_mm.to_array();
                self.log.say(&format!(
                    "pick: {at_text} -> {x:.1},{y:.1},{z:.1} mm (world)"
                ));
                if std::mem::take(&mut self.controls.pick_measures) {
                    if let Err(e) = self.controls.slices.measures.add_point(hit.world_mm) {
                        self.status.error = Some(format!("Measure: {e}"));
                    }
                } else {
                    self.controls.slices.crosshair = Some(hit.world_mm);
                }
            }
            Ok(None) => self
                .log
                .say(&format!("pick: {at_text}: nothing visible there")),
            Err(e) => {
                let message = format!("Pick failed: {}", super::one_line(&e.to_string()));
                self.log.say(&message);
                self.status.error = Some(message);
            }
        }
    }
}
