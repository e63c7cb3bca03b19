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
    let mut tracker = match &opts.placing {
        Placing::Track { params, .. } => Some(Tracker::new(
            w,
            h,
            params.unwrap_or_else(|| TrackParams::for_height(h)),
        )),
        Placing::Commanded(_) => None,
    };
    let mut fusion = Fusion::new(opts, (w, h, channels), make_sink(w, channels)?)?;
    let (mut matched, mut predicted) = (0, 0);
    for (k, frame) in std::iter::once((0, Ok(first))).chain(frames) {
        let frame = frame?;
        let placement = place(&opts.placing, tracker.as_mut(), k, &frame)?;
        match placement.source {
            Source::Matched => matched += 1,
            Source::Predicted => predicted += 1,
            Source::First | Source::Manifest => {}
        }
        on_frame(k, &placement)?;
        fusion.push(k, (placement.row.round() as i64, placement.col), frame)?;
    }
    let (sink, window, window_source, summary) = fusion.finish()?;
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

/// Where frame `k` goes: tracked (its commanded row, if any, as the prediction) or where
/// it was commanded.
fn place(
    placing: &Placing,
    tracker: Option<&mut Tracker>,
    k: usize,
    frame: &Planes,
) -> anyhow::Result<Placement> {
    let commanded = |rows: &Vec<f64>| {
        rows.get(k)
            .copied()
            .with_context(|| format!("frame {k} has no commanded row"))
    };
    Ok(match (placing, tracker) {
        (Placing::Track { commanded: c, .. }, Some(t)) => {
            let c = c.as_ref().map(commanded).transpose()?;
            t.place(frame, c)
        }
        (Placing::Commanded(rows), _) => Placement {
            row: commanded(rows)?,
            source: Source::Manifest,
            score: None,
            col: 0,
        },
        (Placing::Track { .. }, None) => bail!("no aligner"),
    })
}

/// The fusion as placed frames arrive; the window measured on the first frames when
/// neither the options nor the roller's geometry give it.
struct Fusion<'o, S: StripSink> {
    opts: &'o StripOptions,
    /// Width, height and channels of the frames.
    shape: (usize, usize, usize),
    /// The output, until the fuser takes it.
    sink: Option<S>,
    window_source: WindowSource,
    stage: Stage<S>,
}

impl<'o, S: StripSink> Fusion<'o, S> {
    fn new(opts: &'o StripOptions, shape: (usize, usize, usize), sink: S) -> anyhow::Result<Self> {
        let h = shape.1;
        let (window, window_source) = match opts.window {
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
        let mut fusion = Self {
            opts,
            shape,
            sink: Some(sink),
            window_source,
            stage: Stage::Measuring(Vec::new()),
        };
        if let Some(win) = window {
            fusion.stage = Stage::Fusing(Box::new(fusion.start(win)?));
        }
        Ok(fusion)
    }

    /// The fuser over `window`, writing to the sink.
    fn start(&mut self, window: ContactWindow) -> anyhow::Result<RollFuser<S>> {
        let o = self.opts;
        let sink = self.sink.take().context("sink")?;
        RollFuser::new(sink, self.shape, window, o.bands, &o.cfg, o.precision)
    }

    /// The fuser over the window measured on `held`, fed them.
    fn start_measured(
        &mut self,
        held: Vec<(usize, (i64, i64), Planes)>,
    ) -> anyhow::Result<RollFuser<S>> {
        let win = measured(&held, &mut self.window_source, self.shape.1);
        feed(self.start(win)?, held)
    }

    /// Frame `k` placed at `at`: fused, or held until enough frames measure the window.
    fn push(&mut self, k: usize, at: (i64, i64), frame: Planes) -> anyhow::Result<()> {
        match &mut self.stage {
            Stage::Fusing(fuser) => fuser.push(k, at, frame),
            Stage::Measuring(held) => {
                held.push((k, at, frame));
                if held.len() >= MEASURE_FRAMES {
                    let held = std::mem::take(held);
                    self.stage = Stage::Fusing(Box::new(self.start_measured(held)?));
                }
                Ok(())
            }
        }
    }

    /// The sink, the window used and where it came from, and the fusion's summary.
    fn finish(mut self) -> anyhow::Result<(S, ContactWindow, WindowSource, RollSummary)> {
        let fuser = match std::mem::replace(&mut self.stage, Stage::Measuring(Vec::new())) {
            Stage::Fusing(f) => *f,
            Stage::Measuring(held) => self.start_measured(held)?,
        };
        let window = fuser.window();
        let (sink, summary) = fuser.finish()?;
        Ok((sink, window, self.window_source, summary))
    }
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
