//! numpy arrays in and out: images as [`Planes`] (f32 on the 8-bit scale, one plane per
//! channel), read from uint8, uint16 or float arrays and returned as float32, uint8 or
//! uint16 arrays of shape (H, W) or (H, W, 3).

use crate::errors::value_error;
use numpy::ndarray::{ArrayViewD, Axis, IxDyn};
use numpy::{PyArray, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyList, PyTuple};
use rollfuse::image::{Planes, from_u16};

/// A numpy array held for reading, by element type.
pub enum Held<'py> {
    /// uint8: gray levels.
    U8(PyReadonlyArrayDyn<'py, u8>),
    /// uint16: the 8-bit scale times 257, as 16-bit PNGs hold it.
    U16(PyReadonlyArrayDyn<'py, u16>),
    /// float32 on the 8-bit scale.
    F32(PyReadonlyArrayDyn<'py, f32>),
    /// float64 on the 8-bit scale.
    F64(PyReadonlyArrayDyn<'py, f64>),
}

/// A view of a held array: plain data, so work on it can run without the GIL.
#[derive(Clone)]
pub enum Samples<'a> {
    /// uint8.
    U8(ArrayViewD<'a, u8>),
    /// uint16.
    U16(ArrayViewD<'a, u16>),
    /// float32.
    F32(ArrayViewD<'a, f32>),
    /// float64.
    F64(ArrayViewD<'a, f64>),
}

impl<'py> Held<'py> {
    /// Borrows `obj` for reading if it is a numpy array of a supported type; `what` names
    /// it in the error.
    pub fn new(obj: &Bound<'py, PyAny>, what: &str) -> PyResult<Self> {
        if let Ok(a) = obj.cast::<PyArrayDyn<u8>>() {
            return Ok(Held::U8(a.try_readonly()?));
        }
        if let Ok(a) = obj.cast::<PyArrayDyn<u16>>() {
            return Ok(Held::U16(a.try_readonly()?));
        }
        if let Ok(a) = obj.cast::<PyArrayDyn<f32>>() {
            return Ok(Held::F32(a.try_readonly()?));
        }
        if let Ok(a) = obj.cast::<PyArrayDyn<f64>>() {
            return Ok(Held::F64(a.try_readonly()?));
        }
        let got = match obj.cast::<numpy::PyUntypedArray>() {
            Ok(a) => format!("an array of {}", a.dtype()),
            Err(_) => format!("a {}", obj.get_type().name()?),
        };
        Err(value_error(format!(
            "{what} must be a numpy array of uint8, uint16, float32 or float64, got {got}"
        )))
    }

    /// Its samples.
    pub fn view(&self) -> Samples<'_> {
        match self {
            Held::U8(a) => Samples::U8(a.as_array()),
            Held::U16(a) => Samples::U16(a.as_array()),
            Held::F32(a) => Samples::F32(a.as_array()),
            Held::F64(a) => Samples::F64(a.as_array()),
        }
    }
}

impl Samples<'_> {
    /// The array's shape.
    pub fn shape(&self) -> &[usize] {
        match self {
            Samples::U8(a) => a.shape(),
            Samples::U16(a) => a.shape(),
            Samples::F32(a) => a.shape(),
            Samples::F64(a) => a.shape(),
        }
    }

    /// The `k`th sub-array along the first axis (a view).
    pub fn index(&self, k: usize) -> Self {
        match self {
            Samples::U8(a) => Samples::U8(a.clone().index_axis_move(Axis(0), k)),
            Samples::U16(a) => Samples::U16(a.clone().index_axis_move(Axis(0), k)),
            Samples::F32(a) => Samples::F32(a.clone().index_axis_move(Axis(0), k)),
            Samples::F64(a) => Samples::F64(a.clone().index_axis_move(Axis(0), k)),
        }
    }

    /// An image of shape (H, W), (H, W, 1) or (H, W, 3) as planes on the 8-bit scale.
    /// Float values must be finite; `what` names the image in errors.
    pub fn planes(&self, what: &str) -> anyhow::Result<Planes> {
        let (h, w, c) = match *self.shape() {
            [h, w] => (h, w, 1),
            [h, w, c @ (1 | 3)] => (h, w, c),
            ref s => anyhow::bail!(
                "{what} must have shape (H, W) or (H, W, 3), got {}",
                shape_text(s)
            ),
        };
        anyhow::ensure!(h > 0 && w > 0, "{what} is empty ({h}×{w})");
        let (planes, float) = match self {
            Samples::U8(a) => (split(a, c, f32::from), false),
            Samples::U16(a) => (split(a, c, from_u16), false),
            Samples::F32(a) => (split(a, c, |v| v), true),
            Samples::F64(a) => (split(a, c, |v| v as f32), true),
        };
        anyhow::ensure!(
            !float || planes.iter().flatten().all(|v| v.is_finite()),
            "{what} holds values that are not finite (NaN or infinity)"
        );
        Ok(Planes {
            width: w,
            height: h,
            planes,
        })
    }
}

/// An image argument, (H, W) or (H, W, 3), as planes; `what` names it in errors.
pub fn image_planes(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Planes> {
    Held::new(obj, what)?
        .view()
        .planes(what)
        .map_err(crate::errors::to_py)
}

/// `(2, 3, 4)`, as numpy writes a shape.
pub fn shape_text(shape: &[usize]) -> String {
    match shape {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// The `c` channel planes of an (H, W) or (H, W, c) view, each row-major.
fn split<T: Copy>(a: &ArrayViewD<'_, T>, c: usize, f: impl Fn(T) -> f32) -> Vec<Vec<f32>> {
    // A contiguous array is read as a slice: iterating a dynamic-rank view indexes every
    // element, which costs as much as the fusion of uint8 frames.
    if let Some(s) = a.as_slice() {
        if c == 1 {
            return vec![s.iter().map(|&v| f(v)).collect()];
        }
        return (0..c)
            .map(|k| s.iter().skip(k).step_by(c).map(|&v| f(v)).collect())
            .collect();
    }
    if a.ndim() == 2 {
        return vec![a.iter().map(|&v| f(v)).collect()];
    }
    (0..c)
        .map(|k| a.index_axis(Axis(2), k).iter().map(|&v| f(v)).collect())
        .collect()
}

/// A sequence of images: a list or tuple of (H, W) / (H, W, 3) arrays, or one array of
/// shape (N, H, W) or (N, H, W, 3). Holds the arrays for reading.
pub struct Stack<'py> {
    held: Vec<Held<'py>>,
    /// Whether `held` is one array whose first axis runs over the images.
    stacked: bool,
}

impl<'py> Stack<'py> {
    /// Takes `obj` as a sequence of images; `what` names it in errors.
    pub fn new(obj: &Bound<'py, PyAny>, what: &str) -> PyResult<Self> {
        if obj.is_instance_of::<PyList>() || obj.is_instance_of::<PyTuple>() {
            let held = obj
                .try_iter()?
                .enumerate()
                .map(|(k, item)| Held::new(&item?, &format!("{what}[{k}]")))
                .collect::<PyResult<_>>()?;
            return Ok(Self {
                held,
                stacked: false,
            });
        }
        let one = Held::new(obj, what)?;
        let shape = one.view().shape().to_vec();
        if !matches!(shape.len(), 3 | 4) {
            return Err(value_error(format!(
                "{what} must be an array of shape (N, H, W) or (N, H, W, 3), or a list of \
                 images; got shape {}",
                shape_text(&shape)
            )));
        }
        Ok(Self {
            held: vec![one],
            stacked: true,
        })
    }

    /// Views of the images, in order.
    pub fn views(&self) -> Vec<Samples<'_>> {
        if self.stacked {
            let all = self.held[0].view();
            (0..all.shape()[0]).map(|k| all.index(k)).collect()
        } else {
            self.held.iter().map(Held::view).collect()
        }
    }
}

/// The images of `views` as planes, all of one size and all gray or all RGB.
pub fn same_size_planes(views: &[Samples<'_>], what: &str) -> anyhow::Result<Vec<Planes>> {
    let planes: Vec<Planes> = views
        .iter()
        .enumerate()
        .map(|(k, v)| v.planes(&format!("{what}[{k}]")))
        .collect::<anyhow::Result<_>>()?;
    if let Some(first) = planes.first() {
        for (k, p) in planes.iter().enumerate() {
            anyhow::ensure!(
                (p.width, p.height) == (first.width, first.height),
                "{what}[{k}] is {}×{} but {what}[0] is {}×{}: all must have one size",
                p.width,
                p.height,
                first.width,
                first.height
            );
            anyhow::ensure!(
                p.is_rgb() == first.is_rgb(),
                "{what}[0] and {what}[{k}] mix gray and RGB"
            );
        }
    }
    Ok(planes)
}

/// What an image comes back as.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutDtype {
    /// float32 on the 8-bit scale, unrounded.
    F32,
    /// uint8, rounded and clamped as the command line's 8-bit PNGs.
    U8,
    /// uint16, rounded and clamped as its 16-bit PNGs (`--out-bits 16`).
    U16,
}

impl OutDtype {
    /// From its numpy name.
    pub fn parse(name: &str) -> PyResult<Self> {
        match name {
            "float32" => Ok(Self::F32),
            "uint8" => Ok(Self::U8),
            "uint16" => Ok(Self::U16),
            _ => Err(value_error(format!(
                "out_dtype must be 'float32', 'uint8' or 'uint16', got '{name}'"
            ))),
        }
    }
}

/// `planes` as an array of shape (H, W) or (H, W, 3), moved into numpy without a copy
/// where the layout allows (gray float32).
pub fn image_array(py: Python<'_>, planes: Planes, dtype: OutDtype) -> PyResult<Py<PyAny>> {
    let (h, w, c) = (planes.height, planes.width, planes.planes.len());
    let shape = if c == 1 { vec![h, w] } else { vec![h, w, c] };
    match dtype {
        OutDtype::U8 => owned(py, shape, planes.to_u8()),
        OutDtype::U16 => owned(py, shape, planes.to_u16()),
        OutDtype::F32 => owned(py, shape, interleaved(planes)),
    }
}

/// One plane as is, or three interleaved pixel by pixel.
fn interleaved(planes: Planes) -> Vec<f32> {
    let mut planes = planes.planes;
    if planes.len() == 1 {
        return planes.pop().unwrap_or_default();
    }
    let n = planes[0].len();
    (0..n)
        .flat_map(|i| planes.iter().map(move |p| p[i]))
        .collect()
}

/// `data` as an array of `shape`, moved into numpy.
pub fn owned<T: numpy::Element>(
    py: Python<'_>,
    shape: Vec<usize>,
    data: Vec<T>,
) -> PyResult<Py<PyAny>> {
    let array = numpy::ndarray::Array::from_shape_vec(IxDyn(&shape), data)
        .map_err(|e| value_error(format!("internal shape error: {e}")))?;
    Ok(PyArray::from_owned_array(py, array).into_any().unbind())
}
