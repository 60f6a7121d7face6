//! Plain-data vocabulary that every layer reads: the stored samples and their encoding, and the
//! map from stored to physical values.
//!
//! Decisions:
//! - The bottom layer beside `files`: it imports nothing from the crate, so the f64 twins
//!   (`reference`), the tissue analysis (`analysis`) and the loaders (`volume`) all read the same
//!   types without an import running back up (issue 29 item 3; tests/layers.rs).
//! - Data and its encodings only; how a volume is loaded, described or made (orientation,
//!   facts, phantoms) stays in `volume`, which re-exports these where volumes are made.

pub mod linear_map;
pub mod samples;

pub use linear_map::LinearMap;
pub use samples::{SampleKind, Samples};

/// A scan's first frame as the CPU twins read it: samples, grid and intensity map, borrowed
/// from a `volume::Volume` (`Volume::voxel_grid`) without its orientation or metadata.
#[derive(Clone, Copy, Debug)]
pub struct VoxelGrid<'a> {
    /// Stored voxel values, x fastest.
    pub samples: &'a Samples,
    /// Voxels along i, j, k.
    pub dims: [usize; 3],
    /// Stored-to-physical intensity map.
    pub to_physical: LinearMap,
}
