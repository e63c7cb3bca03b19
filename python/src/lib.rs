//! rollfuse for Python: the host library's fusion, depth, metrics and simulation on numpy
//! arrays (the `rollfuse._rollfuse` extension module; the package `rollfuse` in
//! `python/rollfuse/` re-exports it). Every function releases the GIL while it works and
//! raises `ValueError` (bad input) or `OSError` (files) with the command line's messages.

mod arrays;
mod depth;
mod errors;
mod fuse;
mod metrics;
mod roll;
mod sim;
mod stream;
mod wavelet;

use pyo3::prelude::*;

/// The extension module.
#[pymodule]
fn _rollfuse(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(fuse::fuse, m)?)?;
    m.add_function(wrap_pyfunction!(fuse::fuse_pair, m)?)?;
    m.add_function(wrap_pyfunction!(roll::fuse_roll, m)?)?;
    m.add_function(wrap_pyfunction!(wavelet::dwt2, m)?)?;
    m.add_function(wrap_pyfunction!(wavelet::idwt2, m)?)?;
    m.add_class::<depth::PyLights>()?;
    m.add_function(wrap_pyfunction!(depth::depth, m)?)?;
    m.add_function(wrap_pyfunction!(depth::calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::ie, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::ms_ssim, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::strip_std, m)?)?;
    m.add_function(wrap_pyfunction!(sim::simulate, m)?)?;
    m.add_class::<stream::Stream>()?;
    m.add_function(wrap_pyfunction!(stream::stream, m)?)?;
    Ok(())
}
