//! Shape phantoms for the vesselness measure: tubes of known radii (0.5, 1, 2 and 3 mm) along
//! x, y, z and an oblique direction; plates (half-thickness 0.5, 1 and 2.5 mm) in three
//! orientations; balls (radius 1, 2, 4 and 6 mm). Each comes with its labelled centre voxels
//! (tube centrelines, plate mid-planes, ball centres), the ground truth of the ROC test "vesselness
//! ranks tube centrelines above plate and blob centres" (tests/vesselness.rs) and of the accuracy
//! study.
//!
//! Decisions:
//! - Three small volumes (one per kind) of 47 x 39 x 31 voxels at 1 x 1 x 1.25 mm (odd sizes,
//!   anisotropic), rather than the brain phantom: the brain phantom's tests pin its histogram
//!   peaks, and shapes of one kind per volume keep the blur of one from touching another's
//!   centres (structures are >= 9 mm apart, 3 sigma of the largest default scale).
//! - Intensity 1 inside, 0 outside, with a linear partial-volume ramp over 1 mm centred on the
//!   surface (so a 0.5 mm tube is a one-voxel line of intensity 1).
//! - Labelled voxels stay >= 8 mm from a tube's or plate's ends and edges, where the shape stops
//!   being a tube or a plate.

use crate::volume::{AffineSource, LinearMap, Orientation, Samples, Volume};

/// Dimensions of each shape volume.
pub const DIMS: [usize; 3] = [47, 39, 31];
/// Voxel spacing (mm).
pub const SPACING_MM: [f64; 3] = [1.0, 1.0, 1.25];

/// What a labelled voxel is the centre of.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ShapeKind {
    /// A tube's centreline (positive).
    Tube,
    /// A plate's mid-plane (negative).
    Plate,
    /// A ball's centre (negative).
    Blob,
}

/// One labelled voxel.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Labelled {
    /// Linear voxel index (x fastest).
    pub index: usize,
    /// The shape it belongs to.
    pub kind: ShapeKind,
    /// Tube or ball radius, or plate half-thickness (mm).
    pub size_mm: f64,
}

/// A shape volume and its labelled centres.
pub struct ShapeVolume {
    /// The volume (f32 samples in [0, 1]).
    pub volume: Volume,
    /// Labelled centre voxels.
    pub labelled: Vec<Labelled>,
}

type Point = [f64; 3];

fn sub(a: Point, b: Point) -> Point {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: Point, b: Point) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Distance from `p` to the segment `a`-`b`.
fn segment_distance(p: Point, a: Point, b: Point) -> f64 {
    let ab = sub(b, a);
    let t = (dot(sub(p, a), ab) / dot(ab, ab)).clamp(0.0, 1.0);
    let q = [a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2]];
    dot(sub(p, q), sub(p, q)).sqrt()
}

/// Signed distance to an axis-aligned box (negative inside).
fn box_distance(p: Point, centre: Point, half: Point) -> f64 {
    let d = [0, 1, 2].map(|a| (p[a] - centre[a]).abs() - half[a]);
    let outside = d.map(|v| v.max(0.0));
    dot(outside, outside).sqrt() + d[0].max(d[1]).max(d[2]).min(0.0)
}

fn world(index: usize) -> Point {
    let [nx, ny, _] = DIMS;
    let p = [index % nx, (index / nx) % ny, index / (nx * ny)];
    [0, 1, 2].map(|a| p[a] as f64 * SPACING_MM[a])
}

/// The voxel nearest to the world point `p` (mm).
fn nearest(p: Point) -> usize {
    let i = [0, 1, 2].map(|a| ((p[a] / SPACING_MM[a]).round().max(0.0) as usize).min(DIMS[a] - 1));
    i[0] + DIMS[0] * (i[1] + DIMS[1] * i[2])
}

/// Builds a volume of the union of shapes given by their signed distances.
fn build(name: &str, sdf: impl Fn(Point) -> f64, labelled: Vec<Labelled>) -> ShapeVolume {
    let n = DIMS.iter().product::<usize>();
    let values: Vec<f32> = (0..n)
        .map(|i| (0.5 - sdf(world(i))).clamp(0.0, 1.0) as f32)
        .collect();
    let volume = Volume {
        name: name.into(),
        dims: DIMS,
        spacing_mm: SPACING_MM,
        orientation: Orientation::from_spacing(SPACING_MM, AffineSource::Synthetic),
        samples: Samples::from_f32(&values),
        to_physical: LinearMap::IDENTITY,
        warnings: vec![],
        facts: Default::default(),
    };
    ShapeVolume { volume, labelled }
}

/// Tubes: (radius, start, end); the labelled centreline runs between the given fractions.
const TUBES: [(f64, Point, Point); 4] = [
    (0.5, [4.0, 8.0, 7.5], [42.0, 8.0, 7.5]),
    (1.0, [8.0, 4.0, 27.5], [8.0, 34.0, 27.5]),
    (2.0, [30.0, 30.0, 3.75], [30.0, 30.0, 33.75]),
    (3.0, [14.667, 27.333, 15.333], [33.333, 8.667, 24.667]),
];

/// The tube volume.
pub fn tubes() -> ShapeVolume {
    let mut labelled = Vec::new();
    for (r, a, b) in TUBES {
        let ab = sub(b, a);
        let len = dot(ab, ab).sqrt();
        let mut s = 8.0;
        while s <= len - 8.0 {
            let p = [0, 1, 2].map(|k| a[k] + ab[k] * s / len);
            labelled.push(Labelled {
                index: nearest(p),
                kind: ShapeKind::Tube,
                size_mm: r,
            });
            s += 1.0;
        }
    }
    labelled.dedup_by_key(|l| l.index);
    build(
        "vesselness tubes",
        |p| {
            TUBES
                .iter()
                .map(|(r, a, b)| segment_distance(p, *a, *b) - r)
                .fold(f64::INFINITY, f64::min)
        },
        labelled,
    )
}

/// Plates: (centre, half extents); the thin axis's half extent is the half-thickness.
const PLATES: [(Point, Point); 3] = [
    ([23.0, 10.0, 10.0], [19.0, 7.0, 1.0]),
    ([30.0, 28.0, 18.75], [2.5, 8.0, 14.0]),
    ([10.0, 30.0, 25.0], [6.0, 0.5, 8.0]),
];

/// The plate volume.
pub fn plates() -> ShapeVolume {
    let mut labelled = Vec::new();
    for (centre, half) in PLATES {
        let thin = (0..3)
            .min_by(|&a, &b| half[a].total_cmp(&half[b]))
            .unwrap_or(0);
        // The mid-plane's voxels at least 8 mm (or half the extent) inside the edges.
        let mut seen = std::collections::BTreeSet::new();
        let inner = [0, 1, 2].map(|a| {
            if a == thin {
                0.0
            } else {
                (half[a] - 8.0).max(half[a] / 3.0)
            }
        });
        let steps = |a: usize| {
            let n = (inner[a] * 2.0).round() as i64;
            (0..=n).map(move |k| k as f64 * 0.5 - inner[a])
        };
        for dx in steps(0) {
            for dy in steps(1) {
                for dz in steps(2) {
                    let index = nearest([centre[0] + dx, centre[1] + dy, centre[2] + dz]);
                    if seen.insert(index) {
                        labelled.push(Labelled {
                            index,
                            kind: ShapeKind::Plate,
                            size_mm: half[thin],
                        });
                    }
                }
            }
        }
    }
    build(
        "vesselness plates",
        |p| {
            PLATES
                .iter()
                .map(|(c, h)| box_distance(p, *c, *h))
                .fold(f64::INFINITY, f64::min)
        },
        labelled,
    )
}

/// Balls: (radius, centre).
const BALLS: [(f64, Point); 4] = [
    (1.0, [38.0, 32.0, 30.0]),
    (2.0, [10.0, 10.0, 10.0]),
    (4.0, [32.0, 12.0, 15.0]),
    (6.0, [18.0, 27.0, 22.5]),
];

/// The ball volume.
pub fn blobs() -> ShapeVolume {
    let mut labelled = Vec::new();
    for (r, c) in BALLS {
        let centre = nearest(c);
        let [nx, ny, _] = DIMS;
        // The centre, and its six neighbours where the ball is larger than a voxel.
        let neighbours: &[i64] = if r >= 2.0 {
            &[
                0,
                1,
                -1,
                nx as i64,
                -(nx as i64),
                (nx * ny) as i64,
                -((nx * ny) as i64),
            ]
        } else {
            &[0]
        };
        for &offset in neighbours {
            labelled.push(Labelled {
                index: (centre as i64 + offset) as usize,
                kind: ShapeKind::Blob,
                size_mm: r,
            });
        }
    }
    build(
        "vesselness blobs",
        |p| {
            BALLS
                .iter()
                .map(|(r, c)| dot(sub(p, *c), sub(p, *c)).sqrt() - r)
                .fold(f64::INFINITY, f64::min)
        },
        labelled,
    )
}

/// ROC AUC of scores: the probability that a positive outscores a negative (ties count half).
pub fn roc_auc(positives: &[f64], negatives: &[f64]) -> f64 {
    if positives.is_empty() || negatives.is_empty() {
        return f64::NAN;
    }
    let mut wins = 0.0;
    for p in positives {
        for n in negatives {
            wins += if p > n {
                1.0
            } else if p == n {
                0.5
            } else {
                0.0
            };
        }
    }
    wins / (positives.len() * negatives.len()) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labelled_voxels_lie_inside_their_shapes() {
        for shapes in [tubes(), plates(), blobs()] {
            let values = shapes.volume.samples.to_f64_vec();
            assert!(!shapes.labelled.is_empty());
            for l in &shapes.labelled {
                assert!(values[l.index] > 0.99, "{l:?}: {}", values[l.index]);
            }
        }
    }

    #[test]
    fn auc_counts_pairs() {
        assert_eq!(roc_auc(&[2.0, 3.0], &[1.0]), 1.0);
        assert_eq!(roc_auc(&[1.0], &[1.0, 2.0]), 0.25);
    }
}
