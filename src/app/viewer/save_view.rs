//! "Save 3D view": the volume alone, without the panels, rendered offscreen at a size the user
//! chooses (a figure at 2048x2048 from a 1280x800 window), with the same provenance and output
//! rules as a screenshot.
//!
//! Decisions: the scene is the one on screen (`rendered_scene`: the effects the held derived
//! volumes serve), rendered by `Engine::render` into a target made for this one image and read
//! back; the twin is not changed (no derived volumes are computed for a save). The size is
//! checked before anything is rendered (1 to 16384 pixels a side, as `render --size`).

use super::{Viewer, one_line};
use crate::files::png::write_rgba8;
use crate::files::write::{OutputKind, check_output};
use ash::vk;
use std::path::Path;

/// Largest side of a saved view, pixels (as `render --size`).
pub const MAX_SIDE: u32 = 16384;

impl Viewer {
    /// Saves the 3D view alone at `size` to `path`; the outcome goes to the status line and
    /// the log.
    pub(super) fn save_view(&mut self, path: &Path, size: [u32; 2]) {
        match self.try_save_view(path, size) {
            Ok(()) => {
                self.log.say(&format!(
                    "wrote {} (3D view, {}x{})",
                    path.display(),
                    size[0],
                    size[1]
                ));
                self.status.note = Some(format!("Saved {}", path.display()));
            }
            Err(e) => self.status.error = Some(format!("Save 3D view: {}", one_line(&e))),
        }
    }

    fn try_save_view(&mut self, path: &Path, size: [u32; 2]) -> Result<(), String> {
        if size.iter().any(|&s| s == 0 || s > MAX_SIDE) {
            return Err(format!(
                "{}x{} is not a size: each side must be 1 to {MAX_SIDE} pixels",
                size[0], size[1]
            ));
        }
        let scene = self
            .rendered_scene()
            .ok_or("no volume is open, so there is no view to save")?;
        let provenance = self.provenance(&super::paint::folder_of(path));
        let (Some(gpu), Some(current)) = (&mut self.gpu, &self.current) else {
            return Err("the GPU is not ready".into());
        };
        let inputs = current.loaded.source.paths();
        check_output(path, OutputKind::Png, &inputs, false).map_err(|e| e.to_string())?;
        let twin = &current.loaded.twin;
        let mut target = gpu
            .engine
            .render_target(size[0], size[1], vk::Format::R8G8B8A8_UNORM)
            .map_err(|e| e.to_string())?;
        target.read_back = true;
        super::slices::attach_labels(gpu.labels_3d.as_ref(), &self.controls.slices, &mut target);
        let volume = (&*twin.prepared, current.loaded.id);
        super::layers::attach_layers(
            &mut self.controls.layers,
            &mut gpu.engine,
            volume,
            &mut target,
        )?;
        let frame = gpu
            .engine
            .render(&mut target, &twin.prepared, twin.derived(), &scene)
            .map_err(|e| e.to_string())?;
        write_rgba8(path, size[0], size[1], &frame.rgba8, &provenance).map_err(|e| e.to_string())
    }
}
