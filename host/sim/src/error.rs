//! The simulator's error: the file system's fault told apart from the input's.

use rollfuse_io::files::WriteError;
use std::path::PathBuf;

/// Why a scene, a manifest or a simulation's output failed: the file system's fault
/// ([`Error::Read`], and [`Error::Write`]'s I/O case) told apart from the input's
/// ([`Error::Invalid`]).
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A scene file or a manifest could not be read.
    #[error("cannot read {what} {}", path.display())]
    Read {
        /// "scene file" or "manifest".
        what: &'static str,
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        #[source]
        source: std::io::Error,
    },
    /// A scene or manifest that is not valid, or one no built-in scene has the name of:
    /// the message names the file and the field.
    #[error("{0}")]
    Invalid(String),
    /// An output could not be written (the previous one is as it was).
    #[error(transparent)]
    Write(#[from] WriteError),
}

impl Error {
    /// This error, its message put after `context` ("in scene file …: ").
    pub(crate) fn within(self, context: impl std::fmt::Display) -> Self {
        match self {
            Self::Invalid(message) => Self::Invalid(format!("{context}: {message}")),
            other => other,
        }
    }
}

impl rollfuse_io::invalid::Invalid for Error {
    fn invalid(message: String) -> Self {
        Self::Invalid(message)
    }
}
