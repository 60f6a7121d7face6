//! The head phantom (issue 27 item 5, issue 28): the phantom's brain inside realistic layers
//! instead of the plain dark shell, with eyes in front and a neck below, so brain extraction can
//! be tested against a known brain mask ([`brain_truth`]) in every contrast
//! (src/volume/phantom_contrast.rs).
//!
//! Decisions:
//! - Layers, outside in, as offsets of the brain's ellipsoid (distance t outside the brain hull,
//!   first order, exact on the axes), in phantom mm (phantom.rs module doc; 1 mm is one voxel
//!   at cohort A) with floors in voxels so small grids keep every layer: skin 2 mm (floor 1
//!   voxel), subcutaneous fat 4.5 mm (1.5), muscle 6 mm (1.5) times a weight w that is 1 on the
//!   sides and the back of the head below the vertex and 0 on the top and the forehead
//!   (temporalis and neck muscles), the skull: outer table 2 mm (1), diploe 3 mm (1.5), inner
//!   table 2 mm (1); then the brain's own subarachnoid CSF (3 mm) and the brain as in the plain
//!   phantom. Each layer is a nested structure blended with the phantom's one-voxel ramp.
//! - The brain is smaller than the plain phantom's (semi-axes 0.54 / 0.60 / 0.55 of the
//!   half-extent: 69 / 77 / 53 mm at cohort A) so the head, eyes and face fit in the field of
//!   view on every side but the bottom, where the neck leaves it as in a real scan.
//! - [`Anatomy::Head`] adds, besides the layers ([`Anatomy::Scalp`] has only the layers):
//!   - two eyes: vitreous globes (label Eye, CSF-like in MR) of radius 12 mm (floor 2 voxels)
//!     in orbital fat 3 mm thick (floor 1), centred along the brain surface's outward normal at
//!     brain direction (+-0.3, 0.85, -0.3) at the distance of the CSF, the skull, the fat and
//!     the globe radius, so the orbit touches the skull but never the intracranial space (at
//!     cohort A the centres are 60 mm apart, 27 mm below and 90 mm in front of the brain's
//!     centre); skin wraps the orbit (closed eyelids, bulging in front of the face).
//!   - a face: an ellipsoid (centre (0, 0.78, -0.62), semi-axes (0.70, 0.58, 0.55) in brain
//!     units) and a nose (centre (0, 1.22, -0.88), semi-axes (0.15, 0.22, 0.40)), muscle under
//!     the skin and fat, around and below the eyes;
//!   - a neck: an elliptic cylinder (semi-axes 0.74 / 0.62 brain units, centred 0.08 brain
//!     units anterior) from the bottom of the volume up into the head, muscle under skin and
//!     fat, with a vertebral ring of bone (5 mm, floor 1), a CSF sleeve (2 mm, floor 1) and a
//!     spinal cord of radius 6 mm (floor 1.5 voxels, WM signal in every contrast) on a vertical
//!     axis 0.15 brain units posterior. The cord runs up through the foramen magnum and the
//!     subarachnoid space into the brain's white matter (up to 0.45 brain units below the
//!     centre): the brainstem bridge a brain extractor must cut.
//! - The foramen magnum plane is the horizontal plane through the lowest point of the
//!   intracranial space (the inner table's inner surface on the vertical axis through the
//!   brain's centre, t = CSF layer, z = -(brain z semi-axis + CSF layer) from the centre). The
//!   cord is labelled Cord below it and WM above it (the same signal); the true brain mask
//!   ([`brain_truth`]) is every intracranial label (CSF, GM, WM, lesion, vessel, edema) except
//!   the spinal canal's contents (cord and its CSF sleeve) below the plane.
//! - Deterministic and size-independent like the plain phantom: only basic IEEE operations,
//!   geometry in brain units of the extent.

use super::phantom::{Blend, Phantom, PhantomError, PhantomSpec, Tissue};
use super::phantom_contrast::Contrast;
use super::phantom_math::{ellipsoid_inside, norm3};
use crate::volume::Volume;

/// What surrounds the phantom's brain.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Anatomy {
    /// The plain phantom: a dark skull/scalp shell (label SkullFat), byte-identical to the
    /// phantom before the head existed.
    #[default]
    Shell,
    /// Skin, fat, muscle and a three-layer skull around the brain; no eyes, face or neck.
    Scalp,
    /// The layers plus eyes, a face and a neck with the spinal cord joining the brainstem.
    Head,
}

impl Anatomy {
    /// Whether the brain has the head's (smaller) semi-axes and layered surroundings.
    pub fn is_layered(self) -> bool {
        self != Anatomy::Shell
    }
}

/// Brain semi-axes of the layered anatomies, as fractions of the half-extent (module doc).
pub(super) const HEAD_BRAIN_SEMI: [f64; 3] = [0.54, 0.60, 0.55];

/// Smallest head-brain semi-axis in voxels at cohort A (0.55 * 96): one phantom mm.
pub(super) const HEAD_COHORT_A_BMIN: f64 = 0.55 * 96.0;

/// Thickness of each layer in phantom mm and its floor in voxels (module doc).
pub const SKIN_MM: (f64, f64) = (2.0, 1.0);
/// Subcutaneous fat.
pub const FAT_MM: (f64, f64) = (4.5, 1.5);
/// Muscle where its weight is 1 (the sides and back of the head).
pub const MUSCLE_MM: (f64, f64) = (6.0, 1.5);
/// Outer table of the skull.
pub const OUTER_TABLE_MM: (f64, f64) = (2.0, 1.0);
/// Diploe (marrow).
pub const DIPLOE_MM: (f64, f64) = (3.0, 1.5);
/// Inner table of the skull.
pub const INNER_TABLE_MM: (f64, f64) = (2.0, 1.0);

/// Thicknesses in voxels of a layered phantom of `dims` (module doc), outside in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Layers {
    /// Voxels per phantom mm.
    pub voxels_per_mm: f64,
    /// Skin.
    pub skin: f64,
    /// Subcutaneous fat.
    pub fat: f64,
    /// Muscle where its weight is 1.
    pub muscle: f64,
    /// Outer table.
    pub outer_table: f64,
    /// Diploe.
    pub diploe: f64,
    /// Inner table.
    pub inner_table: f64,
    /// Subarachnoid CSF between the inner table and the brain hull.
    pub csf: f64,
}

impl Layers {
    /// The layers of a layered phantom of `dims` voxels.
    pub fn of(dims: [usize; 3]) -> Layers {
        Layers::of_frame(&super::phantom::head_frame(dims))
    }
}

/// The brain frame a head is built around (from phantom.rs's geometry).
pub(super) struct Frame {
    /// Brain semi-axes in voxels.
    pub brain: [f64; 3],
    /// Voxels per phantom mm.
    pub voxels_per_mm: f64,
    /// Subarachnoid CSF thickness in voxels.
    pub csf_layer: f64,
    /// Volume centre in voxel coordinates.
    pub centre: [f64; 3],
}

/// The head's geometry in voxel offsets from the volume centre (RAS: +x right, +y anterior,
/// +z superior).
#[derive(Clone, Debug)]
pub(super) struct HeadGeometry {
    layers: Layers,
    extras: bool,
    eyes: [[f64; 3]; 2],
    eye_r: f64,
    orbit_r: f64,
    face_centre: [f64; 3],
    face_semi: [f64; 3],
    nose_centre: [f64; 3],
    nose_semi: [f64; 3],
    neck_centre_y: f64,
    neck_semi: [f64; 3],
    neck_top: f64,
    canal: Canal,
}

/// The spinal canal: a vertical axis with the cord, its CSF sleeve and the vertebral ring.
#[derive(Clone, Copy, Debug)]
struct Canal {
    y: f64,
    cord_r: f64,
    sleeve_r: f64,
    vertebra_r: f64,
    top: f64,
    foramen: f64,
}

impl Canal {
    fn new(f: &Frame) -> Canal {
        let len = |mm: f64, floor: f64| (mm * f.voxels_per_mm).max(floor);
        let cord_r = len(6.0, 1.5);
        let sleeve_r = cord_r + len(2.0, 1.0);
        Canal {
            y: -0.15 * f.brain[1],
            cord_r,
            sleeve_r,
            vertebra_r: sleeve_r + len(5.0, 1.0),
            top: -0.45 * f.brain[2],
            foramen: -(f.brain[2] + f.csf_layer),
        }
    }

    /// Distance (voxels) from the canal's axis at offset `v`.
    fn radius(&self, v: [f64; 3]) -> f64 {
        let dy = v[1] - self.y;
        (v[0] * v[0] + dy * dy).sqrt()
    }
}

impl HeadGeometry {
    pub(super) fn new(f: &Frame, anatomy: Anatomy) -> HeadGeometry {
        let layers = Layers::of_frame(f);
        let b = f.brain;
        let len = |mm: f64, floor: f64| (mm * f.voxels_per_mm).max(floor);
        let eye_r = len(12.0, 2.0);
        let orbit_r = eye_r + len(3.0, 1.0);
        let depth = layers.csf + layers.inner_table + layers.diploe + layers.outer_table;
        let eyes = [-1.0, 1.0].map(|side| eye_centre(b, [side * 0.3, 0.85, -0.3], depth + orbit_r));
        HeadGeometry {
            layers,
            extras: anatomy == Anatomy::Head,
            eyes,
            eye_r,
            orbit_r,
            face_centre: [0.0, 0.78 * b[1], -0.62 * b[2]],
            face_semi: [0.70 * b[0], 0.58 * b[1], 0.55 * b[2]],
            nose_centre: [0.0, 1.22 * b[1], -0.88 * b[2]],
            nose_semi: [0.15 * b[0], 0.22 * b[1], 0.40 * b[2]],
            neck_centre_y: 0.08 * b[1],
            neck_semi: [0.74 * b[0], 0.62 * b[1], f64::INFINITY],
            neck_top: -0.3 * b[2],
            canal: Canal::new(f),
        }
    }

    /// Muscle weight at brain direction `n` (unit): 1 on the sides and back below the vertex,
    /// 0 on the top and the front, linear in between.
    fn muscle_weight(n: [f64; 3]) -> f64 {
        let side = ((n[0].abs() - 0.35) / 0.35).clamp(0.0, 1.0);
        let back = ((-n[1] - 0.35) / 0.35).clamp(0.0, 1.0);
        let below_vertex = ((0.55 - n[2]) / 0.3).clamp(0.0, 1.0);
        side.max(back) * below_vertex
    }

    /// Blends the extracranial layers at offset `v` into `b` (q: brain-normalised position, r:
    /// its norm, t: distance outside the brain hull). False when the voxel is air.
    pub(super) fn outer(&self, v: [f64; 3], q: [f64; 3], r: f64, t: f64, b: &mut Blend) -> bool {
        let l = &self.layers;
        let n = if r > 1e-9 {
            [q[0] / r, q[1] / r, q[2] / r]
        } else {
            [0.0, 0.0, 1.0]
        };
        let inner_bone = l.csf + l.inner_table;
        let marrow = inner_bone + l.diploe;
        let skull = marrow + l.outer_table;
        let muscle = skull + Self::muscle_weight(n) * l.muscle;
        let mut envelope = muscle + l.fat + l.skin - t;
        let mut soft = muscle - t;
        if self.extras {
            let face = ellipsoid_inside(sub(v, self.face_centre), self.face_semi)
                .max(ellipsoid_inside(sub(v, self.nose_centre), self.nose_semi));
            let lids = self.eye_inside(v, self.orbit_r + l.skin);
            let neck_v = [v[0], v[1] - self.neck_centre_y, 0.0];
            let neck = ellipsoid_inside(neck_v, self.neck_semi).min(self.neck_top - v[2]);
            envelope = envelope.max(face).max(lids).max(neck);
            soft = soft.max(face.max(neck) - l.skin - l.fat);
        }
        if envelope < -0.5 {
            return false;
        }
        b.add(envelope, Tissue::Skin);
        b.add(envelope - l.skin, Tissue::Fat);
        b.add(soft, Tissue::Muscle);
        b.add(skull - t, Tissue::Bone);
        b.add(marrow - t, Tissue::Marrow);
        b.add(inner_bone - t, Tissue::Bone);
        if self.extras {
            let c = &self.canal;
            b.add(
                (c.vertebra_r - c.radius(v)).min(c.foramen - v[2]),
                Tissue::Bone,
            );
            b.add(self.eye_inside(v, self.orbit_r), Tissue::Fat);
            b.add(self.eye_inside(v, self.eye_r), Tissue::Eye);
        }
        true
    }

    /// Signed distance (voxels, > 0 inside) to the nearer of the spheres of `radius` around
    /// the eyes.
    fn eye_inside(&self, v: [f64; 3], radius: f64) -> f64 {
        let d = self
            .eyes
            .iter()
            .map(|e| norm3(sub(v, *e)))
            .fold(f64::INFINITY, f64::min);
        radius - d
    }

    /// Blends the spinal canal's CSF sleeve and the cord over the brain (`hull`: signed
    /// distance to the brain hull, > 0 inside).
    pub(super) fn canal(&self, v: [f64; 3], hull: f64, b: &mut Blend) {
        if !self.extras {
            return;
        }
        let c = &self.canal;
        let rho = c.radius(v);
        if rho > c.sleeve_r + 0.5 || v[2] > c.top + 0.5 {
            return;
        }
        let cap = c.top - v[2];
        b.add((c.sleeve_r - rho).min(-hull).min(cap), Tissue::Csf);
        let cord = if v[2] < c.foramen {
            Tissue::Cord
        } else {
            Tissue::Wm
        };
        b.add((c.cord_r - rho).min(cap), cord);
    }

    /// Whether an intracranial label at offset `v` is in the spinal canal below the foramen
    /// magnum (module doc).
    fn below_foramen(&self, v: [f64; 3]) -> bool {
        self.extras && v[2] < self.canal.foramen && self.canal.radius(v) < self.canal.sleeve_r + 1.0
    }
}

impl Layers {
    fn of_frame(f: &Frame) -> Layers {
        let len = |(mm, floor): (f64, f64)| (mm * f.voxels_per_mm).max(floor);
        Layers {
            voxels_per_mm: f.voxels_per_mm,
            skin: len(SKIN_MM),
            fat: len(FAT_MM),
            muscle: len(MUSCLE_MM),
            outer_table: len(OUTER_TABLE_MM),
            diploe: len(DIPLOE_MM),
            inner_table: len(INNER_TABLE_MM),
            csf: f.csf_layer,
        }
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// Centre of an eye: `offset` voxels along the outward normal of the brain ellipsoid (semi-axes
/// `brain`) at its surface point in brain direction `dir`. The ellipsoid is convex, so the
/// globe's distance to the brain is exactly `offset` minus its radius.
fn eye_centre(brain: [f64; 3], dir: [f64; 3], offset: f64) -> [f64; 3] {
    let n = norm3(dir);
    let p: [f64; 3] = std::array::from_fn(|a| dir[a] / n * brain[a]);
    let normal: [f64; 3] = std::array::from_fn(|a| p[a] / (brain[a] * brain[a]));
    let g = norm3(normal);
    std::array::from_fn(|a| p[a] + offset * normal[a] / g)
}

/// Labels that are intracranial contents when above the foramen magnum.
const BRAIN_LABELS: [Tissue; 6] = [
    Tissue::Csf,
    Tissue::Gm,
    Tissue::Wm,
    Tissue::Lesion,
    Tissue::Vessel,
    Tissue::Edema,
];

/// The true brain mask of a phantom's `labels` (one per voxel of `dims`, made with `anatomy`):
/// the intracranial contents inside the inner table (CSF, GM, WM, lesion, vessels, edema),
/// without the scalp, skull, eyes, face, neck, and the spinal canal below the foramen magnum
/// plane (module doc). Same order as the labels; empty when the lengths disagree.
pub fn brain_truth(labels: &[u8], dims: [usize; 3], anatomy: Anatomy) -> Vec<bool> {
    let count = dims.iter().try_fold(1usize, |a, &d| a.checked_mul(d));
    if count != Some(labels.len()) {
        return Vec::new();
    }
    let frame = super::phantom::head_frame(dims);
    let head = anatomy
        .is_layered()
        .then(|| HeadGeometry::new(&frame, anatomy));
    let [nx, ny, _] = dims;
    labels
        .iter()
        .enumerate()
        .map(|(index, &l)| {
            let brain = BRAIN_LABELS.iter().any(|&t| t as u8 == l);
            brain
                && head.as_ref().is_none_or(|h| {
                    let ijk = [index % nx, (index / nx) % ny, index / (nx * ny)];
                    let v: [f64; 3] = std::array::from_fn(|a| ijk[a] as f64 - frame.centre[a]);
                    !h.below_foramen(v)
                })
        })
        .collect()
}

/// The foramen magnum plane of a head phantom of `dims`, as a voxel index k (fractional): the
/// lowest point of the intracranial space; the cord below it is not brain (module doc).
pub fn foramen_k(dims: [usize; 3]) -> f64 {
    let f = super::phantom::head_frame(dims);
    f.centre[2] - (f.brain[2] + f.csf_layer)
}

/// A head phantom's volume in memory, for tests anywhere: `dims` 1 mm voxels, `contrast`, with
/// or without noise, the default seed (same as `morphray phantom --head --contrast ...`).
pub fn head_volume(
    dims: [usize; 3],
    contrast: Contrast,
    noise: bool,
) -> Result<Volume, PhantomError> {
    Ok(head_phantom(dims, contrast, noise)?.volume)
}

/// [`head_volume`] with its labels and truth ([`Phantom::brain_mask`]).
pub fn head_phantom(
    dims: [usize; 3],
    contrast: Contrast,
    noise: bool,
) -> Result<Phantom, PhantomError> {
    super::phantom::generate(&PhantomSpec::head(dims, contrast, noise))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn muscle_is_on_the_sides_and_back_not_the_top_or_front() {
        assert_eq!(HeadGeometry::muscle_weight([1.0, 0.0, 0.0]), 1.0);
        assert_eq!(HeadGeometry::muscle_weight([0.0, -1.0, 0.0]), 1.0);
        assert_eq!(HeadGeometry::muscle_weight([0.0, 0.0, 1.0]), 0.0);
        assert_eq!(HeadGeometry::muscle_weight([0.0, 1.0, 0.0]), 0.0);
    }

    #[test]
    fn eyes_sit_outside_the_skull_in_front() {
        let frame = super::super::phantom::head_frame([96, 96, 72]);
        let h = HeadGeometry::new(&frame, Anatomy::Head);
        let b = frame.brain;
        for e in h.eyes {
            // In front of the brain, below its equator, and outside it by more than the skull.
            let l = h.layers;
            let skull = l.csf + l.inner_table + l.diploe + l.outer_table;
            assert!(-ellipsoid_inside(e, b) > skull + h.eye_r, "{e:?}");
            assert!(e[1] > b[1] * 0.7 && e[2] < 0.0, "{e:?}");
        }
        assert!(h.eyes[0][0] < 0.0 && h.eyes[1][0] > 0.0);
    }
}
