//! The viewer's side of intensity layers and added label maps (issue 31 item 4): opening them
//! (Add layer..., Add labels..., `view --layer`, a scene document, the script's `layer` and
//! `labels` steps), attaching the layers to each frame's render target, and redrawing the
//! slices when they change (`app::layers_panel` holds the layers and their controls).
//!
//! Decision: a label map added from the viewer replaces the one on screen, as `--overlay`
//! would, and is set up on the volume's grid by the same path as the command line's.

use super::Viewer;
use crate::engine::RenderTarget;
use crate::scene::layer::LayerSpec;
use std::path::Path;

impl Viewer {
    /// Reads and draws the layer `spec` asks for; the outcome in the log and the status line.
    pub(super) fn add_layer(&mut self, spec: &LayerSpec) {
        match self.controls.layers.add(spec) {
            Ok(line) => {
                self.log.say(&line);
                self.status.note = Some(line);
            }
            Err(e) => self.status.error = Some(format!("Add layer: {e}")),
        }
    }

    /// A script's or a panel's layer step.
    pub(super) fn layer_step(&mut self, step: &crate::app::layers_panel::LayerStep) {
        match self.controls.layers.apply(step) {
            Ok(line) => self.log.say(&line),
            Err(e) => {
                self.log.say(&format!("layer step failed: {e}"));
                self.status.error = Some(format!("Layer: {e}"));
            }
        }
    }

    /// Reads the label map at `path` and draws it over the volume (replacing any).
    pub(super) fn add_labels(&mut self, path: &Path) {
        let opacity = self.config.overlay.as_ref().map_or(0.5, |o| o.opacity);
        match crate::scene::overlay::Overlay::open(path, None, opacity) {
            Ok(overlay) => {
                self.config.overlay = Some(overlay);
                self.config.overlay_files = Some((path.to_path_buf(), None, opacity));
                // The slices set the labels up on the volume's grid when it is new to them.
                self.controls.slices.volume = u64::MAX;
                self.controls.slices.dirty = true;
                self.log.say(&format!("labels {} added", path.display()));
            }
            Err(e) => self.status.error = Some(format!("Add labels: {e}")),
        }
    }

    /// Opens the command line's or the document's layers once a volume is on screen, and asks
    /// the slices to draw again after a layer changed.
    pub(super) fn update_layers(&mut self) {
        if self.current.is_some() && !self.config.layers.is_empty() {
            for spec in std::mem::take(&mut self.config.layers) {
                self.add_layer(&spec);
            }
        }
        if std::mem::take(&mut self.controls.layers.changed) {
            self.controls.slices.dirty = true;
        }
    }
}

/// Attaches the layers to `target` for the volume on screen (uploading those not on the GPU for
/// it yet); a failure is the status line's, and the frame is drawn without them.
pub(super) fn attach_layers(
    layers: &mut crate::app::layers_panel::Layers,
    engine: &mut crate::engine::Engine,
    (prepared, volume_id): (&crate::engine::PreparedVolume, u64),
    target: &mut RenderTarget,
) -> Result<(), String> {
    let list = layers
        .attached(engine, prepared, volume_id)
        .map_err(|e| format!("layers in 3D: {e}"))?;
    target.set_layers(list).map_err(|e| e.to_string())
}
