//! `rollfuse.dwt2` and `rollfuse.idwt2`: the float filter banks of `rollfuse-core`, as
//! PyWavelets' `dwt2`/`idwt2` with `mode='periodization'`, so results can be checked
//! against it.

use crate::arrays::{Held, owned};
use crate::errors::value_error;
use numpy::ndarray::{Array2, ArrayView2, s};
use pyo3::prelude::*;
use pyo3::types::PyTuple;
use rollfuse_core::lifting::filter_bank::{self, level_scratch_len, subband_dims};
use rollfuse_core::{Dims, Wavelet};

fn wavelet_named(name: &str) -> PyResult<Wavelet> {
    crate::fuse::choice("wavelet", name)
}

fn core_error(e: rollfuse_core::Error) -> PyErr {
    value_error(e.to_string())
}

/// A 2-D array of any supported dtype as f32 values, row-major, and its (rows, columns).
fn plane(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<(Vec<f32>, usize, usize)> {
    let held = Held::new(obj, what)?;
    let view = held.view();
    let shape = view.shape().to_vec();
    let [h, w] = shape[..] else {
        return Err(value_error(format!(
            "{what} must be 2-D, got shape {}",
            crate::arrays::shape_text(&shape)
        )));
    };
    if h == 0 || w == 0 {
        return Err(value_error(format!("{what} is empty ({h}×{w})")));
    }
    let data = match view {
        crate::arrays::Samples::U8(a) => a.iter().map(|&v| f32::from(v)).collect(),
        crate::arrays::Samples::U16(a) => a.iter().map(|&v| f32::from(v)).collect(),
        crate::arrays::Samples::F32(a) => a.iter().copied().collect(),
        crate::arrays::Samples::F64(a) => a.iter().map(|&v| v as f32).collect(),
    };
    Ok((data, h, w))
}

/// Single-level 2-D discrete wavelet transform, as PyWavelets'
/// `pywt.dwt2(data, wavelet, mode='periodization')` in float32.
///
/// data: a 2-D array (any size ≥ 1; odd sides are extended by their last sample, as
/// PyWavelets does). wavelet: 'haar' or 'db2'.
/// Returns (cA, (cH, cV, cD)), each float32 of shape (⌈H/2⌉, ⌈W/2⌉).
#[pyfunction]
#[pyo3(signature = (data, wavelet="db2"))]
pub fn dwt2<'py>(
    py: Python<'py>,
    data: &Bound<'py, PyAny>,
    wavelet: &str,
) -> PyResult<Bound<'py, PyTuple>> {
    let wavelet = wavelet_named(wavelet)?;
    let (img, h, w) = plane(data, "data")?;
    let (bw, bh) = subband_dims(w, h);
    let dims = Dims::new(w, h).map_err(core_error)?;
    let padded = Dims::new(2 * bw, 2 * bh).map_err(core_error)?;
    let grid = py.detach(|| {
        let mut out = vec![0f32; padded.pixels()];
        let mut scratch = vec![0f32; level_scratch_len(padded)];
        filter_bank::dwt2(wavelet, &img, dims, &mut out, &mut scratch).map(|()| out)
    });
    let grid = Array2::from_shape_vec((2 * bh, 2 * bw), grid.map_err(core_error)?)
        .map_err(|e| value_error(e.to_string()))?;
    // Mallat layout: cA top-left, cV (HL) top-right, cH (LH) bottom-left, cD bottom-right.
    let band = |rows: usize, cols: usize| -> PyResult<Py<PyAny>> {
        let b = grid.slice(s![rows..rows + bh, cols..cols + bw]);
        owned(py, vec![bh, bw], b.iter().copied().collect())
    };
    let details = PyTuple::new(py, [band(bh, 0)?, band(0, bw)?, band(bh, bw)?])?;
    PyTuple::new(py, [band(0, 0)?, details.into_any().unbind()])
}

/// Inverse of `dwt2`, as PyWavelets' `pywt.idwt2(coeffs, wavelet,
/// mode='periodization')` in float32.
///
/// coeffs: (cA, (cH, cV, cD)), four 2-D arrays of one shape (h, w).
/// Returns the float32 image of shape (2h, 2w) (crop it to an odd original's size).
#[pyfunction]
#[pyo3(signature = (coeffs, wavelet="db2"))]
pub fn idwt2(py: Python<'_>, coeffs: &Bound<'_, PyAny>, wavelet: &str) -> PyResult<Py<PyAny>> {
    let wavelet = wavelet_named(wavelet)?;
    let shape_error = || value_error("coeffs must be (cA, (cH, cV, cD))");
    let (ca, details): (Bound<'_, PyAny>, Bound<'_, PyAny>) =
        coeffs.extract().map_err(|_| shape_error())?;
    let (ch, cv, cd): (Bound<'_, PyAny>, Bound<'_, PyAny>, Bound<'_, PyAny>) =
        details.extract().map_err(|_| shape_error())?;
    let bands = [("cA", &ca), ("cH", &ch), ("cV", &cv), ("cD", &cd)]
        .into_iter()
        .map(|(name, b)| plane(b, name))
        .collect::<PyResult<Vec<_>>>()?;
    let (bh, bw) = (bands[0].1, bands[0].2);
    if bands.iter().any(|b| (b.1, b.2) != (bh, bw)) {
        return Err(value_error("cA, cH, cV and cD must have one shape"));
    }
    let padded = Dims::new(2 * bw, 2 * bh).map_err(core_error)?;
    let mut grid = Array2::<f32>::zeros((2 * bh, 2 * bw));
    for ((data, _, _), (rows, cols)) in bands.iter().zip([(0, 0), (bh, 0), (0, bw), (bh, bw)]) {
        let band =
            ArrayView2::from_shape((bh, bw), data).map_err(|e| value_error(e.to_string()))?;
        grid.slice_mut(s![rows..rows + bh, cols..cols + bw])
            .assign(&band);
    }
    let mut coeffs = grid.into_raw_vec_and_offset().0;
    let image = py.detach(|| {
        let mut out = vec![0f32; padded.pixels()];
        let mut scratch = vec![0f32; level_scratch_len(padded)];
        filter_bank::idwt2(wavelet, &mut coeffs, padded, &mut out, &mut scratch).map(|()| out)
    });
    owned(py, vec![2 * bh, 2 * bw], image.map_err(core_error)?)
}
