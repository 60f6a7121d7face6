//! "Save scene...": the scene on screen as a scene document (`scene::document`, issue 31 item
//! 6), which `morphray view --scene` and `render --scene` open again; and the same document in
//! every PNG the viewer writes (`morphray:scene`), for `render --scene-from`.
//!
//! Decisions: the document holds the scene the controls set (the full-quality effects, not the
//! cheaper ones an interaction or a pending derived volume may show for a moment), with the
//! cut-away through the crosshair as drawn; the inputs are recorded relative to the document's
//! folder when they lie under it; the layout and the crosshair go with it.

use super::{Viewer, one_line};
use crate::scene::document::{OverlayRef, SceneDocument, SceneInput, ViewerLayout, recorded_path};
use std::path::Path;

impl Viewer {
    /// The document of the scene on screen, paths recorded relative to `folder`; None without a
    /// volume.
    pub(super) fn scene_document(&self, folder: &Path) -> Option<SceneDocument> {
        let current = self.current.as_ref()?;
        let mut scene = self.rendered_scene()?;
        scene.effects = self.controls.scene.effects;
        let loaded = &current.loaded;
        let input = SceneInput {
            paths: (loaded.source.paths().iter())
                .map(|p| recorded_path(p, folder))
                .collect(),
            sha256: loaded.sha256.clone(),
            frame: loaded.frame.0,
        };
        let mut doc = SceneDocument::new(input, scene);
        doc.denoise = self.config.recipe.denoise;
        doc.size = Some(self.size);
        doc.matcap = self.config.matcap_spec.as_ref().map(|m| {
            if crate::scene::matcap::BUILT_IN.contains(&m.as_str()) {
                m.clone()
            } else {
                recorded_path(Path::new(m), folder)
            }
        });
        doc.overlay = self
            .config
            .overlay_files
            .as_ref()
            .map(|(labels, lut, opacity)| OverlayRef {
                labels: recorded_path(labels, folder),
                lut: lut.as_ref().map(|l| recorded_path(l, folder)),
                opacity: *opacity,
            });
        doc.layers = (self.controls.layers.entries.iter())
            .map(|e| crate::scene::document::LayerRef {
                path: recorded_path(&e.opened.spec.path, folder),
                style: e.opened.style,
            })
            .collect();
        let slices = &self.controls.slices;
        doc.measurements.clone_from(&slices.measures.items);
        doc.viewer = Some(ViewerLayout {
            layout: slices.layout.name().to_string(),
            crosshair_mm: slices.crosshair.map(|c| c.to_array()),
        });
        Some(doc)
    }

    /// Writes the scene document to `path`; the outcome goes to the status line and the log.
    pub(super) fn save_scene(&mut self, path: &Path) {
        let written = match self.scene_document(&super::paint::folder_of(path)) {
            None => Err("no volume is open, so there is no scene to save".to_string()),
            Some(doc) => {
                let source = self.current.as_ref().map(|c| c.loaded.source.clone());
                let inputs = source.as_ref().map(|s| s.paths()).unwrap_or_default();
                doc.write(path, &inputs).map_err(|e| e.to_string())
            }
        };
        match written {
            Ok(()) => {
                self.log
                    .say(&format!("wrote {} (scene document)", path.display()));
                self.status.note = Some(format!("Saved {}", path.display()));
            }
            Err(e) => {
                if self.config.log {
                    eprintln!("morphray: save scene failed: {}", one_line(&e));
                }
                self.status.error = Some(format!("Save scene: {}", one_line(&e)));
            }
        }
    }
}
