//! Crop box and clip planes: the part of the volume a ray may sample.
//!
//! Decisions:
//! - **Cut the ray interval, not the samples.** Each ray's `[t_near, t_far]` is intersected
//!   with the crop box and with every clip half-space before the samples are placed, exactly (a
//!   slab test and one division per plane). The samples of a clipped ray are then the lattice
//!   `t_near + (i + offset) * dt` inside the clipped interval: nothing outside it is ever
//!   fetched, and empty-space skipping and bricking (which only move along the samples of that
//!   interval) respect the cut without knowing about it. No sample is masked per step.
//! - **The crop box is in fractions of the voxel axes i, j, k** (`--crop X0:X1,Y0:Y1,Z0:Z1`),
//!   so it is a box in index space: fraction f sits at index `-0.5 + f * dim`, and the full crop
//!   `0:1` is exactly the volume's box `[-0.5, dim - 0.5]` (bit for bit in f32 and f64), so an
//!   uncropped render is unchanged.
//! - **Clip planes are in world millimetres** (the NIfTI affine's space): a plane `(n, D)` keeps
//!   the closed half-space `n . x + D >= 0` (the side the normal points to). It is carried to
//!   index space once per frame (`n' = A^T n`, `D' = n . b + D` for `x = A p + b`), normalized
//!   so that `n' . p + D'` is a signed distance in voxels; the ray parameter stays in mm.
//! - **A fixed number of planes** ([`MAX_CLIP_PLANES`]), so the scene stays `Copy` and the
//!   uniform block has a fixed layout.
//!
//! The GLSL twin is `clip_ray` in `shaders/include/clip.glsl`; [`intersect_clipped`] is what the
//! f64 reference raymarch uses.

use super::geometry::{MIN_DIRECTION, VolumeGeometry, face_tolerance, intersect_box};
use glam::{DMat3, DVec3, DVec4};

/// How many clip planes a scene can have.
pub const MAX_CLIP_PLANES: usize = 4;

/// One clip plane in world mm: keeps the points with `normal . x + offset_mm >= 0`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ClipPlane {
    /// Normal (any non-zero length), world axes.
    pub normal: [f64; 3],
    /// D in mm (for a unit normal, minus the plane's distance from the origin along it).
    pub offset_mm: f64,
}

/// The crop box and clip planes of a scene.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Clip {
    /// Per voxel axis i, j, k: the kept range as fractions `[lo, hi]`, `0 <= lo < hi <= 1`.
    pub crop: [[f64; 2]; 3],
    /// Up to [`MAX_CLIP_PLANES`] planes; a ray keeps the intersection of all their half-spaces.
    pub planes: [Option<ClipPlane>; MAX_CLIP_PLANES],
}

impl Default for Clip {
    /// No crop, no plane.
    fn default() -> Self {
        Clip {
            crop: [[0.0, 1.0]; 3],
            planes: [None; MAX_CLIP_PLANES],
        }
    }
}

/// A crop or plane that no scene can have; the message uses the command line's names.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct ClipError(pub String);

/// The clip region in index space, as the raymarch uses it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IndexClip {
    /// Crop box corner with the smallest indices.
    pub lo: DVec3,
    /// Crop box corner with the largest indices.
    pub hi: DVec3,
    /// Planes `(n', D')` with unit `n'` in index space: keeps `n' . p + D' >= 0`.
    pub planes: [DVec4; MAX_CLIP_PLANES],
    /// How many of `planes` are used.
    pub count: usize,
}

impl IndexClip {
    /// Whether index position `p` is kept: inside the volume box `[-0.5, dims - 0.5]`, the crop
    /// box and every plane's half-space (twin of `kept` in clip.glsl).
    pub fn keeps(&self, p: DVec3, dims: [u32; 3]) -> bool {
        let box_hi = DVec3::new(f64::from(dims[0]), f64::from(dims[1]), f64::from(dims[2])) - 0.5;
        let lo = self.lo.max(DVec3::splat(-0.5));
        let hi = self.hi.min(box_hi);
        if p.cmplt(lo).any() || p.cmpgt(hi).any() {
            return false;
        }
        self.planes[..self.count.min(MAX_CLIP_PLANES)]
            .iter()
            .all(|plane| plane.truncate().dot(p) + plane.w >= 0.0)
    }
}

impl Clip {
    /// True when nothing is cut away.
    pub fn is_full(&self) -> bool {
        *self == Clip::default()
    }

    /// Adds a plane; fails when all [`MAX_CLIP_PLANES`] slots are taken.
    pub fn add_plane(&mut self, plane: ClipPlane) -> Result<(), ClipError> {
        let slot = self
            .planes
            .iter_mut()
            .find(|p| p.is_none())
            .ok_or_else(|| {
                ClipError(format!(
                    "at most {MAX_CLIP_PLANES} --clip-plane options can be given"
                ))
            })?;
        *slot = Some(plane);
        Ok(())
    }

    /// Fails on a crop range outside `0 <= lo < hi <= 1` or a plane that is not finite or has a
    /// zero normal.
    pub fn check(&self) -> Result<(), ClipError> {
        for (axis, [lo, hi]) in ["X", "Y", "Z"].iter().zip(self.crop) {
            if !(lo.is_finite() && hi.is_finite() && 0.0 <= lo && lo < hi && hi <= 1.0) {
                return Err(ClipError(format!(
                    "--crop {axis} range {lo}:{hi} must satisfy 0 <= LO < HI <= 1 (fractions of \
                     the volume along that voxel axis)"
                )));
            }
        }
        for plane in self.planes.iter().flatten() {
            let n = DVec3::from_array(plane.normal);
            if !(n.is_finite() && plane.offset_mm.is_finite() && n.length() > 0.0) {
                return Err(ClipError(format!(
                    "--clip-plane {},{},{},{} needs a finite, non-zero normal NX,NY,NZ and a \
                     finite D (mm)",
                    plane.normal[0], plane.normal[1], plane.normal[2], plane.offset_mm
                )));
            }
        }
        Ok(())
    }

    /// The region in `geometry`'s index space. Planes with a non-finite or zero index-space
    /// normal (only possible for a clip that fails [`Clip::check`]) are dropped.
    pub fn to_index(&self, geometry: &VolumeGeometry) -> IndexClip {
        let dims = DVec3::new(
            f64::from(geometry.dims[0]),
            f64::from(geometry.dims[1]),
            f64::from(geometry.dims[2]),
        );
        let lo = DVec3::new(self.crop[0][0], self.crop[1][0], self.crop[2][0]);
        let hi = DVec3::new(self.crop[0][1], self.crop[1][1], self.crop[2][1]);
        let linear = DMat3::from_mat4(geometry.index_to_world);
        let translation = geometry.index_to_world.w_axis.truncate();
        let mut planes = [DVec4::ZERO; MAX_CLIP_PLANES];
        let mut count = 0;
        for plane in self.planes.iter().flatten() {
            let n = DVec3::from_array(plane.normal);
            let n_index = linear.transpose() * n;
            let d_index = n.dot(translation) + plane.offset_mm;
            let length = n_index.length();
            if length > 0.0 && length.is_finite() && d_index.is_finite() {
                planes[count] = (n_index / length).extend(d_index / length);
                count += 1;
            }
        }
        IndexClip {
            lo: -0.5 + lo * dims,
            hi: -0.5 + hi * dims,
            planes,
            count,
        }
    }
}

/// Parses `X0:X1,Y0:Y1,Z0:Z1` (fractions 0..1 of the voxel axes), as `--crop` and the viewer's
/// scripts write it, and checks it.
pub fn parse_crop(text: &str) -> Result<[[f64; 2]; 3], ClipError> {
    let parts: Vec<&str> = text.split(',').collect();
    if parts.len() != 3 {
        return Err(ClipError(format!(
            "`{text}`: expected three ranges X0:X1,Y0:Y1,Z0:Z1 (fractions 0..1), e.g. \
             0:1,0:1,0.5:1"
        )));
    }
    let mut crop = [[0.0; 2]; 3];
    for ((axis, part), range) in ["X", "Y", "Z"].iter().zip(&parts).zip(&mut crop) {
        let (lo, hi) = part.split_once(':').ok_or_else(|| {
            ClipError(format!(
                "{axis} range `{part}`: expected LO:HI, e.g. 0.25:0.75"
            ))
        })?;
        let number = |v: &str| {
            v.trim()
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| {
                    ClipError(format!(
                        "{axis} range `{part}`: `{v}` is not a finite number"
                    ))
                })
        };
        *range = [number(lo)?, number(hi)?];
    }
    Clip {
        crop,
        ..Clip::default()
    }
    .check()?;
    Ok(crop)
}

/// `intersect_box` against the crop box and the clip planes: the ray interval `(t_near, t_far)`
/// (t_near clamped at 0) that lies in the volume, the crop box and every kept half-space, or
/// None. With no crop and no plane it is exactly [`intersect_box`].
pub fn intersect_clipped(
    origin: DVec3,
    direction: DVec3,
    dims: [u32; 3],
    clip: &IndexClip,
) -> Option<(f64, f64)> {
    // The volume box first: the crop box lies inside it, but the box test is the one every
    // unclipped ray takes, tolerance included.
    intersect_box(origin, direction, dims)?;
    let mut t_near = f64::NEG_INFINITY;
    let mut t_far = f64::INFINITY;
    let tolerance = face_tolerance(origin, dims);
    for axis in 0..3 {
        let d = direction[axis];
        let (lo_face, hi_face) = (clip.lo[axis], clip.hi[axis]);
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
    for plane in &clip.planes[..clip.count.min(MAX_CLIP_PLANES)] {
        let normal = plane.truncate();
        let side = normal.dot(origin) + plane.w; // signed distance of the origin, voxels
        let rate = normal.dot(direction); // its change per mm of ray
        if rate.abs() < MIN_DIRECTION {
            if side < 0.0 {
                return None;
            }
            continue;
        }
        let t = -side / rate;
        if rate > 0.0 {
            t_near = t_near.max(t);
        } else {
            t_far = t_far.min(t);
        }
    }
    (t_near <= t_far && t_far >= 0.0).then_some((t_near.max(0.0), t_far))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn geometry(dims: [u32; 3], spacing: [f64; 3], origin: [f64; 3]) -> VolumeGeometry {
        VolumeGeometry::new(
            dims,
            [
                [spacing[0], 0.0, 0.0, origin[0]],
                [0.0, spacing[1], 0.0, origin[1]],
                [0.0, 0.0, spacing[2], origin[2]],
                [0.0, 0.0, 0.0, 1.0],
            ],
        )
        .unwrap()
    }

    #[test]
    fn no_clip_is_exactly_the_box_test() {
        let g = geometry([17, 13, 11], [1.0, 1.5, 2.0], [3.0, -4.0, 5.0]);
        let clip = Clip::default().to_index(&g);
        assert_eq!(clip.lo, DVec3::splat(-0.5));
        assert_eq!(clip.hi, DVec3::new(16.5, 12.5, 10.5));
        for (o, d) in [
            (DVec3::new(-5.0, 3.3, 2.1), DVec3::new(1.0, 0.1, -0.05)),
            (DVec3::new(-0.5, -5.0, 1.0), DVec3::Y),
            (DVec3::splat(4.0), DVec3::new(-0.3, 0.2, 0.9)),
            (DVec3::new(40.0, 3.0, 3.0), DVec3::X),
        ] {
            assert_eq!(
                intersect_clipped(o, d, g.dims, &clip),
                intersect_box(o, d, g.dims)
            );
        }
    }

    #[test]
    fn crop_fractions_are_index_faces() {
        let g = geometry([10, 20, 4], [1.0; 3], [0.0; 3]);
        let clip = Clip {
            crop: [[0.2, 0.6], [0.0, 0.5], [0.25, 1.0]],
            ..Clip::default()
        };
        clip.check().unwrap();
        let c = clip.to_index(&g);
        assert_eq!(c.lo, DVec3::new(1.5, -0.5, 0.5));
        assert_eq!(c.hi, DVec3::new(5.5, 9.5, 3.5));
        // Along +x through the middle: enters at x = 1.5, leaves at x = 5.5.
        let hit = intersect_clipped(DVec3::new(-3.0, 2.0, 2.0), DVec3::X, g.dims, &c).unwrap();
        assert_eq!(hit, (4.5, 8.5));
        // A ray in the cropped-away upper half of y misses.
        assert!(intersect_clipped(DVec3::new(-3.0, 12.0, 2.0), DVec3::X, g.dims, &c).is_none());
    }

    #[test]
    fn plane_entry_lies_on_the_plane_in_world_mm() {
        // Anisotropic spacing and an offset origin: the world plane x = 7 mm keeps x >= 7.
        let g = geometry([17, 13, 11], [0.7, 1.3, 2.1], [-2.0, 1.0, 3.0]);
        let mut clip = Clip::default();
        clip.add_plane(ClipPlane {
            normal: [2.0, 0.0, 0.0],
            offset_mm: -14.0,
        })
        .unwrap();
        clip.check().unwrap();
        let c = clip.to_index(&g);
        let origin_world = DVec3::new(-20.0, 5.0, 10.0);
        let direction_world = DVec3::new(1.0, 0.2, 0.1).normalize();
        let (o, d) = g.ray_to_index(origin_world, direction_world);
        let (t_near, t_far) = intersect_clipped(o, d, g.dims, &c).unwrap();
        let entry = origin_world + direction_world * t_near;
        assert!((entry.x - 7.0).abs() < 1e-9, "entry {entry}");
        let (_, box_far) = intersect_box(o, d, g.dims).unwrap();
        assert_eq!(t_far, box_far);
        // The opposite normal keeps x <= 7: the exit is on the plane.
        let mut flipped = Clip::default();
        flipped
            .add_plane(ClipPlane {
                normal: [-1.0, 0.0, 0.0],
                offset_mm: 7.0,
            })
            .unwrap();
        let (_, t_far) = intersect_clipped(o, d, g.dims, &flipped.to_index(&g)).unwrap();
        assert!(((origin_world + direction_world * t_far).x - 7.0).abs() < 1e-9);
    }

    #[test]
    fn parallel_rays_keep_or_lose_the_whole_half_space() {
        let g = geometry([8, 8, 8], [1.0; 3], [0.0; 3]);
        let mut clip = Clip::default();
        clip.add_plane(ClipPlane {
            normal: [1.0, 0.0, 0.0],
            offset_mm: -3.0,
        })
        .unwrap();
        let c = clip.to_index(&g);
        let kept = intersect_clipped(DVec3::new(5.0, -2.0, 4.0), DVec3::Y, g.dims, &c);
        assert_eq!(kept, Some((1.5, 9.5)));
        assert!(intersect_clipped(DVec3::new(1.0, -2.0, 4.0), DVec3::Y, g.dims, &c).is_none());
    }

    #[test]
    fn bad_crops_and_planes_are_refused_with_the_option_name() {
        for crop in [
            [0.5, 0.5],
            [0.6, 0.4],
            [-0.1, 1.0],
            [0.0, 1.1],
            [f64::NAN, 1.0],
        ] {
            let clip = Clip {
                crop: [[0.0, 1.0], crop, [0.0, 1.0]],
                ..Clip::default()
            };
            let e = clip.check().unwrap_err();
            assert!(e.0.contains("--crop Y"), "{e}");
        }
        let mut clip = Clip::default();
        clip.add_plane(ClipPlane {
            normal: [0.0; 3],
            offset_mm: 1.0,
        })
        .unwrap();
        assert!(clip.check().unwrap_err().0.contains("--clip-plane"));
        let mut full = Clip::default();
        for _ in 0..MAX_CLIP_PLANES {
            full.add_plane(ClipPlane {
                normal: [1.0, 0.0, 0.0],
                offset_mm: 0.0,
            })
            .unwrap();
        }
        assert!(
            full.add_plane(ClipPlane {
                normal: [1.0, 0.0, 0.0],
                offset_mm: 0.0
            })
            .is_err()
        );
    }
}
