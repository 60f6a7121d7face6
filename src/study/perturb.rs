//! Scanner perturbations of a T1 volume for the peak-finder study (issue 11, item 2): from one
//! volume and a tissue label per voxel, the original plus five perturbed copies, each with its
//! labels moved the same way geometrically. Truth ranges and scoring are in `perturb_score`.
//!
//! Decisions:
//! - Labels, not probability maps, travel with the volumes: one [`Label`] per voxel (outside the
//!   head, inside the head without a class, CSF, GM, WM). Callers build them from whatever they
//!   hold ([`labels_from_maps`] for a T1 with GM/WM probability maps, the phantom's labels in
//!   the CI test).
//! - Every perturbation is computed in f64 on the PHYSICAL intensity (`stored * slope +
//!   intercept`) and then stored; the truth is computed afterwards from what was stored, so
//!   quantization is part of the perturbation, never a discrepancy.
//! - Deterministic: a splitmix64 generator seeded per perturbation (Box-Muller for normals), so
//!   the same input gives the same volumes on every run.
//! - The six volumes ([`PerturbationKind::ALL`]):
//!   1. `original`, as given;
//!   2. `scale_offset`: `3.2 I + 150`, stored as i16 with a non-unit scl_slope and intercept
//!      (integer storage with scaling);
//!   3. `bias_rician`: a smooth multiplicative field of +-15 % (a sine of a tilted plane through
//!      the volume, so it spans the whole range once), then Rician noise of sigma 3 % of the
//!      head's 99th percentile on the biased signal, everywhere (air becomes a Rayleigh floor, as
//!      in magnitude images), stored as f32;
//!   4. `thick_lps`: 3 mm slices (the mean of 3 consecutive slices along k, voxel size tripled,
//!      a leftover of 1-2 slices dropped) stored LPS (i and j flipped, the affine flipped with
//!      them so every voxel keeps its world position; see `perturb_geometry`);
//!   5. `hot_voxels`: 8 voxels inside the head set to 20-40x the head's maximum (saturated
//!      vessels, spikes), stored as i16 with the slope the range needs;
//!   6. `float_negative`: f32 storage with scl_slope 0.05 and an intercept that puts every
//!      physical value below 0.
//! - No panics on input: mismatched lengths, empty heads and unwritable ranges are
//!   [`PerturbError`]s.

use super::perturb_geometry::{thick_slices, to_lps};
use crate::volume::{LinearMap, Samples, Volume, VolumeError};

/// What a voxel is, for the truth ranges.
#[repr(u8)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Label {
    /// Outside the head (air, or zeros outside a skull-stripped brain).
    Outside = 0,
    /// Inside the head but none of the three classes (skull, partial volume, lesions).
    Head = 1,
    /// Cerebrospinal fluid.
    Csf = 2,
    /// Grey matter.
    Gm = 3,
    /// White matter.
    Wm = 4,
}

impl Label {
    /// Whether the voxel is inside the head.
    pub fn in_head(self) -> bool {
        self != Label::Outside
    }
}

/// The six volumes of the study.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PerturbationKind {
    /// The input as given.
    Original,
    /// `3.2 I + 150`, i16 storage with scl_slope/intercept.
    ScaleOffset,
    /// +-15 % smooth bias field, then Rician noise.
    BiasRician,
    /// 3 mm slices stored LPS.
    ThickLps,
    /// A handful of voxels at 20-40x the maximum.
    HotVoxels,
    /// f32 with scl_slope/intercept, all physical values negative.
    FloatNegative,
}

impl PerturbationKind {
    /// Every kind, in table order.
    pub const ALL: [PerturbationKind; 6] = [
        PerturbationKind::Original,
        PerturbationKind::ScaleOffset,
        PerturbationKind::BiasRician,
        PerturbationKind::ThickLps,
        PerturbationKind::HotVoxels,
        PerturbationKind::FloatNegative,
    ];

    /// Short name for tables, JSON and file names.
    pub fn name(self) -> &'static str {
        match self {
            PerturbationKind::Original => "original",
            PerturbationKind::ScaleOffset => "scale_offset",
            PerturbationKind::BiasRician => "bias_rician",
            PerturbationKind::ThickLps => "thick_lps",
            PerturbationKind::HotVoxels => "hot_voxels",
            PerturbationKind::FloatNegative => "float_negative",
        }
    }
}

/// One volume of the study with its labels on the same grid.
#[derive(Clone, Debug)]
pub struct Perturbed {
    /// Which perturbation.
    pub kind: PerturbationKind,
    /// The volume as the engine will see it.
    pub volume: Volume,
    /// One label per voxel, same order as the samples.
    pub labels: Vec<Label>,
}

/// Why the perturbations could not be built.
#[derive(Debug, thiserror::Error)]
pub enum PerturbError {
    /// The labels (or a map) do not cover the volume voxel for voxel.
    #[error("{what} has {got} voxels but the T1 volume has {expected}; give maps on the T1's grid")]
    GridMismatch {
        /// Which input.
        what: String,
        /// Its voxel count.
        got: usize,
        /// The volume's.
        expected: usize,
    },
    /// No finite voxel is inside the head.
    #[error("no finite voxel of {0:?} is inside the head; check the tissue maps")]
    EmptyHead(String),
    /// The volume is too thin along k for 3 mm slices.
    #[error("{0:?} has fewer than 3 slices along k; thick slices need at least 3")]
    TooThin(String),
    /// A built volume was rejected (non-finite range).
    #[error("a perturbed volume could not be formed: {0}")]
    Volume(#[from] VolumeError),
}

/// Labels from a T1 volume and GM/WM probability maps on its grid: GM or WM where that map is
/// at least half of its own maximum and above the other map; inside the head (T1 above its
/// finite minimum: the skull-stripped template's zeros are outside) and neither: CSF when
/// `gm + wm` is below a quarter of the maps' maxima, else [`Label::Head`] (partial volume).
pub fn labels_from_maps(t1: &Volume, gm: &Volume, wm: &Volume) -> Result<Vec<Label>, PerturbError> {
    let n = t1.voxel_count();
    for (what, map) in [("the GM map", gm), ("the WM map", wm)] {
        if map.voxel_count() != n {
            return Err(PerturbError::GridMismatch {
                what: format!("{what} {:?}", map.name),
                got: map.voxel_count(),
                expected: n,
            });
        }
    }
    let t1v = physical(t1);
    let gmv = physical(gm);
    let wmv = physical(wm);
    let finite_max = |v: &[f64]| {
        v.iter()
            .copied()
            .filter(|x| x.is_finite())
            .fold(0.0, f64::max)
    };
    let floor = t1v
        .iter()
        .copied()
        .filter(|x| x.is_finite())
        .fold(f64::INFINITY, f64::min);
    let (gmax, wmax) = (finite_max(&gmv), finite_max(&wmv));
    let labels = (0..n)
        .map(|i| {
            let (t, g, w) = (t1v[i], gmv[i] / gmax.max(1e-300), wmv[i] / wmax.max(1e-300));
            if !(t.is_finite() && t > floor) {
                Label::Outside
            } else if g >= 0.5 && g >= w {
                Label::Gm
            } else if w >= 0.5 && w > g {
                Label::Wm
            } else if g + w < 0.25 {
                Label::Csf
            } else {
                Label::Head
            }
        })
        .collect();
    Ok(labels)
}

/// The original and the five perturbations of `volume` with `labels` (one per voxel).
pub fn build_all(volume: &Volume, labels: &[Label]) -> Result<Vec<Perturbed>, PerturbError> {
    if labels.len() != volume.voxel_count() {
        return Err(PerturbError::GridMismatch {
            what: "the label vector".into(),
            got: labels.len(),
            expected: volume.voxel_count(),
        });
    }
    PerturbationKind::ALL
        .iter()
        .map(|&kind| build(kind, volume, labels))
        .collect()
}

/// One perturbation of `volume` (labels must cover it; see [`build_all`]).
pub fn build(
    kind: PerturbationKind,
    volume: &Volume,
    labels: &[Label],
) -> Result<Perturbed, PerturbError> {
    if labels.len() != volume.voxel_count() {
        return Err(PerturbError::GridMismatch {
            what: "the label vector".into(),
            got: labels.len(),
            expected: volume.voxel_count(),
        });
    }
    let values = physical(volume);
    let head = head_stats(volume, &values, labels)?;
    let name = format!("{} [{}]", volume.name, kind.name());
    let (volume, labels) = match kind {
        PerturbationKind::Original => (volume.clone(), labels.to_vec()),
        PerturbationKind::ScaleOffset => {
            let v: Vec<f64> = values.iter().map(|x| 3.2 * x + 150.0).collect();
            (store_i16(volume, &name, &v, 150.0)?, labels.to_vec())
        }
        PerturbationKind::BiasRician => {
            let v = bias_rician(volume.dims, &values, 0.03 * head.p99, 0x6269_6173);
            (
                store_f32(volume, &name, &v, LinearMap::IDENTITY)?,
                labels.to_vec(),
            )
        }
        PerturbationKind::ThickLps => {
            let (thick, thick_labels) = thick_slices(volume, &values, labels)?;
            let lps = to_lps(&thick, &thick_labels.0, &thick_labels.1)?;
            let mut out = lps.0;
            out.name = name;
            (out, lps.1)
        }
        PerturbationKind::HotVoxels => {
            let v = with_hot_voxels(&values, labels, head.max, 8, 0x686f_7421);
            (store_i16(volume, &name, &v, 0.0)?, labels.to_vec())
        }
        PerturbationKind::FloatNegative => {
            let intercept = -(1.2 * head.max.abs() + 100.0);
            let map = LinearMap {
                slope: 0.05,
                intercept,
            };
            let v: Vec<f64> = values.iter().map(|x| x + intercept).collect();
            (store_f32(volume, &name, &v, map)?, labels.to_vec())
        }
    };
    Ok(Perturbed {
        kind,
        volume,
        labels,
    })
}

/// Physical intensity of every voxel (`stored * slope + intercept`).
pub fn physical(volume: &Volume) -> Vec<f64> {
    (0..volume.samples.len())
        .map(|i| volume.to_physical.apply(volume.samples.get(i)))
        .collect()
}

/// The head's maximum and 99th percentile (finite voxels inside the head).
struct HeadStats {
    max: f64,
    p99: f64,
}

fn head_stats(
    volume: &Volume,
    values: &[f64],
    labels: &[Label],
) -> Result<HeadStats, PerturbError> {
    let mut inside: Vec<f64> = values
        .iter()
        .zip(labels)
        .filter(|(v, l)| l.in_head() && v.is_finite())
        .map(|(v, _)| *v)
        .collect();
    if inside.is_empty() {
        return Err(PerturbError::EmptyHead(volume.name.clone()));
    }
    inside.sort_unstable_by(f64::total_cmp);
    let at = |q: f64| inside[((inside.len() - 1) as f64 * q).round() as usize];
    Ok(HeadStats {
        max: at(1.0),
        p99: at(0.99),
    })
}

/// splitmix64 with Box-Muller normals (deterministic, no dependency).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn uniform(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }

    fn normal(&mut self) -> f64 {
        let u = 1.0 - self.uniform(); // (0, 1]: ln is finite
        let v = self.uniform();
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// The multiplicative bias field at voxel (i, j, k): `1 + 0.15 sin(pi/2 * t)` with `t` a tilted
/// plane in [-1, 1] across the volume, so the field sweeps its full +-15 % once, smoothly.
pub fn bias_field(dims: [usize; 3], index: [usize; 3]) -> f64 {
    let unit = |axis: usize| {
        let n = dims[axis].max(2) as f64 - 1.0;
        2.0 * index[axis] as f64 / n - 1.0
    };
    let t = 0.6 * unit(0) + 0.3 * unit(1) - 0.1 * unit(2);
    1.0 + 0.15 * (std::f64::consts::FRAC_PI_2 * t).sin()
}

/// `|b I + n1 + i n2|` with independent normals of standard deviation `sigma` per voxel.
fn bias_rician(dims: [usize; 3], values: &[f64], sigma: f64, seed: u64) -> Vec<f64> {
    let mut rng = Rng(seed);
    let mut out = Vec::with_capacity(values.len());
    for (index, &v) in values.iter().enumerate() {
        let i = index % dims[0];
        let j = (index / dims[0]) % dims[1];
        let k = index / (dims[0] * dims[1]);
        let real = bias_field(dims, [i, j, k]) * v + sigma * rng.normal();
        let imaginary = sigma * rng.normal();
        out.push(real.hypot(imaginary));
    }
    out
}

/// `count` distinct voxels inside the head set to 20-40x `max` (positions and factors from
/// `seed`); the rest unchanged. With fewer head voxels than `count`, every head voxel is hot.
fn with_hot_voxels(
    values: &[f64],
    labels: &[Label],
    max: f64,
    count: usize,
    seed: u64,
) -> Vec<f64> {
    let head: Vec<usize> = (0..values.len()).filter(|&i| labels[i].in_head()).collect();
    let mut out = values.to_vec();
    let mut rng = Rng(seed);
    let mut chosen = std::collections::BTreeSet::new();
    let want = count.min(head.len());
    while chosen.len() < want {
        chosen.insert(head[(rng.next() % head.len() as u64) as usize]);
    }
    for &i in &chosen {
        out[i] = max.abs().max(1.0) * (20.0 + 20.0 * rng.uniform());
    }
    out
}

/// The indices of the hot voxels of a [`PerturbationKind::HotVoxels`] volume (for tests and
/// reports): the values above the topmost jump of at least 15x between consecutive sorted
/// values (hot voxels are at least 20x the ordinary maximum). Meant for positive volumes.
pub fn hot_voxel_indices(values: &[f64]) -> Vec<usize> {
    let mut sorted: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    sorted.sort_unstable_by(f64::total_cmp);
    let Some(ordinary) = sorted
        .windows(2)
        .rev()
        .find(|w| w[0] > 0.0 && w[1] >= 15.0 * w[0])
        .map(|w| w[0])
    else {
        return Vec::new();
    };
    (0..values.len())
        .filter(|&i| values[i] > ordinary)
        .collect()
}

/// Physical `values` stored as f32 under `map` (`stored = (v - intercept) / slope`).
fn store_f32(
    like: &Volume,
    name: &str,
    values: &[f64],
    map: LinearMap,
) -> Result<Volume, PerturbError> {
    let stored: Vec<f32> = values
        .iter()
        .map(|v| ((v - map.intercept) / map.slope) as f32)
        .collect();
    Ok(Volume::from_voxels(
        name,
        like.dims,
        Samples::from_f32(&stored),
        like.orientation.affine,
        map,
    )?)
}

/// Physical `values` stored as i16 with `intercept` and the slope that maps the largest
/// `|v - intercept|` to 32000 (never below 1/64, so small ranges are not blown up into noise).
fn store_i16(
    like: &Volume,
    name: &str,
    values: &[f64],
    intercept: f64,
) -> Result<Volume, PerturbError> {
    let reach = values
        .iter()
        .filter(|v| v.is_finite())
        .map(|v| (v - intercept).abs())
        .fold(0.0, f64::max);
    let slope = (reach / 32000.0).max(1.0 / 64.0);
    let stored: Vec<i16> = values
        .iter()
        .map(|v| {
            let s = ((v - intercept) / slope).round();
            // Non-finite inputs become 0 (i16 cannot hold them); the range is bounded above.
            if s.is_finite() {
                s.clamp(-32767.0, 32767.0) as i16
            } else {
                0
            }
        })
        .collect();
    Ok(Volume::from_voxels(
        name,
        like.dims,
        Samples::from_i16(&stored),
        like.orientation.affine,
        LinearMap { slope, intercept },
    )?)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) fn small() -> (Volume, Vec<Label>) {
        let dims = [4, 3, 7];
        let n = 4 * 3 * 7;
        let values: Vec<u16> = (0..n as u16).map(|i| 10 + i * 3).collect();
        let affine = [
            [2.0, 0.0, 0.0, -3.0],
            [0.0, 1.0, 0.0, 5.0],
            [0.0, 0.0, 1.5, -7.0],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let v = Volume::from_voxels(
            "small",
            dims,
            Samples::from_u16(&values),
            affine,
            LinearMap::IDENTITY,
        )
        .unwrap();
        let labels = (0..n)
            .map(|i| match i % 5 {
                0 => Label::Outside,
                1 => Label::Csf,
                2 => Label::Gm,
                3 => Label::Wm,
                _ => Label::Head,
            })
            .collect();
        (v, labels)
    }

    #[test]
    fn every_perturbation_is_built_and_stores_what_it_says() {
        let (v, labels) = small();
        let all = build_all(&v, &labels).unwrap();
        assert_eq!(all.len(), 6);
        let orig = physical(&v);
        for p in &all {
            assert_eq!(p.labels.len(), p.volume.voxel_count(), "{:?}", p.kind);
        }
        let scaled = physical(&all[1].volume);
        assert!(all[1].volume.to_physical.slope != 1.0);
        for (a, b) in orig.iter().zip(&scaled) {
            assert!((3.2 * a + 150.0 - b).abs() <= all[1].volume.to_physical.slope);
        }
        let negative = physical(&all[5].volume);
        assert!(negative.iter().all(|&x| x < 0.0));
        for (a, b) in orig.iter().zip(&negative) {
            assert!((b - a - (negative[0] - orig[0])).abs() < 1e-2);
        }
        let hot = physical(&all[4].volume);
        let found = hot_voxel_indices(&hot);
        assert_eq!(found.len(), 8);
        assert!(found.iter().all(|&i| labels[i].in_head()));
        let biased = physical(&all[2].volume);
        assert!(biased.iter().all(|&x| x >= 0.0));
        assert_ne!(biased, orig);
    }

    #[test]
    fn bias_field_spans_plus_minus_15_percent_smoothly() {
        let dims = [20, 20, 20];
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        for k in 0..20 {
            for j in 0..20 {
                for i in 0..20 {
                    let b = bias_field(dims, [i, j, k]);
                    lo = lo.min(b);
                    hi = hi.max(b);
                    if i > 0 {
                        assert!((b - bias_field(dims, [i - 1, j, k])).abs() < 0.02);
                    }
                }
            }
        }
        assert!(
            (lo - 0.85).abs() < 1e-9 && (hi - 1.15).abs() < 1e-9,
            "{lo} {hi}"
        );
    }

    #[test]
    fn bad_inputs_are_errors_not_panics() {
        let (v, labels) = small();
        assert!(matches!(
            build_all(&v, &labels[1..]),
            Err(PerturbError::GridMismatch { .. })
        ));
        let outside = vec![Label::Outside; labels.len()];
        assert!(matches!(
            build_all(&v, &outside),
            Err(PerturbError::EmptyHead(_))
        ));
        let flat = Volume::from_voxels(
            "flat",
            [2, 2, 2],
            Samples::from_u8(vec![5; 8]),
            v.orientation.affine,
            LinearMap::IDENTITY,
        )
        .unwrap();
        assert!(matches!(
            build(PerturbationKind::ThickLps, &flat, &[Label::Gm; 8]),
            Err(PerturbError::TooThin(_))
        ));
        assert!(matches!(
            labels_from_maps(&v, &flat, &flat),
            Err(PerturbError::GridMismatch { .. })
        ));
    }
}
