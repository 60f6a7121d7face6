//! The file panel: Open..., Open folder..., Phantom, Save PNG..., Save 3D view..., Save scene...,
//! the series picker of a DICOM input, and files dropped on the window.
//!
//! Decisions:
//! - What to open is a [`VolumeSource`], as for every other client of the library: a dropped
//!   folder or file is one source, several files dropped together are one (a DICOM series as a
//!   file manager drags it), so the viewer reads exactly what `morphray render` would.
//! - The series picker lists every stack of the DICOM input on screen (the `--series` indices
//!   of `morphray info`), marks the one shown and greys out those that cannot be a volume (a
//!   localizer of one slice can still be chosen: opening it says why it is not a volume, in the
//!   status line, as `--series` would). Choosing one asks the viewer to open the same source
//!   with that series; nothing is read here.

use super::ui::Request;
use crate::volume::source::{SeriesListing, VolumeSource};
use egui::Ui;
use std::path::PathBuf;

/// The file dialog and the series of the volume on screen.
pub struct FilePanel {
    dialog: egui_file_dialog::FileDialog,
    purpose: Purpose,
    /// The series of the DICOM input on screen (None for other inputs).
    pub series: Option<SeriesListing>,
    /// Size "Save 3D view..." renders at (width, height in pixels).
    pub view_size: [u32; 2],
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Purpose {
    Open,
    Save,
    SaveView,
    SaveScene,
    ExportMeasures,
    AddLayer,
    AddLabels,
}

impl Default for FilePanel {
    fn default() -> Self {
        FilePanel {
            dialog: egui_file_dialog::FileDialog::new()
                .title("Open a NIfTI volume or a DICOM file")
                .add_file_filter_extensions("NIfTI", vec!["nii", "gz", "hdr"])
                .add_file_filter_extensions("DICOM", vec!["dcm", "dicom", "ima"]),
            purpose: Purpose::Open,
            series: None,
            view_size: [2048, 2048],
        }
    }
}

impl FilePanel {
    /// Opens the file dialog for opening a volume.
    pub fn open_dialog(&mut self) {
        self.purpose = Purpose::Open;
        self.dialog.pick_file();
    }

    /// Opens the file dialog for a layer over the volume (Add layer...).
    pub fn add_layer_dialog(&mut self) {
        self.purpose = Purpose::AddLayer;
        self.dialog.pick_file();
    }

    /// Opens the file dialog for a label map over the volume (Add labels...).
    pub fn add_labels_dialog(&mut self) {
        self.purpose = Purpose::AddLabels;
        self.dialog.pick_file();
    }

    /// Opens the file dialog for exporting the measurements (.csv or .json).
    pub fn export_measures_dialog(&mut self) {
        self.purpose = Purpose::ExportMeasures;
        self.dialog.save_file();
    }

    /// True while the file dialog is open.
    pub fn dialog_is_open(&self) -> bool {
        *self.dialog.state() == egui_file_dialog::DialogState::Open
    }

    /// The panel's buttons and, for a DICOM input of several series, the series picker.
    pub fn draw(&mut self, ui: &mut Ui, requests: &mut Vec<Request>) {
        ui.horizontal(|ui| {
            if ui
                .button("Open...")
                .on_hover_text("A NIfTI or DICOM file; or drop files or a folder on the window")
                .clicked()
            {
                self.open_dialog();
            }
            if ui
                .button("Open folder...")
                .on_hover_text("A DICOM exam: its largest 3-D series (or drop the folder)")
                .clicked()
            {
                self.purpose = Purpose::Open;
                self.dialog.pick_directory();
            }
            if ui.button("Phantom").clicked() {
                requests.push(Request::Open(VolumeSource::from_paths(&[])));
            }
            if ui
                .button("Save PNG...")
                .on_hover_text("The window, with provenance")
                .clicked()
            {
                self.purpose = Purpose::Save;
                self.dialog.save_file();
            }
        });
        ui.horizontal(|ui| {
            if ui
                .button("Save 3D view...")
                .on_hover_text("The volume alone, without the panels, rendered at this size")
                .clicked()
            {
                self.purpose = Purpose::SaveView;
                self.dialog.save_file();
            }
            if ui
                .button("Save scene...")
                .on_hover_text(
                    "The scene as a .json document (camera, tissues, windows, colours, clip, \
                     layout): view --scene or render --scene opens it again",
                )
                .clicked()
            {
                self.purpose = Purpose::SaveScene;
                self.dialog.save_file();
            }
            let max = super::viewer::MAX_VIEW_SIDE;
            ui.add(egui::DragValue::new(&mut self.view_size[0]).range(1..=max));
            ui.label("x");
            ui.add(egui::DragValue::new(&mut self.view_size[1]).range(1..=max));
        });
        if let Some(listing) = &self.series {
            series_picker(ui, listing, requests);
        }
    }

    /// The dialog (floating over everything) and files dropped on the window this frame.
    pub fn after_panels(&mut self, ctx: &egui::Context, requests: &mut Vec<Request>) {
        self.dialog.update(ctx);
        if let Some(path) = self.dialog.take_picked() {
            requests.push(match self.purpose {
                Purpose::Open => Request::Open(VolumeSource::File(path)),
                Purpose::Save => Request::Screenshot(path),
                Purpose::SaveView => Request::SaveView(path, self.view_size),
                Purpose::SaveScene => Request::SaveScene(path),
                Purpose::ExportMeasures => Request::ExportMeasures(path),
                Purpose::AddLayer => Request::AddLayer(path),
                Purpose::AddLabels => Request::AddLabels(path),
            });
        }
        let dropped: Vec<PathBuf> = ctx.input(|i| {
            i.raw
                .dropped_files
                .iter()
                .map(|f| f.path().to_path_buf())
                .collect()
        });
        if !dropped.is_empty() {
            requests.push(Request::Open(VolumeSource::from_paths(&dropped)));
        }
    }
}

/// A combo box of the input's series when it has more than one.
fn series_picker(ui: &mut Ui, listing: &SeriesListing, requests: &mut Vec<Request>) {
    if listing.all.len() < 2 {
        return;
    }
    let label = |i: usize| series_label(listing, i);
    ui.horizontal(|ui| {
        ui.label("Series");
        egui::ComboBox::from_id_salt("dicom-series")
            .selected_text(label(listing.chosen))
            .width(ui.available_width())
            .show_ui(ui, |ui| {
                for (i, info) in listing.all.iter().enumerate() {
                    let text = label(i);
                    let entry = ui.selectable_label(i == listing.chosen, text);
                    let entry = match (&info.problem, info.dims) {
                        (Some(problem), _) => entry.on_hover_text(problem),
                        (None, Some(d)) => entry.on_hover_text(format!(
                            "{}x{}x{} voxels, {} file(s)",
                            d[0], d[1], d[2], info.count
                        )),
                        (None, None) => entry,
                    };
                    if entry.clicked() && i != listing.chosen {
                        requests.push(Request::Series(i));
                    }
                }
            });
    });
}

/// `2: #7 "T2 axial" (256x256x24)`, the index being `--series`'s.
pub fn series_label(listing: &SeriesListing, index: usize) -> String {
    let Some(info) = listing.all.get(index) else {
        return format!("{index}");
    };
    let mut text = format!("{index}:");
    if let Some(n) = info.number {
        text.push_str(&format!(" #{n}"));
    }
    if !info.description.is_empty() {
        text.push_str(&format!(" \"{}\"", info.description));
    }
    match info.dims {
        Some(d) => text.push_str(&format!(" ({}x{}x{})", d[0], d[1], d[2])),
        None => text.push_str(" (not a volume)"),
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;
    use egui::{Pos2, Rect, vec2};

    #[derive(Debug)]
    struct Dropped(PathBuf);

    impl egui::DroppedFile for Dropped {
        fn path(&self) -> &std::path::Path {
            &self.0
        }
        fn bytes(&self) -> Result<Vec<u8>, String> {
            Ok(Vec::new())
        }
    }

    fn dropped_on_the_window(paths: &[&str]) -> Vec<Request> {
        let ctx = egui::Context::default();
        let mut panel = FilePanel::default();
        let input = egui::RawInput {
            screen_rect: Some(Rect::from_min_size(Pos2::ZERO, vec2(900.0, 600.0))),
            dropped_files: paths
                .iter()
                .map(|p| std::sync::Arc::new(Dropped(PathBuf::from(p))) as std::sync::Arc<_>)
                .collect(),
            ..Default::default()
        };
        let mut requests = Vec::new();
        ctx.run_ui(input, |ui| panel.after_panels(ui.ctx(), &mut requests))
            .drop_without_applying_deltas();
        requests
    }

    #[test]
    fn a_dropped_file_is_opened_and_several_dropped_files_are_one_input() {
        assert_eq!(
            dropped_on_the_window(&["/data/t1.nii.gz"]),
            vec![Request::Open(VolumeSource::File("/data/t1.nii.gz".into()))]
        );
        assert_eq!(
            dropped_on_the_window(&["/d/1.dcm", "/d/2.dcm"]),
            vec![Request::Open(VolumeSource::Files(vec![
                "/d/1.dcm".into(),
                "/d/2.dcm".into()
            ]))]
        );
        assert!(dropped_on_the_window(&[]).is_empty());
        let mut panel = FilePanel::default();
        panel.open_dialog();
        assert!(panel.dialog_is_open());
    }
}
