//! The library's top-level error: one variant per layer, each a sentence a person can act on.

use crate::files::png::PngError;
use crate::gpu::GpuError;
use crate::volume::nifti::NiftiError;
use crate::volume::phantom::PhantomError;

/// Any failure of a morphray command.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Reading or decoding a NIfTI file (I/O errors name the path themselves).
    #[error(transparent)]
    Nifti(#[from] NiftiError),
    /// Reading a volume source, whatever its format (see `volume::source`).
    #[error(transparent)]
    Input(#[from] crate::volume::source::InputError),
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
    DoesNotFit(#[from] crate::engine::plan::DoesNotFit),
    /// A scene document that cannot be read or written.
    #[error(transparent)]
    SceneDocument(#[from] crate::scene::document::SceneDocError),
    /// Arguments that parse but do not make sense together.
    #[error("{0}")]
    Usage(String),
    /// A batch that ran but where some scans failed: the others are written, and the process
    /// exits with [`Error::SCANS_FAILED_EXIT`] so a workflow notices.
    #[error("{0}")]
    ScansFailed(String),
}

impl Error {
    /// The exit status of [`Error::ScansFailed`] (1 is "could not run", 2 a usage error).
    pub const SCANS_FAILED_EXIT: u8 = 3;

    /// The process exit status for this error.
    pub fn exit_code(&self) -> u8 {
        match self {
            Error::ScansFailed(_) => Error::SCANS_FAILED_EXIT,
            _ => 1,
        }
    }
}

impl From<crate::engine::SessionError> for Error {
    /// Each cause as the variant it always was, so messages do not depend on the path taken.
    fn from(e: crate::engine::SessionError) -> Error {
        use crate::engine::SessionError;
        match e {
            SessionError::Recipe(e) => Error::Usage(e.0),
            SessionError::Input(e) => Error::Input(e),
            SessionError::Gpu(e) => Error::Gpu(e),
            SessionError::Open(e) => Error::Open(e),
        }
    }
}
