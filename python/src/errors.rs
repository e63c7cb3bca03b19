//! Rust errors as Python exceptions, with the command line's messages.

use pyo3::PyErr;
use pyo3::exceptions::{PyOSError, PyValueError};

/// An error of the library as a Python exception: `OSError` when a file could not be
/// read or written (an I/O error anywhere in the chain), `ValueError` otherwise. The
/// message is the whole chain, as the command line prints it.
pub fn to_py(e: anyhow::Error) -> PyErr {
    let message = format!("{e:#}");
    if e.chain().any(|c| rollfuse::files::io_cause(c).is_some()) {
        PyOSError::new_err(message)
    } else {
        PyValueError::new_err(message)
    }
}

/// A `ValueError` with `message`.
pub fn value_error(message: impl Into<String>) -> PyErr {
    PyValueError::new_err(message.into())
}

/// A result of the library (any crate's error, or `anyhow`'s) into a Python result.
pub trait OrPy<T> {
    /// The value, or the error as a Python exception ([`to_py`]).
    fn or_py(self) -> pyo3::PyResult<T>;
}

impl<T, E: Into<anyhow::Error>> OrPy<T> for Result<T, E> {
    fn or_py(self) -> pyo3::PyResult<T> {
        self.map_err(|e| to_py(e.into()))
    }
}
