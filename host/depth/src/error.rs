//! Depth's error: the file system's fault told apart from the input's.

use rollfuse_io::files::WriteError;
use std::path::PathBuf;

/// Why depth failed: a light file that could not be read ([`Error::Read`]) or an output
/// that could not be written ([`Error::Write`]) told apart from input that cannot give a
/// height map ([`Error::Invalid`]: a gray image, sizes that differ, a light file out of
/// range, slopes that do not integrate).
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A light file could not be read.
    #[error("cannot read light file {}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        #[source]
        source: std::io::Error,
    },
    /// Input that cannot give a height map; the message says which and why.
    #[error("{0}")]
    Invalid(String),
    /// An output could not be written (the previous one is as it was).
    #[error(transparent)]
    Write(#[from] WriteError),
}

impl rollfuse_io::invalid::Invalid for Error {
    fn invalid(message: String) -> Self {
        Self::Invalid(message)
    }
}
