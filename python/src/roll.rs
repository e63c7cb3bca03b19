//! `rollfuse.fuse_roll`: a whole roll into a strip, as `rollfuse fuse --mode roll` fuses
//! it (frames tracked along the belt, fused band by band over the contact window).

use crate::arrays::{Frames, Stack, image_array, owned};
use crate::errors::{OrPy, value_error};
use crate::fuse::{Settings, choice};
use numpy::PyReadonlyArray1;
use pyo3::exceptions::PyRuntimeWarning;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rollfuse::fullres::FrameSource;
use rollfuse::fullres::register::{Placement, TrackParams};
use rollfuse::fullres::roll::{Bands, StripSink};
use rollfuse::fullres::strip::{Placing, StripOptions, StripReport, WindowChoice, fuse_strip};
use rollfuse::fullres::window::{Geometry, WindowSource};
use rollfuse::image::Planes;
use rollfuse::names::Named;

/// How frames are placed along the belt, as `--align` names it for a roll.
#[derive(Clone, Copy, PartialEq)]
enum RollAlign {
    /// Matched frame to frame near a prediction (the rows given, if any).
    Template,
    /// The rows given, as they are.
    Motion,
}

impl Named for RollAlign {
    const VALUES: &'static [(&'static str, &'static str, Self)] = &[
        (
            "template",
            "matched frame to frame near a prediction",
            RollAlign::Template,
        ),
        ("motion", "the rows given, as they are", RollAlign::Motion),
    ];
}

/// The strip's rows in memory, from its first; a jump in the belt rows (frames that no
/// longer overlap) is refused, as one array cannot hold the rows between.
struct Rows {
    first: Option<i64>,
    planes: Planes,
}

impl StripSink for Rows {
    fn row(&mut self, row: i64, channels: &[&[f32]]) -> anyhow::Result<()> {
        let first = *self.first.get_or_insert(row);
        let expected = first + self.planes.height as i64;
        anyhow::ensure!(
            row == expected,
            "the belt jumps from row {} to row {row}: no frame covers the rows between; \
             fuse the frames either side of the jump separately",
            expected - 1
        );
        for (plane, values) in self.planes.planes.iter_mut().zip(channels) {
            plane.extend_from_slice(values);
        }
        self.planes.height += 1;
        Ok(())
    }
}

/// The roller's geometry from a dict (as `simulate` returns it); the apex defaults to the
/// middle row of frames `height` rows high.
fn geometry_of(d: &Bound<'_, PyDict>, height: usize) -> PyResult<Geometry> {
    let number = |key: &str| -> PyResult<Option<f64>> {
        d.get_item(key)?.map(|v| v.extract::<f64>()).transpose()
    };
    let required =
        |key: &str| number(key)?.ok_or_else(|| value_error(format!("geometry has no '{key}'")));
    Ok(Geometry {
        roller_radius_mm: required("roller_radius_mm")?,
        press_depth_mm: required("press_depth_mm")?,
        mm_per_px: required("mm_per_px")?,
        apex_row: number("apex_row")?.unwrap_or(height as f64 / 2.0),
    })
}

/// The strip options from the keyword arguments.
struct RollArgs<'a, 'py> {
    align: &'a str,
    rows: Option<Vec<f64>>,
    window_rows: Option<usize>,
    geometry: Option<&'a Bound<'py, PyDict>>,
    bands: Bands,
    track: TrackParams,
}

impl RollArgs<'_, '_> {
    fn options(self, settings: &Settings, height: usize) -> PyResult<StripOptions> {
        let placing = match (choice::<RollAlign>("align", self.align)?, self.rows) {
            (RollAlign::Motion, Some(rows)) => Placing::Commanded(rows),
            (RollAlign::Motion, None) => {
                return Err(value_error(
                    "align='motion' needs rows= (each frame's belt row)",
                ));
            }
            (RollAlign::Template, commanded) => Placing::Track {
                params: Some(self.track),
                commanded,
            },
        };
        let window = match (self.window_rows, self.geometry) {
            (Some(0), _) => return Err(value_error("window_rows must be at least 1")),
            (Some(rows), _) => WindowChoice::Rows(rows),
            (None, Some(g)) => WindowChoice::Geometry(geometry_of(g, height)?),
            (None, None) => WindowChoice::Measure,
        };
        Ok(StripOptions {
            window,
            bands: self.bands,
            cfg: settings.cfg,
            precision: settings.precision,
            placing,
        })
    }
}

/// Each frame's placement as arrays: row (float64), col (int64), score (float64, NaN
/// where none), sigma (float64: the step's standard deviation, rows) and source (a list
/// of names).
fn placements_dict<'py>(py: Python<'py>, p: &[Placement]) -> PyResult<Bound<'py, PyDict>> {
    let n = p.len();
    let d = PyDict::new(py);
    d.set_item(
        "row",
        owned(py, vec![n], p.iter().map(|p| p.row).collect())?,
    )?;
    d.set_item(
        "col",
        owned(py, vec![n], p.iter().map(|p| p.col).collect())?,
    )?;
    let score = p
        .iter()
        .map(|p| p.score.map_or(f64::NAN, f64::from))
        .collect();
    d.set_item("score", owned(py, vec![n], score)?)?;
    d.set_item(
        "sigma",
        owned(py, vec![n], p.iter().map(|p| p.sigma).collect())?,
    )?;
    let source: Vec<&str> = p.iter().map(|p| p.source.name()).collect();
    d.set_item("source", source)?;
    Ok(d)
}

/// The report as a dict; the bands fused from outside every window, or left as zeros,
/// are also issued as a RuntimeWarning, as the command line warns of them.
fn report_dict<'py>(
    py: Python<'py>,
    r: &StripReport,
    first_row: i64,
) -> PyResult<Bound<'py, PyDict>> {
    let s = &r.summary;
    let d = PyDict::new(py);
    d.set_item("first_row", first_row)?;
    d.set_item("window", (r.window.top, r.window.rows))?;
    let source = match r.window_source {
        WindowSource::Option => "window_rows",
        WindowSource::Geometry => "geometry",
        WindowSource::Measured => "measured",
        WindowSource::Default => "default",
    };
    d.set_item("window_source", source)?;
    let (matched, predicted, unmatched, predicted_rows) =
        r.placement.as_ref().map_or((0, 0, 0, 0.0), |p| {
            (p.matched, p.predicted, p.unmatched, p.predicted_rows)
        });
    d.set_item("matched", matched)?;
    d.set_item("predicted", predicted)?;
    d.set_item("unmatched", unmatched)?;
    d.set_item("predicted_rows", predicted_rows)?;
    d.set_item("trusted", r.doubts.is_empty())?;
    d.set_item("doubts", r.doubts.clone())?;
    d.set_item("bands", s.bands)?;
    d.set_item("bands_outside_window", s.bands_outside_window)?;
    d.set_item("gap_bands", s.gap_bands)?;
    d.set_item("frames_behind", s.frames_behind)?;
    if s.bands_outside_window + s.gap_bands + s.frames_behind > 0 {
        let text = format!(
            "{} band(s) outside every contact window (fused from the nearest frame), {} \
             band(s) no frame covered (zeros), {} frame(s) wholly behind the strip already \
             fused (out of belt order?)",
            s.bands_outside_window, s.gap_bands, s.frames_behind
        );
        PyErr::warn(
            py,
            &py.get_type::<PyRuntimeWarning>(),
            &std::ffi::CString::new(text)?,
            2,
        )?;
    }
    if !r.doubts.is_empty() {
        let text = format!(
            "the frames' placement cannot be trusted: {}",
            r.doubts.join("; ")
        );
        PyErr::warn(
            py,
            &py.get_type::<PyRuntimeWarning>(),
            &std::ffi::CString::new(text)?,
            2,
        )?;
    }
    Ok(d)
}

/// Fuses a whole roll into a strip, as `rollfuse fuse --mode roll` does: each frame is
/// placed along the belt (tracked by matching, or at the rows given) and the strip is
/// fused band by band from the frames whose contact window held the band. Memory holds
/// the frames of one window, not the roll, besides the strip itself.
///
/// frames: (N, H, W) / (N, H, W, 3) array or a list of (H, W) / (H, W, 3) arrays, in
///     acquisition order, as for `fuse`.
/// rows: each frame's belt row (of its top row), e.g. `simulate(...)["strip_row"]`:
///     with align='template' they predict where to match; with align='motion' they place
///     the frames as they are.
/// window_rows: the contact window's rows, centred on the middle row; else from
///     `geometry` (a dict: roller_radius_mm, press_depth_mm, mm_per_px, apex_row
///     optional; `simulate` returns one), else measured on the first frames.
/// band_rows, blend_rows, search_rows, max_shift, min_score, subpixel, max_drift_cols:
///     as the command line's --band-rows … --max-drift-cols.
/// Returns (strip, placements, report): the strip (float32 on the 0–255 scale, or uint8
/// / uint16 with `out_dtype`) from belt row report['first_row']; placements, a dict of
/// (N,) arrays row, col, score and the list source; report, a dict of the window and the
/// bands.
#[pyfunction]
#[pyo3(signature = (frames, *, rows=None, align="template", window_rows=None, geometry=None,
    band_rows=32, blend_rows=8, search_rows=None, max_shift=None, min_score=None,
    subpixel=true, max_drift_cols=0, wavelet="db2", levels=1, ablation="none",
    precision="f32", ll_weighting="paper", out_dtype="float32"))]
pub fn fuse_roll<'py>(
    py: Python<'py>,
    frames: &Bound<'py, PyAny>,
    rows: Option<PyReadonlyArray1<'py, f64>>,
    align: &str,
    window_rows: Option<usize>,
    geometry: Option<&Bound<'py, PyDict>>,
    band_rows: usize,
    blend_rows: usize,
    search_rows: Option<usize>,
    max_shift: Option<usize>,
    min_score: Option<f32>,
    subpixel: bool,
    max_drift_cols: usize,
    wavelet: &str,
    levels: u8,
    ablation: &str,
    precision: &str,
    ll_weighting: &str,
    out_dtype: &str,
) -> PyResult<(Py<PyAny>, Bound<'py, PyDict>, Bound<'py, PyDict>)> {
    let settings = Settings::new(
        wavelet,
        levels,
        ablation,
        precision,
        ll_weighting,
        out_dtype,
    )?;
    let stack = Stack::new(frames, "frames")?;
    let frames = Frames::new(stack.views(), "frames").or_py()?;
    let (_, height, channels) = frames.shape();
    let n = frames.frames();
    let rows = rows.map(|r| r.as_array().to_vec());
    if let Some(r) = rows.as_ref().filter(|r| r.len() != n) {
        return Err(value_error(format!(
            "rows has {} values for {n} frames",
            r.len()
        )));
    }
    let mut track = TrackParams::for_height(height);
    track.search_rows = search_rows;
    if let Some(m) = max_shift {
        track.first_search_rows = m;
    }
    if let Some(m) = min_score.filter(|m| (0.0..=1.0).contains(m)) {
        track.min_score = m;
    } else if let Some(m) = min_score {
        return Err(value_error(format!("min_score must be in 0..=1, got {m}")));
    }
    track.subpixel = subpixel;
    track.max_drift_cols = max_drift_cols;
    track.check(frames.shape().0, height).or_py()?;
    let args = RollArgs {
        align,
        rows,
        window_rows,
        geometry,
        bands: Bands {
            band_rows,
            blend_rows,
        },
        track,
    };
    let opts = args.options(&settings, height)?;
    let mut placements = Vec::with_capacity(n);
    let fused = py.detach(|| {
        let sink = |width, _| {
            Ok(Rows {
                first: None,
                planes: Planes {
                    width,
                    height: 0,
                    planes: vec![Vec::new(); channels],
                },
            })
        };
        let on_frame = |p: &Placement| {
            placements.push(*p);
            Ok(())
        };
        fuse_strip(frames.each().map(Ok), &opts, sink, on_frame)
    });
    let (strip, report) = fused.or_py()?;
    if strip.planes.height == 0 {
        return Err(value_error("the roll gave no strip rows"));
    }
    let report = report_dict(py, &report, strip.first.unwrap_or(0))?;
    let image = image_array(py, strip.planes, settings.out)?;
    Ok((image, placements_dict(py, &placements)?, report))
}
