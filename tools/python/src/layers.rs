//! Intensity layers for `Volume.render(layers=[...])` and `save_scene(layers=[...])` (issue 31
//! item 4): the specs the command line's `--layer` takes, read and styled by the library's one
//! function (`scene::layer_open`), kept per volume so a second render reads nothing, uploaded
//! once per prepared volume.

use crate::errors;
use morphray::engine::{Engine, LayerVolume, PreparedVolume, RenderTarget};
use morphray::scene::document::{LayerRef, recorded_path};
use morphray::scene::layer::{LayerSpec, MAX_LAYERS};
use morphray::scene::layer_open::OpenedLayer;
use pyo3::PyResult;
use std::path::Path;
use std::sync::{Arc, Weak};

struct Entry {
    opened: OpenedLayer,
    // The GPU copy and the prepared volume it was made for (weak: its memory is not reused for
    // another while this is held, so the comparison cannot be fooled).
    uploaded: Option<(Weak<PreparedVolume>, Arc<LayerVolume>)>,
}

/// The layers a volume has drawn, by spec.
#[derive(Default)]
pub struct Layers {
    entries: Vec<Entry>,
}

/// Parses `--layer` specs (at most [`MAX_LAYERS`]).
pub fn parse(words: &[String]) -> PyResult<Vec<LayerSpec>> {
    if words.len() > MAX_LAYERS {
        return Err(errors::usage(format!(
            "{} layers: at most {MAX_LAYERS} are drawn over a volume",
            words.len()
        )));
    }
    words
        .iter()
        .map(|w| LayerSpec::parse(w).map_err(|e| errors::usage(format!("layers: {e}"))))
        .collect()
}

impl Layers {
    /// The opened layer for `spec`, read on first use.
    fn entry(&mut self, spec: &LayerSpec) -> PyResult<usize> {
        if let Some(at) = self.entries.iter().position(|e| &e.opened.spec == spec) {
            return Ok(at);
        }
        let opened = OpenedLayer::open(spec).map_err(|e| errors::usage(e.to_string()))?;
        self.entries.push(Entry {
            opened,
            uploaded: None,
        });
        Ok(self.entries.len() - 1)
    }

    /// Draws `specs` in `target`'s next frames over `prepared` (none: no layers).
    pub fn attach(
        &mut self,
        specs: &[LayerSpec],
        engine: &mut Engine,
        prepared: &Arc<PreparedVolume>,
        target: &mut RenderTarget,
    ) -> PyResult<()> {
        let mut list = Vec::new();
        for spec in specs {
            let at = self.entry(spec)?;
            let entry = &mut self.entries[at];
            let uploaded = match &entry.uploaded {
                Some((made_for, u)) if Weak::ptr_eq(made_for, &Arc::downgrade(prepared)) => {
                    u.clone()
                }
                _ => {
                    let drawn = (*entry.opened.drawn).clone();
                    let u = Arc::new(engine.upload_layer(prepared, drawn).map_err(errors::gpu)?);
                    entry.uploaded = Some((Arc::downgrade(prepared), u.clone()));
                    u
                }
            };
            list.push((uploaded, entry.opened.style));
        }
        target.set_layers(list).map_err(errors::gpu)
    }

    /// The scene document's records of `specs`, paths relative to `folder`.
    pub fn records(&mut self, specs: &[LayerSpec], folder: &Path) -> PyResult<Vec<LayerRef>> {
        let mut records = Vec::new();
        for spec in specs {
            let at = self.entry(spec)?;
            let opened = &self.entries[at].opened;
            records.push(LayerRef {
                path: recorded_path(&opened.spec.path, folder),
                style: opened.style,
            });
        }
        Ok(records)
    }
}
