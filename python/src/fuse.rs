//! `rollfuse.fuse` and `rollfuse.fuse_pair`: the command line's mosaic fusion
//! (`rollfuse fuse --mode mosaic`) on numpy frames.

use crate::arrays::{Frames, OutDtype, Samples, Stack, image_array};
use crate::errors::{OrPy, value_error};
use numpy::ndarray::Array2;
use numpy::{PyArray, PyReadonlyArrayDyn};
use pyo3::exceptions::PyRuntimeWarning;
use pyo3::prelude::*;
use rollfuse::fullres::align::{Aligned, Offset, TemplateParams, align_chain};
use rollfuse::fullres::{FrameSource, Precision, fuse_mosaic_from, fuse_mosaic_mut};
use rollfuse::image::{DEFAULT_MAX_PIXELS, PixelLimit, Planes};
use rollfuse::names::Named;
use rollfuse::progress::Silent;
use rollfuse_core::{FuseConfig, SaliencyNorm};

/// A choice named as on the command line (`--wavelet db2`, …).
pub fn choice<T: Named>(name: &str, value: &str) -> PyResult<T> {
    rollfuse::names::parse(name, value).map_err(value_error)
}

/// The fusion settings shared by `fuse` and `fuse_pair`.
pub struct Settings {
    /// The fuse step's configuration.
    pub cfg: FuseConfig,
    /// f32 or the MCU's integer path.
    pub precision: Precision,
    /// What the image comes back as.
    pub out: OutDtype,
    /// The largest canvas built (`fuse`'s `max_pixels`).
    pub limit: PixelLimit,
}

impl Settings {
    /// From the keyword arguments, named as the command line's options.
    pub fn new(
        wavelet: &str,
        levels: u8,
        ablation: &str,
        precision: &str,
        ll_weighting: &str,
        out_dtype: &str,
    ) -> PyResult<Self> {
        if !(1..=4).contains(&levels) {
            return Err(value_error(format!("levels must be 1..=4, got {levels}")));
        }
        let cfg = FuseConfig {
            wavelet: choice("wavelet", wavelet)?,
            levels,
            ablation: choice("ablation", ablation)?,
            norm: SaliencyNorm::Local,
            ll_weighting: choice("ll_weighting", ll_weighting)?,
        };
        Ok(Self {
            cfg,
            precision: choice("precision", precision)?,
            out: OutDtype::parse(out_dtype)?,
            limit: PixelLimit::default(),
        })
    }
}

/// How the frames are placed on the canvas.
enum Placement {
    /// All at the origin.
    None,
    /// Matched frame to frame.
    Template(TemplateParams),
    /// Given by the caller, one (rows, columns) offset per frame.
    Given(Vec<Offset>),
}

/// Each frame's offset, or why it was left out; and the warnings for the caller.
struct Placed {
    offsets: Vec<Result<Offset, String>>,
    warnings: Vec<String>,
}

/// Frames matched frame to frame, as `rollfuse fuse --align template` places them.
fn by_template(frames: &[Planes], params: &TemplateParams) -> Placed {
    let mut warnings = Vec::new();
    let offsets = align_chain(frames, params, &Silent)
        .into_iter()
        .enumerate()
        .map(|(k, aligned)| match aligned {
            Aligned::Placed { at, matched } => {
                let doubts = matched.iter().flat_map(|m| m.doubts(params.max_dy));
                warnings.extend(doubts.map(|d| format!("frame {k} {d}")));
                Ok(at)
            }
            Aligned::Skipped(reason) => {
                warnings.push(format!("skipped frame {k}: {reason}"));
                Err(reason)
            }
        })
        .collect();
    Placed { offsets, warnings }
}

/// Reads `align` and its companions into a placement.
fn placement(
    align: &str,
    offsets: Option<PyReadonlyArrayDyn<'_, i64>>,
    template_rows: (f64, f64),
    max_shift: Option<usize>,
    min_score: Option<f32>,
) -> PyResult<Placement> {
    match (align, offsets) {
        ("offsets", Some(o)) => given_offsets(&o).map(Placement::Given),
        ("offsets", None) => Err(value_error("align='offsets' needs offsets=")),
        (_, Some(_)) => Err(value_error("offsets= is used only with align='offsets'")),
        ("none", None) => Ok(Placement::None),
        ("template", None) => {
            let (top, bottom) = template_rows;
            if !(0.0 <= top && top < bottom && bottom <= 1.0) {
                return Err(value_error(format!(
                    "template_rows must be two fractions 0 ≤ top < bottom ≤ 1, got ({top}, {bottom})"
                )));
            }
            if let Some(m) = min_score.filter(|m| !(0.0..=1.0).contains(m)) {
                return Err(value_error(format!("min_score must be in 0..=1, got {m}")));
            }
            let defaults = TemplateParams::default();
            Ok(Placement::Template(TemplateParams {
                rows: template_rows,
                max_dy: max_shift.unwrap_or(defaults.max_dy),
                min_score: min_score.unwrap_or(defaults.min_score),
                ..defaults
            }))
        }
        (other, None) => Err(value_error(format!(
            "align must be 'none', 'template' or 'offsets', got '{other}'"
        ))),
    }
}

/// Offsets given as an (N,) array of rows or an (N, 2) array of (rows, columns).
fn given_offsets(o: &PyReadonlyArrayDyn<'_, i64>) -> PyResult<Vec<Offset>> {
    let a = o.as_array();
    match *a.shape() {
        [_] => Ok(a.iter().map(|&dy| Offset { dy, dx: 0 }).collect()),
        [_, 2] => Ok(a
            .rows()
            .into_iter()
            .map(|r| Offset { dy: r[0], dx: r[1] })
            .collect()),
        ref s => Err(value_error(format!(
            "offsets must have shape (N,) or (N, 2), got {}",
            crate::arrays::shape_text(s)
        ))),
    }
}

/// Places and fuses `views` (without the GIL); the fused image and the placement.
/// Matching by template needs every frame converted at once; otherwise each frame is
/// converted as fusion reaches it.
fn fuse_views(
    views: Vec<Samples<'_>>,
    placement: &Placement,
    settings: &Settings,
) -> anyhow::Result<(Planes, Placed)> {
    anyhow::ensure!(
        views.len() >= 2,
        "fusion needs at least two frames, got {}",
        views.len()
    );
    let frames = Frames::new(views, "frames")?;
    let (cfg, precision, limit) = (&settings.cfg, settings.precision, settings.limit);
    let offsets = match placement {
        Placement::Template(params) => return fuse_by_template(&frames, params, settings),
        Placement::None => vec![Offset { dy: 0, dx: 0 }; frames.frames()],
        Placement::Given(given) => {
            anyhow::ensure!(
                given.len() == frames.frames(),
                "offsets has {} rows for {} frames",
                given.len(),
                frames.frames()
            );
            given.clone()
        }
    };
    let fused = fuse_mosaic_from(&frames, &offsets, cfg, precision, limit)?;
    let placed = Placed {
        offsets: offsets.into_iter().map(Ok).collect(),
        warnings: Vec::new(),
    };
    Ok((fused, placed))
}

/// Matches `frames` frame to frame and fuses those placed.
fn fuse_by_template(
    frames: &Frames,
    params: &TemplateParams,
    settings: &Settings,
) -> anyhow::Result<(Planes, Placed)> {
    let frames = frames.planes();
    let placed = by_template(&frames, params);
    let mut kept: Vec<(Planes, Offset)> = frames
        .into_iter()
        .zip(&placed.offsets)
        .filter_map(|(f, at)| Some((f, *at.as_ref().ok()?)))
        .collect();
    anyhow::ensure!(
        kept.len() >= 2,
        "only {} frame could be aligned; nothing to fuse ({})",
        kept.len(),
        placed.warnings.join("; ")
    );
    let fused = fuse_mosaic_mut(&mut kept, &settings.cfg, settings.precision, settings.limit)?;
    Ok((fused, placed))
}

/// The offsets as an (N, 2) float64 array, NaN for frames left out.
fn offsets_array(py: Python<'_>, offsets: &[Result<Offset, String>]) -> Py<PyAny> {
    let rows = Array2::from_shape_fn((offsets.len(), 2), |(k, j)| match &offsets[k] {
        Ok(at) => [at.dy, at.dx][j] as f64,
        Err(_) => f64::NAN,
    });
    PyArray::from_owned_array(py, rows).into_any().unbind()
}

/// Issues each line of `warnings` as a Python `RuntimeWarning`.
fn warn_all(py: Python<'_>, warnings: &[String]) -> PyResult<()> {
    let category = py.get_type::<PyRuntimeWarning>();
    for w in warnings {
        let text = std::ffi::CString::new(w.replace('\0', " "))?;
        PyErr::warn(py, &category, &text, 2)?;
    }
    Ok(())
}

/// Fuses a sequence of frames into one image, as `rollfuse fuse --mode mosaic` does (a
/// whole roll, longer than a frame, is `fuse_roll`'s: fused over the contact window).
///
/// frames: an array of shape (N, H, W) or (N, H, W, 3), or a list of (H, W) / (H, W, 3)
///     arrays; uint8, uint16 (scaled by 255/65535) or float32/float64 on the 0–255 scale.
/// align: 'template' (each frame matched against the last one kept; frames that do not
///     match are left out with a RuntimeWarning), 'none' (all at the origin) or
///     'offsets' (the `offsets` given: (N,) rows or (N, 2) rows and columns, int64).
/// Returns (image, offsets): the fused image, float32 on the 0–255 scale (or uint8 /
/// uint16 with `out_dtype`, rounded as the command line's PNGs), shape (H', W') or
/// (H', W', 3) covering every frame placed; and an (N, 2) float64 array of each frame's
/// (rows, columns) offset on that canvas before its origin shift, NaN where left out.
/// max_pixels: the largest canvas built, pixels (the command line's --max-pixels): offsets
///     that would span more are refused before anything is allocated.
#[pyfunction]
#[pyo3(signature = (frames, *, wavelet="db2", levels=1, align="template", offsets=None,
    template_rows=(1.0 / 3.0, 2.0 / 3.0), max_shift=None, min_score=None, ablation="none",
    precision="f32", ll_weighting="paper", out_dtype="float32",
    max_pixels=DEFAULT_MAX_PIXELS))]
pub fn fuse(
    py: Python<'_>,
    frames: &Bound<'_, PyAny>,
    wavelet: &str,
    levels: u8,
    align: &str,
    offsets: Option<PyReadonlyArrayDyn<'_, i64>>,
    template_rows: (f64, f64),
    max_shift: Option<usize>,
    min_score: Option<f32>,
    ablation: &str,
    precision: &str,
    ll_weighting: &str,
    out_dtype: &str,
    max_pixels: u64,
) -> PyResult<(Py<PyAny>, Py<PyAny>)> {
    let settings = Settings {
        limit: PixelLimit(max_pixels),
        ..Settings::new(
            wavelet,
            levels,
            ablation,
            precision,
            ll_weighting,
            out_dtype,
        )?
    };
    let placement = placement(align, offsets, template_rows, max_shift, min_score)?;
    let stack = Stack::new(frames, "frames")?;
    let views = stack.views();
    let (fused, placed) = py
        .detach(|| fuse_views(views, &placement, &settings))
        .or_py()?;
    warn_all(py, &placed.warnings)?;
    let image = image_array(py, fused, settings.out)?;
    Ok((image, offsets_array(py, &placed.offsets)))
}

/// Fuses two images of one size (the fuse step once: `fuse([a, b], align='none')`).
///
/// a, b: (H, W) or (H, W, 3) arrays, uint8, uint16 or float on the 0–255 scale.
/// Returns the fused image: float32 on the 0–255 scale, or uint8 / uint16 with
/// `out_dtype`.
#[pyfunction]
#[pyo3(signature = (a, b, *, wavelet="db2", levels=1, ablation="none", precision="f32",
    ll_weighting="paper", out_dtype="float32"))]
pub fn fuse_pair(
    py: Python<'_>,
    a: &Bound<'_, PyAny>,
    b: &Bound<'_, PyAny>,
    wavelet: &str,
    levels: u8,
    ablation: &str,
    precision: &str,
    ll_weighting: &str,
    out_dtype: &str,
) -> PyResult<Py<PyAny>> {
    let settings = Settings::new(
        wavelet,
        levels,
        ablation,
        precision,
        ll_weighting,
        out_dtype,
    )?;
    let pair = pyo3::types::PyTuple::new(py, [a, b])?;
    let stack = Stack::new(pair.as_any(), "images")?;
    let views = stack.views();
    let (fused, _) = py
        .detach(|| fuse_views(views, &Placement::None, &settings))
        .or_py()?;
    image_array(py, fused, settings.out)
}
