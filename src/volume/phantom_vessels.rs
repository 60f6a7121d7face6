//! The phantom's vessels of known radii (issue 15 item 6): four straight segments inside the
//! brain's white matter, of radius 3, 2, 1 and 0.5 mm, along x, y, z and one oblique
//! direction, for measuring vesselness and thin-structure rendering against a known answer.
//!
//! Decisions:
//! - Radii are the phantom's "mm" (cohort-A voxels scaled like every other length, see the
//!   phantom's module doc) with NO floor in voxels: a floor would make the known radius wrong,
//!   which is the point of these vessels. On small grids the thin ones are sub-voxel and show
//!   only as partial-volume brightening (a 0.5 mm vessel of a 96-voxel phantom peaks at about
//!   0.72 of the vessel's contrast on its centre line) or vanish: expected.
//! - Endpoints are in brain-normalised coordinates q (voxel offset / brain semi-axis), chosen at
//!   brain radius <= 0.7 (below the sulci, which reach down to 0.8) and clear of the ventricles,
//!   the lesion with its edema, the fissure and each other, so each vessel is surrounded by WM.
//!   Three lie in the right hemisphere (world x > 0), the oblique one in the left, below the
//!   lesion.
//! - They carry the existing vessel label and intensity ([`super::phantom::Tissue::Vessel`],
//!   1450), blended as one structure with the older vessels (the union of the two distances).

/// One segment: endpoints in brain-normalised coordinates, radius in phantom mm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KnownVessel {
    /// Direction it runs along, as a word (`x`, `y`, `z`, `oblique`).
    pub axis: &'static str,
    /// First endpoint, q units.
    pub from: [f64; 3],
    /// Second endpoint, q units.
    pub to: [f64; 3],
    /// Radius in phantom mm.
    pub radius_mm: f64,
}

/// The vessels of known radii (module doc).
pub const KNOWN_VESSELS: [KnownVessel; 4] = [
    KnownVessel {
        axis: "x",
        from: [0.25, 0.35, -0.25],
        to: [0.55, 0.35, -0.25],
        radius_mm: 3.0,
    },
    KnownVessel {
        axis: "y",
        from: [0.45, -0.4, -0.35],
        to: [0.45, 0.2, -0.35],
        radius_mm: 2.0,
    },
    KnownVessel {
        axis: "z",
        from: [0.33, -0.3, -0.45],
        to: [0.33, -0.3, 0.35],
        radius_mm: 1.0,
    },
    KnownVessel {
        axis: "oblique",
        from: [-0.5, -0.3, -0.35],
        to: [-0.3, 0.35, -0.15],
        radius_mm: 0.5,
    },
];

/// The segments in voxel offsets from the volume centre.
#[derive(Clone, Debug)]
pub(super) struct Vessels {
    segments: [([f64; 3], [f64; 3], f64); 4],
}

impl Vessels {
    /// `brain`: semi-axes in voxels; `voxels_per_mm`: the phantom's mm scale.
    pub(super) fn new(brain: [f64; 3], voxels_per_mm: f64) -> Vessels {
        let to_voxels = |q: [f64; 3]| -> [f64; 3] { std::array::from_fn(|a| q[a] * brain[a]) };
        Vessels {
            segments: KNOWN_VESSELS.map(|k| {
                (
                    to_voxels(k.from),
                    to_voxels(k.to),
                    k.radius_mm * voxels_per_mm,
                )
            }),
        }
    }

    /// Signed distance (voxels, > 0 inside) to the nearest of the vessels at offset `v`.
    pub(super) fn inside(&self, v: [f64; 3]) -> f64 {
        self.segments
            .iter()
            .map(|(a, b, r)| r - segment_distance(v, *a, *b))
            .fold(f64::NEG_INFINITY, f64::max)
    }
}

/// Distance from `p` to the segment `a`-`b` (only +, -, *, /, sqrt, min/max: deterministic).
fn segment_distance(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let ab: [f64; 3] = std::array::from_fn(|i| b[i] - a[i]);
    let ap: [f64; 3] = std::array::from_fn(|i| p[i] - a[i]);
    let len2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
    let t = if len2 > 0.0 {
        ((ap[0] * ab[0] + ap[1] * ab[1] + ap[2] * ab[2]) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let d: [f64; 3] = std::array::from_fn(|i| ap[i] - t * ab[i]);
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segment_distance_is_perpendicular_inside_and_to_the_end_outside() {
        let (a, b) = ([0.0, 0.0, 0.0], [10.0, 0.0, 0.0]);
        assert_eq!(segment_distance([5.0, 3.0, 4.0], a, b), 5.0);
        assert_eq!(segment_distance([-3.0, 4.0, 0.0], a, b), 5.0);
        assert_eq!(segment_distance([13.0, 0.0, 4.0], a, b), 5.0);
    }

    #[test]
    fn vessels_are_deep_in_the_brain_and_have_the_radii_asked() {
        let radii: Vec<f64> = KNOWN_VESSELS.iter().map(|k| k.radius_mm).collect();
        assert_eq!(radii, [3.0, 2.0, 1.0, 0.5]);
        for k in KNOWN_VESSELS {
            for q in [k.from, k.to] {
                let r = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
                assert!(r <= 0.7, "{} vessel end {q:?} at brain radius {r}", k.axis);
            }
        }
        // Centre line inside, radius out at the surface.
        let v = Vessels::new([60.0, 80.0, 60.0], 1.0);
        let mid = [0.4 * 60.0, 0.35 * 80.0, -0.25 * 60.0];
        assert!((v.inside(mid) - 3.0).abs() < 1e-12);
        assert!(v.inside([mid[0], mid[1] + 3.0, mid[2]]).abs() < 1e-12);
    }
}
