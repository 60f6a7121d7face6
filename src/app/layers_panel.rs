//! The viewer's intensity layers (issue 31 item 4): the layers opened over the volume (Add
//! layer..., `view --layer`, a scene document, the script's `layer` steps), their controls
//! (colour map, window, threshold, negative side, cluster size, opacity, remove), their blend
//! over the slices and their value at the crosshair.
//!
//! Decisions:
//! - A layer is read and styled by the library's one function (`scene::layer_open`), so the
//!   viewer shows what `render --layer` draws; its GPU copy is made per volume on screen
//!   (`engine::upload_layer`) and dropped when the volume or the drawn voxels change.
//! - Reading happens on the interface thread: a layer is a map or a second scan of a few MB
//!   (the 2 mm z-map of tools/figures/synthetic_zmap.py reads in well under a second here), and
//!   a scripted run must see it before its next step.
//! - An edit of the threshold, the negative side or the cluster size removes clusters again on
//!   the host and uploads the drawn voxels anew; the window, colour map and opacity are uniform
//!   and table writes only.

use crate::engine::{Engine, LayerVolume, PreparedVolume};
use crate::scene::layer::{LayerColormap, LayerSpec, LayerStyle, MAX_LAYERS};
use crate::scene::layer_grid::{LayerCodes, blend_layer_slice, sample_codes};
use crate::scene::layer_open::OpenedLayer;
use crate::scene::slice::IndexGrid;
use egui::Ui;
use glam::{DVec3, DVec4};
use std::sync::Arc;

/// One layer over the volume.
pub struct LayerEntry {
    /// The layer as read and styled.
    pub opened: OpenedLayer,
    /// The drawn voxels' 16-bit codes (the slices sample them as the GPU does).
    codes: Arc<LayerCodes>,
    /// Its GPU copy and the volume it was made for.
    uploaded: Option<(u64, Arc<LayerVolume>)>,
}

/// The layers and what changed since the slices were drawn.
#[derive(Default)]
pub struct Layers {
    /// In drawing order (at most [`MAX_LAYERS`]).
    pub entries: Vec<LayerEntry>,
    /// A layer was added, removed or restyled: the slices draw again.
    pub changed: bool,
}

/// A script's layer step (`layer add SPEC`, `layer N threshold T`, ...), N from 1.
#[derive(Clone, Debug, PartialEq)]
pub enum LayerStep {
    /// `layer add FILE[:MAP[:LO:HI]]...`.
    Add(String),
    /// `layer remove N`.
    Remove(usize),
    /// `layer N window LO HI`.
    Window(usize, f64, f64),
    /// `layer N threshold T`.
    Threshold(usize, f64),
    /// `layer N opacity A`.
    Opacity(usize, f64),
    /// `layer N cluster VOXELS`.
    Cluster(usize, u32),
    /// `layer N colormap MAP`.
    Colormap(usize, LayerColormap),
    /// `layer N negative MAP|off`.
    Negative(usize, Option<LayerColormap>),
}

impl LayerStep {
    /// Parses the words after `layer`.
    pub fn parse(words: &[&str]) -> Result<LayerStep, String> {
        let usage = "expected `layer add SPEC`, `layer remove N` or `layer N window LO HI | \
                     threshold T | opacity A | cluster VOXELS | colormap MAP | negative MAP|off`";
        let number = |w: Option<&&str>| -> Result<f64, String> {
            w.and_then(|t| t.parse::<f64>().ok())
                .filter(|v| v.is_finite())
                .ok_or_else(|| usage.to_string())
        };
        let map = |w: Option<&&str>| -> Result<LayerColormap, String> {
            let name = w.ok_or(usage)?;
            LayerColormap::parse(name).ok_or_else(|| {
                format!(
                    "unknown colour map `{name}`; use {}",
                    crate::scene::layer::map_names()
                )
            })
        };
        match words {
            ["add", spec] => return Ok(LayerStep::Add(spec.to_string())),
            ["remove", n] => return Ok(LayerStep::Remove(layer_number(n)?)),
            _ => {}
        }
        let n = layer_number(words.first().ok_or(usage)?)?;
        Ok(match words.get(1).copied() {
            Some("window") => LayerStep::Window(n, number(words.get(2))?, number(words.get(3))?),
            Some("threshold") => LayerStep::Threshold(n, number(words.get(2))?),
            Some("opacity") => LayerStep::Opacity(n, number(words.get(2))?),
            Some("cluster") => LayerStep::Cluster(n, number(words.get(2))?.max(0.0) as u32),
            Some("colormap") => LayerStep::Colormap(n, map(words.get(2))?),
            Some("negative") if words.get(2) == Some(&"off") => LayerStep::Negative(n, None),
            Some("negative") => LayerStep::Negative(n, Some(map(words.get(2))?)),
            _ => return Err(usage.into()),
        })
    }
}

fn layer_number(word: &str) -> Result<usize, String> {
    match word.parse::<usize>() {
        Ok(n) if (1..=MAX_LAYERS).contains(&n) => Ok(n),
        _ => Err(format!("layer `{word}`: give 1 to {MAX_LAYERS}")),
    }
}

impl Layers {
    /// Reads and adds the layer `spec` asks for; the line saying what is drawn, or why not.
    pub fn add(&mut self, spec: &LayerSpec) -> Result<String, String> {
        if self.entries.len() >= MAX_LAYERS {
            return Err(format!(
                "{MAX_LAYERS} layers are open: remove one before adding {}",
                spec.path.display()
            ));
        }
        let opened = OpenedLayer::open(spec).map_err(|e| e.to_string())?;
        let line = opened.describe();
        self.entries.push(LayerEntry {
            codes: Arc::new(opened.drawn.codes()),
            opened,
            uploaded: None,
        });
        self.changed = true;
        Ok(line)
    }

    /// Applies a script step (other than `add`); the line saying what changed.
    pub fn apply(&mut self, step: &LayerStep) -> Result<String, String> {
        let index = match step {
            LayerStep::Add(spec) => {
                let spec = LayerSpec::parse(spec).map_err(|e| e.to_string())?;
                return self.add(&spec);
            }
            LayerStep::Remove(n) => {
                self.entry(*n)?;
                let gone = self.entries.remove(n - 1);
                self.changed = true;
                return Ok(format!("layer {} removed", gone.opened.grid.name));
            }
            LayerStep::Window(n, ..)
            | LayerStep::Threshold(n, _)
            | LayerStep::Opacity(n, _)
            | LayerStep::Cluster(n, _)
            | LayerStep::Colormap(n, _)
            | LayerStep::Negative(n, _) => *n,
        };
        let mut style = self.entry(index)?.opened.style;
        match *step {
            LayerStep::Window(_, lo, hi) => (style.lo, style.hi) = (lo, hi),
            LayerStep::Threshold(_, t) => style.threshold = t,
            LayerStep::Opacity(_, a) => style.opacity = a,
            LayerStep::Cluster(_, c) => style.cluster = c,
            LayerStep::Colormap(_, m) => style.colormap = m,
            LayerStep::Negative(_, m) => style.negative = m,
            LayerStep::Add(_) | LayerStep::Remove(_) => {}
        }
        self.restyle(index - 1, style)?;
        Ok(self.entries[index - 1].opened.describe())
    }

    fn entry(&self, n: usize) -> Result<&LayerEntry, String> {
        self.entries
            .get(n.wrapping_sub(1))
            .ok_or_else(|| format!("there is no layer {n} ({} open)", self.entries.len()))
    }

    /// Draws layer `index` with `style` (clusters removed again when the drawn voxels change).
    pub fn restyle(&mut self, index: usize, style: LayerStyle) -> Result<(), String> {
        let Some(entry) = self.entries.get_mut(index) else {
            return Err(format!("there is no layer {}", index + 1));
        };
        let before = entry.opened.style;
        if before == style {
            return Ok(());
        }
        let voxels_change = before.threshold != style.threshold
            || before.negative.is_some() != style.negative.is_some()
            || before.cluster != style.cluster;
        let spec = LayerSpec::from_style(entry.opened.spec.path.clone(), &style);
        // Clusters depend on which voxels pass: remove them again when those change.
        if voxels_change && (style.cluster > 1 || before.cluster > 1) {
            entry.opened = OpenedLayer::with_style(spec, entry.opened.grid.clone(), style)
                .map_err(|e| e.to_string())?;
            entry.codes = Arc::new(entry.opened.drawn.codes());
            entry.uploaded = None;
        } else {
            style.check().map_err(|e| e.to_string())?;
            entry.opened.style = style;
            entry.opened.spec = spec;
        }
        self.changed = true;
        Ok(())
    }

    /// The layers to attach to a render target for the volume `volume_id` (`prepared`),
    /// uploading those not yet on the GPU for it.
    pub fn attached(
        &mut self,
        engine: &mut Engine,
        prepared: &PreparedVolume,
        volume_id: u64,
    ) -> Result<Vec<(Arc<LayerVolume>, LayerStyle)>, crate::gpu::GpuError> {
        let mut list = Vec::new();
        for entry in &mut self.entries {
            let current = entry.uploaded.as_ref().filter(|(id, _)| *id == volume_id);
            let uploaded = match current {
                Some((_, u)) => u.clone(),
                None => {
                    let u = Arc::new(engine.upload_layer(prepared, (*entry.opened.drawn).clone())?);
                    entry.uploaded = Some((volume_id, u.clone()));
                    u
                }
            };
            list.push((uploaded, entry.opened.style));
        }
        Ok(list)
    }

    /// Blends every layer over a slice whose pixels lie at the base index positions `slice` of
    /// a volume with index-to-world `affine`.
    pub fn blend(&self, rgba: &mut [u8], slice: &IndexGrid, affine: &[[f64; 4]; 4]) {
        for entry in &self.entries {
            let layer = &entry.opened;
            let map = layer.drawn.index_map(affine);
            let tables = layer.style.tables();
            blend_layer_slice(
                rgba,
                slice,
                (&layer.drawn, &entry.codes, map),
                &layer.style,
                &tables,
            );
        }
    }

    /// Each layer's value at the world point `mm` ("zmap.nii.gz 4.21"; "-" off its grid).
    pub fn readout(&self, mm: DVec3) -> Vec<String> {
        self.entries
            .iter()
            .map(|entry| {
                let grid = &entry.opened.drawn;
                let q = (grid.to_world.inverse() * DVec4::from((mm, 1.0))).truncate();
                match sample_codes(grid, &entry.codes, q) {
                    Some(v) => format!("{} {v:.4}", grid.name),
                    None => format!("{} -", grid.name),
                }
            })
            .collect()
    }

    /// The panel: per layer its map, window, threshold, negative side, cluster size, opacity
    /// and a remove button; `add` is set when Add layer... was pressed.
    pub fn panel(&mut self, ui: &mut Ui) -> bool {
        let mut add = false;
        ui.horizontal(|ui| {
            let room = self.entries.len() < MAX_LAYERS;
            let button = ui.add_enabled(room, egui::Button::new("Add layer..."));
            add = button
                .on_hover_text(
                    "A second volume over this one (a statistical map, PET, FLAIR) on its own \
                     grid: coloured above its threshold, drawn on the slices and in 3D",
                )
                .clicked();
        });
        let mut remove = None;
        let mut edits = Vec::new();
        for (index, entry) in self.entries.iter().enumerate() {
            let mut style = entry.opened.style;
            ui.label(egui::RichText::new(&entry.opened.grid.name).strong());
            if style_controls(ui, index, &mut style) {
                edits.push((index, style));
            }
            if ui.small_button("Remove").clicked() {
                remove = Some(index);
            }
        }
        for (index, style) in edits {
            if let Err(e) = self.restyle(index, style) {
                ui.colored_label(egui::Color32::LIGHT_RED, e);
            }
        }
        if let Some(index) = remove {
            self.entries.remove(index);
            self.changed = true;
        }
        add
    }
}

/// The tools panel's Layers section: the layers' controls, Add layer... and Add labels...
/// (open by default: they are how a second volume is found).
pub fn section(ui: &mut Ui, controls: &mut super::ui::Controls) {
    egui::CollapsingHeader::new("Layers")
        .default_open(true)
        .show(ui, |ui| {
            if controls.layers.panel(ui) {
                controls.files.add_layer_dialog();
            }
            if ui
                .button("Add labels...")
                .on_hover_text("An integer label map (a segmentation) over the volume")
                .clicked()
            {
                controls.files.add_labels_dialog();
            }
        });
}

/// One layer's controls; true when one changed.
fn style_controls(ui: &mut Ui, index: usize, style: &mut LayerStyle) -> bool {
    let before = *style;
    let speed = ((style.hi - style.lo).abs() / 100.0).max(1e-4);
    egui::ComboBox::from_id_salt(("layer map", index))
        .selected_text(style.colormap.name())
        .show_ui(ui, |ui| {
            for map in LayerColormap::ALL {
                ui.selectable_value(&mut style.colormap, map, map.name());
            }
        });
    ui.horizontal(|ui| {
        ui.label("window");
        ui.add(egui::DragValue::new(&mut style.lo).speed(speed));
        ui.add(egui::DragValue::new(&mut style.hi).speed(speed));
    });
    ui.horizontal(|ui| {
        ui.label("threshold |v| >=");
        ui.add(
            egui::DragValue::new(&mut style.threshold)
                .speed(speed)
                .range(0.0..=f64::MAX),
        );
    });
    ui.horizontal(|ui| {
        let mut negative = style.negative.is_some();
        if ui
            .checkbox(&mut negative, "negative side")
            .on_hover_text("Values <= -threshold, in their own map (a two-sided z-map)")
            .changed()
        {
            style.negative = negative.then_some(LayerColormap::BlueLightblue);
        }
        if let Some(map) = &mut style.negative {
            egui::ComboBox::from_id_salt(("layer negative map", index))
                .selected_text(map.name())
                .show_ui(ui, |ui| {
                    for choice in LayerColormap::ALL {
                        ui.selectable_value(map, choice, choice.name());
                    }
                });
        }
    });
    ui.horizontal(|ui| {
        ui.label("min cluster");
        ui.add(egui::DragValue::new(&mut style.cluster).range(0..=1_000_000))
            .on_hover_text("Drop 26-connected clusters of fewer voxels (0: keep all)");
    });
    ui.add(egui::Slider::new(&mut style.opacity, 0.0..=1.0).text("opacity"));
    // An edit that breaks the window (lo >= hi) is not taken.
    *style != before && style.check().is_ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_parse_and_bad_ones_say_why() {
        assert_eq!(
            LayerStep::parse(&["add", "z.nii:hot"]).unwrap(),
            LayerStep::Add("z.nii:hot".into())
        );
        assert_eq!(
            LayerStep::parse(&["2", "window", "3", "8"]).unwrap(),
            LayerStep::Window(2, 3.0, 8.0)
        );
        assert_eq!(
            LayerStep::parse(&["1", "negative", "off"]).unwrap(),
            LayerStep::Negative(1, None)
        );
        assert_eq!(
            LayerStep::parse(&["1", "colormap", "hot"]).unwrap(),
            LayerStep::Colormap(1, LayerColormap::Hot)
        );
        for bad in [
            &["3", "opacity", "1"][..],
            &["1", "fly"],
            &["1", "threshold", "x"],
            &[],
        ] {
            assert!(LayerStep::parse(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn a_missing_layer_is_an_error_not_a_panic() {
        let mut layers = Layers::default();
        assert!(layers.apply(&LayerStep::Threshold(1, 2.0)).is_err());
        assert!(layers.apply(&LayerStep::Remove(2)).is_err());
        assert!(
            layers
                .apply(&LayerStep::Add("/nonexistent/z.nii".into()))
                .is_err()
        );
    }
}
