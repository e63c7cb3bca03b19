//! numpy arrays in and out: images as [`Planes`] (f32 on the 8-bit scale, one plane per
//! channel), read from uint8, uint16 or float arrays and returned as float32, uint8 or
//! uint16 arrays of shape (H, W) or (H, W, 3).

use crate::errors::value_error;
use numpy::ndarray::{ArrayViewD, Axis, IxDyn};
use numpy::{PyArray, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyList, PyTuple};
use rollfuse::fullres::FrameSource;
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

    /// The (height, width, channels) of an image of shape (H, W), (H, W, 1) or (H, W, 3);
    /// `what` names it in errors.
    pub fn image_shape(&self, what: &str) -> anyhow::Result<(usize, usize, usize)> {
        let (h, w, c) = match *self.shape() {
            [h, w] => (h, w, 1),
            [h, w, c @ (1 | 3)] => (h, w, c),
            ref s => anyhow::bail!(
                "{what} must have shape (H, W) or (H, W, 3), got {}",
                shape_text(s)
            ),
        };
        anyhow::ensure!(h > 0 && w > 0, "{what} is empty ({h}×{w})");
        Ok((h, w, c))
    }

    /// Refuses float values that are not finite; `what` names the image in the error.
    pub fn check_finite(&self, what: &str) -> anyhow::Result<()> {
        let finite = match self {
            Samples::U8(_) | Samples::U16(_) => true,
            Samples::F32(a) => all(a, |v| v.is_finite()),
            Samples::F64(a) => all(a, |v| v.is_finite()),
        };
        anyhow::ensure!(
            finite,
            "{what} holds values that are not finite (NaN or infinity)"
        );
        Ok(())
    }

    /// Writes channel `k` of an image with `c` channels (checked by [`Self::image_shape`])
    /// into `out`, row-major on the 8-bit scale.
    pub fn read_channel(&self, k: usize, c: usize, out: &mut [f32]) {
        match self {
            Samples::U8(a) => read(a, k, c, out, f32::from),
            Samples::U16(a) => read(a, k, c, out, from_u16),
            Samples::F32(a) => read(a, k, c, out, |v| v),
            Samples::F64(a) => read(a, k, c, out, |v| v as f32),
        }
    }

    /// An image of shape (H, W), (H, W, 1) or (H, W, 3) as planes on the 8-bit scale.
    /// Float values must be finite; `what` names the image in errors.
    pub fn planes(&self, what: &str) -> anyhow::Result<Planes> {
        let (h, w, c) = self.image_shape(what)?;
        self.check_finite(what)?;
        Ok(self.converted((h, w, c)))
    }

    /// The image, of the checked shape `(h, w, c)`, as planes.
    fn converted(&self, (h, w, c): (usize, usize, usize)) -> Planes {
        let planes = (0..c)
            .map(|k| {
                let mut plane = vec![0.0; h * w];
                self.read_channel(k, c, &mut plane);
                plane
            })
            .collect();
        Planes {
            width: w,
            height: h,
            planes,
        }
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

/// Whether every value of `a` passes `test`.
fn all<T: Copy>(a: &ArrayViewD<'_, T>, test: impl Fn(T) -> bool) -> bool {
    match a.as_slice() {
        Some(s) => s.iter().all(|&v| test(v)),
        None => a.iter().all(|&v| test(v)),
    }
}

/// Channel `k` of an (H, W) or (H, W, c) view into `out`, row-major, through `f`.
fn read<T: Copy>(a: &ArrayViewD<'_, T>, k: usize, c: usize, out: &mut [f32], f: impl Fn(T) -> f32) {
    // A contiguous array is read as a slice: iterating a dynamic-rank view indexes every
    // element, which costs as much as the fusion of uint8 frames.
    // One channel gets its own loop: `step_by` keeps the compiler from vectorising it.
    match a.as_slice() {
        Some(s) if c == 1 => {
            for (o, &v) in out.iter_mut().zip(s) {
                *o = f(v);
            }
            return;
        }
        Some(s) => {
            for (o, &v) in out.iter_mut().zip(s.iter().skip(k).step_by(c)) {
                *o = f(v);
            }
            return;
        }
        None => {}
    }
    let channel = if a.ndim() == 2 {
        a.view()
    } else {
        a.index_axis(Axis(2), k)
    };
    for (o, &v) in out.iter_mut().zip(channel.iter()) {
        *o = f(v);
    }
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

/// Images of one size, all gray or all RGB, read channel by channel as fusion reaches
/// them: no frame is converted before it is needed.
pub struct Frames<'a> {
    views: Vec<Samples<'a>>,
    /// (height, width, channels).
    shape: (usize, usize, usize),
}

impl<'a> Frames<'a> {
    /// Checks `views` (shapes, sizes, finite values); `what` names them in errors.
    pub fn new(views: Vec<Samples<'a>>, what: &str) -> anyhow::Result<Self> {
        let mut shape = None;
        for (k, v) in views.iter().enumerate() {
            let name = format!("{what}[{k}]");
            let (h, w, c) = v.image_shape(&name)?;
            v.check_finite(&name)?;
            let (h0, w0, c0) = *shape.get_or_insert((h, w, c));
            anyhow::ensure!(
                (w, h) == (w0, h0),
                "{name} is {w}×{h} but {what}[0] is {w0}×{h0}: all must have one size"
            );
            anyhow::ensure!(c == c0, "{what}[0] and {name} mix gray and RGB");
        }
        let shape = shape.unwrap_or((0, 0, 1));
        Ok(Self { views, shape })
    }

    /// Every image as planes (for the work that needs them all at once).
    pub fn planes(&self) -> Vec<Planes> {
        self.each().collect()
    }

    /// The images as planes, each converted when it is taken.
    pub fn each(&self) -> impl Iterator<Item = Planes> + '_ {
        self.views.iter().map(|v| v.converted(self.shape))
    }
}

impl FrameSource for Frames<'_> {
    fn frames(&self) -> usize {
        self.views.len()
    }

    fn shape(&self) -> (usize, usize, usize) {
        let (h, w, c) = self.shape;
        (w, h, c)
    }

    fn read(&self, frame: usize, channel: usize, out: &mut [f32]) {
        self.views[frame].read_channel(channel, self.shape.2, out);
    }
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
