//! Region-of-interest statistics (issue 31 item 3): the voxels whose centres lie in a sphere or
//! a box given in world millimetres, their count, volume, and the mean, SD, minimum and maximum
//! of their physical values (the file's scaling applied: Hounsfield units for CT).
//!
//! Decisions:
//! - A voxel belongs to the region when its centre does (FSLeyes', ITK-SNAP's and NiiVue's
//!   rule); the volume is the count times one voxel's volume (|det| of the affine's linear
//!   part), so an oblique grid is measured in mm^3 too.
//! - Only the voxels inside the region's index-space bounding box are visited (its eight world
//!   corners through the inverse affine, clipped to the grid): a 10 mm sphere in a 256^3 head
//!   visits a few thousand voxels, not 16 M. The box is the region's world box, so a region
//!   larger than the volume is clipped to it, never an allocation.
//! - Non-finite samples are left out (counted in `skipped`), as the histogram does; the mean
//!   and SD are accumulated in f64 with Welford's update (no cancellation on CT's -1000 HU).

use super::Volume;
use glam::{DMat4, DVec3, DVec4};

/// A region in world millimetres (RAS+).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Region {
    /// Centre and radius, mm.
    Sphere {
        /// Centre, world mm.
        centre: [f64; 3],
        /// Radius, mm.
        radius_mm: f64,
    },
    /// Two opposite corners of an axis-aligned (world) box, mm.
    Box {
        /// One corner.
        a: [f64; 3],
        /// The opposite corner.
        b: [f64; 3],
    },
}

impl Region {
    /// Whether world point `p` lies in the region (on the boundary counts).
    pub fn contains(&self, p: DVec3) -> bool {
        match *self {
            Region::Sphere { centre, radius_mm } => {
                p.distance_squared(DVec3::from_array(centre)) <= radius_mm * radius_mm
            }
            Region::Box { a, b } => {
                let (lo, hi) = corners(a, b);
                p.cmpge(lo).all() && p.cmple(hi).all()
            }
        }
    }

    /// The world box around the region (min, max corners).
    pub fn world_box(&self) -> (DVec3, DVec3) {
        match *self {
            Region::Sphere { centre, radius_mm } => {
                let c = DVec3::from_array(centre);
                let r = DVec3::splat(radius_mm.abs());
                (c - r, c + r)
            }
            Region::Box { a, b } => corners(a, b),
        }
    }

    /// Whether every number is finite (a region made from a script or a document).
    pub fn is_finite(&self) -> bool {
        match *self {
            Region::Sphere { centre, radius_mm } => {
                centre.iter().all(|v| v.is_finite()) && radius_mm.is_finite()
            }
            Region::Box { a, b } => a.iter().chain(&b).all(|v| v.is_finite()),
        }
    }
}

fn corners(a: [f64; 3], b: [f64; 3]) -> (DVec3, DVec3) {
    let (a, b) = (DVec3::from_array(a), DVec3::from_array(b));
    (a.min(b), a.max(b))
}

/// What a region holds.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct RoiStats {
    /// Voxels whose centre lies in the region and whose value is finite.
    pub voxels: u64,
    /// `voxels` times one voxel's volume, mm^3.
    pub volume_mm3: f64,
    /// Mean of the physical values (None without a voxel).
    pub mean: Option<f64>,
    /// Sample standard deviation (n - 1; None below two voxels).
    pub sd: Option<f64>,
    /// Smallest physical value.
    pub min: Option<f64>,
    /// Largest physical value.
    pub max: Option<f64>,
    /// Voxels in the region left out for a non-finite value.
    pub skipped: u64,
}

/// The statistics of frame 0 of `volume` inside `region` (module doc).
pub fn roi_stats(volume: &Volume, region: &Region) -> RoiStats {
    let index_to_world = DMat4::from_cols_array_2d(&volume.orientation.affine).transpose();
    let voxel_mm3 = index_to_world.determinant().abs();
    let world_to_index = index_to_world.inverse();
    let mut stats = Accumulator::default();
    if let Some(ranges) = region
        .is_finite()
        .then(|| index_box(&world_to_index, region.world_box(), volume.dims))
        .flatten()
    {
        let [nx, ny, _] = volume.dims;
        for k in ranges[2].0..=ranges[2].1 {
            for j in ranges[1].0..=ranges[1].1 {
                for i in ranges[0].0..=ranges[0].1 {
                    let centre = index_to_world * DVec4::new(i as f64, j as f64, k as f64, 1.0);
                    if !region.contains(centre.truncate()) {
                        continue;
                    }
                    let stored = volume.samples.get(i + nx * (j + ny * k));
                    stats.add(volume.to_physical.apply(stored));
                }
            }
        }
    }
    stats.finish(voxel_mm3)
}

/// The inclusive index ranges per axis that the world box maps into, clipped to the grid; None
/// when it misses the grid or the affine is singular.
fn index_box(
    world_to_index: &DMat4,
    (lo, hi): (DVec3, DVec3),
    dims: [usize; 3],
) -> Option<[(usize, usize); 3]> {
    let mut min = DVec3::splat(f64::INFINITY);
    let mut max = DVec3::splat(f64::NEG_INFINITY);
    for c in 0..8 {
        let corner = DVec3::new(
            if c & 1 == 0 { lo.x } else { hi.x },
            if c & 2 == 0 { lo.y } else { hi.y },
            if c & 4 == 0 { lo.z } else { hi.z },
        );
        let q = (*world_to_index * corner.extend(1.0)).truncate();
        min = min.min(q);
        max = max.max(q);
    }
    if !(min.is_finite() && max.is_finite()) {
        return None;
    }
    let mut out = [(0, 0); 3];
    for a in 0..3 {
        let last = dims[a].checked_sub(1)? as f64;
        let (from, to) = (min[a].ceil().max(0.0), max[a].floor().min(last));
        if from > to {
            return None;
        }
        out[a] = (from as usize, to as usize);
    }
    Some(out)
}

/// Welford's running mean and variance, with the extremes.
#[derive(Default)]
struct Accumulator {
    n: u64,
    mean: f64,
    m2: f64,
    min: f64,
    max: f64,
    skipped: u64,
}

impl Accumulator {
    fn add(&mut self, v: f64) {
        if !v.is_finite() {
            self.skipped += 1;
            return;
        }
        if self.n == 0 {
            (self.min, self.max) = (v, v);
        }
        self.n += 1;
        let d = v - self.mean;
        self.mean += d / self.n as f64;
        self.m2 += d * (v - self.mean);
        self.min = self.min.min(v);
        self.max = self.max.max(v);
    }

    fn finish(self, voxel_mm3: f64) -> RoiStats {
        let some = |v| (self.n > 0).then_some(v);
        RoiStats {
            voxels: self.n,
            volume_mm3: self.n as f64 * voxel_mm3,
            mean: some(self.mean),
            sd: (self.n > 1).then(|| (self.m2 / (self.n - 1) as f64).sqrt()),
            min: some(self.min),
            max: some(self.max),
            skipped: self.skipped,
        }
    }
}

#[cfg(test)]
#[path = "roi_tests.rs"]
mod tests;
