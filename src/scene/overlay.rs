//! Label overlays: an integer label map (a segmentation) on the same or another grid, its
//! colours (a FreeSurfer-style lookup table or a default palette), its resampling onto the
//! volume's grid, and its blending over a greyscale slice.
//!
//! Decisions:
//! - Resampling is nearest neighbour through the two affines, in f64, on the CPU, once per
//!   label file: for every voxel centre of the volume, the label voxel whose centre is nearest
//!   in the label map's index space (`round(A_labels^-1 A_volume ijk)`), 0 outside the label
//!   map. Nearest neighbour because labels are categories (an interpolated 2.5 between labels
//!   2 and 3 means nothing); the CPU because it runs once, is exact, and is its own f64
//!   reference. A label map of the volume's own grid is copied unchanged.
//! - Label values are the stored integers, rounded; negative, non-finite or above 65535 values
//!   are refused (they are not a label map). Label 0 is background and never drawn.
//! - Colours: a lookup table in FreeSurfer's format (`index name R G B A` per line, `#`
//!   comments), where FreeSurfer's A is a transparency (its own table writes 0 for opaque), so
//!   a label's opacity is `1 - A/255`, times `--overlay-opacity`. Labels missing from the table
//!   take the default palette: hues spaced by the golden angle, so neighbouring label numbers
//!   get clearly different colours.
//! - Slices: the label at a slice pixel is the resampled label of the volume voxel nearest to
//!   the pixel's position (the slice samples I_norm trilinearly; labels stay categorical), and
//!   the colour is blended over the grey: `grey (1 - a) + colour a`.

use super::slice::IndexGrid;
use crate::volume::Volume;
use glam::{DMat4, DVec3, DVec4};
use std::collections::HashMap;

/// Largest label value accepted.
pub const MAX_LABEL: f64 = 65535.0;

/// Why a label map or table cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum OverlayError {
    /// A voxel value that is no label.
    #[error(
        "{name}: voxel {index} holds {value}, not a label (labels are integers 0..65535); is it a label map?"
    )]
    NotLabels {
        /// The label file's name.
        name: String,
        /// The voxel.
        index: usize,
        /// Its value.
        value: f64,
    },
    /// An affine that cannot be inverted.
    #[error("{0}: the label map's affine cannot be inverted")]
    Singular(String),
    /// A bad line in a lookup table.
    #[error("{file}:{line}: {message}")]
    Table {
        /// The table file.
        file: String,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        message: String,
    },
}

/// A label map resampled onto a volume's grid (x fastest).
#[derive(Clone, Debug, PartialEq)]
pub struct Labels {
    /// The volume's dimensions.
    pub dims: [usize; 3],
    /// One label per volume voxel.
    pub values: Vec<u16>,
}

fn affine_of(a: &[[f64; 4]; 4]) -> DMat4 {
    DMat4::from_cols_array_2d(a).transpose()
}

/// A label map with its colours and overall opacity, as a client holds it before resampling it
/// onto each volume it shows.
#[derive(Clone, Debug)]
pub struct Overlay {
    /// The label map as read.
    pub labels: Volume,
    /// Its colours.
    pub table: LabelTable,
    /// Overall opacity 0..1.
    pub opacity: f64,
}

impl Overlay {
    /// Reads the label map at `labels` (any input the readers take) and its FreeSurfer-style
    /// table `lut` (16 MiB at most, UTF-8); the message says which file is wrong and why.
    pub fn open(
        labels: &std::path::Path,
        lut: Option<&std::path::Path>,
        opacity: f64,
    ) -> Result<Overlay, String> {
        let source = crate::volume::source::VolumeSource::File(labels.to_path_buf());
        let read = crate::volume::source::read(&source, &Default::default());
        let labels = read.map_err(|e| e.to_string())?.volume;
        let table = match lut {
            None => LabelTable::default(),
            Some(lut) => {
                let bytes = crate::files::read::read_regular(lut, 16 << 20)
                    .map_err(|e| format!("cannot read the lookup table {}: {e}", lut.display()))?;
                let text = String::from_utf8(bytes).map_err(|_| {
                    format!("{}: the lookup table is not UTF-8 text", lut.display())
                })?;
                LabelTable::parse(&text, &lut.display().to_string()).map_err(|e| e.to_string())?
            }
        };
        Ok(Overlay {
            labels,
            table,
            opacity,
        })
    }
}

/// The label map `labels` resampled onto `volume`'s grid (module decisions).
pub fn resample(labels: &Volume, volume: &Volume) -> Result<Labels, OverlayError> {
    resample_onto(labels, volume.dims, &volume.orientation.affine)
}

/// [`resample`] onto a grid of `dims` voxels with the row-major index-to-world `affine`.
pub fn resample_onto(
    labels: &Volume,
    dims: [usize; 3],
    affine: &[[f64; 4]; 4],
) -> Result<Labels, OverlayError> {
    let stored: Vec<u16> = (0..labels.samples.len())
        .map(|i| {
            let value = labels.to_physical.apply(labels.samples.get(i));
            let rounded = value.round();
            if !(0.0..=MAX_LABEL).contains(&rounded) || (value - rounded).abs() > 1e-3 {
                return Err(OverlayError::NotLabels {
                    name: labels.name.clone(),
                    index: i,
                    value,
                });
            }
            Ok(rounded as u16)
        })
        .collect::<Result<_, _>>()?;
    let to_world = affine_of(affine);
    let label_to_world = affine_of(&labels.orientation.affine);
    if labels.dims == dims && to_world.abs_diff_eq(label_to_world, 1e-9) {
        return Ok(Labels {
            dims,
            values: stored,
        });
    }
    let det = label_to_world.determinant();
    if !det.is_finite() || det.abs() < 1e-300 {
        return Err(OverlayError::Singular(labels.name.clone()));
    }
    // Volume index -> label index, composed once in f64.
    let m = label_to_world.inverse() * to_world;
    let [nx, ny, nz] = dims;
    let ld = labels.dims;
    let mut values = Vec::with_capacity(nx * ny * nz);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let p = m * DVec4::new(i as f64, j as f64, k as f64, 1.0);
                values.push(label_at(&stored, ld, p.truncate()));
            }
        }
    }
    Ok(Labels { dims, values })
}

/// The label of the voxel nearest to index position `p`, 0 outside the grid.
fn label_at(values: &[u16], dims: [usize; 3], p: DVec3) -> u16 {
    let r = p.round();
    let inside = (0..3).all(|a| r[a] >= 0.0 && r[a] < dims[a] as f64);
    if !inside {
        return 0;
    }
    let (i, j, k) = (r.x as usize, r.y as usize, r.z as usize);
    values[i + dims[0] * (j + dims[1] * k)]
}

/// A label's colour and opacity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LabelStyle {
    /// RGB 0..255.
    pub rgb: [u8; 3],
    /// Opacity 0..1 (before the overall overlay opacity).
    pub opacity: f64,
}

/// Label colours: a table's entries, the default palette for the rest.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LabelTable {
    /// Entries read from a table (label -> name, style).
    pub entries: HashMap<u16, (String, LabelStyle)>,
}

/// The default palette's colour of `label` (golden-angle hues, full saturation).
pub fn default_colour(label: u16) -> [u8; 3] {
    let hue = (label as f64 * 137.507_764_05).rem_euclid(360.0) / 60.0;
    let x = 1.0 - (hue % 2.0 - 1.0).abs();
    let (r, g, b) = match hue as u32 {
        0 => (1.0, x, 0.0),
        1 => (x, 1.0, 0.0),
        2 => (0.0, 1.0, x),
        3 => (0.0, x, 1.0),
        4 => (x, 0.0, 1.0),
        _ => (1.0, 0.0, x),
    };
    [r, g, b].map(|c: f64| (c * 255.0).round() as u8)
}

impl LabelTable {
    /// Parses a FreeSurfer-style table (`index name R G B A`; `#` starts a comment).
    pub fn parse(text: &str, file: &str) -> Result<LabelTable, OverlayError> {
        let mut entries = HashMap::new();
        for (n, raw) in text.lines().enumerate() {
            let line = raw.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let bad = |message: String| OverlayError::Table {
                file: file.to_string(),
                line: n + 1,
                message,
            };
            let words: Vec<&str> = line.split_whitespace().collect();
            if words.len() < 5 {
                return Err(bad(format!(
                    "expected `index name R G B [A]`, got {} field(s)",
                    words.len()
                )));
            }
            let index: u16 = words[0]
                .parse()
                .map_err(|_| bad(format!("`{}` is not a label 0..65535", words[0])))?;
            let channel = |w: &str| {
                w.parse::<u8>()
                    .map_err(|_| bad(format!("`{w}` is not a colour value 0..255")))
            };
            let rgb = [channel(words[2])?, channel(words[3])?, channel(words[4])?];
            let transparency = match words.get(5) {
                Some(w) => channel(w)?,
                None => 0,
            };
            let style = LabelStyle {
                rgb,
                opacity: 1.0 - transparency as f64 / 255.0,
            };
            entries.insert(index, (words[1].to_string(), style));
        }
        Ok(LabelTable { entries })
    }

    /// The style of `label`.
    pub fn style(&self, label: u16) -> LabelStyle {
        match self.entries.get(&label) {
            Some((_, style)) => *style,
            None => LabelStyle {
                rgb: default_colour(label),
                opacity: 1.0,
            },
        }
    }
}

impl Labels {
    /// The distinct non-zero labels present, ascending.
    pub fn present(&self) -> Vec<u16> {
        let set: std::collections::BTreeSet<u16> =
            self.values.iter().copied().filter(|&l| l != 0).collect();
        set.into_iter().collect()
    }
}

/// Blends `labels` over the greyscale slice `rgba` (the slice `grid` of the labels' volume, in
/// index space) with overall `opacity`, leaving out the `hidden` labels; returns how many pixels
/// got a label.
pub fn blend_slice(
    rgba: &mut [u8],
    grid: &IndexGrid,
    labels: &Labels,
    table: &LabelTable,
    opacity: f64,
    hidden: &std::collections::BTreeSet<u16>,
) -> usize {
    let mut drawn = 0;
    for y in 0..grid.height as usize {
        for x in 0..grid.width as usize {
            let p = DVec3::from_array(std::array::from_fn(|a| {
                grid.origin[a] + x as f64 * grid.du[a] + y as f64 * grid.dv[a]
            }));
            let label = label_at(&labels.values, labels.dims, p);
            if label == 0 || hidden.contains(&label) {
                continue;
            }
            let style = table.style(label);
            let a = (style.opacity * opacity).clamp(0.0, 1.0);
            let at = 4 * (y * grid.width as usize + x);
            for c in 0..3 {
                let grey = rgba[at + c] as f64;
                rgba[at + c] = (grey * (1.0 - a) + style.rgb[c] as f64 * a).round() as u8;
            }
            drawn += 1;
        }
    }
    drawn
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{LinearMap, Samples};

    fn vol(dims: [usize; 3], affine: [[f64; 4]; 4], values: Vec<u8>) -> Volume {
        Volume::from_voxels(
            "v",
            dims,
            Samples::from_u8(values),
            affine,
            LinearMap::IDENTITY,
        )
        .unwrap()
    }

    #[test]
    fn a_coarser_flipped_label_grid_lands_on_the_same_world_voxels() {
        // Volume: 6x4x2 at 1 mm. Labels: 3x2x1 at 2 mm, x flipped, covering the same box.
        let id = [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let volume = vol([6, 4, 2], id, vec![0; 48]);
        let flipped = [
            [-2.0, 0.0, 0.0, 4.5],
            [0.0, 2.0, 0.0, 0.5],
            [0.0, 0.0, 2.0, 0.5],
            [0.0, 0.0, 0.0, 1.0],
        ];
        // Label voxel i covers world x = 4.5 - 2i +- 1: label 5 at i = 0 (x 3.5..5.5).
        let labels = vol([3, 2, 1], flipped, vec![5, 0, 9, 0, 0, 0]);
        let r = resample(&labels, &volume).unwrap();
        // Volume x = 4, 5 (row j = 0, 1 -> label row j' = round((j - 0.5) / 2) = 0).
        let at = |i: usize, j: usize, k: usize| r.values[i + 6 * (j + 4 * k)];
        assert_eq!(at(4, 0, 0), 5);
        assert_eq!(at(5, 1, 1), 5);
        assert_eq!(at(0, 0, 0), 9);
        assert_eq!(at(2, 0, 0), 0);
        // Same grid: copied unchanged.
        let same = vol([6, 4, 2], id, (0..48).map(|n| n as u8).collect());
        assert_eq!(resample(&same, &volume).unwrap().values[47], 47);
    }

    #[test]
    fn non_labels_and_bad_tables_are_refused_with_their_place() {
        let id = [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let volume = vol([2, 1, 1], id, vec![0, 0]);
        let half = Volume::from_voxels(
            "half.nii",
            [2, 1, 1],
            Samples::from_f32(&[1.0, 2.5]),
            id,
            LinearMap::IDENTITY,
        )
        .unwrap();
        let err = resample(&half, &volume).unwrap_err().to_string();
        assert!(err.contains("half.nii") && err.contains("2.5"), "{err}");
        let t = LabelTable::parse("# FreeSurfer\n0 Unknown 0 0 0 0\n17 Left-Hippocampus 220 216 20 0\n\n53 Right 10 20 30 255\n", "lut.txt").unwrap();
        assert_eq!(t.style(17).rgb, [220, 216, 20]);
        assert_eq!(t.style(17).opacity, 1.0);
        assert_eq!(t.style(53).opacity, 0.0);
        assert_eq!(t.style(4).rgb, default_colour(4));
        let e = LabelTable::parse("1 a 2 3\n", "lut.txt")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("lut.txt:1:"), "{e}");
        let e = LabelTable::parse("\n1 a 2 3 300\n", "lut.txt")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("lut.txt:2:") && e.contains("300"), "{e}");
    }

    #[test]
    fn default_colours_differ_between_neighbouring_labels() {
        for l in 1..50u16 {
            let (a, b) = (default_colour(l), default_colour(l + 1));
            let d: i32 = (0..3).map(|c| (a[c] as i32 - b[c] as i32).abs()).sum();
            assert!(d > 100, "labels {l} and {}: {a:?} {b:?}", l + 1);
        }
    }
}
