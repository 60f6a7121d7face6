//! Volumes: what the engine renders, independent of where the voxels came from.
//!
//! Decisions:
//! - A [`Volume`] holds frame 0 of a scan as little-endian [`Samples`] in one of the few encodings
//!   the GPU kernels read directly (u8, i8, u16, i16, f32). Other NIfTI datatypes are converted
//!   once on load (see `nifti`), so every kernel has exactly five variants and never a per-voxel
//!   branch on the datatype.
//! - Physical intensity is `stored * slope + intercept` in f64 ([`LinearMap`]): NIfTI's
//!   scl_slope/scl_inter, plus any offset the loader subtracted to keep f64 data representable in
//!   f32 (for example 1e30 + tiny ranges, NUMERICS.md).
//! - Geometry is a full f64 index-to-world affine (mm, RAS+) with voxel centres at integer indices,
//!   so the sampled box in index space is `[-0.5, dim - 0.5]` per axis.
//! - Non-finite voxels stay in the data (only f32 samples can hold them); every consumer counts and
//!   excludes them.

pub mod nifti;
pub mod phantom;
pub mod samples;
pub mod stats;

pub use samples::{SampleKind, Samples};

/// Maps stored sample values to physical intensities: `physical = stored * slope + intercept`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct LinearMap {
    /// Multiplier applied to a stored sample (never 0, never non-finite).
    pub slope: f64,
    /// Added after the multiplication.
    pub intercept: f64,
}

impl LinearMap {
    /// The identity map: stored samples are physical intensities.
    pub const IDENTITY: LinearMap = LinearMap {
        slope: 1.0,
        intercept: 0.0,
    };

    /// Physical intensity of one stored sample value.
    pub fn apply(&self, stored: f64) -> f64 {
        stored * self.slope + self.intercept
    }
}

/// Where the index-to-world affine came from (NIfTI's three methods, in priority order).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AffineSource {
    /// `sform_code > 0`: the general affine in srow_x/y/z.
    Sform,
    /// `qform_code > 0`: quaternion, offsets, pixdim and qfac.
    Qform,
    /// Neither code set (ANALYZE 7.5 style): a diagonal scaling by pixdim.
    Pixdim,
    /// Built by the engine (the phantom, or raw voxels handed in through the API).
    Synthetic,
}

/// Index-space to world-space (mm) geometry of a volume.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Orientation {
    /// Row-major 4x4 matrix mapping (i, j, k, 1) voxel-centre indices to (x, y, z, 1) in mm.
    pub affine: [[f64; 4]; 4],
    /// Which header field produced [`Orientation::affine`].
    pub source: AffineSource,
}

impl Orientation {
    /// A diagonal affine with the given voxel spacing and the origin at voxel (0, 0, 0).
    pub fn from_spacing(spacing_mm: [f64; 3], source: AffineSource) -> Self {
        let mut affine = [[0.0; 4]; 4];
        for (axis, &s) in spacing_mm.iter().enumerate() {
            affine[axis][axis] = s;
        }
        affine[3][3] = 1.0;
        Orientation { affine, source }
    }

    /// The upper-left 3x3 block: how one index step moves in world space, per axis (columns).
    pub fn linear_part(&self) -> [[f64; 3]; 3] {
        let a = &self.affine;
        [
            [a[0][0], a[0][1], a[0][2]],
            [a[1][0], a[1][1], a[1][2]],
            [a[2][0], a[2][1], a[2][2]],
        ]
    }
}

/// Frame 0 of a scan, ready for the GPU and for the CPU reference kernels.
#[derive(Clone, Debug)]
pub struct Volume {
    /// File name (without directories) or a fixed name such as `phantom`.
    pub name: String,
    /// Voxels along i, j, k (x fastest in [`Volume::samples`]).
    pub dims: [usize; 3],
    /// Voxel spacing along i, j, k in mm (always finite and > 0; the loader repairs bad pixdim).
    pub spacing_mm: [f64; 3],
    /// Index-to-world geometry.
    pub orientation: Orientation,
    /// Stored voxel values of frame 0.
    pub samples: Samples,
    /// Stored-to-physical intensity map.
    pub to_physical: LinearMap,
    /// Repairs made and oddities found while loading, one readable sentence each.
    pub warnings: Vec<String>,
}

impl Volume {
    /// Number of voxels in frame 0.
    pub fn voxel_count(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }
}
