//! The measurements' values and export in the viewer (issue 31 item 3): the panel's lines are
//! computed from the host volume when the list changes (`scene::measure::MeasureRow`), each new
//! one is logged, and Export... writes them as CSV or JSON.

use super::{Viewer, one_line};
use crate::scene::measure::{MeasureRow, export};
use std::path::Path;

impl Viewer {
    /// The rows of the measurements on the volume on screen (empty without one).
    fn measure_rows(&self) -> Vec<MeasureRow> {
        let Some(current) = &self.current else {
            return Vec::new();
        };
        let volume = &current.loaded.host;
        (self.controls.slices.measures.items.iter().enumerate())
            .map(|(i, m)| MeasureRow::of(i, m, volume))
            .collect()
    }

    /// Recomputes the panel's lines after a change of the list, and logs the last one added.
    pub(super) fn update_measures(&mut self) {
        if !self.controls.slices.measures.changed {
            return;
        }
        let unit = self.values_unit();
        let rows = self.measure_rows();
        let lines: Vec<String> = rows.iter().map(|r| r.line(unit)).collect();
        let measures = &mut self.controls.slices.measures;
        let added = lines.len() > measures.lines.len();
        if let Some(last) = lines.last().filter(|_| added) {
            self.log.say(&format!("measure: {last}"));
        }
        measures.lines = lines;
        measures.changed = false;
    }

    /// `HU` when the volume's values are Hounsfield units, else empty.
    fn values_unit(&self) -> &'static str {
        match &self.current {
            Some(c) if crate::scene::preset::values_are_hu(&c.loaded.report) => "HU",
            _ => "",
        }
    }

    /// Writes the measurements to `path` (.csv or .json); the outcome goes to the status line.
    pub(super) fn export_measures(&mut self, path: &Path) {
        let rows = self.measure_rows();
        match export(&rows, path) {
            Ok(()) => {
                self.log.say(&format!(
                    "wrote {} ({} measurements)",
                    path.display(),
                    rows.len()
                ));
                self.status.note = Some(format!("Saved {}", path.display()));
            }
            Err(e) => {
                let text = one_line(&e.to_string());
                if self.config.log {
                    eprintln!("morphray: export failed: {text}");
                }
                self.status.error = Some(format!("Export: {text}"));
            }
        }
    }

    /// Runs a script's `measure ...` step.
    pub(super) fn measure_step(&mut self, step: &crate::app::measure_panel::MeasureStep) {
        use crate::app::measure_panel::MeasureStep;
        let measures = &mut self.controls.slices.measures;
        let outcome = match step {
            MeasureStep::Add(m) => measures.push(*m),
            MeasureStep::Point(p) => measures.add_point(*p).map(|_| ()),
            MeasureStep::Pick(at) => {
                self.controls.pick = Some(*at);
                self.controls.pick_measures = true;
                self.run_pick();
                Ok(())
            }
            MeasureStep::Mode(mode) => {
                measures.mode = *mode;
                measures.pending.clear();
                Ok(())
            }
            MeasureStep::Clear => {
                measures.clear();
                Ok(())
            }
            MeasureStep::Export(path) => {
                self.update_measures();
                self.export_measures(path);
                Ok(())
            }
        };
        if let Err(e) = outcome {
            self.log.say(&format!("measure: {e}"));
            self.status.error = Some(format!("Measure: {e}"));
        }
        self.update_measures();
    }
}
