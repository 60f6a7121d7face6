//! Index-space / world-space geometry of a volume, as the raymarch needs it.
//!
//! Decisions: rays are generated in world space (mm, from the NIfTI affine) and marched in index
//! space, where the volume is the box `[-0.5, dim - 0.5]` (voxel centres at integers) and
//! texture coordinates are `(p + 0.5) / dim`. The ray parameter stays in world millimetres
//! (the direction is transformed, not normalized), so the step length, and with it opacity
//! correction, means the same physical distance for anisotropic and oblique volumes.

use glam::{DMat3, DMat4, DVec3, DVec4};

/// Geometry of one volume.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumeGeometry {
    /// Voxels along i, j, k.
    pub dims: [u32; 3],
    /// Index (i, j, k, 1) to world (x, y, z, 1) in mm.
    pub index_to_world: DMat4,
    /// The inverse.
    pub world_to_index: DMat4,
    /// `A^-T`: maps index-space gradients to world-space gradients.
    pub gradient_to_world: DMat3,
    /// World length of the shortest index step (mm): one "voxel" of step size.
    pub voxel_mm: f64,
}

/// The affine cannot be inverted (singular or non-finite): the header's voxel sizes or axes
/// are unusable, which only the header's owner can fix.
#[derive(Debug, thiserror::Error)]
#[error(
    "the voxel spacing ({:e} x {:e} x {:e} mm) is unusable: the index-to-world affine cannot be \
     inverted (determinant {determinant:e}); set the header's pixdim and sform/qform to the real \
     voxel size in mm (nibabel, fslchpixdim)",
    .spacing_mm[0], .spacing_mm[1], .spacing_mm[2]
)]
pub struct SingularAffine {
    /// Determinant of the linear part.
    pub determinant: f64,
    /// Lengths of the affine's three columns (mm per index step).
    pub spacing_mm: [f64; 3],
}

impl VolumeGeometry {
    /// Builds the geometry from dims and a row-major 4x4 affine.
    pub fn new(dims: [u32; 3], affine: [[f64; 4]; 4]) -> Result<Self, SingularAffine> {
        let index_to_world = DMat4::from_cols_array_2d(&affine).transpose();
        let linear = DMat3::from_mat4(index_to_world);
        let determinant = linear.determinant();
        if !determinant.is_finite() || determinant.abs() < 1e-12 || !index_to_world.is_finite() {
            return Err(SingularAffine {
                determinant,
                spacing_mm: [0, 1, 2].map(|c| linear.col(c).length()),
            });
        }
        let voxel_mm = (0..3)
            .map(|c| linear.col(c).length())
            .fold(f64::INFINITY, f64::min);
        Ok(VolumeGeometry {
            dims,
            index_to_world,
            world_to_index: index_to_world.inverse(),
            gradient_to_world: linear.inverse().transpose(),
            voxel_mm,
        })
    }

    /// World-space axis-aligned bounds of the sampled box `[-0.5, dim - 0.5]`.
    pub fn world_bounds(&self) -> (DVec3, DVec3) {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for corner in 0..8 {
            let p = DVec4::new(
                if corner & 1 == 0 {
                    -0.5
                } else {
                    self.dims[0] as f64 - 0.5
                },
                if corner & 2 == 0 {
                    -0.5
                } else {
                    self.dims[1] as f64 - 0.5
                },
                if corner & 4 == 0 {
                    -0.5
                } else {
                    self.dims[2] as f64 - 0.5
                },
                1.0,
            );
            let w = (self.index_to_world * p).truncate();
            lo = lo.min(w);
            hi = hi.max(w);
        }
        (lo, hi)
    }

    /// A world ray (origin, unit direction) in index space; the parameter stays in mm.
    pub fn ray_to_index(&self, origin: DVec3, direction: DVec3) -> (DVec3, DVec3) {
        let o = (self.world_to_index * origin.extend(1.0)).truncate();
        let d = (self.world_to_index * direction.extend(0.0)).truncate();
        (o, d)
    }
}

/// Smallest |direction component| the slab test divides by; smaller ones are treated as
/// parallel to the slab (NUMERICS.md: no 0 * inf).
pub const MIN_DIRECTION: f64 = 1e-20;

/// How far outside a face a ray parallel to it may lie and still count as on the face, in voxels:
/// 1e-4 plus 3e-6 of the larger of the origin's and the box's magnitude. f32 rounding and fused
/// multiply-adds (which NVIDIA's compiler forms and lavapipe's does not) move an origin that lies
/// exactly on a face by a few ulps; within the tolerance clamp-to-edge sampling sees the border
/// voxels, as a ray on the face does. Rays crossing the faces keep exact slab parameters. The
/// GLSL twin is `face_tolerance` in `geometry.glsl`.
pub fn face_tolerance(origin: DVec3, dims: [u32; 3]) -> f64 {
    let o = origin.abs();
    let scale = o
        .max_element()
        .max(dims.iter().copied().max().unwrap_or(0) as f64);
    1e-4 + 3e-6 * scale
}

/// Robust ray/box intersection in index space against the closed box `[-0.5, dim - 0.5]`
/// (parallel rays within [`face_tolerance`] of a face count as on it):
/// `(t_near, t_far)` with `t_near <= t_far` (t_near clamped at 0) on a hit, or None on a miss.
/// A direction component smaller than 1e-20 in magnitude (including +-0, whose sign GPUs need
/// not keep) makes that axis a containment test instead of a division: inside the slab
/// (boundary included) constrains nothing, outside misses. So rays parallel to a face, lying on
/// either face, grazing an edge, or starting inside are all handled without 0 * inf, the same
/// way on both faces. The GLSL twin is `shaders/include/geometry.glsl`.
pub fn intersect_box(origin: DVec3, direction: DVec3, dims: [u32; 3]) -> Option<(f64, f64)> {
    let mut t_near = f64::NEG_INFINITY;
    let mut t_far = f64::INFINITY;
    let tolerance = face_tolerance(origin, dims);
    for axis in 0..3 {
        let d = direction[axis];
        let (lo_face, hi_face) = (-0.5, dims[axis] as f64 - 0.5);
        if d.abs() < MIN_DIRECTION {
            if origin[axis] < lo_face - tolerance || origin[axis] > hi_face + tolerance {
                return None;
            }
            continue;
        }
        let inv = 1.0 / d;
        let lo = (lo_face - origin[axis]) * inv;
        let hi = (hi_face - origin[axis]) * inv;
        t_near = t_near.max(lo.min(hi));
        t_far = t_far.min(lo.max(hi));
    }
    (t_near <= t_far && t_far >= 0.0).then_some((t_near.max(0.0), t_far))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn anisotropic_geometry_uses_the_finest_axis_as_a_voxel() {
        let g = VolumeGeometry::new(
            [10, 10, 10],
            [
                [0.5, 0.0, 0.0, 0.0],
                [0.0, 1.0, 0.0, 0.0],
                [0.0, 0.0, 3.0, 0.0],
                [0.0, 0.0, 0.0, 1.0],
            ],
        )
        .unwrap();
        assert_eq!(g.voxel_mm, 0.5);
        let (lo, hi) = g.world_bounds();
        assert!((lo - DVec3::new(-0.25, -0.5, -1.5)).length() < 1e-12);
        assert!((hi - DVec3::new(4.75, 9.5, 28.5)).length() < 1e-12);
    }

    #[test]
    fn axis_aligned_rays_on_faces_edges_and_corners_hit() {
        let dims = [4, 4, 4];
        // On the face x = -0.5, travelling along +y: crossing faces keep exact parameters.
        let origin = DVec3::new(-0.5, -5.0, 1.0);
        let hit = intersect_box(origin, DVec3::Y, dims).unwrap();
        assert_eq!(hit, (4.5, 8.5));
        assert!((face_tolerance(origin, dims) - (1e-4 + 3e-6 * 5.0)).abs() < 1e-15);
        // Along the edge x = -0.5, z = -0.5.
        assert!(intersect_box(DVec3::new(-0.5, -5.0, -0.5), DVec3::Y, dims).is_some());
        // Through the corner diagonal.
        let d = DVec3::ONE.normalize();
        assert!(intersect_box(DVec3::splat(-1.5), d, dims).is_some());
        // Within the tolerance outside a face (f32 rounding of an origin on it): on the face.
        // Beyond it: a miss, not NaN.
        assert_eq!(
            intersect_box(DVec3::new(-0.50005, -5.0, 1.0), DVec3::Y, dims),
            Some((4.5, 8.5))
        );
        assert!(intersect_box(DVec3::new(-0.501, -5.0, 1.0), DVec3::Y, dims).is_none());
        // Both faces behave alike, whatever the sign of the zero component.
        for zero in [0.0, -0.0] {
            for x in [-0.5, 3.5] {
                let hit = intersect_box(DVec3::new(x, -5.0, 1.0), DVec3::new(zero, 1.0, 0.0), dims);
                assert_eq!(hit, Some((4.5, 8.5)), "face x = {x}, zero {zero}");
            }
        }
    }

    #[test]
    fn camera_inside_starts_at_zero_and_misses_take_no_samples() {
        let (t0, t1) = intersect_box(DVec3::splat(1.5), DVec3::X, [4, 4, 4]).unwrap();
        assert_eq!((t0, t1), (0.0, 2.0));
        assert!(
            intersect_box(DVec3::new(10.0, 1.0, 1.0), DVec3::X, [4, 4, 4]).is_none(),
            "box behind the ray"
        );
    }
}
