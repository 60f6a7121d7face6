//! The library's top-level error: one variant per layer, each a sentence a person can act on.

use crate::cli::png::PngError;
use crate::gpu::GpuError;
use crate::volume::nifti::NiftiError;
use crate::volume::phantom::PhantomError;

/// Any failure of a morphray command.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Reading or decoding a NIfTI file (I/O errors name the path themselves).
    #[error(transparent)]
    Nifti(#[from] NiftiError),
    /// Decoding the contents of a named file.
    #[error("{file}: {source}")]
    Input {
        /// The file's name.
        file: String,
        /// What is wrong with it.
        source: NiftiError,
    },
    /// Raw voxels that cannot form a volume.
    #[error(transparent)]
    Volume(#[from] crate::volume::VolumeError),
    /// Building the phantom.
    #[error(transparent)]
    Phantom(#[from] PhantomError),
    /// Vulkan, device memory or shaders.
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// Writing an image.
    #[error(transparent)]
    Png(#[from] PngError),
    /// An output that cannot be written, found before the work or while writing.
    #[error(transparent)]
    Output(#[from] crate::files::write::OutputError),
    /// Writing another output file.
    #[error("cannot write {path}: {source}")]
    Write {
        /// The file.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
    /// Opening a volume (GPU work or the memory plan).
    #[error(transparent)]
    Open(#[from] crate::engine::OpenError),
    /// No plan of the scene fits the memory budget, even fully degraded.
    #[error(transparent)]
    DoesNotFit(#[from] crate::scene::plan::DoesNotFit),
    /// The interactive viewer (window system, script, interface).
    #[error(transparent)]
    App(#[from] crate::app::AppError),
    /// Arguments that parse but do not make sense together.
    #[error("{0}")]
    Usage(String),
}
