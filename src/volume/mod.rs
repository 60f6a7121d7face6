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

pub mod clusters;
pub mod facts;
pub mod host_memory;
pub mod nifti;
pub mod phantom;
pub mod phantom_contrast;
mod phantom_edema;
pub mod phantom_head;
mod phantom_math;
mod phantom_tissue;
pub mod phantom_vessels;
pub mod roi;
pub mod shape_phantoms;
pub mod source;
pub mod stats;

// The sample containers and the stored-to-physical map are plain data every layer reads: they
// live in `model` (below reference/ and analysis/), re-exported here where volumes are made.
pub use crate::model::{LinearMap, SampleKind, Samples, VoxelGrid};

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
    /// A DICOM series: ImageOrientationPatient, PixelSpacing and the slices'
    /// ImagePositionPatient (LPS turned to RAS).
    Dicom,
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
    /// What the file says about the scan (modality, sequence, timing, names; `facts`), for
    /// deciding its modality and contrast; empty for volumes without metadata.
    pub facts: crate::analysis::ScanFacts,
}

/// Why raw voxels cannot form a volume.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum VolumeError {
    /// A side is 0, or the voxel count overflows.
    #[error(
        "volume dimensions {0:?} must all be at least 1 (and their product must fit in memory)"
    )]
    BadDimensions([usize; 3]),
    /// The sample count does not match the dimensions.
    #[error("{samples} samples do not fill {dims:?} = {expected} voxels")]
    WrongSampleCount {
        /// Dimensions given.
        dims: [usize; 3],
        /// Their product.
        expected: usize,
        /// Samples given.
        samples: usize,
    },
    /// The affine has a non-finite entry, a bottom row other than (0, 0, 0, 1), or a
    /// degenerate (singular) linear part.
    #[error("the index-to-world affine is unusable: {0}")]
    BadAffine(String),
    /// The stored-to-physical map is not invertible or not finite.
    #[error("the intensity map {0:?} needs a finite, non-zero slope and a finite intercept")]
    BadIntensityMap(LinearMap),
}

impl Volume {
    /// Frame 0's samples, grid and intensity map, as the CPU twins read them.
    pub fn voxel_grid(&self) -> VoxelGrid<'_> {
        VoxelGrid {
            samples: &self.samples,
            dims: self.dims,
            to_physical: self.to_physical,
        }
    }

    /// Number of voxels in frame 0.
    pub fn voxel_count(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }

    /// A volume from voxels already in memory (x fastest, then y, then z) and a row-major
    /// index-to-world affine in mm (RAS+, voxel centres at integer indices), for integrators that
    /// hold the scan themselves. Samples are the stored values; `to_physical` maps them to
    /// intensities (use [`LinearMap::IDENTITY`] when they already are).
    pub fn from_voxels(
        name: &str,
        dims: [usize; 3],
        samples: Samples,
        affine: [[f64; 4]; 4],
        to_physical: LinearMap,
    ) -> Result<Volume, VolumeError> {
        let expected = dims
            .iter()
            .try_fold(1usize, |acc, &d| acc.checked_mul(d))
            .filter(|_| dims.iter().all(|&d| d > 0))
            .ok_or(VolumeError::BadDimensions(dims))?;
        if samples.len() != expected {
            return Err(VolumeError::WrongSampleCount {
                dims,
                expected,
                samples: samples.len(),
            });
        }
        if affine.iter().flatten().any(|v| !v.is_finite()) {
            return Err(VolumeError::BadAffine("it has a non-finite entry".into()));
        }
        if affine[3] != [0.0, 0.0, 0.0, 1.0] {
            return Err(VolumeError::BadAffine(format!(
                "its bottom row is {:?}, not [0, 0, 0, 1]",
                affine[3]
            )));
        }
        let column = |axis: usize| (0..3).map(|r| affine[r][axis].powi(2)).sum::<f64>().sqrt();
        let spacing_mm = [column(0), column(1), column(2)];
        let a = &affine;
        let det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
            - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
        let lengths = spacing_mm.iter().product::<f64>();
        if lengths.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)
            || det.abs() < 1e-12 * lengths
        {
            return Err(VolumeError::BadAffine(format!(
                "its linear part is singular (determinant {det:e})"
            )));
        }
        let usable = to_physical.slope.is_finite()
            && to_physical.slope != 0.0
            && to_physical.intercept.is_finite();
        if !usable {
            return Err(VolumeError::BadIntensityMap(to_physical));
        }
        Ok(Volume {
            name: name.to_string(),
            dims,
            spacing_mm,
            orientation: Orientation {
                affine,
                source: AffineSource::Synthetic,
            },
            samples,
            to_physical,
            warnings: Vec::new(),
            facts: crate::analysis::ScanFacts::default(),
        })
    }

    /// Frame 0 of a NIfTI-1/2 file (`.nii`, `.nii.gz`, or a `.hdr`/`.img` pair), with the
    /// loader's repairs listed in [`Volume::warnings`].
    pub fn open(path: &std::path::Path) -> Result<Volume, nifti::NiftiError> {
        nifti::load_path(path, &nifti::LoadOptions::default()).map(|loaded| loaded.volume)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn diagonal(h: f64) -> [[f64; 4]; 4] {
        [
            [h, 0.0, 0.0, 10.0],
            [0.0, h, 0.0, -5.0],
            [0.0, 0.0, 2.0 * h, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ]
    }

    #[test]
    fn raw_voxels_become_a_volume_with_spacing_from_the_affine() {
        let samples = Samples::from_u16(&[7; 2 * 3 * 4]);
        let v = Volume::from_voxels(
            "mem",
            [2, 3, 4],
            samples,
            diagonal(0.5),
            LinearMap::IDENTITY,
        )
        .unwrap();
        assert_eq!(v.spacing_mm, [0.5, 0.5, 1.0]);
        assert_eq!(v.orientation.source, AffineSource::Synthetic);
        assert_eq!(v.voxel_count(), 24);
    }

    #[test]
    fn bad_raw_voxels_are_typed_errors() {
        let s = |n: usize| Samples::from_u8(vec![0; n]);
        let id = LinearMap::IDENTITY;
        assert_eq!(
            Volume::from_voxels("m", [0, 3, 4], s(0), diagonal(1.0), id).unwrap_err(),
            VolumeError::BadDimensions([0, 3, 4])
        );
        assert!(matches!(
            Volume::from_voxels("m", [2, 3, 4], s(23), diagonal(1.0), id),
            Err(VolumeError::WrongSampleCount {
                expected: 24,
                samples: 23,
                ..
            })
        ));
        assert!(matches!(
            Volume::from_voxels("m", [usize::MAX, 2, 2], s(1), diagonal(1.0), id),
            Err(VolumeError::BadDimensions(_))
        ));
        let mut flat = diagonal(1.0);
        flat[2][2] = 0.0;
        assert!(matches!(
            Volume::from_voxels("m", [2, 3, 4], s(24), flat, id),
            Err(VolumeError::BadAffine(_))
        ));
        let mut nan = diagonal(1.0);
        nan[0][3] = f64::NAN;
        assert!(matches!(
            Volume::from_voxels("m", [2, 3, 4], s(24), nan, id),
            Err(VolumeError::BadAffine(_))
        ));
        let zero_slope = LinearMap {
            slope: 0.0,
            intercept: 0.0,
        };
        assert!(matches!(
            Volume::from_voxels("m", [2, 3, 4], s(24), diagonal(1.0), zero_slope),
            Err(VolumeError::BadIntensityMap(_))
        ));
        // Micrometre voxels are fine (singularity is judged relative to the axes' lengths).
        assert!(Volume::from_voxels("m", [2, 3, 4], s(24), diagonal(1e-3), id).is_ok());
    }
}
