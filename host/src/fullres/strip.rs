//! A whole roll into a strip: frames aligned one at a time ([`super::track`]), fused band
//! by band over the contact window ([`super::roll`]), rows handed to a sink as soon as no
//! later frame can change them. Memory does not grow with the roll: the frames of one
//! window, the aligner's ring of four frame heights, and (to measure the window) the
//! first [`MEASURE_FRAMES`] frames.

use super::Precision;
use super::roll::{Bands, RollFuser, RollSummary, StripSink};
use super::track::{Placement, Source, TrackParams, Tracker};
use super::window::{ContactWindow, Geometry, WindowSource};
use crate::image::Planes;
use anyhow::{Context, bail};
use rollfuse_core::FuseConfig;

/// Frames the window is measured over when neither the user nor the geometry gives it.
pub const MEASURE_FRAMES: usize = 32;

/// Where the contact window comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum WindowChoice {
    /// This many rows centred on the frame's middle row.
    Rows(usize),
    /// From the roller's geometry.
    Geometry(Geometry),
    /// Measured from the first frames.
    Measure,
}

/// How frames are placed along the belt.
#[derive(Debug, Clone, PartialEq)]
pub enum Placing {
    /// Matched near a prediction; `commanded` rows (one per frame), when given, predict.
    Track {
        /// The aligner's settings.
        params: Option<TrackParams>,
        /// Commanded belt rows of the frames' tops, from a manifest.
        commanded: Option<Vec<f64>>,
    },
    /// The commanded rows taken as they are.
    Commanded(Vec<f64>),
}

/// Everything [`fuse_strip`] needs besides the frames.
#[derive(Debug, Clone)]
pub struct StripOptions {
    /// The contact window.
    pub window: WindowChoice,
    /// Band layout.
    pub bands: Bands,
    /// The fuse step.
    pub cfg: FuseConfig,
    /// Arithmetic.
    pub precision: Precision,
    /// Alignment.
    pub placing: Placing,
}

impl StripOptions {
    /// The window from `geometry`, frames placed by the tracker near the `commanded` rows
    /// (each frame's top row on the strip), the default bands and fuse step, in f32.
    pub fn tracked(geometry: Geometry, commanded: Vec<f64>) -> Self {
        Self {
            window: WindowChoice::Geometry(geometry),
            bands: Bands::default(),
            cfg: FuseConfig::default(),
            precision: Precision::F32,
            placing: Placing::Track {
                params: None,
                commanded: Some(commanded),
            },
        }
    }
}

/// What [`fuse_strip`] reports.
#[derive(Debug, Clone, serde::Serialize)]
pub struct StripReport {
    /// The window used (frame rows).
    pub window: ContactWindow,
    /// Where it came from.
    pub window_source: WindowSource,
    /// Bands and rows.
    pub summary: RollSummary,
    /// Frames placed by a match.
    pub matched: usize,
    /// Frames placed at their prediction (no texture to match).
    pub predicted: usize,
}

/// The state while frames arrive: the window not yet known (frames buffered), or the
/// fuser running.
enum Stage<S: StripSink> {
    Measuring(Vec<(usize, (i64, i64), Planes)>),
    Fusing(Box<RollFuser<S>>),
}

/// Fuses a roll. `frames` yields decoded frames in acquisition order; `make_sink(width,
/// channels)` opens the output once the first frame's size is known; `on_frame(k,
/// placement)` sees every frame's placement (for a report) as it is made.
pub fn fuse_strip<S: StripSink>(
    frames: impl IntoIterator<Item = anyhow::Result<Planes>>,
    opts: &StripOptions,
    make_sink: impl FnOnce(usize, usize) -> anyhow::Result<S>,
    mut on_frame: impl FnMut(usize, &Placement) -> anyhow::Result<()>,
) -> anyhow::Result<(S, StripReport)> {
    let mut frames = frames.into_iter().enumerate();
    let Some((_, first)) = frames.next() else {
        bail!("no frames to fuse");
    };
    let first = first?;
    let (w, h, channels) = (first.width, first.height, first.planes.len());
    let (window, mut window_source) = match opts.window {
        WindowChoice::Rows(rows) => (
            Some(ContactWindow::centred(h as f64 / 2.0, rows, h)),
            WindowSource::Option,
        ),
        WindowChoice::Geometry(g) => match ContactWindow::from_geometry(&g, h) {
            Some(win) => (Some(win), WindowSource::Geometry),
            None => (None, WindowSource::Measured),
        },
        WindowChoice::Measure => (None, WindowSource::Measured),
    };
    let mut tracker = match &opts.placing {
        Placing::Track { params, .. } => Some(Tracker::new(
            w,
            h,
            params.unwrap_or_else(|| TrackParams::for_height(h)),
        )),
        Placing::Commanded(_) => None,
    };
    let mut sink = Some(make_sink(w, channels)?);
    let start = |window: ContactWindow, sink: S| {
        RollFuser::new(
            sink,
            (w, h, channels),
            window,
            opts.bands,
            &opts.cfg,
            opts.precision,
        )
    };
    let mut stage = match window {
        Some(win) => Stage::Fusing(Box::new(start(win, sink.take().context("sink")?)?)),
        None => Stage::Measuring(Vec::new()),
    };
    let (mut matched, mut predicted) = (0, 0);
    for (k, frame) in std::iter::once((0, Ok(first))).chain(frames) {
        let frame = frame?;
        let commanded = |rows: &Vec<f64>| {
            rows.get(k)
                .copied()
                .with_context(|| format!("frame {k} has no commanded row"))
        };
        let placement = match (&opts.placing, tracker.as_mut()) {
            (Placing::Track { commanded: c, .. }, Some(t)) => {
                let c = c.as_ref().map(commanded).transpose()?;
                t.place(&frame, c)
            }
            (Placing::Commanded(rows), _) => Placement {
                row: commanded(rows)?,
                source: Source::Manifest,
                score: None,
                col: 0,
            },
            (Placing::Track { .. }, None) => bail!("no aligner"),
        };
        match placement.source {
            Source::Matched => matched += 1,
            Source::Predicted => predicted += 1,
            Source::First | Source::Manifest => {}
        }
        on_frame(k, &placement)?;
        let at = (placement.row.round() as i64, placement.col);
        stage = match stage {
            Stage::Fusing(mut fuser) => {
                fuser.push(k, at, frame)?;
                Stage::Fusing(fuser)
            }
            Stage::Measuring(mut held) => {
                held.push((k, at, frame));
                if held.len() < MEASURE_FRAMES {
                    Stage::Measuring(held)
                } else {
                    let win = measured(&held, &mut window_source, h);
                    Stage::Fusing(Box::new(feed(
                        start(win, sink.take().context("sink")?)?,
                        held,
                    )?))
                }
            }
        };
    }
    let fuser = match stage {
        Stage::Fusing(f) => *f,
        Stage::Measuring(held) => {
            let win = measured(&held, &mut window_source, h);
            feed(start(win, sink.take().context("sink")?)?, held)?
        }
    };
    let window = fuser.window();
    let (sink, summary) = fuser.finish()?;
    Ok((
        sink,
        StripReport {
            window,
            window_source,
            summary,
            matched,
            predicted,
        },
    ))
}

/// The window measured on `held`, or the default (and the source says which).
fn measured(
    held: &[(usize, (i64, i64), Planes)],
    source: &mut WindowSource,
    h: usize,
) -> ContactWindow {
    let frames: Vec<&Planes> = held.iter().map(|(_, _, f)| f).collect();
    match ContactWindow::measure(&frames) {
        Some(win) => {
            *source = WindowSource::Measured;
            win
        }
        None => {
            *source = WindowSource::Default;
            ContactWindow::default_for(h)
        }
    }
}

fn feed<S: StripSink>(
    mut fuser: RollFuser<S>,
    held: Vec<(usize, (i64, i64), Planes)>,
) -> anyhow::Result<RollFuser<S>> {
    for (k, at, frame) in held {
        fuser.push(k, at, frame)?;
    }
    Ok(fuser)
}
