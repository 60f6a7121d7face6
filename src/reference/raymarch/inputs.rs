//! The reference raymarch's inputs and their validation: I_norm and the derived volumes as f64
//! arrays, checked once (lengths against dims, finite values), and the typed error for inputs it
//! cannot render.

/// Why the reference cannot render the given inputs.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ReferenceError {
    /// A dimension is zero, or the voxel count does not fit in memory addresses.
    #[error("volume dimensions {dims:?} are empty or too large")]
    BadDims {
        /// The offending dimensions.
        dims: [u32; 3],
    },
    /// A voxel array's length does not match the dimensions.
    #[error("the {what} has {actual} values, but dimensions {dims:?} need {expected}")]
    Length {
        /// Which array (`I_norm`, `gradient magnitude`, ...).
        what: &'static str,
        /// Dimensions it was checked against.
        dims: [u32; 3],
        /// Voxel count of `dims`.
        expected: usize,
        /// Values given.
        actual: usize,
    },
    /// A voxel value is NaN or infinite.
    #[error("the {what} has a non-finite value at voxel {index}")]
    NonFiniteVoxel {
        /// Which array.
        what: &'static str,
        /// Linear index of the first bad voxel (x fastest).
        index: usize,
    },
    /// The geometry describes a different grid than the volume.
    #[error("the geometry's dimensions {geometry:?} differ from the volume's {volume:?}")]
    DimsMismatch {
        /// `VolumeGeometry::dims`.
        geometry: [u32; 3],
        /// `ReferenceVolume::dims`.
        volume: [u32; 3],
    },
    /// The scene reads a precomputed derived volume that was not supplied.
    #[error(
        "the scene reads a precomputed {what} volume, but none was given (supply it, or render \
         with GradientSource::OnTheFly)"
    )]
    MissingDerived {
        /// `gradient magnitude`, `curvature` or `normals`.
        what: &'static str,
    },
    /// A scene, geometry or gradient parameter is out of its domain.
    #[error("the parameter {what} is {value}, which the raymarch cannot use")]
    BadParameter {
        /// Which parameter.
        what: &'static str,
        /// Its value.
        value: f64,
    },
}

/// The normalized volume I_norm, validated: `dims` are all >= 1, `norm` holds exactly
/// `dims[0] * dims[1] * dims[2]` finite values, x fastest.
#[derive(Clone, Copy)]
pub struct ReferenceVolume<'a> {
    pub(super) dims: [u32; 3],
    pub(super) norm: &'a [f64],
}

impl<'a> ReferenceVolume<'a> {
    /// Validates and wraps I_norm (x fastest, then y, then z).
    pub fn new(dims: [u32; 3], norm: &'a [f64]) -> Result<Self, ReferenceError> {
        check_values("I_norm", dims, norm, |v| v.is_finite())?;
        Ok(ReferenceVolume { dims, norm })
    }

    /// Voxels along i, j, k.
    pub fn dims(&self) -> [u32; 3] {
        self.dims
    }

    /// The values, x fastest.
    pub fn norm(&self) -> &'a [f64] {
        self.norm
    }
}

/// Per-voxel derived volumes for `GradientSource::Precomputed` (same dims and order as I_norm),
/// in the units the derivative pass stores: |g| in I_norm per mm, k in I_norm per mm^2, normals
/// as world-space vectors (unit, or zero where |g| <= tau). Only those the scene reads are
/// required; any that is given is validated.
#[derive(Clone, Copy, Default)]
pub struct ReferenceDerived<'a> {
    /// |grad I_norm| per voxel (the gradient texture's `.r`).
    pub gradient_magnitude: Option<&'a [f64]>,
    /// Directional curvature k per voxel (the gradient texture's `.g`).
    pub curvature: Option<&'a [f64]>,
    /// World-space unit gradient direction per voxel (the normal texture's `.xyz`).
    pub normals: Option<&'a [[f64; 3]]>,
}

impl ReferenceDerived<'static> {
    /// No derived volumes (MIP, MinIP, on-the-fly gradients).
    pub const NONE: ReferenceDerived<'static> = ReferenceDerived {
        gradient_magnitude: None,
        curvature: None,
        normals: None,
    };
}

// Debug output names sizes, not millions of voxel values.
impl std::fmt::Debug for ReferenceVolume<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "ReferenceVolume({:?}, {} values)",
            self.dims,
            self.norm.len()
        )
    }
}

impl std::fmt::Debug for ReferenceDerived<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ReferenceDerived")
            .field(
                "gradient_magnitude",
                &self.gradient_magnitude.map(<[f64]>::len),
            )
            .field("curvature", &self.curvature.map(<[f64]>::len))
            .field("normals", &self.normals.map(<[[f64; 3]]>::len))
            .finish()
    }
}

pub(super) fn voxel_count(dims: [u32; 3]) -> Result<usize, ReferenceError> {
    let bad = ReferenceError::BadDims { dims };
    if dims.contains(&0) {
        return Err(bad);
    }
    dims.iter()
        .try_fold(1usize, |n, &d| n.checked_mul(d as usize))
        .ok_or(bad)
}

pub(super) fn check_values<T>(
    what: &'static str,
    dims: [u32; 3],
    values: &[T],
    finite: impl Fn(&T) -> bool,
) -> Result<(), ReferenceError> {
    let expected = voxel_count(dims)?;
    if values.len() != expected {
        return Err(ReferenceError::Length {
            what,
            dims,
            expected,
            actual: values.len(),
        });
    }
    match values.iter().position(|v| !finite(v)) {
        Some(index) => Err(ReferenceError::NonFiniteVoxel { what, index }),
        None => Ok(()),
    }
}

/// `value` when finite, else the parameter error naming `what`.
pub(super) fn finite(what: &'static str, value: f64) -> Result<f64, ReferenceError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(ReferenceError::BadParameter { what, value })
    }
}
