//! The crosshair's readout (issue 31 item 1): where it is in world millimetres and in voxels,
//! and the value there in the scanner's units, as the status bar and the scripted log show it:
//! `crosshair  R 12.0  P 3.5  S 20.0 mm  |  voxel 98, 116, 94  |  value 182`.
//!
//! Decisions:
//! - The value is the nearest voxel's stored sample through the file's scaling (NIfTI
//!   scl_slope/scl_inter, DICOM RescaleSlope/Intercept), so a CT reads in Hounsfield units
//!   (`HU`) and an MR in its scanner's arbitrary units: what FSLeyes, MRIcroGL and NiiVue
//!   show; not I_norm, which is this program's own scale.
//! - World coordinates are RAS+ mm written with the anatomical letter of their sign (R/L,
//!   A/P, S/I), as the slices' orientation letters are, so nothing depends on a convention the
//!   reader has to know.
//! - Outside the volume the readout says so instead of clamping to the border voxel.
//! - With a label overlay the label under the crosshair follows, with its name when the
//!   overlay's lookup table has one (`label 17 Left-Hippocampus`); label 0 (no label) is not
//!   shown.

use crate::volume::Volume;
use glam::{DMat4, DVec3, DVec4};

/// The crosshair at `world` (RAS+ mm) over `volume`.
#[derive(Clone, Debug, PartialEq)]
pub struct Readout {
    /// World position, mm.
    pub world: DVec3,
    /// The nearest voxel (i, j, k), None outside the volume.
    pub voxel: Option<[usize; 3]>,
    /// The value there in the scanner's units.
    pub value: Option<f64>,
    /// `HU` for CT, empty otherwise.
    pub unit: &'static str,
    /// The overlay's label at the voxel and its name in the lookup table, when there is one.
    pub label: Option<(u16, Option<String>)>,
}

/// The readout of `volume` at `world`; `hounsfield`: its values are Hounsfield units.
pub fn readout(volume: &Volume, world: DVec3, hounsfield: bool) -> Readout {
    let a = volume.orientation.affine;
    let index_to_world = DMat4::from_cols_array_2d(&a).transpose();
    let index = index_to_world.inverse() * DVec4::new(world.x, world.y, world.z, 1.0);
    let nearest = [index.x, index.y, index.z].map(f64::round);
    let inside = nearest
        .iter()
        .zip(volume.dims)
        .all(|(&i, d)| i.is_finite() && i >= 0.0 && i < d as f64);
    let voxel = inside.then(|| nearest.map(|i| i as usize));
    let value = voxel.map(|[i, j, k]| {
        let [nx, ny, _] = volume.dims;
        let stored = volume.samples.get(i + nx * (j + ny * k));
        volume.to_physical.slope * stored + volume.to_physical.intercept
    });
    Readout {
        world,
        voxel,
        value,
        unit: if hounsfield { "HU" } else { "" },
        label: None,
    }
}

impl Readout {
    /// This readout with the label of `labels` (on the volume's grid) at its voxel, named by
    /// `table`; label 0 is no label.
    pub fn with_label(
        mut self,
        labels: &crate::scene::overlay::Labels,
        table: &crate::scene::overlay::LabelTable,
    ) -> Readout {
        let [nx, ny, _] = labels.dims;
        self.label = self
            .voxel
            .and_then(|[i, j, k]| labels.values.get(i + nx * (j + ny * k)).copied())
            .filter(|&l| l != 0)
            .map(|l| (l, table.entries.get(&l).map(|(name, _)| name.clone())));
        self
    }
}

/// `R 12.0` / `L 12.0`: a coordinate with the letter of its sign.
fn lettered(value: f64, positive: char, negative: char) -> String {
    let letter = if value >= 0.0 { positive } else { negative };
    format!("{letter} {:.1}", value.abs())
}

/// A value with up to four significant decimals, no trailing zeros (`182`, `0.0374`).
fn value_text(value: f64) -> String {
    if value.is_finite() && value == value.round() && value.abs() < 1e15 {
        return format!("{value:.0}");
    }
    let text = format!("{value:.4}");
    text.trim_end_matches('0').trim_end_matches('.').to_string()
}

impl Readout {
    /// The status bar's line.
    pub fn text(&self) -> String {
        let w = self.world;
        let position = format!(
            "crosshair  {}  {}  {} mm",
            lettered(w.x, 'R', 'L'),
            lettered(w.y, 'A', 'P'),
            lettered(w.z, 'S', 'I')
        );
        match (self.voxel, self.value) {
            (Some([i, j, k]), Some(v)) => {
                let unit = if self.unit.is_empty() {
                    String::new()
                } else {
                    format!(" {}", self.unit)
                };
                let label = match &self.label {
                    Some((l, Some(name))) => format!("  |  label {l} {name}"),
                    Some((l, None)) => format!("  |  label {l}"),
                    None => String::new(),
                };
                format!(
                    "{position}  |  voxel {i}, {j}, {k}  |  value {}{unit}{label}",
                    value_text(v)
                )
            }
            _ => format!("{position}  |  outside the volume"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{LinearMap, Samples};

    /// 3x4x5 int16 voxels valued 100 i + 10 j + k, 2 mm voxels, the origin at -10 mm, with a
    /// CT-like scaling (slope 1, intercept -1024).
    fn volume() -> Volume {
        let dims = [3, 4, 5];
        let values: Vec<i16> = (0..5)
            .flat_map(|k| (0..4).flat_map(move |j| (0..3).map(move |i| 100 * i + 10 * j + k)))
            .collect();
        let mut affine = [[0.0; 4]; 4];
        for (axis, row) in affine.iter_mut().take(3).enumerate() {
            row[axis] = 2.0;
            row[3] = -10.0;
        }
        affine[3][3] = 1.0;
        let map = LinearMap {
            slope: 1.0,
            intercept: -1024.0,
        };
        Volume::from_voxels("t", dims, Samples::from_i16(&values), affine, map).unwrap()
    }

    #[test]
    fn the_value_is_the_nearest_voxels_in_the_scanners_units() {
        let v = volume();
        // Voxel (2, 1, 3) is at world (-6, -8, -4); 0.9 mm off rounds to it.
        let r = readout(&v, DVec3::new(-6.9, -8.0, -3.2), true);
        assert_eq!(r.voxel, Some([2, 1, 3]));
        assert_eq!(r.value, Some(213.0 - 1024.0));
        assert_eq!(
            r.text(),
            "crosshair  L 6.9  P 8.0  I 3.2 mm  |  voxel 2, 1, 3  |  value -811 HU"
        );
        let mr = readout(&v, DVec3::new(-10.0, -10.0, -10.0), false);
        assert!(
            mr.text().ends_with("voxel 0, 0, 0  |  value -1024"),
            "{}",
            mr.text()
        );
    }

    #[test]
    fn outside_the_volume_it_says_so() {
        let v = volume();
        let r = readout(&v, DVec3::new(40.0, 0.0, 0.0), false);
        assert_eq!(r.voxel, None);
        assert!(r.text().starts_with("crosshair  R 40.0  A 0.0  S 0.0 mm"));
        assert!(r.text().ends_with("outside the volume"), "{}", r.text());
    }

    #[test]
    fn the_label_under_the_crosshair_is_named_by_the_table() {
        let v = volume();
        let mut values = vec![0u16; 3 * 4 * 5];
        values[2 + 3 * (1 + 4 * 3)] = 17;
        values[0] = 5;
        let labels = crate::scene::overlay::Labels {
            dims: [3, 4, 5],
            values,
        };
        let table = crate::scene::overlay::LabelTable::parse(
            "17 Left-Hippocampus 220 216 20 0\n",
            "lut.txt",
        )
        .unwrap();
        let at = |x: f64, y: f64, z: f64| {
            readout(&v, DVec3::new(x, y, z), false)
                .with_label(&labels, &table)
                .text()
        };
        assert!(
            at(-6.0, -8.0, -4.0).ends_with("value -811  |  label 17 Left-Hippocampus"),
            "{}",
            at(-6.0, -8.0, -4.0)
        );
        assert!(at(-10.0, -10.0, -10.0).ends_with("value -1024  |  label 5"));
        assert!(
            at(-8.0, -10.0, -10.0).ends_with("value -924"),
            "label 0 is not shown"
        );
    }

    #[test]
    fn values_keep_their_decimals() {
        assert_eq!(value_text(0.0374), "0.0374");
        assert_eq!(value_text(182.0), "182");
        assert_eq!(value_text(1.5), "1.5");
    }
}
