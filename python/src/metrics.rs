//! `rollfuse.metrics`: the paper's IE and MS-SSIM and their spread over strips, as
//! `rollfuse metrics` reports them.

use crate::arrays::image_planes;
use crate::errors::OrPy;
use crate::fuse::choice;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rollfuse::eval::metrics::StripAxis;
use rollfuse::eval::report;

/// Information entropy (bits) of the gray-normalized image: `rollfuse metrics`' IE.
///
/// img: (H, W) or (H, W, 3) array, uint8, uint16 or float (RGB is averaged to gray).
#[pyfunction]
pub fn ie(py: Python<'_>, img: &Bound<'_, PyAny>) -> PyResult<f64> {
    let img = image_planes(img, "img")?;
    py.detach(|| report::ie(&img)).or_py()
}

/// MS-SSIM of `img` against `ref` (same size), both gray-normalized: `rollfuse metrics
/// --reference`.
#[pyfunction]
#[pyo3(name = "ms_ssim")]
pub fn ms_ssim(py: Python<'_>, img: &Bound<'_, PyAny>, r#ref: &Bound<'_, PyAny>) -> PyResult<f64> {
    let img = image_planes(img, "img")?;
    let reference = image_planes(r#ref, "ref")?;
    py.detach(|| report::ms_ssim(&img, &reference)).or_py()
}

/// Every figure of `rollfuse metrics --json`, as a dict: ie, ie_std, ms_ssim,
/// ms_ssim_std (None without a reference), strip_ie, strip_ms_ssim (eqs. 8–9).
///
/// strips: equal strips for the spread; axis: 'rows' (bands of rows, along the belt) or
/// 'columns'.
#[pyfunction]
#[pyo3(signature = (img, reference=None, *, strips=10, axis="rows"))]
pub fn strip_std<'py>(
    py: Python<'py>,
    img: &Bound<'py, PyAny>,
    reference: Option<&Bound<'py, PyAny>>,
    strips: usize,
    axis: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let axis: StripAxis = choice("axis", axis)?;
    let img = image_planes(img, "img")?;
    let reference = reference
        .map(|r| image_planes(r, "reference"))
        .transpose()?;
    let r = py
        .detach(|| report::measure(&img, reference.as_ref(), strips, axis))
        .or_py()?;
    let d = PyDict::new(py);
    d.set_item("ie", r.ie)?;
    d.set_item("ie_std", r.ie_std)?;
    d.set_item("ms_ssim", r.ms_ssim)?;
    d.set_item("ms_ssim_std", r.ms_ssim_std)?;
    d.set_item("strip_ie", r.strip_ie)?;
    d.set_item("strip_ms_ssim", r.strip_ms_ssim)?;
    Ok(d)
}
