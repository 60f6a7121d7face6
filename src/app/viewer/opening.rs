//! Opening volumes and keeping their plan and derived volumes in line with the scene: the
//! loader's results adopted, the twin's update rule applied, the plan made again when the
//! scene's needs change, and the volume opened again when a new plan needs another layout (see
//! the decisions in the parent module).

use super::super::loader::LoadedVolume;
use super::super::status::Loading;
use super::{Current, Viewer, describe, one_line, peak_text};
use crate::app::frame_log::{Pending, Until};
use crate::engine::plan::{Layout, Plan};
use crate::engine::{OpenOptions, TwinStep, twin_step};
use crate::scene::{Scene, SceneRecipe};
use crate::volume::source::ReadOptions;
use crate::volume::source::VolumeSource;
use crate::volume::source::dicom::SeriesChoice;
use std::time::Instant;

impl Viewer {
    pub(super) fn adopt(&mut self, loaded: LoadedVolume) {
        self.pending_load = None;
        self.status.loading = None;
        self.status.error = None;
        let prepared = &loaded.twin.prepared;
        let extent_mm = (0..3)
            .map(|i| prepared.dims[i] as f64 * loaded.spacing_mm[i])
            .fold(0.0, f64::max);
        let keep = (self.keep_scene == Some(loaded.id))
            .then_some((self.controls.scene, self.controls.windows));
        self.controls
            .adopt_volume(loaded.report.clone(), prepared.histogram, extent_mm);
        match keep {
            Some((scene, windows)) => {
                self.controls.scene = scene;
                self.controls.windows = windows;
            }
            // The head layer's window is this volume's (above its background, or the
            // command line's by hand); its switch, colour and opacity stay the person's.
            None => {
                self.controls.scene.classification.head.window =
                    loaded.scene.classification.head.window
            }
        }
        self.adopt_preset_look(&loaded);
        self.render_blocked = None;
        self.status.file = loaded.label.clone();
        let r = &loaded.report;
        let unit = if crate::scene::preset::values_are_hu(r) {
            "HU"
        } else {
            ""
        };
        self.controls.slices.units = (r.imax > r.imin).then_some((r.imin, r.imax, unit));
        let identity = crate::app::status::identity_text(&loaded.report);
        let preset = self.config.recipe.preset_for(&loaded.report).name();
        self.log
            .say(&format!("identity: {identity}  |  preset {preset}"));
        self.status.identity = Some(format!("{identity}  |  preset {preset}"));
        self.controls.files.series = loaded.series.clone();
        self.status.dims = prepared.dims;
        self.status.spacing_mm = loaded.spacing_mm;
        self.status.ttfp_ms = None;
        // As every command does: a view of a repaired file must not look like a clean one.
        for warning in &loaded.warnings {
            eprintln!("morphray: warning: {}: {warning}", loaded.label);
        }
        self.arrived
            .push((format!("load {}", loaded.label), loaded.passes.clone()));
        let (frame, frames) = loaded.frame;
        self.log.say(&format!(
            "loaded {} ({}x{}x{}){}; peaks CSF {} GM {} WM {}",
            loaded.label,
            prepared.dims[0],
            prepared.dims[1],
            prepared.dims[2],
            if frames > 1 {
                format!(" frame {frame} of {frames}")
            } else {
                String::new()
            },
            peak_text(loaded.report.peaks.csf),
            peak_text(loaded.report.peaks.gm),
            peak_text(loaded.report.peaks.wm)
        ));
        // The plan may have degraded the requested effects to fit the budget: show what fits.
        if !loaded.plan.degradations.is_empty() {
            self.controls.scene.effects = loaded.scene.effects;
        }
        self.status.plan = Some(plan_text(&loaded.plan));
        self.log.say(&format!("plan: {}", plan_text(&loaded.plan)));
        self.current = Some(Current {
            loaded,
            shown: false,
        });
        self.cine_adopted();
        // A scene document's measurements, with the first volume (world mm: they stay when
        // another frame or file is opened, until Clear).
        let measurements = std::mem::take(&mut self.config.measurements);
        if !measurements.is_empty() {
            let measures = &mut self.controls.slices.measures;
            measures.items = measurements;
            measures.changed = true;
        }
        self.request_derived();
    }

    /// Brings the twin in line with the requested effects by the twin's rule (module
    /// decisions): steps without GPU work at once, a recomputation on the loader thread (one at
    /// a time); then picks the effects to render now (what the held volumes serve).
    pub(super) fn request_derived(&mut self) {
        if self.pending_derive.is_none() && self.pending_load.is_none() {
            self.replan_for_wanted();
        }
        let Some(current) = &mut self.current else {
            return;
        };
        let twin = &mut current.loaded.twin;
        let wanted = self.controls.scene.effects;
        match twin_step(twin.outputs(), wanted.derivative_outputs()) {
            TwinStep::Recompute(outputs) => {
                // Not during a frame change: its result replaces this twin (`cine.rs`); the
                // next frame asks again for the new frame.
                if self.pending_derive.is_none() && !self.cine.changing() {
                    let what = describe(outputs);
                    self.status.deriving = Some(format!("Computing the {what} (once)..."));
                    self.log.say(&format!("requesting derived volumes: {what}"));
                    self.loader
                        .derive(current.loaded.id, twin.prepared.clone(), outputs);
                    self.pending_derive = Some(outputs);
                }
            }
            step => {
                twin.apply(step);
            }
        }
        if twin.serves(&wanted) {
            self.active_effects = wanted;
        } else if !twin.serves(&self.active_effects) {
            // Nothing renderable yet with derived volumes: MIP needs none.
            self.active_effects.mode = crate::scene::RenderMode::Mip;
        }
    }

    /// When the requested effects need other derived volumes, plans them again as the open
    /// did, within the same budget: what fits with the same layout and format is adopted (the
    /// effects possibly degraded, as `render` would degrade them); another layout or format
    /// opens the volume again for them; nothing that fits keeps the effects that were shown.
    pub(super) fn replan_for_wanted(&mut self) {
        let wanted = self.controls.scene.effects;
        let (Some(current), Some(gpu)) = (&self.current, &self.gpu) else {
            return;
        };
        let twin = &current.loaded.twin;
        if !matches!(
            twin_step(twin.outputs(), wanted.derivative_outputs()),
            TwinStep::Recompute(_)
        ) {
            return;
        }
        let old = &current.loaded.plan;
        let replanned = gpu.engine.replan(twin, old, wanted, self.size);
        let same_layout = |new: &Plan| {
            std::mem::discriminant(&new.layout) == std::mem::discriminant(&old.layout)
                && new.normalized_format == old.normalized_format
        };
        match replanned {
            Ok(new) if same_layout(&new) => {
                let text = plan_text(&new);
                if new.effects != wanted {
                    self.controls.scene.effects = new.effects;
                    self.status.note = Some(format!("To fit the memory budget: {text}"));
                }
                if self.status.plan.as_deref() != Some(text.as_str()) {
                    self.log.say(&format!("plan: {text}"));
                    self.status.plan = Some(text);
                }
                if let Some(current) = &mut self.current {
                    current.loaded.plan = new;
                }
            }
            Ok(_) => {
                let scene = self.controls.scene;
                self.reopen(
                    scene,
                    "the memory plan for these effects needs another layout",
                );
            }
            Err(e) => {
                self.controls.scene.effects = self.active_effects;
                self.status.error = Some(format!(
                    "Cannot show that within the memory budget: {}",
                    one_line(&e.to_string())
                ));
            }
        }
    }

    /// Queues opening `source` (`series`: which of a DICOM input's series; None the default)
    /// with the scene's effects planned for.
    pub(super) fn open(
        &mut self,
        source: VolumeSource,
        series: Option<SeriesChoice>,
        label_for_log: Option<String>,
    ) {
        let mut recipe = self.config.recipe.clone();
        recipe.effects = self.controls.scene.effects;
        self.open_recipe(source, series, recipe, label_for_log);
    }

    /// Opens the DICOM input on screen again with its series `index` (the series picker);
    /// an index the input does not have is an error in the status line.
    pub(super) fn open_series(&mut self, index: usize, label_for_log: Option<String>) {
        let Some(current) = &self.current else {
            self.status.error = Some("No volume is open: there is no series to choose".into());
            return;
        };
        let count = current.loaded.series.as_ref().map_or(0, |l| l.all.len());
        if index >= count {
            self.status.error = Some(format!(
                "{} has no series {index} ({count} series)",
                current.loaded.label
            ));
            return;
        }
        let source = current.loaded.source.clone();
        self.open(source, Some(SeriesChoice::Index(index)), label_for_log);
    }

    /// Shows frame `index` of the 4-D file on screen (the frame slider, the time course, the
    /// script's `frame`, playback): prepared like the frame on screen when it can be
    /// (`cine.rs`), else opened again the full way; later files open at that frame too, as
    /// `view --frame` does. An index the file does not have is an error in the status line.
    pub(super) fn open_frame(&mut self, index: usize, label_for_log: Option<String>) {
        let Some(current) = &self.current else {
            self.status.error = Some("No volume is open: there is no frame to choose".into());
            return;
        };
        let (_, count) = current.loaded.frame;
        if index >= count {
            self.status.error = Some(format!(
                "{} has no frame {index} ({count} frame(s), from 0)",
                current.loaded.label
            ));
            return;
        }
        if !self.change_frame(index, label_for_log.clone()) {
            self.reopen_frame(index, label_for_log);
        }
    }

    /// Opens the 4-D file on screen again at `index` the full way (read, plan, analyse).
    pub(super) fn reopen_frame(&mut self, index: usize, label_for_log: Option<String>) {
        let Some(current) = &self.current else {
            return;
        };
        let source = current.loaded.source.clone();
        let series = shown_series(&current.loaded);
        self.frame = index;
        self.open(source, series, label_for_log);
    }

    /// A volume whose look by modality (`scene::preset`) is not the plain MR one, or differs
    /// from the last volume's, is shown as the preset draws it: its tissue styles (windows in
    /// HU for a CT, the bright band for an angiogram, which tissues are shown, colours,
    /// opacities) and its vessel channel, as `render` shows it. Between two `mr` volumes the
    /// person's styles stay (only the windows follow the new volume).
    fn adopt_preset_look(&mut self, loaded: &LoadedVolume) {
        let preset = self.config.recipe.preset_for(&loaded.report);
        let changed = self.shown_preset != Some(preset);
        self.shown_preset = Some(preset);
        if self.keep_scene == Some(loaded.id) || (preset == crate::scene::Preset::Mr && !changed) {
            return;
        }
        self.controls.scene.classification = loaded.scene.classification;
        // The command line's choice or the preset's: a channel an earlier look turned on goes.
        self.controls.scene.effects.vessels = self.config.recipe.vessels_for(&loaded.report);
        let shown: Vec<&str> = crate::scene::TissueClass::ALL
            .into_iter()
            .filter(|&t| loaded.scene.classification.style(t).visible)
            .map(|t| t.name())
            .collect();
        self.log.say(&format!(
            "look: preset {}: shows {}; vessels {}",
            preset.name(),
            shown.join(", "),
            if self.controls.scene.effects.vessels {
                "on"
            } else {
                "off"
            }
        ));
    }

    /// Takes the volume on screen (and those opened after it) as `choice` says (the modality,
    /// contrast and preset menus, the script's steps) and opens it again, as the command line's
    /// flags would have opened it (`app::identity_panel`).
    pub(super) fn reidentify(
        &mut self,
        choice: crate::app::identity_panel::IdentityChoice,
        label_for_log: Option<String>,
    ) {
        self.controls.identity = choice;
        self.config.recipe.preset = choice.preset;
        self.loader.set_identity(choice.contrast, choice.modality);
        let Some(current) = &self.current else {
            return;
        };
        let source = current.loaded.source.clone();
        let series = shown_series(&current.loaded);
        self.log.say(&format!(
            "modality {:?}, contrast {:?}, preset {}: opening the volume again",
            choice.modality,
            choice.contrast,
            choice.preset.map_or("auto", |p| p.name())
        ));
        self.open(source, series, label_for_log);
    }

    /// Queues opening `source` with `recipe` (its effects planned for); returns the request's
    /// id.
    pub(super) fn open_recipe(
        &mut self,
        source: VolumeSource,
        series: Option<SeriesChoice>,
        recipe: SceneRecipe,
        label_for_log: Option<String>,
    ) -> u64 {
        let id = self.next_id;
        self.next_id += 1;
        let label = source.label();
        let now = Instant::now();
        self.status.loading = Some(Loading {
            label: label.clone(),
            stage: "queued".into(),
            since: now,
        });
        self.loader.load(
            id,
            source,
            now,
            open_options(recipe, self.size, series, self.frame),
        );
        self.pending_load = Some((id, label));
        if let Some(text) = label_for_log {
            self.log.pending.push(Pending {
                label: text,
                since: now,
                until: Until::VolumeShown(id),
            });
        }
        id
    }

    /// The bricked volume on screen holds the bricks of another scene (tissues or mode changed
    /// what can be seen): opens it again for the scene shown now, once per scene (the same
    /// failure twice is an error in the status line, never a loop).
    pub(super) fn reopen_for_scene(&mut self, message: &str) {
        if let Some(scene) = self.rendered_scene() {
            self.reopen(scene, message);
        }
    }

    /// Opens the volume on screen again for `scene` (see [`Viewer::reopen_for_scene`]);
    /// `message` is the error shown when that was tried for this scene already.
    pub(super) fn reopen(&mut self, scene: Scene, message: &str) {
        let Some(current) = &self.current else {
            return;
        };
        if self.pending_load.is_some() {
            // The volume is being opened (again): the next one shows this scene.
            return;
        }
        // Compared as recipes: the frame counter (jitter seed) changes every scripted frame.
        // The denoising is the command line's (not part of a scene): kept on every reopen.
        let recipe = SceneRecipe {
            denoise: self.config.recipe.denoise,
            ..SceneRecipe::from_scene(&scene)
        };
        if self.reopened_for.as_ref() == Some(&recipe) {
            self.status.error = Some(one_line(message));
            return;
        }
        let source = current.loaded.source.clone();
        let series = shown_series(&current.loaded);
        self.reopened_for = Some(recipe.clone());
        self.log.say(&format!(
            "{message}: opening the volume again for this scene"
        ));
        let id = self.open_recipe(source, series, recipe, None);
        self.keep_scene = Some(id);
    }

    /// True when the volume on screen is bricked.
    pub(super) fn bricked_now(&self) -> bool {
        self.current
            .as_ref()
            .is_some_and(|c| matches!(c.loaded.plan.layout, Layout::Bricked { .. }))
    }
}

/// The series on screen as a choice that opens it again (None: not DICOM).
pub(super) fn shown_series(loaded: &LoadedVolume) -> Option<SeriesChoice> {
    loaded
        .series
        .as_ref()
        .map(|l| SeriesChoice::Index(l.chosen))
}

/// How the viewer opens a volume: planned for the window's size, hashed for screenshots'
/// provenance, pipelines ahead of time, the DICOM series `series`, the frame `frame` of a 4-D
/// file.
pub(super) fn open_options(
    recipe: SceneRecipe,
    size: [u32; 2],
    series: Option<SeriesChoice>,
    frame: usize,
) -> OpenOptions {
    OpenOptions {
        read: ReadOptions {
            frame,
            hash: true,
            series,
        },
        image: size,
        recipe,
        first_frame: true,
    }
}

/// The plan for the status bar and the log: layout, then each degradation.
fn plan_text(plan: &Plan) -> String {
    let layout = match plan.layout {
        Layout::Whole => "whole volume".to_string(),
        Layout::Bricked { grid, resident, .. } => format!(
            "bricked ({resident} of {} bricks resident)",
            grid[0] * grid[1] * grid[2]
        ),
    };
    let budget = plan.budget / (1 << 20);
    if plan.degradations.is_empty() {
        return format!("{layout} within {budget} MiB");
    }
    let what: Vec<&str> = plan.degradations.iter().map(|d| d.what.as_str()).collect();
    format!(
        "{layout} within {budget} MiB; degraded: {}",
        what.join("; ")
    )
}
