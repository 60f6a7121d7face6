//! The slice panels beside the 3D view: layouts, the crosshair linked across the three slices
//! and into the 3D view, scroll to move a slice, window/level drag, the radiological /
//! neurological switch and the orientation letters.
//!
//! Decisions:
//! - Layouts: 3D only, 3D + the three slices (a column at the right), or one slice large (the
//!   slice takes most of the width, the 3D view stays small at the left, so the crosshair is
//!   always visible in both). Switched from the buttons over the view, by the key V (as in
//!   NiiVue) and by the script step `layout 3d|slices|axial|coronal|sagittal`.
//! - The crosshair is ONE world point (RAS mm): each slice shows the plane through it, a click
//!   or primary drag on a slice moves it within that plane, scrolling moves it along the
//!   slice's normal one pixel (the finest voxel spacing) per notch. So the three slices and the
//!   3D marker can never disagree.
//! - Secondary drag on a slice is window/level in I_norm units: right widens, up brightens
//!   (lower level), as in most DICOM viewers.
//! - The slices are sampled on the GPU from the volume's own I_norm image (`engine::slice`),
//!   read back and shown as egui textures; they are rendered again only when what they show
//!   changes (`SliceControls::wanted` against the last rendered key), not every frame.
//! - Everything here is interface state and drawing; the GPU work is in `viewer/slices.rs`.

use crate::scene::VolumeGeometry;
use crate::scene::slice::{Convention, Plane, SliceGrid, centre_position, edge_letters};
use egui::{Color32, Pos2, Rect, Ui, vec2};
use glam::DVec3;

/// How the central area is shared between the 3D view and the slices.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Layout {
    /// The 3D view alone.
    #[default]
    ThreeD,
    /// The 3D view and the three slices in a column: `morphray view`'s first view (as in
    /// FSLeyes, NiiVue and MRIcroGL; issue 31 item 7), with the crosshair's readout below.
    ThreeDAndSlices,
    /// One slice large beside a small 3D view.
    One(Plane),
}

impl Layout {
    /// The word the script and the log use.
    pub fn name(self) -> &'static str {
        match self {
            Layout::ThreeD => "3d",
            Layout::ThreeDAndSlices => "slices",
            Layout::One(p) => p.name(),
        }
    }

    /// Parses [`Layout::name`].
    pub fn parse(word: &str) -> Option<Layout> {
        Some(match word {
            "3d" => Layout::ThreeD,
            "slices" => Layout::ThreeDAndSlices,
            "axial" => Layout::One(Plane::Axial),
            "coronal" => Layout::One(Plane::Coronal),
            "sagittal" => Layout::One(Plane::Sagittal),
            _ => return None,
        })
    }

    /// The next layout in the cycle the V key walks.
    pub fn next(self) -> Layout {
        match self {
            Layout::ThreeD => Layout::ThreeDAndSlices,
            Layout::ThreeDAndSlices => Layout::One(Plane::Axial),
            Layout::One(Plane::Axial) => Layout::One(Plane::Coronal),
            Layout::One(Plane::Coronal) => Layout::One(Plane::Sagittal),
            Layout::One(Plane::Sagittal) => Layout::ThreeD,
        }
    }

    /// The planes shown.
    pub fn planes(self) -> Vec<Plane> {
        match self {
            Layout::ThreeD => Vec::new(),
            Layout::ThreeDAndSlices => Plane::ALL.to_vec(),
            Layout::One(p) => vec![p],
        }
    }
}

/// One rendered slice on screen.
pub struct ShownSlice {
    /// Its pixel grid.
    pub grid: SliceGrid,
    /// Its texture.
    pub texture: egui::TextureHandle,
}

/// The slices' interface state.
#[derive(Default)]
pub struct SliceControls {
    /// The layout.
    pub layout: Layout,
    /// Which side the patient's right is drawn on.
    pub convention: Convention,
    /// The crosshair (world mm); None before a volume.
    pub crosshair: Option<DVec3>,
    /// Grey window in I_norm (black, white).
    pub window: (f64, f64),
    /// The volume's geometry (set by the viewer for each volume).
    pub geometry: Option<VolumeGeometry>,
    /// What is on screen now, per plane (axial, coronal, sagittal).
    pub shown: [Option<ShownSlice>; 3],
    /// Where each plane's image was drawn in the last frame (points).
    pub rects: [Option<Rect>; 3],
    /// The id of the volume the geometry belongs to (0: none).
    pub volume: u64,
    /// The window the slices on screen were rendered with.
    pub rendered_window: (f64, f64),
    /// The label overlay on this volume's grid, if one was given.
    pub overlay: Option<SliceOverlay>,
    /// Labels switched off.
    pub hidden: std::collections::BTreeSet<u16>,
    /// What the slices show changed without their grids changing (a label toggle, the overlay
    /// opacity): render them again.
    pub dirty: bool,
    /// Leave the label overlay out of the 3D view (it is drawn there by default).
    pub labels_not_in_3d: bool,
    /// Grows with every change of the labels' switches or opacity, so the 3D view renders
    /// again (its scene is unchanged).
    pub overlay_revision: u64,
    /// The brain mask in use, outlined on the slices (`brain_outline.rs`); None when the
    /// picture uses no mask. The viewer sets it and marks the slices dirty when it changes.
    pub brain: Option<std::sync::Arc<super::brain_outline::BrainOutline>>,
    /// The file's units for the window's numbers: the physical values of I_norm 0 and 1, and
    /// `HU` for a CT (set by the viewer for each volume); None: I_norm.
    pub units: Option<(f64, f64, &'static str)>,
    /// The crosshair's readout (`app::readout`), drawn under the slices.
    pub readout: Option<String>,
    /// Distances, angles and regions, drawn on the slices and in 3D (`measure_panel.rs`).
    pub measures: super::measure_panel::Measures,
}

impl SliceControls {
    /// The grey window in the file's units (`window 40..400 HU`), I_norm without them.
    pub fn window_text(&self) -> String {
        let (lo, hi) = self.window;
        match self.units {
            Some((imin, imax, unit)) => {
                let raw = |v: f64| in_units(v, imin, imax);
                let unit = if unit.is_empty() {
                    String::new()
                } else {
                    format!(" {unit}")
                };
                format!("window {}..{}{unit}", raw(lo), raw(hi))
            }
            None => format!("window {lo:.2}..{hi:.2} (I_norm)"),
        }
    }
}

impl SliceControls {
    /// The grey window's low and high ends as the grey bar labels them: the file's units with
    /// their name (`40 HU`), or I_norm.
    pub fn window_ends(&self) -> (String, String) {
        let (lo, hi) = self.window;
        super::colour_bar::end_labels([lo, hi], self.units)
    }
}

/// I_norm `v` in the file's units (I_norm 0 and 1 are `imin` and `imax`): whole numbers over a
/// range of 100 and more (HU, most MR), else 2 or 4 decimals. The slices' window and the colour
/// bar read values this way.
pub fn in_units(v: f64, imin: f64, imax: f64) -> String {
    let span = (imax - imin).abs();
    let decimals = if span >= 100.0 {
        0
    } else if span >= 1.0 {
        2
    } else {
        4
    };
    format!("{:.*}", decimals, imin + v * (imax - imin))
}

/// A label overlay resampled onto the volume's grid, with its colours.
pub struct SliceOverlay {
    /// One label per volume voxel.
    pub labels: crate::scene::overlay::Labels,
    /// Colours.
    pub table: crate::scene::overlay::LabelTable,
    /// Overall opacity.
    pub opacity: f64,
    /// Non-zero labels present (for the toggles).
    pub present: Vec<u16>,
}

fn slot(plane: Plane) -> usize {
    match plane {
        Plane::Axial => 0,
        Plane::Coronal => 1,
        Plane::Sagittal => 2,
    }
}

impl SliceControls {
    /// The 3D view's label colour table (`engine::label_colours`), or None when no overlay is
    /// drawn in 3D.
    pub fn label_colours_3d(&self) -> Option<Vec<u32>> {
        let overlay = self.overlay.as_ref().filter(|_| !self.labels_not_in_3d)?;
        Some(crate::engine::label_colours(
            &overlay.table,
            &overlay.present,
            overlay.opacity,
            &self.hidden,
        ))
    }

    /// Starts a new volume: its geometry, the crosshair at its centre, the full window.
    pub fn set_volume(&mut self, id: u64, geometry: VolumeGeometry) {
        self.volume = id;
        let centre = DVec3::new(
            centre_position(&geometry, Plane::Sagittal),
            centre_position(&geometry, Plane::Coronal),
            centre_position(&geometry, Plane::Axial),
        );
        self.crosshair = Some(centre);
        self.geometry = Some(geometry);
        self.window = (0.0, 1.0);
        self.shown = Default::default();
    }

    /// The grids the layout needs now (plane, grid); empty without a volume.
    pub fn wanted(&self) -> Vec<SliceGrid> {
        let (Some(geometry), Some(cross)) = (&self.geometry, self.crosshair) else {
            return Vec::new();
        };
        self.layout
            .planes()
            .into_iter()
            .filter_map(|plane| {
                let position = cross[plane.normal_axis()];
                SliceGrid::new(
                    geometry,
                    plane,
                    self.convention,
                    position,
                    geometry.voxel_mm,
                )
                .ok()
            })
            .collect()
    }

    /// True when the slices on screen are not those [`SliceControls::wanted`] describes.
    pub fn stale(&self, wanted: &[SliceGrid]) -> bool {
        self.dirty
            || self.window != self.rendered_window
            || wanted.iter().any(|g| {
                self.shown[slot(g.plane)]
                    .as_ref()
                    .is_none_or(|s| s.grid != *g)
            })
    }

    /// Installs a rendered slice.
    pub fn install(&mut self, grid: SliceGrid, texture: egui::TextureHandle) {
        self.shown[slot(grid.plane)] = Some(ShownSlice { grid, texture });
    }

    /// Moves the crosshair along `plane`'s normal by `steps` pixels, within the volume.
    pub fn scroll(&mut self, plane: Plane, steps: f64) {
        let (Some(geometry), Some(cross)) = (&self.geometry, &mut self.crosshair) else {
            return;
        };
        let axis = plane.normal_axis();
        let (lo, hi) = geometry.world_bounds();
        cross[axis] = (cross[axis] + steps * geometry.voxel_mm).clamp(lo[axis], hi[axis]);
    }

    /// Window/level drag: `dx` widens, `dy` (down) darkens, in fractions of the panel.
    pub fn window_level(&mut self, dx: f64, dy: f64) {
        let (lo, hi) = self.window;
        let width = ((hi - lo) * (1.0 + dx)).clamp(0.01, 2.0);
        let level = (lo + hi) / 2.0 + dy * 0.5;
        self.window = (level - width / 2.0, level + width / 2.0);
    }
}

/// Where a `w` x `h` image is drawn inside `area`: centred, square pixels, as large as fits.
pub fn fit(area: Rect, w: u32, h: u32) -> Rect {
    let scale = (area.width() / w as f32)
        .min(area.height() / h as f32)
        .max(0.0);
    Rect::from_center_size(area.center(), vec2(w as f32 * scale, h as f32 * scale))
}

/// The layout buttons over the view, the key V, and the slice column when the layout has one.
pub fn show(ui: &mut Ui, slices: &mut SliceControls) {
    let ctx = ui.ctx().clone();
    if !ctx.egui_wants_keyboard_input() && ctx.input(|i| i.key_pressed(egui::Key::V)) {
        slices.layout = slices.layout.next();
    }
    if slices.layout == Layout::ThreeD {
        return;
    }
    let fraction = match slices.layout {
        Layout::One(_) => 0.62,
        _ => 0.34,
    };
    let width = (ui.available_width() * fraction).max(120.0);
    egui::Panel::right("slices")
        .resizable(false)
        .exact_size(width)
        .show(ui, |ui| slice_column(ui, slices));
}

fn slice_column(ui: &mut Ui, slices: &mut SliceControls) {
    ui.horizontal(|ui| {
        for convention in [Convention::Radiological, Convention::Neurological] {
            ui.selectable_value(&mut slices.convention, convention, convention.name());
        }
    });
    ui.label(
        egui::RichText::new(format!(
            "{} (right-drag); click: crosshair; scroll: move",
            slices.window_text()
        ))
        .small()
        .weak(),
    );
    grey_bar(ui, slices);
    if let Some(readout) = &slices.readout {
        ui.label(egui::RichText::new(readout).small());
    }
    let planes = slices.layout.planes();
    let area = ui.available_rect_before_wrap();
    let each = area.height() / planes.len().max(1) as f32;
    slices.rects = [None; 3];
    for (n, plane) in planes.into_iter().enumerate() {
        let cell = Rect::from_min_size(
            Pos2::new(area.left(), area.top() + n as f32 * each),
            vec2(area.width(), each),
        )
        .shrink(2.0);
        slice_cell(ui, slices, plane, cell);
    }
    ui.allocate_rect(area, egui::Sense::hover());
}

/// The slices' grey scale under the window's numbers (`window_text`): black at its low end to
/// white at its high end, each end's value under it (in the file's units, as `window_text`).
fn grey_bar(ui: &mut Ui, slices: &SliceControls) {
    let (rect, _) = ui.allocate_exact_size(vec2(ui.available_width(), 22.0), egui::Sense::hover());
    let bar = Rect::from_min_max(rect.left_top(), Pos2::new(rect.right(), rect.top() + 10.0));
    let mut mesh = egui::Mesh::default();
    let (top, bottom) = (bar.top(), bar.bottom());
    for (x, grey) in [(bar.left(), 0u8), (bar.right(), 255u8)] {
        let colour = Color32::from_gray(grey);
        mesh.colored_vertex(Pos2::new(x, top), colour);
        mesh.colored_vertex(Pos2::new(x, bottom), colour);
    }
    mesh.add_triangle(0, 1, 2);
    mesh.add_triangle(1, 2, 3);
    let painter = ui.painter();
    painter.add(egui::Shape::mesh(mesh));
    let (lo, hi) = slices.window_ends();
    let font = egui::FontId::proportional(11.0);
    let colour = ui.visuals().weak_text_color();
    painter.text(
        bar.left_bottom(),
        egui::Align2::LEFT_TOP,
        lo,
        font.clone(),
        colour,
    );
    painter.text(
        bar.right_bottom(),
        egui::Align2::RIGHT_TOP,
        hi,
        font,
        colour,
    );
}

/// The label overlay's section of the tools panel (nothing without `--overlay`): whether it is
/// drawn in the 3D view, one switch per label present (the first 32) in the label's colour, and
/// the opacity; the switches apply to the slices and the 3D view alike.
pub fn label_panel(ui: &mut Ui, slices: &mut SliceControls) {
    let Some(overlay) = &mut slices.overlay else {
        return;
    };
    ui.separator();
    ui.heading("Labels");
    let mut in_3d = !slices.labels_not_in_3d;
    let mut changed = ui.checkbox(&mut in_3d, "in 3D").changed();
    slices.labels_not_in_3d = !in_3d;
    ui.horizontal_wrapped(|ui| {
        for &label in overlay.present.iter().take(32) {
            let style = overlay.table.style(label);
            let name = overlay
                .table
                .entries
                .get(&label)
                .map_or_else(|| label.to_string(), |(n, _)| n.clone());
            let [r, g, b] = style.rgb;
            let mut on = !slices.hidden.contains(&label);
            let text = egui::RichText::new(name).color(Color32::from_rgb(r, g, b));
            if ui.checkbox(&mut on, text).changed() {
                if on {
                    slices.hidden.remove(&label);
                } else {
                    slices.hidden.insert(label);
                }
                changed = true;
            }
        }
    });
    let slider = egui::Slider::new(&mut overlay.opacity, 0.0..=1.0).text("label opacity");
    changed |= ui.add(slider).changed();
    slices.dirty |= changed;
    slices.overlay_revision += u64::from(changed);
}

fn slice_cell(ui: &mut Ui, slices: &mut SliceControls, plane: Plane, cell: Rect) {
    let Some(shown) = &slices.shown[slot(plane)] else {
        ui.painter().text(
            cell.center(),
            egui::Align2::CENTER_CENTER,
            plane.name(),
            egui::FontId::proportional(14.0),
            Color32::GRAY,
        );
        return;
    };
    let grid = shown.grid;
    let rect = fit(cell, grid.width, grid.height);
    slices.rects[slot(plane)] = Some(rect);
    let painter = ui.painter_at(cell);
    painter.image(
        shown.texture.id(),
        rect,
        Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0)),
        Color32::WHITE,
    );
    let to_screen = |(x, y): (f64, f64)| {
        Pos2::new(
            rect.left() + ((x + 0.5) / grid.width as f64) as f32 * rect.width(),
            rect.top() + ((y + 0.5) / grid.height as f64) as f32 * rect.height(),
        )
    };
    if let Some(cross) = slices.crosshair {
        let p = to_screen(grid.pixel_of_world(cross));
        let stroke = egui::Stroke::new(1.0, Color32::from_rgb(0, 200, 255));
        painter.line_segment(
            [Pos2::new(rect.left(), p.y), Pos2::new(rect.right(), p.y)],
            stroke,
        );
        painter.line_segment(
            [Pos2::new(p.x, rect.top()), Pos2::new(p.x, rect.bottom())],
            stroke,
        );
    }
    super::measure_panel::draw_marks(
        &painter,
        &slices.measures,
        |w| Some(to_screen(grid.pixel_of_world(w))),
        |w| grid.is_on_plane(w),
    );
    let letters = edge_letters(plane, slices.convention);
    let m = 4.0;
    let places = [
        (
            Pos2::new(rect.left() + m, rect.center().y),
            egui::Align2::LEFT_CENTER,
        ),
        (
            Pos2::new(rect.right() - m, rect.center().y),
            egui::Align2::RIGHT_CENTER,
        ),
        (
            Pos2::new(rect.center().x, rect.top() + m),
            egui::Align2::CENTER_TOP,
        ),
        (
            Pos2::new(rect.center().x, rect.bottom() - m),
            egui::Align2::CENTER_BOTTOM,
        ),
    ];
    for (letter, (pos, align)) in letters.into_iter().zip(places) {
        let font = egui::FontId::proportional(14.0);
        painter.text(pos, align, letter, font, Color32::from_rgb(255, 220, 0));
    }
    let id = ui.id().with(("slice", plane.name()));
    let response = ui.interact(rect, id, egui::Sense::click_and_drag());
    let from_screen = |p: Pos2| {
        let x = ((p.x - rect.left()) / rect.width()) as f64 * grid.width as f64 - 0.5;
        let y = ((p.y - rect.top()) / rect.height()) as f64 * grid.height as f64 - 0.5;
        grid.world_of_pixel(x, y)
    };
    let shift = ui.input(|i| i.modifiers.shift);
    if response.clicked()
        && shift
        && let Some(p) = response.interact_pointer_pos()
    {
        // A measurement point; a failure (a full list) shows in the panel's count.
        let _ = slices.measures.add_point(from_screen(p));
    } else if (response.clicked() || response.dragged_by(egui::PointerButton::Primary))
        && let Some(p) = response.interact_pointer_pos()
    {
        slices.crosshair = Some(from_screen(p));
    }
    if response.dragged_by(egui::PointerButton::Secondary) {
        let d = response.drag_delta();
        slices.window_level((d.x / rect.width()) as f64, (d.y / rect.height()) as f64);
    }
    if response.hovered() {
        let scroll = ui.input(|i| i.smooth_scroll_delta.y);
        if scroll != 0.0 {
            slices.scroll(plane, (scroll / 20.0).round().clamp(-10.0, 10.0) as f64);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts_cycle_through_all_and_parse_their_names() {
        let mut l = Layout::ThreeD;
        let mut seen = Vec::new();
        for _ in 0..5 {
            seen.push(l.name());
            assert_eq!(Layout::parse(l.name()), Some(l));
            l = l.next();
        }
        assert_eq!(l, Layout::ThreeD);
        assert_eq!(seen, ["3d", "slices", "axial", "coronal", "sagittal"]);
    }

    #[test]
    fn the_v_key_cycles_the_layout_and_the_column_leaves_the_view_narrower() {
        let ctx = egui::Context::default();
        let mut s = SliceControls::default();
        let v = egui::Event::Key {
            key: egui::Key::V,
            physical_key: None,
            pressed: true,
            repeat: false,
            modifiers: Default::default(),
        };
        let run = |events: Vec<egui::Event>, s: &mut SliceControls| {
            let input = egui::RawInput {
                screen_rect: Some(Rect::from_min_size(Pos2::ZERO, vec2(900.0, 600.0))),
                events,
                ..Default::default()
            };
            let mut left = None;
            ctx.run_ui(input, |ui| {
                show(ui, s);
                left = Some(ui.available_rect_before_wrap().width());
            })
            .drop_without_applying_deltas();
            left.unwrap()
        };
        let full = run(vec![], &mut s);
        assert_eq!(s.layout, Layout::ThreeD);
        run(vec![v.clone()], &mut s);
        assert_eq!(s.layout, Layout::ThreeDAndSlices);
        let narrower = run(vec![], &mut s);
        assert!(narrower < full * 0.7, "{narrower} of {full}");
        run(vec![v], &mut s);
        assert_eq!(s.layout, Layout::One(Plane::Axial));
    }

    #[test]
    fn a_click_on_a_slice_moves_the_crosshair_and_a_right_drag_sets_the_window() {
        let ctx = egui::Context::default();
        let a = [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let mut s = SliceControls::default();
        s.set_volume(1, VolumeGeometry::new([20, 10, 8], a).unwrap());
        s.layout = Layout::One(Plane::Axial);
        for grid in s.wanted() {
            let image = egui::ColorImage::new([20, 10], vec![Color32::GRAY; 200]);
            let texture = ctx.load_texture("t", image, Default::default());
            s.install(grid, texture);
        }
        let run = |events: Vec<egui::Event>, s: &mut SliceControls| {
            let input = egui::RawInput {
                screen_rect: Some(Rect::from_min_size(Pos2::ZERO, vec2(900.0, 600.0))),
                events,
                ..Default::default()
            };
            ctx.run_ui(input, |ui| show(ui, s))
                .drop_without_applying_deltas();
        };
        run(vec![], &mut s);
        let rect = s.rects[0].expect("the axial slice is drawn");
        // A quarter from the left and the top: radiological, so x is the larger quarter.
        let at = rect.min + vec2(rect.width() * 0.25, rect.height() * 0.25);
        let button = |button, pressed, pos| egui::Event::PointerButton {
            pos,
            button,
            pressed,
            modifiers: Default::default(),
        };
        let primary = egui::PointerButton::Primary;
        run(vec![egui::Event::PointerMoved(at)], &mut s);
        run(vec![button(primary, true, at)], &mut s);
        run(vec![button(primary, false, at)], &mut s);
        let cross = s.crosshair.unwrap();
        // The box spans x -0.5..19.5 and y -0.5..9.5 (mm); z is unchanged (3.5).
        assert!((cross.x - 14.5).abs() < 0.6, "{cross}");
        assert!((cross.y - 7.0).abs() < 0.6, "{cross}");
        assert_eq!(cross.z, 3.5);
        let secondary = egui::PointerButton::Secondary;
        let to = at + vec2(rect.width() * 0.5, 0.0);
        run(vec![button(secondary, true, at)], &mut s);
        for step in 1..=5 {
            let p = at + (to - at) * (step as f32 / 5.0);
            run(vec![egui::Event::PointerMoved(p)], &mut s);
        }
        run(vec![button(secondary, false, to)], &mut s);
        let width = s.window.1 - s.window.0;
        assert!(
            width > 1.2,
            "right-drag to the right widens the window: {:?}",
            s.window
        );
        assert_eq!(
            s.crosshair.unwrap(),
            cross,
            "a right-drag does not move the crosshair"
        );
    }

    #[test]
    fn the_window_reads_in_the_files_units() {
        let mut s = SliceControls {
            window: (0.25, 0.5),
            ..Default::default()
        };
        assert_eq!(s.window_text(), "window 0.25..0.50 (I_norm)");
        s.units = Some((-1000.0, 3000.0, "HU"));
        assert_eq!(s.window_text(), "window 0..1000 HU");
        s.units = Some((0.0, 1.0, ""));
        assert_eq!(s.window_text(), "window 0.25..0.50");
        s.units = Some((-1009.6207, 1409.8882, "HU"));
        assert_eq!(s.window_text(), "window -405..200 HU");
    }

    #[test]
    fn scrolling_and_window_level_stay_in_range() {
        let a = [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let mut s = SliceControls::default();
        s.set_volume(1, VolumeGeometry::new([10, 10, 10], a).unwrap());
        assert_eq!(s.crosshair, Some(DVec3::splat(4.5)));
        s.scroll(Plane::Axial, 2.0);
        assert_eq!(s.crosshair.unwrap().z, 6.5);
        s.scroll(Plane::Axial, 100.0);
        assert_eq!(s.crosshair.unwrap().z, 9.5);
        s.window_level(1.0, 0.0);
        assert!((s.window.1 - s.window.0 - 2.0).abs() < 1e-12);
        s.layout = Layout::ThreeDAndSlices;
        assert_eq!(s.wanted().len(), 3);
    }
}
