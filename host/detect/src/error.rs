//! The detector's error: a file that could not be read or written told apart from input
//! the detector cannot take.

/// A result of this crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Why detection, training or a model file failed. Both keep the whole chain of causes
/// (`{:#}` prints it as the command line does).
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read or written: an I/O error is among the causes (a full
    /// disk, a missing or unreadable model, labels or image).
    #[error(transparent)]
    Io(anyhow::Error),
    /// Input the detector cannot take — an image, labels, a model file, a setting — and
    /// why.
    #[error(transparent)]
    Invalid(anyhow::Error),
}

impl Error {
    /// The operating system's error kind, for [`Error::Io`].
    pub fn io_kind(&self) -> Option<std::io::ErrorKind> {
        match self {
            Self::Io(e) => io_cause(e).map(std::io::Error::kind),
            Self::Invalid(_) => None,
        }
    }
}

/// The first I/O error among the causes of `e`.
fn io_cause(e: &anyhow::Error) -> Option<&std::io::Error> {
    e.chain().find_map(rollfuse_io::files::io_cause)
}

impl From<anyhow::Error> for Error {
    fn from(e: anyhow::Error) -> Self {
        if io_cause(&e).is_some() {
            Self::Io(e)
        } else {
            Self::Invalid(e)
        }
    }
}

/// Errors of the crates below, taken with `?` and sorted by their causes.
macro_rules! sorted_from {
    ($($t:ty),*) => {$(
        impl From<$t> for Error {
            fn from(e: $t) -> Self {
                anyhow::Error::from(e).into()
            }
        }
    )*};
}
sorted_from!(
    std::io::Error,
    rollfuse_io::files::WriteError,
    rollfuse_io::image::ReadError,
    rollfuse_io::image::OutsideImage,
    rollfuse_fullres::Error,
    rollfuse_sim::Error,
    serde_json::Error
);

impl rollfuse_io::invalid::Invalid for Error {
    fn invalid(message: String) -> Self {
        Self::Invalid(anyhow::Error::msg(message))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_model_that_is_not_there_is_told_from_one_that_is_not_a_model() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("model.safetensors");
        let missing = crate::Detector::load(&path).err().unwrap();
        assert_eq!(
            missing.io_kind(),
            Some(std::io::ErrorKind::NotFound),
            "{missing:#}"
        );
        std::fs::write(&path, b"a text file, not a model").unwrap();
        let other = crate::Detector::load(&path).err().unwrap();
        assert!(matches!(other, Error::Invalid(_)), "{other:#}");
        assert!(
            format!("{other:#}").contains("model.safetensors"),
            "{other:#}"
        );
        // A setting out of range is the input's fault too.
        assert!(matches!(
            crate::check_threshold(2.0),
            Err(Error::Invalid(_))
        ));
    }
}
