//! f64 CPU twins of the GPU kernels: the definitions the kernels are tested against.
//!
//! Why twins exist: a GPU kernel can be wrong in ways that only show at awkward sizes (a volume
//! that is not a multiple of the workgroup or subgroup size, inactive lanes in a subgroup
//! reduction, a border voxel's stencil) or on one device only (lavapipe runs subgroups of 8, the
//! H100 subgroups of 32, Intel Xe-LP 8 to 32). Each kernel therefore has a straightforward CPU
//! version here, written for clarity rather than speed, and tests compare the GPU's output with
//! it at sizes such as 1, 31, 32, 33 and 1000003 voxels on every device they run on.
//!
//! Decisions:
//! - f64 wherever the kernel's result is a real number (min/max, normalization, derivatives), so
//!   the twin is the accurate answer and the GPU's f32 error can be measured against it.
//! - The histogram twin is f32 on purpose: a bin index is discrete, and computing it in the
//!   kernel's own f32 arithmetic makes the twin bit-exact given the same inputs.
//! - Twins are total functions on data (non-finite samples, constant volumes, 1-voxel axes) with
//!   the policies of NUMERICS.md; only caller errors (mismatched lengths, a singular affine) are
//!   typed errors.
//! - Volumes are x fastest: voxel `(i, j, k)` is at `i + nx * (j + ny * k)`.

pub mod brain;
pub mod brick_distance;
pub mod denoise;
pub mod derivatives;
pub mod eigen;
pub mod fine_histogram;
pub mod histogram;
pub mod minmax;
pub mod normalize;
pub mod raymarch;
pub mod slice;
pub mod tissue_fit;
pub mod vesselness;

pub use derivatives::{
    DEFAULT_TAU, DerivativeError, DerivativeOptions, Derivatives, IndexToWorld, Sym3,
    VoxelDerivatives, derivatives, voxel_derivatives,
};
pub use histogram::{BINS, bin_of, histogram, histogram_of_samples};
pub use minmax::{finite_min_max, nonfinite_count};
pub use normalize::{normalize, normalize_value, physical_range};
pub mod brain_components;
pub mod brain_depth;
pub mod brain_mask;
pub mod brain_params;
pub mod brain_report;
pub mod brain_working;
