//! `rollfuse.simulate`: a scene's frames and ground truth as arrays, as
//! `rollfuse simulate` renders them (its PNGs, its `truth/height.npy`, its manifest's
//! positions), without files.

use crate::arrays::owned;
use crate::depth::PyLights;
use crate::errors::{OrPy, value_error};
use pyo3::exceptions::PyUserWarning;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};
use rollfuse::depth::lights::Lights;
use rollfuse::sim::{Effect, Scene, Simulator};
use std::path::PathBuf;

/// A scene from a path to its TOML file, or from a dict of the same tables.
fn scene_of(py: Python<'_>, scene: &Bound<'_, PyAny>) -> PyResult<Scene> {
    if let Ok(table) = scene.cast::<PyDict>() {
        // Through JSON and TOML text: the dict is read exactly as a scene file is.
        let json: String = py
            .import("json")?
            .call_method1("dumps", (table,))?
            .extract()?;
        let value: toml::Value = serde_json::from_str(&json)
            .map_err(|e| value_error(format!("scene dict: {e} (None has no TOML form)")))?;
        let text = toml::to_string(&value).map_err(|e| value_error(format!("scene dict: {e}")))?;
        return Scene::parse(&text, "scene").or_py();
    }
    if scene.is_instance_of::<PyString>() || scene.hasattr("__fspath__")? {
        let path: PathBuf = scene.extract()?;
        return Scene::load(&path).or_py();
    }
    Err(value_error(format!(
        "scene must be a path to a scene file or a dict, got a {}",
        scene.get_type().name()?
    )))
}

/// What the simulation returns, made without the GIL.
struct Rendered {
    frames: Vec<u8>,
    channels: usize,
    offset_mm: Vec<f64>,
    actual_offset_mm: Vec<f64>,
    strip_row: Vec<f64>,
    actual_strip_row: Vec<f64>,
    ideal: Vec<u8>,
    ideal_channels: usize,
}

fn render(sim: &Simulator) -> Rendered {
    let n = sim.frames();
    let ideal = sim.ideal();
    let mut out = Rendered {
        frames: Vec::new(),
        channels: 1,
        offset_mm: Vec::with_capacity(n),
        actual_offset_mm: Vec::with_capacity(n),
        strip_row: Vec::with_capacity(n),
        actual_strip_row: Vec::with_capacity(n),
        ideal: ideal.to_u8(),
        ideal_channels: ideal.planes.len(),
    };
    for k in 0..n {
        let f = sim.frame(k);
        out.channels = f.image.planes.len();
        // The 8-bit samples `rollfuse simulate` writes to frame_NNNN.png.
        out.frames.extend(f.image.to_u8());
        out.offset_mm.push(f.offset_mm);
        out.actual_offset_mm.push(f.actual_offset_mm);
        out.strip_row.push(sim.strip_row_of_top(f.offset_mm));
        out.actual_strip_row
            .push(sim.strip_row_of_top(f.actual_offset_mm));
    }
    out
}

/// Renders a scene's frames and ground truth, as `rollfuse simulate` does.
///
/// scene: a path to a scene file (e.g. host/scenes/letters.toml) or a dict of the same
/// tables. frames, seed: override the scene's frame count and seed.
/// Returns a dict: frames (uint8, (N, H, W) or (N, H, W, 3): what frame_NNNN.png hold),
/// offset_mm, actual_offset_mm, strip_row, actual_strip_row (float64 (N,): the
/// manifest's positions; round strip_row for fuse's align='offsets'), height_mm (float32
/// (rows, W): truth/height.npy), ideal (uint8: truth/ideal.png), lights (the Lights the
/// frames were rendered with, RGB scenes; else None), scene (its name), seed, mm_per_px,
/// geometry (the roller's, for fuse_roll: roller_radius_mm, press_depth_mm, mm_per_px,
/// apex_row).
/// The scene's warnings are issued as UserWarning.
#[pyfunction]
#[pyo3(signature = (scene, frames=None, seed=None))]
pub fn simulate<'py>(
    py: Python<'py>,
    scene: &Bound<'py, PyAny>,
    frames: Option<usize>,
    seed: Option<u64>,
) -> PyResult<Bound<'py, PyDict>> {
    let mut scene = scene_of(py, scene)?;
    if let Some(n) = frames {
        scene.sensor.frames = n;
    }
    if let Some(s) = seed {
        scene.seed = s;
    }
    scene
        .validate()
        .map_err(|e| anyhow::Error::from(e).context("with the overrides"))
        .or_py()?;
    let category = py.get_type::<PyUserWarning>();
    for w in scene.warnings() {
        PyErr::warn(py, &category, &std::ffi::CString::new(w)?, 1)?;
    }
    let sim = Simulator::new(&scene).or_py()?;
    let r = py.detach(|| render(&sim));
    let s = &scene.sensor;
    let mut shape = vec![sim.frames(), s.height_px, s.width_px];
    if r.channels == 3 {
        shape.push(3);
    }
    let strip = sim.strip();
    let d = PyDict::new(py);
    d.set_item("frames", owned(py, shape, r.frames)?)?;
    d.set_item(
        "offset_mm",
        owned(py, vec![r.offset_mm.len()], r.offset_mm)?,
    )?;
    let n = r.actual_offset_mm.len();
    d.set_item("actual_offset_mm", owned(py, vec![n], r.actual_offset_mm)?)?;
    d.set_item("strip_row", owned(py, vec![n], r.strip_row)?)?;
    d.set_item("actual_strip_row", owned(py, vec![n], r.actual_strip_row)?)?;
    let height = strip.height_mm.clone();
    d.set_item(
        "height_mm",
        owned(py, vec![strip.rows, strip.width], height)?,
    )?;
    let ideal_shape = if r.ideal_channels == 3 {
        vec![strip.rows, strip.width, 3]
    } else {
        vec![strip.rows, strip.width]
    };
    d.set_item("ideal", owned(py, ideal_shape, r.ideal)?)?;
    d.set_item("lights", true_lights(&scene))?;
    d.set_item("scene", &scene.name)?;
    d.set_item("seed", scene.seed)?;
    d.set_item("mm_per_px", s.mm_per_px)?;
    let g = s.roller_geometry();
    let geometry = PyDict::new(py);
    geometry.set_item("roller_radius_mm", g.roller_radius_mm)?;
    geometry.set_item("press_depth_mm", g.press_depth_mm)?;
    geometry.set_item("mm_per_px", g.mm_per_px)?;
    geometry.set_item("apex_row", g.apex_row)?;
    d.set_item("geometry", geometry)?;
    Ok(d)
}

/// The light file of an RGB scene's own LEDs (what `rollfuse simulate` writes as
/// lights.toml); none for gray scenes.
fn true_lights(scene: &Scene) -> Option<PyLights> {
    scene.has(Effect::Rgb).then_some(PyLights {
        inner: Lights {
            mm_per_px: scene.sensor.mm_per_px,
            red: scene.lights.red,
            green: scene.lights.green,
            blue: scene.lights.blue,
            gains: [1.0; 3],
        },
    })
}
