//! Measurements (issue 31 item 3): distances, angles and regions of interest in world
//! millimetres, what each measures on a volume, and their export as CSV or JSON.
//!
//! Decisions:
//! - A measurement is its points in world mm (RAS+), not in voxels or pixels: it stays where it
//!   is when the camera, the layout or the slices move, goes into scene documents as it is,
//!   and means the same on every grid of the same scan.
//! - Its values are computed when asked (`MeasureRow::of`): lengths and angles from the points,
//!   a region's statistics from the volume's physical values (`volume::roi`), so a window or a
//!   colour change never makes a stored number stale.
//! - Export: one row per measurement with the same columns in CSV and JSON (empty / null where
//!   a column does not apply), written atomically like every output.

use crate::volume::Volume;
use crate::volume::roi::{Region, RoiStats, roi_stats};
use glam::DVec3;

/// Most measurements a scene keeps (a document with more is refused).
pub const MAX_MEASUREMENTS: usize = 256;

/// One measurement, in world mm.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Measurement {
    /// The distance between two points.
    Distance {
        /// The two points.
        points: [[f64; 3]; 2],
    },
    /// The angle at `points[1]` between the rays to `points[0]` and `points[2]`.
    Angle {
        /// The three points, the vertex in the middle.
        points: [[f64; 3]; 3],
    },
    /// A sphere or a box: its voxel count, volume and the statistics of the values inside.
    /// Written as the region itself (`{"sphere": {"centre": ..., "radius_mm": ...}}`).
    #[serde(untagged)]
    Region(Region),
}

impl Measurement {
    /// The points that define it (a sphere's centre, a box's two corners).
    pub fn points(&self) -> Vec<DVec3> {
        let v = |p: &[f64; 3]| DVec3::from_array(*p);
        match self {
            Measurement::Distance { points } => points.iter().map(v).collect(),
            Measurement::Angle { points } => points.iter().map(v).collect(),
            Measurement::Region(Region::Sphere { centre, .. }) => vec![v(centre)],
            Measurement::Region(Region::Box { a, b }) => vec![v(a), v(b)],
        }
    }

    /// The region it encloses (spheres and boxes).
    pub fn region(&self) -> Option<Region> {
        match *self {
            Measurement::Region(region) => Some(region),
            _ => None,
        }
    }

    /// The word for its kind (`distance`, `angle`, `sphere`, `box`).
    pub fn kind(&self) -> &'static str {
        match self {
            Measurement::Distance { .. } => "distance",
            Measurement::Angle { .. } => "angle",
            Measurement::Region(Region::Sphere { .. }) => "sphere",
            Measurement::Region(Region::Box { .. }) => "box",
        }
    }

    /// Whether every number is finite (a script's or a document's).
    pub fn is_finite(&self) -> bool {
        match self.region() {
            Some(region) => region.is_finite(),
            None => self.points().iter().all(|p| p.is_finite()),
        }
    }
}

/// The distance between two world points, mm.
pub fn distance_mm(a: DVec3, b: DVec3) -> f64 {
    a.distance(b)
}

/// The angle at `vertex` between the rays to `a` and `c`, degrees (None when a ray has no
/// length).
pub fn angle_deg(a: DVec3, vertex: DVec3, c: DVec3) -> Option<f64> {
    let (u, v) = (a - vertex, c - vertex);
    let len = u.length() * v.length();
    (len > 0.0).then(|| {
        // atan2 of |u x v| and u . v: exact near 0 and 180 degrees, where acos is not.
        u.cross(v).length().atan2(u.dot(v)).to_degrees()
    })
}

/// What one measurement measures on a volume: one row of the panel and of the export.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct MeasureRow {
    /// 1-based position in the list.
    pub index: usize,
    /// `distance`, `angle`, `sphere` or `box`.
    pub kind: &'static str,
    /// The defining points, world mm.
    pub points: Vec<[f64; 3]>,
    /// The distance (mm), the angle (degrees), a sphere's radius (mm), or None for a box.
    pub value: Option<f64>,
    /// The unit of `value`.
    pub unit: &'static str,
    /// A region's statistics (None for distances and angles).
    pub stats: Option<RoiStats>,
}

impl MeasureRow {
    /// The row of measurement `index` (0-based) on `volume`.
    pub fn of(index: usize, m: &Measurement, volume: &Volume) -> MeasureRow {
        let points = m.points();
        let (value, unit, stats) = match m {
            Measurement::Distance { .. } => (Some(distance_mm(points[0], points[1])), "mm", None),
            Measurement::Angle { .. } => (angle_deg(points[0], points[1], points[2]), "deg", None),
            Measurement::Region(region) => {
                let radius = match region {
                    Region::Sphere { radius_mm, .. } => Some(*radius_mm),
                    Region::Box { .. } => None,
                };
                (radius, "mm", Some(roi_stats(volume, region)))
            }
        };
        MeasureRow {
            index: index + 1,
            kind: m.kind(),
            points: points.iter().map(|p| p.to_array()).collect(),
            value,
            unit,
            stats,
        }
    }

    /// One line for the panel and the log, e.g. `2 distance 12.41 mm` or `3 sphere r 5.00 mm:
    /// 523 voxels, 523.0 mm^3, mean 181.2 SD 12.3 min 140 max 220` (`unit`: the values' unit,
    /// `HU` or empty).
    pub fn line(&self, unit: &str) -> String {
        let value = self.value.map_or("-".into(), |v| format!("{v:.2}"));
        let head = match self.kind {
            "sphere" => format!("{} sphere r {value} mm", self.index),
            "box" => format!("{} box", self.index),
            kind => format!("{} {kind} {value} {}", self.index, self.unit),
        };
        let Some(s) = &self.stats else {
            return head;
        };
        let num = |v: Option<f64>| v.map_or("-".into(), |v| format!("{v:.1}"));
        let unit = if unit.is_empty() {
            String::new()
        } else {
            format!(" {unit}")
        };
        format!(
            "{head}: {} voxels, {:.1} mm^3, mean {} SD {} min {} max {}{unit}",
            s.voxels,
            s.volume_mm3,
            num(s.mean),
            num(s.sd),
            num(s.min),
            num(s.max)
        )
    }
}

/// The rows as CSV (a header, then one line per row; points as `x y z` triples separated by
/// `;`).
pub fn to_csv(rows: &[MeasureRow]) -> String {
    let mut out =
        String::from("index,kind,points_mm,value,unit,voxels,volume_mm3,mean,sd,min,max\n");
    let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v}"));
    for r in rows {
        let points: Vec<String> = r
            .points
            .iter()
            .map(|p| format!("{} {} {}", p[0], p[1], p[2]))
            .collect();
        let s = r.stats.as_ref();
        out.push_str(&format!(
            "{},{},{},{},{},{},{},{},{},{},{}\n",
            r.index,
            r.kind,
            points.join(";"),
            opt(r.value),
            r.unit,
            s.map_or(String::new(), |s| s.voxels.to_string()),
            opt(s.map(|s| s.volume_mm3)),
            opt(s.and_then(|s| s.mean)),
            opt(s.and_then(|s| s.sd)),
            opt(s.and_then(|s| s.min)),
            opt(s.and_then(|s| s.max)),
        ));
    }
    out
}

/// The rows as a JSON array.
pub fn to_json(rows: &[MeasureRow]) -> String {
    serde_json::to_string_pretty(rows).unwrap_or_else(|_| "[]".into())
}

/// Writes the rows to `path` as CSV (`.csv`) or JSON (`.json`), atomically.
pub fn export(
    rows: &[MeasureRow],
    path: &std::path::Path,
) -> Result<(), crate::files::write::OutputError> {
    use crate::files::write::{OutputKind, check_output, write_file};
    let csv = OutputKind::Csv.accepts(path);
    let kind = if csv {
        OutputKind::Csv
    } else {
        OutputKind::Json
    };
    check_output(path, kind, &[], false)?;
    let text = if csv {
        to_csv(rows)
    } else {
        format!("{}\n", to_json(rows))
    };
    write_file(path, text.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances_and_angles_are_exact_where_they_are_easy() {
        let o = DVec3::ZERO;
        assert_eq!(distance_mm(o, DVec3::new(3.0, 4.0, 12.0)), 13.0);
        let right = angle_deg(DVec3::X, o, DVec3::Y).unwrap();
        assert!((right - 90.0).abs() < 1e-12);
        // Nearly straight and nearly folded: atan2 keeps the digits acos loses.
        let straight = angle_deg(DVec3::X, o, DVec3::new(-1.0, 1e-9, 0.0)).unwrap();
        assert!((straight - 180.0).abs() < 1e-6, "{straight}");
        let folded = angle_deg(DVec3::X, o, DVec3::new(1.0, 1e-9, 0.0)).unwrap();
        assert!(folded > 0.0 && folded < 1e-6, "{folded}");
        assert_eq!(angle_deg(o, o, DVec3::X), None);
    }

    #[test]
    fn the_csv_has_one_header_and_a_row_per_measurement() {
        let rows = vec![
            MeasureRow {
                index: 1,
                kind: "distance",
                points: vec![[0.0, 0.0, 0.0], [3.0, 4.0, 0.0]],
                value: Some(5.0),
                unit: "mm",
                stats: None,
            },
            MeasureRow {
                index: 2,
                kind: "box",
                points: vec![[0.0; 3], [1.0; 3]],
                value: None,
                unit: "mm",
                stats: Some(RoiStats {
                    voxels: 8,
                    volume_mm3: 8.0,
                    mean: Some(2.5),
                    sd: Some(1.0),
                    min: Some(1.0),
                    max: Some(4.0),
                    skipped: 0,
                }),
            },
        ];
        let csv = to_csv(&rows);
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(lines.len(), 3);
        assert_eq!(lines[1], "1,distance,0 0 0;3 4 0,5,mm,,,,,,");
        assert_eq!(lines[2], "2,box,0 0 0;1 1 1,,mm,8,8,2.5,1,1,4");
        let json: serde_json::Value = serde_json::from_str(&to_json(&rows)).unwrap();
        assert_eq!(json[1]["stats"]["voxels"], 8);
        assert_eq!(
            rows[1].line("HU"),
            "2 box: 8 voxels, 8.0 mm^3, mean 2.5 SD 1.0 min 1.0 max 4.0 HU"
        );
    }
}
