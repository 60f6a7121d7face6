//! The measurement panel and marks (issue 31 items 2 and 3): distances, angles, spheres and
//! boxes placed with Shift+click on a slice or on the 3D view's surface (depth picking), listed
//! with their values, drawn on the slices and in the 3D view, exported as CSV or JSON.
//!
//! Decisions:
//! - Points are world mm (`scene::measure`), so a measurement stays put when the camera or the
//!   slices move. A kind needs 2 points (distance; sphere: centre, then a point on its
//!   surface; box: two corners) or 3 (angle: the vertex second); the points placed so far are
//!   drawn as pending marks until the last one completes it.
//! - The values are computed by the viewer from the host volume (`MeasureRow::of`) when the
//!   list changes, not every frame; the panel shows those lines.
//! - Marks are drawn over the pictures, not depth-tested (as the crosshair): on a slice every
//!   mark is projected onto it, dimmed when none of its points lies within a pixel's size of
//!   the slice's plane.

use crate::scene::measure::{MAX_MEASUREMENTS, Measurement};
use crate::volume::roi::Region;
use egui::{Color32, Pos2, Stroke, Ui};
use glam::DVec3;

/// What the next points make.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MeasureMode {
    /// Two points.
    #[default]
    Distance,
    /// Three points, the vertex second.
    Angle,
    /// A centre, then a point on the surface.
    Sphere,
    /// Two opposite corners.
    Box,
}

impl MeasureMode {
    /// Every mode, in the panel's order.
    pub const ALL: [MeasureMode; 4] = [
        MeasureMode::Distance,
        MeasureMode::Angle,
        MeasureMode::Sphere,
        MeasureMode::Box,
    ];

    /// The word the panel and the script use.
    pub fn name(self) -> &'static str {
        match self {
            MeasureMode::Distance => "distance",
            MeasureMode::Angle => "angle",
            MeasureMode::Sphere => "sphere",
            MeasureMode::Box => "box",
        }
    }

    fn points_needed(self) -> usize {
        if self == MeasureMode::Angle { 3 } else { 2 }
    }
}

/// The measurements of the volume on screen and the points placed toward the next one.
#[derive(Clone, Debug, Default)]
pub struct Measures {
    /// The finished measurements.
    pub items: Vec<Measurement>,
    /// What the next points make.
    pub mode: MeasureMode,
    /// Points placed toward the next measurement.
    pub pending: Vec<DVec3>,
    /// One line per item (the viewer fills them from the host volume; `MeasureRow::line`).
    pub lines: Vec<String>,
    /// The items changed: the viewer recomputes `lines` and logs the new one.
    pub changed: bool,
}

impl Measures {
    /// Adds a point toward the next measurement; the measurement when it completes one.
    pub fn add_point(&mut self, p: DVec3) -> Result<Option<Measurement>, String> {
        if !p.is_finite() {
            return Err("a measurement point must be a finite position".into());
        }
        self.pending.push(p);
        if self.pending.len() < self.mode.points_needed() {
            return Ok(None);
        }
        let pts: Vec<[f64; 3]> = self.pending.drain(..).map(|p| p.to_array()).collect();
        let m = match self.mode {
            MeasureMode::Distance => Measurement::Distance {
                points: [pts[0], pts[1]],
            },
            MeasureMode::Angle => Measurement::Angle {
                points: [pts[0], pts[1], pts[2]],
            },
            MeasureMode::Sphere => Measurement::Region(Region::Sphere {
                centre: pts[0],
                radius_mm: DVec3::from_array(pts[0]).distance(DVec3::from_array(pts[1])),
            }),
            MeasureMode::Box => Measurement::Region(Region::Box {
                a: pts[0],
                b: pts[1],
            }),
        };
        self.push(m)?;
        Ok(Some(m))
    }

    /// Adds a finished measurement (at most [`MAX_MEASUREMENTS`], finite numbers only).
    pub fn push(&mut self, m: Measurement) -> Result<(), String> {
        if !m.is_finite() {
            return Err("a measurement's numbers must be finite".into());
        }
        if self.items.len() >= MAX_MEASUREMENTS {
            return Err(format!(
                "at most {MAX_MEASUREMENTS} measurements: delete some first"
            ));
        }
        self.items.push(m);
        self.changed = true;
        Ok(())
    }

    /// Removes every measurement and pending point.
    pub fn clear(&mut self) {
        self.items.clear();
        self.pending.clear();
        self.changed = true;
    }
}

/// A script's `measure ...` step.
#[derive(Clone, Debug, PartialEq)]
pub enum MeasureStep {
    /// A finished measurement (`measure distance X Y Z X Y Z`, `measure angle` with nine
    /// numbers, `measure sphere X Y Z R`, `measure box X Y Z X Y Z`; world mm).
    Add(Measurement),
    /// What the next points make (`measure mode angle`).
    Mode(MeasureMode),
    /// A point as a Shift+click places it (`measure point X Y Z`).
    Point(DVec3),
    /// A point depth-picked in the 3D view as Shift+click there places it (`measure pick X Y`,
    /// fractions of the view from its top left).
    Pick([f32; 2]),
    /// Remove every measurement (`measure clear`).
    Clear,
    /// Write the list (`measure export FILE.csv|.json`).
    Export(std::path::PathBuf),
}

impl MeasureStep {
    /// Parses the words after `measure`.
    pub fn parse(words: &[&str]) -> Result<MeasureStep, String> {
        let numbers = |n: usize| -> Result<Vec<f64>, String> {
            let v: Vec<f64> = words[1..]
                .iter()
                .filter_map(|w| w.parse::<f64>().ok().filter(|v| v.is_finite()))
                .collect();
            if v.len() != n || words.len() != n + 1 {
                return Err(format!(
                    "`measure {}` takes {n} numbers (world mm)",
                    words[0]
                ));
            }
            Ok(v)
        };
        let p = |v: &[f64], i: usize| [v[i], v[i + 1], v[i + 2]];
        let Some(&kind) = words.first() else {
            return Err(
                "expected distance, angle, sphere, box, mode, point, pick, clear or export".into(),
            );
        };
        Ok(match kind {
            "distance" => {
                let v = numbers(6)?;
                MeasureStep::Add(Measurement::Distance {
                    points: [p(&v, 0), p(&v, 3)],
                })
            }
            "angle" => {
                let v = numbers(9)?;
                MeasureStep::Add(Measurement::Angle {
                    points: [p(&v, 0), p(&v, 3), p(&v, 6)],
                })
            }
            "sphere" => {
                let v = numbers(4)?;
                if v[3] <= 0.0 {
                    return Err(format!(
                        "measure sphere: radius {} must be above 0 mm",
                        v[3]
                    ));
                }
                MeasureStep::Add(Measurement::Region(Region::Sphere {
                    centre: p(&v, 0),
                    radius_mm: v[3],
                }))
            }
            "box" => {
                let v = numbers(6)?;
                MeasureStep::Add(Measurement::Region(Region::Box {
                    a: p(&v, 0),
                    b: p(&v, 3),
                }))
            }
            "point" => MeasureStep::Point(DVec3::from_array(p(&numbers(3)?, 0))),
            "pick" => {
                let v = numbers(2)?;
                if !v.iter().all(|f| (0.0..=1.0).contains(f)) {
                    return Err("measure pick X Y: fractions of the view, 0..1".into());
                }
                MeasureStep::Pick([v[0] as f32, v[1] as f32])
            }
            "mode" => {
                let word = words.get(1).copied().unwrap_or_default();
                let mode = MeasureMode::ALL.into_iter().find(|m| m.name() == word);
                MeasureStep::Mode(mode.ok_or_else(|| {
                    format!("measure mode `{word}`: distance, angle, sphere or box")
                })?)
            }
            "clear" => MeasureStep::Clear,
            "export" => match words.get(1) {
                Some(path) => MeasureStep::Export(std::path::PathBuf::from(path)),
                None => return Err("measure export: expected a .csv or .json path".into()),
            },
            other => {
                return Err(format!(
                    "measure `{other}`: distance, angle, sphere, box, mode, point, pick, clear or \
                     export"
                ));
            }
        })
    }
}

/// What the panel asks the viewer to do.
#[derive(Clone, Debug, PartialEq)]
pub enum MeasureRequest {
    /// Open the file dialog to export the list.
    Export,
}

/// The panel: the mode, the pending points, the list with a delete button each, Clear and
/// Export....
pub fn panel(ui: &mut Ui, measures: &mut Measures) -> Option<MeasureRequest> {
    let mut request = None;
    ui.horizontal(|ui| {
        for mode in MeasureMode::ALL {
            if ui
                .selectable_value(&mut measures.mode, mode, mode.name())
                .clicked()
            {
                measures.pending.clear();
            }
        }
    });
    ui.label(format!(
        "Shift+click on a slice or on the 3D surface: {} of {} points",
        measures.pending.len(),
        measures.mode.points_needed()
    ));
    let mut delete = None;
    for (i, line) in measures.lines.iter().enumerate() {
        ui.horizontal(|ui| {
            if ui.small_button("x").on_hover_text("Delete").clicked() {
                delete = Some(i);
            }
            ui.label(line);
        });
    }
    if let Some(i) = delete.filter(|&i| i < measures.items.len()) {
        measures.items.remove(i);
        measures.changed = true;
    }
    ui.horizontal(|ui| {
        if ui.button("Clear").clicked() {
            measures.clear();
        }
        if ui
            .add_enabled(!measures.items.is_empty(), egui::Button::new("Export..."))
            .on_hover_text("The list as .csv or .json (values in the scanner's units)")
            .clicked()
        {
            request = Some(MeasureRequest::Export);
        }
    });
    request
}

/// The colour of finished marks and of pending points.
const MARK: Color32 = Color32::from_rgb(255, 170, 0);
const PENDING: Color32 = Color32::from_rgb(255, 80, 200);

/// Draws every measurement and pending point through `to_screen` (None: not visible), `near`
/// saying whether a world point lies on the picture's plane (slices; always true in 3D).
pub fn draw_marks(
    painter: &egui::Painter,
    measures: &Measures,
    to_screen: impl Fn(DVec3) -> Option<Pos2>,
    near: impl Fn(DVec3) -> bool,
) {
    for m in &measures.items {
        let points = m.points();
        let on_plane = points.iter().any(|&p| near(p));
        let colour = if on_plane {
            MARK
        } else {
            MARK.gamma_multiply(0.35)
        };
        let screen: Vec<Option<Pos2>> = points.iter().map(|&p| to_screen(p)).collect();
        let stroke = Stroke::new(1.5, colour);
        match m {
            Measurement::Distance { .. } | Measurement::Angle { .. } => {
                for pair in screen.windows(2) {
                    if let [Some(a), Some(b)] = pair {
                        painter.line_segment([*a, *b], stroke);
                    }
                }
            }
            Measurement::Region(Region::Sphere { centre, radius_mm }) => {
                // The radius on screen: the longest of the projected radii along the world
                // axes (on a slice, the in-plane ones; in 3D about the silhouette's).
                let c = DVec3::from_array(*centre);
                let Some(sc) = to_screen(c) else {
                    continue;
                };
                let r = [DVec3::X, DVec3::Y, DVec3::Z]
                    .iter()
                    .filter_map(|&d| to_screen(c + d * *radius_mm))
                    .map(|q| (q - sc).length())
                    .fold(0.0f32, f32::max);
                painter.circle_stroke(sc, r, stroke);
            }
            Measurement::Region(Region::Box { a, b }) => {
                let (a, b) = (DVec3::from_array(*a), DVec3::from_array(*b));
                for (p, q) in box_edges(a, b) {
                    if let (Some(p), Some(q)) = (to_screen(p), to_screen(q)) {
                        painter.line_segment([p, q], stroke);
                    }
                }
            }
        }
        for p in screen.into_iter().flatten() {
            painter.circle_filled(p, 3.0, colour);
        }
    }
    for p in measures.pending.iter().filter_map(|&p| to_screen(p)) {
        painter.circle_filled(p, 3.5, PENDING);
    }
}

/// The 12 edges of the world box between corners `a` and `b`.
fn box_edges(a: DVec3, b: DVec3) -> Vec<(DVec3, DVec3)> {
    let corner = |i: usize| {
        DVec3::new(
            if i & 1 == 0 { a.x } else { b.x },
            if i & 2 == 0 { a.y } else { b.y },
            if i & 4 == 0 { a.z } else { b.z },
        )
    };
    let mut edges = Vec::with_capacity(12);
    for i in 0..8 {
        for bit in [1, 2, 4] {
            if i & bit == 0 {
                edges.push((corner(i), corner(i | bit)));
            }
        }
    }
    edges
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_complete_each_kind_and_the_list_is_bounded() {
        let mut m = Measures::default();
        assert_eq!(m.add_point(DVec3::ZERO), Ok(None));
        let d = m.add_point(DVec3::new(3.0, 4.0, 0.0)).unwrap().unwrap();
        assert_eq!(d.kind(), "distance");
        m.mode = MeasureMode::Angle;
        for p in [DVec3::X, DVec3::ZERO] {
            assert_eq!(m.add_point(p), Ok(None));
        }
        assert_eq!(m.add_point(DVec3::Y).unwrap().unwrap().kind(), "angle");
        m.mode = MeasureMode::Sphere;
        m.add_point(DVec3::ZERO).unwrap();
        let s = m.add_point(DVec3::new(0.0, 0.0, 2.5)).unwrap().unwrap();
        assert_eq!(
            s,
            Measurement::Region(Region::Sphere {
                centre: [0.0; 3],
                radius_mm: 2.5
            })
        );
        assert!(m.add_point(DVec3::NAN).is_err());
        assert_eq!(m.items.len(), 3);
        while m.items.len() < MAX_MEASUREMENTS {
            m.push(d).unwrap();
        }
        assert!(m.push(d).is_err());
        m.clear();
        assert!(m.items.is_empty() && m.pending.is_empty() && m.changed);
    }

    #[test]
    fn measure_steps_parse_and_bad_ones_say_why() {
        assert_eq!(
            MeasureStep::parse(&["sphere", "1", "2", "3", "4.5"]),
            Ok(MeasureStep::Add(Measurement::Region(Region::Sphere {
                centre: [1.0, 2.0, 3.0],
                radius_mm: 4.5
            })))
        );
        assert_eq!(
            MeasureStep::parse(&["mode", "box"]),
            Ok(MeasureStep::Mode(MeasureMode::Box))
        );
        for bad in [
            vec!["distance", "1", "2"],
            vec!["sphere", "0", "0", "0", "-1"],
            vec!["angle", "1", "2", "3", "4", "5", "6", "7", "8", "nan"],
            vec!["mode", "ruler"],
            vec!["export"],
            vec!["volume"],
            vec![],
        ] {
            assert!(MeasureStep::parse(&bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn a_box_has_twelve_distinct_edges() {
        let edges = box_edges(DVec3::ZERO, DVec3::ONE);
        assert_eq!(edges.len(), 12);
        assert!(edges.iter().all(|(p, q)| (*p - *q).length() == 1.0));
    }
}
