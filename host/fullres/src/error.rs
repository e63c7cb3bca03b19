//! Full-resolution fusion's error: what the input makes impossible told apart from the
//! file system's fault and from the errors of what the caller hands in.

use rollfuse_io::files::WriteError;
use std::path::PathBuf;

/// A result of this crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Why fusion, placement or a strip's files failed.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Frames, offsets or settings that cannot be fused (sizes that differ, a canvas over
    /// the pixel limit, bands that do not fit the frame …): the message says which.
    #[error("{0}")]
    Invalid(String),
    /// The core refused a size or setting.
    #[error(transparent)]
    Core(#[from] rollfuse_core::Error),
    /// A strip's index could not be read.
    #[error("cannot read the strip index {}", path.display())]
    Read {
        /// The index.
        path: PathBuf,
        /// What the operating system said.
        #[source]
        source: std::io::Error,
    },
    /// A strip's segment or index could not be written (the previous one is as it was).
    #[error(transparent)]
    Write(#[from] WriteError),
    /// The error of what the caller handed in: a frame it could not read, its sink, its
    /// callback.
    #[error(transparent)]
    Caller(#[from] anyhow::Error),
}

impl rollfuse_io::invalid::Invalid for Error {
    fn invalid(message: String) -> Self {
        Self::Invalid(message)
    }
}
