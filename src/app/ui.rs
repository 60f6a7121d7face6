//! The interface: tissue panel (histogram with draggable windows, switches, colours,
//! opacities, presets), rendering panel, camera buttons, status bar, and the 3D view's input and
//! overlays (orientation letters, load progress, errors).
//!
//! Decisions:
//! - Laid out for a clinician: tissues first (what is shown), then how it is rendered, then the
//!   camera; technical numbers (GPU ms per pass) only in the status bar at the bottom.
//! - All state a widget changes lives in [`Controls`]; its methods are what the widgets and the
//!   script runner both call, so a scripted run exercises the interface's own code paths.
//! - The 3D view is the central panel without a frame: the presenter copies the raymarched image
//!   under it, egui draws only the overlays; its rectangle (in pixels) sizes the render target.
//!   Its input and overlays are in `view_area.rs`, the status bar in `status_bar.rs`, the file
//!   panel in `file_panel.rs`.
//! - Camera input is read from egui's response on the view (so egui decides who owns a drag:
//!   a slider drag never orbits the volume), keys only when no text field has focus.

use super::camera_control::{CameraController, StandardView};
use super::file_panel::FilePanel;
use super::histogram;
use super::script::Preset;
use super::status::Status;
use crate::analysis::TissueReport;
use crate::scene::visibility::{EmptyScene, predict_empty};
use crate::scene::{Classification, Cutaway, LightModel, RenderMode, Scene, TissueClass};
use crate::volume::source::VolumeSource;
use egui::{Color32, Rect, RichText, Ui, vec2};
use std::path::PathBuf;

/// Width of the tool panel, points.
pub const PANEL_WIDTH: f32 = 320.0;

/// What the interface asks the viewer to do beyond changing [`Controls`].
#[derive(Clone, Debug, PartialEq)]
pub enum Request {
    /// Open a volume source (a file, several DICOM files, or the phantom).
    Open(VolumeSource),
    /// Open the source on screen again with this series of its DICOM input (an index as
    /// `--series` takes it).
    Series(usize),
    /// Save the window as PNG.
    Screenshot(PathBuf),
    /// Show this frame of the 4-D file on screen (0-based; `viewer/cine.rs`).
    Frame(usize),
    /// Save the 3D view alone, rendered at this size (width, height), as PNG.
    SaveView(PathBuf, [u32; 2]),
    /// Save the scene on screen as a scene document (.json).
    SaveScene(PathBuf),
    /// Export the measurements as .csv or .json.
    ExportMeasures(PathBuf),
    /// Open the volume on screen again taken as this modality, contrast and preset.
    Identity(super::identity_panel::IdentityChoice),
    /// Draw this file over the volume as an intensity layer (Add layer...).
    AddLayer(PathBuf),
    /// Draw this label map over the volume (Add labels...).
    AddLabels(PathBuf),
}

/// Which window presets the tissue windows follow.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WindowSource {
    /// Around the peaks of the current volume.
    Adaptive,
    /// The paper's constants.
    Paper,
    /// Edited by hand.
    Custom,
}

/// Everything the interface lets a person change.
pub struct Controls {
    /// The scene as requested (effects may wait for derived volumes before they show).
    pub scene: Scene,
    /// Where the windows came from.
    pub windows: WindowSource,
    /// Mouse sensitivities.
    pub camera: CameraController,
    /// The current volume's analysis (for presets and peaks).
    pub report: Option<TissueReport>,
    /// The current volume's histogram.
    pub histogram: Option<[u32; 256]>,
    /// Largest side of the volume's bounding box, mm (for panning).
    pub extent_mm: f64,
    /// Open/save dialogs and the DICOM series picker.
    pub files: FilePanel,
    /// A drag on the view in progress (for the script runner: a drag is one action).
    pub dragging: bool,
    /// A depth pick asked for (a click on the 3D view, or the script's `pick`): where, as
    /// fractions of the view's width and height from its top left (viewer/pick.rs runs it).
    pub pick: Option<[f32; 2]>,
    /// The pick places a measurement point instead of moving the crosshair (Shift+click).
    pub pick_measures: bool,
    /// Slice layout, crosshair, window and convention (`slices_panel.rs`).
    pub slices: super::slices_panel::SliceControls,
    /// Intensity layers over the volume (`layers_panel.rs`).
    pub layers: super::layers_panel::Layers,
    /// What brain extraction decided for the volume on screen (`brain_panel.rs`).
    pub brain: super::brain_panel::BrainShown,
    /// The modality, contrast and preset menus (`identity_panel.rs`).
    pub identity: super::identity_panel::IdentityChoice,
    /// The 4-D panel: frame, playback, time course.
    pub cine: super::cine_panel::CinePanel,
}

impl Controls {
    /// Controls around a scene.
    pub fn new(scene: Scene) -> Self {
        Controls {
            scene,
            windows: WindowSource::Adaptive,
            camera: CameraController::default(),
            report: None,
            histogram: None,
            extent_mm: 200.0,
            files: FilePanel::default(),
            dragging: false,
            pick: None,
            pick_measures: false,
            slices: Default::default(),
            layers: Default::default(),
            brain: Default::default(),
            identity: Default::default(),
            cine: Default::default(),
        }
    }

    /// Takes a new volume's analysis: windows from the current preset (custom windows fall back
    /// to adaptive, since they were made for another volume), other styles kept.
    pub fn adopt_volume(&mut self, report: TissueReport, histogram: [u32; 256], extent_mm: f64) {
        self.report = Some(report);
        self.histogram = Some(histogram);
        self.extent_mm = extent_mm;
        if self.windows == WindowSource::Custom {
            self.windows = WindowSource::Adaptive;
        }
        self.apply_window_source();
        if let Some(r) = &self.report {
            self.scene.minip_floor = r.background_threshold as f32;
        }
    }

    fn apply_window_source(&mut self) {
        let Some(report) = &self.report else { return };
        let windows = match self.windows {
            WindowSource::Paper => &report.paper_windows,
            _ => &report.adaptive_windows,
        };
        let fresh = Classification::from_tissue_windows(windows);
        for t in TissueClass::ALL {
            self.scene.classification.style_mut(t).window = fresh.style(t).window;
        }
    }

    /// Switches a tissue on or off.
    pub fn toggle(&mut self, tissue: TissueClass) {
        let style = self.scene.classification.style_mut(tissue);
        style.visible = !style.visible;
    }

    /// Sets a tissue's visibility.
    pub fn set_visible(&mut self, tissue: TissueClass, visible: bool) {
        self.scene.classification.style_mut(tissue).visible = visible;
    }

    /// Sets a tissue's window bounds (keeping its edge softness).
    pub fn set_window(&mut self, tissue: TissueClass, lo: f64, hi: f64) {
        self.scene.classification.set_window(tissue, lo, hi);
        self.windows = WindowSource::Custom;
    }

    /// Sets a tissue's opacity.
    pub fn set_opacity(&mut self, tissue: TissueClass, opacity: f32) {
        self.scene.classification.style_mut(tissue).opacity = opacity.clamp(0.0, 1.0);
    }

    /// Sets a tissue's colour.
    pub fn set_colour(&mut self, tissue: TissueClass, colour: [f32; 3]) {
        self.scene.classification.style_mut(tissue).colour = colour;
    }

    /// Applies a window preset.
    pub fn preset(&mut self, preset: Preset) {
        match preset {
            Preset::Adaptive => self.windows = WindowSource::Adaptive,
            Preset::Paper => self.windows = WindowSource::Paper,
            Preset::Reset => {
                self.windows = WindowSource::Adaptive;
                if let Some(report) = &self.report {
                    // The head layer's window is the volume's (above its background).
                    let head = self.scene.classification.head.window;
                    self.scene.classification =
                        Classification::from_tissue_windows(&report.adaptive_windows);
                    self.scene.classification.head.window = head;
                }
            }
        }
        self.apply_window_source();
    }

    /// Selects a standard view.
    pub fn view(&mut self, view: StandardView) {
        self.camera.set_view(&mut self.scene.camera, view);
    }

    /// Orbits by degrees.
    pub fn orbit_degrees(&mut self, azimuth: f64, elevation: f64) {
        let c = CameraController {
            degrees_per_pixel: 1.0,
            ..self.camera
        };
        c.orbit(&mut self.scene.camera, [azimuth, elevation]);
    }

    /// Sets the rendering mode.
    pub fn set_mode(&mut self, mode: RenderMode) {
        self.scene.effects.mode = mode;
    }

    /// Opens the file dialog for opening a volume.
    pub fn open_dialog(&mut self) {
        self.files.open_dialog();
    }
}

/// What one frame of the interface produced.
#[derive(Debug)]
pub struct Outcome {
    /// The 3D view's rectangle in points.
    pub view: Rect,
    /// The histogram widget's rectangle in points (None when not shown).
    pub histogram: Option<Rect>,
    /// Requests for the viewer.
    pub requests: Vec<Request>,
}

/// Frame-specific facts the interface shows.
pub struct Shown<'a> {
    /// Status line content.
    pub status: &'a Status,
    /// True once a volume is on screen.
    pub has_volume: bool,
    /// The volume on screen has a single intensity (its normalization is constant).
    pub constant_volume: bool,
}

/// The message drawn over a view that can only show the background (never a silent empty
/// image), with what to try in this interface; None when something can show.
pub fn empty_view_message(scene: &Scene, constant_volume: bool) -> Option<String> {
    let why = predict_empty(scene, constant_volume)?;
    let hint = match &why {
        EmptyScene::ConstantVolume => "Open another file",
        EmptyScene::AllHidden => "Switch a tissue on in the panel",
        EmptyScene::NoWindow(_) => "Drag a band in the histogram, or press Paper",
        EmptyScene::ZeroOpacity(_) => "Raise an opacity in the panel",
        EmptyScene::NothingSampled => "Move a band in the histogram",
    };
    Some(format!("Nothing to show: {}. {hint}.", why.reason()))
}

/// Draws the whole interface for one frame.
pub fn draw(ui: &mut Ui, controls: &mut Controls, shown: &Shown) -> Outcome {
    let mut requests = Vec::new();
    let mut histogram_rect = None;
    let identity_before = controls.identity;
    let ctx = ui.ctx().clone();

    egui::Panel::bottom("status")
        .resizable(false)
        .show(ui, |ui| super::status_bar::status_bar(ui, shown.status));

    egui::Panel::left("tools")
        .resizable(false)
        .exact_size(PANEL_WIDTH)
        .show(ui, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| {
                super::cine_panel::panel(ui, &mut controls.cine, &mut requests);
                histogram_rect = tissue_panel(ui, controls);
                ui.separator();
                rendering_panel(ui, controls);
                super::clip_panel::clip_panel(ui, &mut controls.scene, controls.extent_mm);
                super::slices_panel::label_panel(ui, &mut controls.slices);
                super::layers_panel::section(ui, controls);
                ui.collapsing("Measure", |ui| {
                    let asked = super::measure_panel::panel(ui, &mut controls.slices.measures);
                    if asked.is_some() {
                        controls.files.export_measures_dialog();
                    }
                });
                ui.separator();
                camera_panel(ui, controls);
                ui.separator();
                controls.files.draw(ui, &mut requests);
            });
        });

    super::slices_panel::show(ui, &mut controls.slices);
    let view = egui::CentralPanel::no_frame()
        .show(ui, |ui| {
            let rect = ui.max_rect();
            super::view_area::view_input(ui, rect, controls);
            super::view_area::view_overlays(ui, rect, controls, shown);
            super::crosshair_3d::decorate_view(ui, rect, controls, shown.has_volume);
            rect
        })
        .inner;

    // The file dialog floats over everything; then files dropped onto the window.
    controls.files.after_panels(&ctx, &mut requests);
    if controls.identity != identity_before {
        requests.push(Request::Identity(controls.identity));
    }
    Outcome {
        view,
        histogram: histogram_rect,
        requests,
    }
}

fn tissue_panel(ui: &mut Ui, controls: &mut Controls) -> Option<Rect> {
    ui.heading("Tissues");
    let mut rect = None;
    if let Some(hist) = controls.histogram {
        let top = ui.cursor().min;
        if histogram::show(
            ui,
            &hist,
            controls.report.as_ref(),
            &mut controls.scene.classification,
        ) {
            controls.windows = WindowSource::Custom;
        }
        rect = Some(Rect::from_min_size(
            top,
            vec2(ui.available_width(), histogram::Layout::height()),
        ));
        ui.label(
            RichText::new(format!(
                "{}, counts on a log scale; drag a band or its edges",
                axis_text(controls.report.as_ref())
            ))
            .small()
            .weak(),
        );
    } else {
        ui.label(RichText::new("Histogram appears when a volume is loaded").weak());
    }
    let names = [
        (TissueClass::Csf, "CSF"),
        (TissueClass::Gm, "Grey matter"),
        (TissueClass::Wm, "White matter"),
        (TissueClass::Pathology, "Pathology / contrast"),
    ];
    ui.spacing_mut().slider_width = 64.0;
    egui::Grid::new("tissues").num_columns(4).show(ui, |ui| {
        for (tissue, name) in names {
            let style = controls.scene.classification.style_mut(tissue);
            ui.checkbox(&mut style.visible, name)
                .on_hover_text("Show or hide this tissue (only uniforms change)");
            ui.color_edit_button_rgb(&mut style.colour);
            ui.add(egui::Slider::new(&mut style.opacity, 0.0..=1.0).show_value(false))
                .on_hover_text("Opacity per millimetre of ray");
            match style.window {
                Some(w) => ui
                    .label(RichText::new(window_text(w, controls.report.as_ref())).small())
                    .on_hover_text(format!("I_norm {:.3}-{:.3}", w.lo, w.hi.min(1.0))),
                None => ui.label(RichText::new("not found").small().weak()),
            };
            ui.end_row();
        }
    });
    super::vessels_panel::vessel_row(ui, &mut controls.scene);
    super::brain_panel::brain_rows(ui, &mut controls.scene, &controls.brain);
    ui.horizontal(|ui| {
        ui.label("Windows:");
        let source = controls.windows;
        if ui
            .selectable_label(source == WindowSource::Adaptive, "Adaptive")
            .on_hover_text("Placed around the CSF/GM/WM peaks of this volume")
            .clicked()
        {
            controls.preset(Preset::Adaptive);
        }
        if ui
            .selectable_label(source == WindowSource::Paper, "Paper (T1)")
            .on_hover_text(
                "The paper's fixed T1 constants (CSF 0.05-0.12, GM 0.12-0.18, WM > 0.18); \
                 wrong tissues on a T2 volume",
            )
            .clicked()
        {
            controls.preset(Preset::Paper);
        }
        if ui
            .button("Reset")
            .on_hover_text("Adaptive windows with default colours and opacities")
            .clicked()
        {
            controls.preset(Preset::Reset);
        }
    });
    contrast_label(ui, controls);
    super::identity_panel::identity_rows(ui, &mut controls.identity, controls.report.as_ref());
    rect
}

/// The scanner's units of `report`'s volume: `HU` for a CT in Hounsfield units, none otherwise.
fn units(report: &TissueReport) -> &'static str {
    if crate::scene::preset::values_are_hu(report) {
        " HU"
    } else {
        ""
    }
}

/// The histogram's axis in the scanner's units (I_norm 0..1 maps `imin..imax`).
fn axis_text(report: Option<&TissueReport>) -> String {
    match report {
        Some(r) if r.imax > r.imin => {
            format!("{:.0} -> {:.0}{}", r.imin, r.imax, units(r))
        }
        _ => "I_norm 0 -> 1".to_string(),
    }
}

/// A tissue window in the scanner's units (the table's column; I_norm on hover).
fn window_text(w: crate::scene::Window, report: Option<&TissueReport>) -> String {
    match report {
        Some(r) if r.imax > r.imin => {
            let raw = |v: f64| r.imin + v.min(1.0) * (r.imax - r.imin);
            format!("{:.0}-{:.0}{}", raw(w.lo), raw(w.hi), units(r))
        }
        _ => format!("{:.2}-{:.2}", w.lo, w.hi.min(1.0)),
    }
}

/// The contrast the tissues were labelled for, its reason on hover, and a warning when the
/// paper's T1 windows are applied to a volume labelled T2.
fn contrast_label(ui: &mut Ui, controls: &Controls) {
    let Some(report) = &controls.report else {
        return;
    };
    let c = &report.contrast;
    let m = &report.modality;
    let text = format!("{}: {} ({})", m.modality.name(), c.label(), c.basis.name());
    ui.label(RichText::new(text).small()).on_hover_text(format!(
        "{}\n{}",
        m.summary(),
        c.summary()
    ));
    if !c.contrast.is_t1_order() && controls.windows == WindowSource::Paper {
        ui.label(
            RichText::new(format!(
                "Paper windows are T1 windows: wrong tissues on this {} volume",
                c.contrast.name()
            ))
            .small()
            .color(Color32::YELLOW),
        );
    }
}

fn rendering_panel(ui: &mut Ui, controls: &mut Controls) {
    ui.heading("Rendering");
    let scene = &mut controls.scene;
    ui.horizontal(|ui| {
        ui.selectable_value(&mut scene.effects.mode, RenderMode::Dvr, "DVR")
            .on_hover_text("Tissue rendering (the paper's composite)");
        ui.selectable_value(&mut scene.effects.mode, RenderMode::Mip, "MIP")
            .on_hover_text("Maximum intensity projection");
        ui.selectable_value(&mut scene.effects.mode, RenderMode::MinIp, "MinIP")
            .on_hover_text("Minimum intensity projection");
    });
    ui.add(
        egui::Slider::new(&mut scene.step_voxels, 0.25..=2.0)
            .logarithmic(true)
            .text("ray step (voxels)"),
    )
    .on_hover_text("Smaller is finer and slower");
    ui.horizontal(|ui| {
        ui.checkbox(&mut scene.effects.curvature, "Curvature")
            .on_hover_text("Emphasize folded structures (computes the Hessian once)");
        ui.add_enabled(
            scene.effects.curvature,
            egui::Slider::new(&mut scene.curvature_strength, 0.0..=4.0).text("strength"),
        );
    });
    ui.checkbox(&mut scene.effects.shading, "Shading")
        .on_hover_text("Phong shading with gradient normals (computes normals once)");
    lighting_controls(ui, scene);
    ui.horizontal(|ui| {
        ui.label("Background");
        ui.color_edit_button_rgb(&mut scene.background);
    });
}

/// Lighting model, depth cues and the cut-away (issue 34); `render`'s stills use studio + cues.
fn lighting_controls(ui: &mut Ui, scene: &mut Scene) {
    let model = &mut scene.effects.lighting.model;
    ui.add_enabled_ui(scene.effects.shading, |ui| {
        ui.horizontal(|ui| {
            ui.selectable_value(model, LightModel::Headlight, "Headlight")
                .on_hover_text("The light at the eye: the cheapest (the paper's look)");
            ui.selectable_value(model, LightModel::Studio, "Studio")
                .on_hover_text(
                    "Key light from the upper left, highlight, outlines (the stills' look)",
                );
            ui.selectable_value(model, LightModel::Matcap, "Matcap")
                .on_hover_text("The colour times a matcap image (view --matcap; clay by default)");
        });
    });
    ui.checkbox(&mut scene.effects.lighting.depth_cues, "Depth cues")
        .on_hover_text(
            "Ambient occlusion and a soft shadow at the visible surface (14 fetches per pixel)",
        );
    let mut open = scene.cutaway.is_some();
    if ui
        .checkbox(&mut open, "Open the brain")
        .on_hover_text(
            "Cut away the side facing the camera through the crosshair; the cut face shows the \
             tissues solid (turn the view to an oblique angle)",
        )
        .changed()
    {
        scene.cutaway = open.then(Cutaway::default);
    }
}

fn camera_panel(ui: &mut Ui, controls: &mut Controls) {
    ui.heading("View");
    ui.horizontal(|ui| {
        for view in StandardView::ALL {
            if ui
                .button(view.letter().to_string())
                .on_hover_text(format!("View from {} (key {})", view.name(), view.letter()))
                .clicked()
            {
                controls.view(view);
            }
        }
        if ui
            .button("Reset")
            .on_hover_text("Double-click the view")
            .clicked()
        {
            controls.camera.reset(&mut controls.scene.camera);
        }
    });
    ui.label(
        RichText::new("Left-drag orbit, right/shift-drag pan, wheel zoom")
            .small()
            .weak(),
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Camera, Window};
    use egui::Pos2;

    fn controls() -> Controls {
        let w = |lo, hi| Some(Window { lo, hi, edge: 0.01 });
        Controls::new(Scene::new(Classification::with_windows([
            w(0.1, 0.2),
            w(0.3, 0.5),
            w(0.6, 0.8),
            w(0.85, 1.01),
        ])))
    }

    fn run(ctx: &egui::Context, controls: &mut Controls, events: Vec<egui::Event>) -> Outcome {
        let status = Status::default();
        let shown = Shown {
            status: &status,
            has_volume: true,
            constant_volume: false,
        };
        let input = egui::RawInput {
            screen_rect: Some(Rect::from_min_size(Pos2::ZERO, vec2(900.0, 600.0))),
            events,
            ..Default::default()
        };
        let mut outcome = None;
        ctx.run_ui(input, |ui| outcome = Some(draw(ui, controls, &shown)))
            .drop_without_applying_deltas();
        outcome.unwrap()
    }

    #[test]
    fn dragging_on_the_view_orbits_and_keys_select_views() {
        let ctx = egui::Context::default();
        let mut c = controls();
        let view = run(&ctx, &mut c, vec![]).view;
        assert!(
            view.left() >= PANEL_WIDTH,
            "the view is right of the panel: {view:?}"
        );
        let start = view.center();
        let press = |pos, pressed| egui::Event::PointerButton {
            pos,
            button: egui::PointerButton::Primary,
            pressed,
            modifiers: Default::default(),
        };
        run(&ctx, &mut c, vec![egui::Event::PointerMoved(start)]);
        run(&ctx, &mut c, vec![press(start, true)]);
        run(
            &ctx,
            &mut c,
            vec![egui::Event::PointerMoved(start + vec2(20.0, 0.0))],
        );
        run(
            &ctx,
            &mut c,
            vec![egui::Event::PointerMoved(start + vec2(50.0, 0.0))],
        );
        run(&ctx, &mut c, vec![press(start + vec2(50.0, 0.0), false)]);
        // Only the motion after the drag threshold counts; it is at least the last 30 px.
        assert!(
            c.scene.camera.azimuth_deg >= 30.0 * 0.4 - 1e-9
                && c.scene.camera.azimuth_deg <= 50.0 * 0.4 + 1e-9,
            "azimuth {}",
            c.scene.camera.azimuth_deg
        );
        assert_eq!(c.scene.camera.elevation_deg, 0.0);
        let key = |key| egui::Event::Key {
            key,
            physical_key: None,
            pressed: true,
            repeat: false,
            modifiers: Default::default(),
        };
        run(&ctx, &mut c, vec![key(egui::Key::S)]);
        assert_eq!(c.scene.camera.elevation_deg, 90.0);
        run(&ctx, &mut c, vec![key(egui::Key::L)]);
        assert_eq!(
            (c.scene.camera.azimuth_deg, c.scene.camera.elevation_deg),
            (-90.0, 0.0)
        );
        // Double-click resets.
        let p = view.center();
        run(
            &ctx,
            &mut c,
            vec![
                press(p, true),
                press(p, false),
                press(p, true),
                press(p, false),
            ],
        );
        assert_eq!(c.scene.camera, Camera::default());
    }

    #[test]
    fn toggles_presets_and_window_edits_change_the_scene_only() {
        let mut c = controls();
        let before = c.scene;
        c.toggle(TissueClass::Wm);
        assert!(!c.scene.classification.style(TissueClass::Wm).visible);
        c.toggle(TissueClass::Wm);
        assert_eq!(c.scene, before);
        c.set_window(TissueClass::Wm, 0.7, 0.9);
        let wm = c
            .scene
            .classification
            .style(TissueClass::Wm)
            .window
            .unwrap();
        assert_eq!((wm.lo, wm.hi, wm.edge), (0.7, 0.9, 0.01));
        assert_eq!(c.windows, WindowSource::Custom);
        // The effects (what selects passes) never change with these edits.
        assert_eq!(c.scene.effects, before.effects);
    }
}
