//! A whole roll into a strip: the contact measured on the first frames
//! ([`super::contact`]), frames placed on the belt ([`super::register`]), fused band by
//! band over the contact window ([`super::roll`]), rows handed to a sink as soon as no
//! later frame can change them. Memory does not grow with the roll: the first
//! [`MEASURE_FRAMES`] frames (to measure the contact), the frames the tracker has not
//! placed yet ([`super::register::WINDOW`]) and the frames of one contact window.

use super::Precision;
use super::contact::{ContactProfile, NoContact};
use super::register::{Placement, Source, Summary, TrackParams, Tracker};
use super::roll::{Bands, RollFuser, RollSummary, StripSink};
use super::window::{ContactWindow, Geometry, WindowSource};
use rollfuse_core::FuseConfig;
use rollfuse_io::image::Planes;
use std::collections::VecDeque;

pub use super::contact::MEASURE_FRAMES;

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
    /// Why the window could not be measured, when it was to be (the middle half was used).
    pub no_contact: Option<NoContact>,
    /// Bands and rows.
    pub summary: RollSummary,
    /// What the frames' placement rests on (absent when the commanded rows are taken as
    /// they are).
    pub placement: Option<Summary>,
    /// Why the placement cannot be trusted; empty when it can.
    pub doubts: Vec<String>,
}

/// Fuses a roll. `frames` yields decoded frames in acquisition order; `make_sink(width,
/// channels)` opens the output once the first frame's size is known; `on_frame(placement)`
/// sees every frame's placement (for a report) once it is final, in roll order.
///
/// The first [`MEASURE_FRAMES`] frames are read before any is placed: the contact profile
/// (the frame-fixed background and where features are visible) is measured on them.
pub fn fuse_strip<S: StripSink>(
    frames: impl IntoIterator<Item = anyhow::Result<Planes>>,
    opts: &StripOptions,
    make_sink: impl FnOnce(usize, usize) -> anyhow::Result<S>,
    mut on_frame: impl FnMut(&Placement) -> anyhow::Result<()>,
) -> crate::Result<(S, StripReport)> {
    let mut frames = frames.into_iter();
    let mut head = Vec::with_capacity(MEASURE_FRAMES);
    for frame in frames.by_ref() {
        head.push(frame?);
        if head.len() == MEASURE_FRAMES {
            break;
        }
    }
    let Some(first) = head.first() else {
        rollfuse_io::invalid!("no frames to fuse");
    };
    let shape = (first.width, first.height, first.planes.len());
    for (k, f) in head.iter().enumerate() {
        same_shape(k, f, shape)?;
    }
    let profile = ContactProfile::measure(&head.iter().collect::<Vec<_>>());
    let (window, window_source, no_contact) = choose_window(&opts.window, &profile);
    let mut fuser = RollFuser::new(
        make_sink(shape.0, shape.2)?,
        shape,
        window,
        opts.bands,
        &opts.cfg,
        opts.precision,
    )?;
    let mut placer = Placer::new(&opts.placing, &profile);
    let mut take = |placed: Vec<(Placement, Planes)>| -> crate::Result<()> {
        for (p, image) in placed {
            on_frame(&p)?;
            fuser.push(p.frame, (p.row.round() as i64, p.col), image)?;
        }
        Ok(())
    };
    for (k, frame) in head.into_iter().map(Ok).chain(frames).enumerate() {
        let frame = frame?;
        same_shape(k, &frame, shape)?;
        take(placer.push(k, frame)?)?;
    }
    take(placer.finish())?;
    let (placement, frames_seen) = placer.summary();
    let doubts = placement
        .as_ref()
        .map(|s| s.doubts(frames_seen))
        .unwrap_or_default();
    let window = fuser.window();
    let (sink, summary) = fuser.finish()?;
    Ok((
        sink,
        StripReport {
            window,
            window_source,
            no_contact,
            summary,
            placement,
            doubts,
        },
    ))
}

/// Refuses frame `k` unless it is `width × height` with `channels` planes.
fn same_shape(k: usize, f: &Planes, (w, h, c): (usize, usize, usize)) -> crate::Result<()> {
    rollfuse_io::require!(
        (f.width, f.height, f.planes.len()) == (w, h, c),
        "frame {k} is {}×{} with {} channels; the roll's frames are {w}×{h} with {c}",
        f.width,
        f.height,
        f.planes.len()
    );
    Ok(())
}

/// The window `choice` names, where it came from, and why it could not be measured.
fn choose_window(
    choice: &WindowChoice,
    profile: &ContactProfile,
) -> (ContactWindow, WindowSource, Option<NoContact>) {
    let h = profile.height;
    let measured = || match profile.window {
        Ok(win) => (win, WindowSource::Measured, None),
        Err(why) => (
            ContactWindow::default_for(h),
            WindowSource::Default,
            Some(why),
        ),
    };
    match choice {
        WindowChoice::Rows(rows) => (
            ContactWindow::centred(h as f64 / 2.0, *rows, h),
            WindowSource::Option,
            None,
        ),
        WindowChoice::Geometry(g) => match ContactWindow::from_geometry(g, h) {
            Some(win) => (win, WindowSource::Geometry, None),
            None => measured(),
        },
        WindowChoice::Measure => measured(),
    }
}

/// Places frames: by the tracker (frames wait until their placement is final) or at
/// their commanded rows.
enum Placer {
    Track {
        tracker: Box<Tracker>,
        commanded: Option<Vec<f64>>,
        waiting: VecDeque<Planes>,
        pushed: usize,
    },
    Commanded(Vec<f64>),
}

impl Placer {
    fn new(placing: &Placing, profile: &ContactProfile) -> Self {
        match placing {
            Placing::Track { params, commanded } => Placer::Track {
                tracker: Box::new(Tracker::new(
                    profile,
                    params.unwrap_or_else(|| TrackParams::for_height(profile.height)),
                )),
                commanded: commanded.clone(),
                waiting: VecDeque::new(),
                pushed: 0,
            },
            Placing::Commanded(rows) => Placer::Commanded(rows.clone()),
        }
    }

    /// Frame `k`; the frames whose placement is now final, with it.
    fn push(&mut self, k: usize, frame: Planes) -> crate::Result<Vec<(Placement, Planes)>> {
        let commanded_row = |rows: &[f64]| {
            rows.get(k)
                .copied()
                .ok_or_else(|| crate::Error::Invalid(format!("frame {k} has no commanded row")))
        };
        match self {
            Placer::Track {
                tracker,
                commanded,
                waiting,
                pushed,
            } => {
                let c = commanded.as_deref().map(commanded_row).transpose()?;
                let placed = tracker.push(&frame, c);
                waiting.push_back(frame);
                *pushed += 1;
                Ok(pair(placed, waiting))
            }
            Placer::Commanded(rows) => {
                let placement = Placement {
                    frame: k,
                    row: commanded_row(rows)?,
                    source: Source::Manifest,
                    score: None,
                    sigma: 0.0,
                    col: 0,
                };
                Ok(vec![(placement, frame)])
            }
        }
    }

    /// The frames still waiting, placed.
    fn finish(&mut self) -> Vec<(Placement, Planes)> {
        match self {
            Placer::Track {
                tracker, waiting, ..
            } => pair(tracker.finish(), waiting),
            Placer::Commanded(_) => Vec::new(),
        }
    }

    /// The tracker's summary, if frames were tracked, and the frames seen.
    fn summary(&self) -> (Option<Summary>, usize) {
        match self {
            Placer::Track {
                tracker, pushed, ..
            } => (Some(tracker.summary().clone()), *pushed),
            Placer::Commanded(rows) => (None, rows.len()),
        }
    }
}

/// Each placement with its frame, the oldest waiting (placements come in roll order).
fn pair(placed: Vec<Placement>, waiting: &mut VecDeque<Planes>) -> Vec<(Placement, Planes)> {
    placed
        .into_iter()
        .filter_map(|p| waiting.pop_front().map(|f| (p, f)))
        .collect()
}
