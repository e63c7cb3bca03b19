//! `rollfuse.depth`, `rollfuse.calibrate` and `rollfuse.Lights`: photometric-stereo
//! height maps of RGB tactile images, as `rollfuse depth` and `rollfuse calibrate`.

use crate::arrays::{image_planes, owned};
use crate::errors::{OrPy, value_error};
use pyo3::prelude::*;
use rollfuse::depth::calibrate::{Circle, calibrate as fit_lights};
use rollfuse::depth::lights::Lights;
use rollfuse::depth::reconstruct;
use std::path::PathBuf;

/// The image scale and the three LEDs' directions and gains: the light file
/// (`lights.toml`) that `rollfuse depth` reads and `rollfuse calibrate` writes.
#[pyclass(name = "Lights", module = "rollfuse", frozen, eq)]
#[derive(Clone, PartialEq)]
pub struct PyLights {
    /// The checked light set.
    pub inner: Lights,
}

#[pymethods]
impl PyLights {
    /// Lights from their values, checked as a light file is (unit directions, a
    /// well-conditioned matrix, positive gains).
    #[new]
    #[pyo3(signature = (mm_per_px, red, green, blue, gains=[1.0, 1.0, 1.0]))]
    fn new(
        mm_per_px: f64,
        red: [f64; 3],
        green: [f64; 3],
        blue: [f64; 3],
        gains: [f64; 3],
    ) -> PyResult<Self> {
        let inner = Lights {
            mm_per_px,
            red,
            green,
            blue,
            gains,
        };
        inner.check().or_py()?;
        Ok(Self { inner })
    }

    /// Reads and checks a light file (TOML). OSError if it cannot be read, ValueError if
    /// it is not a valid light file.
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Self> {
        Ok(Self {
            inner: Lights::load(&path).or_py()?,
        })
    }

    /// The module's three LEDs (35° above the gel, 120° apart, equal gains) at `mm_per_px`.
    #[staticmethod]
    fn product(mm_per_px: f64) -> Self {
        Self {
            inner: Lights::product(mm_per_px),
        }
    }

    /// Writes the light file (whole or not at all).
    fn save(&self, path: PathBuf) -> PyResult<()> {
        self.inner.save(&path).or_py()
    }

    /// The light file's text.
    fn to_toml(&self) -> PyResult<String> {
        self.inner.to_toml().or_py()
    }

    /// The condition number of the light matrix.
    fn condition(&self) -> f64 {
        self.inner.condition()
    }

    /// Millimetres per pixel of the image.
    #[getter]
    fn mm_per_px(&self) -> f64 {
        self.inner.mm_per_px
    }

    /// Unit vector toward the red LED (x right, y down, z toward the camera).
    #[getter]
    fn red(&self) -> [f64; 3] {
        self.inner.red
    }

    /// Unit vector toward the green LED.
    #[getter]
    fn green(&self) -> [f64; 3] {
        self.inner.green
    }

    /// Unit vector toward the blue LED.
    #[getter]
    fn blue(&self) -> [f64; 3] {
        self.inner.blue
    }

    /// Each channel's shading contrast.
    #[getter]
    fn gains(&self) -> [f64; 3] {
        self.inner.gains
    }

    fn __repr__(&self) -> String {
        let l = &self.inner;
        format!(
            "Lights(mm_per_px={:?}, red={:?}, green={:?}, blue={:?}, gains={:?})",
            l.mm_per_px, l.red, l.green, l.blue, l.gains
        )
    }
}

/// The height map of an RGB tactile image, mm (float32, shape (H, W); 0 is the
/// undisturbed gel), by photometric stereo and Poisson integration, as `rollfuse depth`
/// writes it to STEM.npy.
///
/// image: (H, W, 3) uint8, uint16 or float on the 0–255 scale. lights: a Lights.
/// background: the no-contact frame, same shape (else a smooth estimate from the image).
#[pyfunction]
#[pyo3(signature = (image, lights, *, background=None))]
pub fn depth(
    py: Python<'_>,
    image: &Bound<'_, PyAny>,
    lights: &PyLights,
    background: Option<&Bound<'_, PyAny>>,
) -> PyResult<Py<PyAny>> {
    let image = image_planes(image, "image")?;
    let background = background
        .map(|b| image_planes(b, "background"))
        .transpose()?;
    let map = py
        .detach(|| reconstruct(&image, background.as_ref(), &lights.inner))
        .or_py()?;
    owned(py, vec![map.height, map.width], map.height_mm)
}

/// Fits the light file from an image of a ball pressed into the gel, as
/// `rollfuse calibrate`.
///
/// image: (H, W, 3) array. radius_mm: the ball's radius. mm_per_px: the image scale.
/// background: the no-contact frame (else a smooth estimate). circle: the contact disc
/// (x, y, r) in pixels instead of finding it.
/// Returns (lights, (x, y, r)): the fitted Lights and the contact disc used.
#[pyfunction]
#[pyo3(signature = (image, *, radius_mm, mm_per_px, background=None, circle=None))]
pub fn calibrate(
    py: Python<'_>,
    image: &Bound<'_, PyAny>,
    radius_mm: f64,
    mm_per_px: f64,
    background: Option<&Bound<'_, PyAny>>,
    circle: Option<(f64, f64, f64)>,
) -> PyResult<(PyLights, (f64, f64, f64))> {
    let circle = match circle {
        None => None,
        Some((x, y, r)) if x.is_finite() && y.is_finite() && r.is_finite() && r > 0.0 => {
            Some(Circle { x, y, r })
        }
        Some(c) => {
            return Err(value_error(format!(
                "circle must be (x, y, r) with r > 0, got {c:?}"
            )));
        }
    };
    let image = image_planes(image, "image")?;
    let background = background
        .map(|b| image_planes(b, "background"))
        .transpose()?;
    let (inner, disc) = py
        .detach(|| fit_lights(&image, background.as_ref(), radius_mm, mm_per_px, circle))
        .or_py()?;
    Ok((PyLights { inner }, (disc.x, disc.y, disc.r)))
}
