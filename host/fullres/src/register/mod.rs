//! Registration: where each frame of a roll lies on the belt, from all the evidence at
//! once, with its source and how sure it is.
//!
//! - **Features** ([`features`]). Each frame minus the frame-fixed background (the
//!   median of the first frames, then following slow drifts), over the band of rows where
//!   moving features are visible ([`crate::contact`]).
//! - **Matches** ([`pairs`]). Each new frame against the last frames whose bands it
//!   overlaps (up to [`LAGS`] back), near the predicted shift, by a correlation in which
//!   each frame's rows are weighted by the other's visibility. A match is kept when its
//!   score is within [`GATE`] times the roll's typical mismatch (1 − score) and its peak is
//!   sharp; its standard deviation grows with both. A view in which a feature is entering
//!   or leaving the contact band, or a wide flat plateau fills it, scores lower and is
//!   left to the prediction rather than let shorten the belt. Matches kept before the
//!   typical mismatch is known are judged again once it is.
//! - **Prediction.** The commanded motion when there is a manifest; otherwise the robust
//!   mean of the last measured steps (the speed: steps between frames a match joins), with
//!   a standard deviation of 17 % of a step (a speed varying by ±30 %). The search centres
//!   on it from the first measured step; it carries frames once 4 are measured.
//! - **Positions** ([`solve`]). Least squares over the last [`WINDOW`] frames, the older
//!   ones held: every kept match, the prediction of every step, and with a manifest each
//!   frame's commanded row (loosely: it carries the belt's unknown error); inconsistent
//!   matches are dropped one at a time. A frame is placed for good once [`WINDOW`] newer
//!   frames have been seen. Every match has the roll's pull toward no motion added back
//!   ([`pull`]), measured where a long match and the lag-1 matches along it disagree.
//! - **Lost and found.** A textured frame that matches nothing near the prediction is
//!   searched for over the whole reach (`first_search_rows` either side) and kept if the
//!   match is unambiguous.
//! - **Honesty.** Every placement carries its source and the standard deviation of its
//!   step; the [`Summary`] says how much of the belt rests on predictions and whether the
//!   placement can be trusted.

pub mod features;
pub mod pairs;
pub mod pull;
pub mod solve;

use crate::contact::{ContactProfile, MEASURE_FRAMES};
use features::{Features, Featurizer};
use pairs::{Match, best_match};
use pull::Pull;
use rollfuse_io::image::Planes;
use solve::{Anchor, Problem, Relation};
use std::collections::VecDeque;

/// Frames solved together; a frame is placed for good when it leaves this window.
pub const WINDOW: usize = 10;
/// Frames held while no motion is known (a roll that starts bare), at most.
pub const HOLD_UNTIL_MOTION: usize = 48;
/// Measured steps that make the motion known at the start of a roll.
const SPEED_TO_START: usize = 4;
/// How many frames back a new frame is matched against (those its band still overlaps).
pub const LAGS: [usize; 6] = [1, 2, 3, 4, 6, 8];
/// A match is kept when its mismatch (1 − score) is at most this many times the roll's
/// typical mismatch.
pub const GATE: f32 = 3.0;
/// The typical mismatch is taken as at least this: on frames with little noise, scores
/// differ by the features' own change of appearance, not by noise.
const MIN_TYPICAL_MISMATCH: f32 = 0.02;
/// Steps the speed is measured over.
const SPEED_STEPS: usize = 64;
/// A step counts toward the speed when its standard deviation is at most this fraction of
/// it (or 0.3 rows): a step resting on weak matches (a feature entering or leaving the
/// contact band) or on the prediction itself does not.
const SPEED_SIGMA: f64 = 0.05;
/// The mismatch of a frame's best match is compared with this many recent ones.
const TYPICAL_SCORES: usize = 32;
/// A frame whose residual's mean square is at least this many times the noise's shows
/// texture.
const TEXTURE: f32 = 3.0;
/// Standard deviation of a commanded row (the belt's unknown error), rows.
const COMMANDED_SIGMA: f64 = 2.0;
/// Placed frames over which the matched positions are anchored to the commanded rows.
const ANCHOR_FRAMES: usize = 40;
/// A run of this many textured frames matching nothing means the belt was lost.
pub const LOST_RUN: usize = 8;
/// A stretch of at least this many predicted frames has its speed checked against the
/// matched steps after it…
pub const SPEED_CHECK_FRAMES: usize = 8;
/// …over this many of them (their median)…
const SPEED_CHECK_STEPS: usize = 8;
/// …and is a doubt when the two differ by more than this fraction of the matched speed
/// (the median of 8 steps of a belt varying by ±30 % is good to about 8 %).
pub const SPEED_DISAGREEMENT: f64 = 0.3;
/// Commanded travel after which matched steps are rescaled to it, rows.
const SCALE_AFTER: f64 = 100.0;

/// Standard deviation of a predicted step, a fraction of the speed (a speed varying by
/// ±30 %), and at least [`MIN_PREDICTION_SIGMA`] rows.
const PREDICTION_SIGMA: f64 = 0.173;
const MIN_PREDICTION_SIGMA: f64 = 0.5;

/// The standard deviation of a step of `rows` predicted from the speed.
fn prediction_sigma(rows: f64) -> f64 {
    (PREDICTION_SIGMA * rows.abs()).max(MIN_PREDICTION_SIGMA)
}

/// Registration settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackParams {
    /// Rows searched either side of the predicted shift; `None`: 3 plus 30 % of the
    /// predicted shift (a speed varying by ±25 % stays inside).
    pub search_rows: Option<usize>,
    /// Rows searched either side before any motion is known, and when the belt is lost.
    pub first_search_rows: usize,
    /// Lowest normalized correlation a match may have.
    pub min_score: f32,
    /// Refine matches to a fraction of a row.
    pub subpixel: bool,
    /// Columns the belt may drift sideways from one frame to the next (0: none).
    pub max_drift_cols: usize,
}

impl TrackParams {
    /// The defaults for frames `height` rows high: the first search spans half a frame.
    pub fn for_height(height: usize) -> Self {
        Self {
            search_rows: None,
            first_search_rows: height / 2,
            min_score: 0.5,
            subpixel: true,
            max_drift_cols: 0,
        }
    }

    /// Refuses a reach past frames of `width × height`: the search around a prediction
    /// (`--search-rows`) from 1 to the height, the first search (`--max-shift`) and the
    /// sideways drift (`--max-drift-cols`) at most the height and the width, the score
    /// from −1 to 1. A search past the frame finds nothing more, and costs time.
    pub fn check(&self, width: usize, height: usize) -> crate::Result<()> {
        if let Some(r) = self.search_rows {
            rollfuse_io::require!(
                (1..=height).contains(&r),
                "--search-rows must be from 1 to the frames' height ({height} rows), got {r}"
            );
        }
        rollfuse_io::require!(
            self.first_search_rows <= height,
            "--max-shift must be at most the frames' height ({height} rows), got {}",
            self.first_search_rows
        );
        rollfuse_io::require!(
            self.max_drift_cols <= width,
            "--max-drift-cols must be at most the frames' width ({width}), got {}",
            self.max_drift_cols
        );
        rollfuse_io::require!(
            (-1.0..=1.0).contains(&self.min_score),
            "--min-score must be from -1 to 1, got {}",
            self.min_score
        );
        Ok(())
    }
}

/// How a frame's position was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Source {
    /// The first frame: the origin, or its commanded row.
    First,
    /// Matched against the frames before or after it.
    Matched,
    /// No texture to match: the prediction (the speed, or the commanded motion).
    Predicted,
    /// Texture, but nothing it matched: the prediction, and a sign the belt was lost.
    Unmatched,
    /// The manifest's commanded row, taken as it is (`--align motion`).
    Manifest,
}

impl Source {
    /// The name used in reports.
    pub fn name(self) -> &'static str {
        match self {
            Source::First => "first",
            Source::Matched => "matched",
            Source::Predicted => "predicted",
            Source::Unmatched => "unmatched",
            Source::Manifest => "manifest",
        }
    }
}

/// Where a frame lies: the belt row of its top row.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Placement {
    /// The frame's index in the roll.
    pub frame: usize,
    /// Belt row of the frame's row 0 (fractional with sub-pixel matching).
    pub row: f64,
    /// How it was found.
    pub source: Source,
    /// The best correlation among its kept matches, else the best found (absent for the
    /// first frame, manifest rows, and frames nothing could be compared with).
    pub score: Option<f32>,
    /// Standard deviation of the step from the frame before, rows (0 for the first).
    pub sigma: f64,
    /// Belt column of the frame's column 0 (always 0 unless sideways drift is allowed).
    pub col: i64,
}

/// What the placement of a whole roll rests on.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct Summary {
    /// Frames by source.
    pub matched: usize,
    /// Frames with no texture, placed by the prediction.
    pub predicted: usize,
    /// Textured frames that matched nothing.
    pub unmatched: usize,
    /// Rows of belt travel whose steps rest on predictions (either end of the step not
    /// matched), and all of the travel.
    pub predicted_rows: f64,
    /// All rows of travel.
    pub travel_rows: f64,
    /// The longest run of predicted or unmatched frames: its length and first frame.
    pub longest_guess: (usize, usize),
    /// The longest run of textured frames with no match kept (unmatched, or matched
    /// only by matches rejected or dropped): its length and first frame. Single frames
    /// where a feature enters or leaves the contact band are left to the prediction; a
    /// run of them is a belt lost.
    pub longest_lost: (usize, usize),
    /// Matches dropped as inconsistent with the others.
    pub inconsistent: usize,
    /// Matches kept.
    pub matches: usize,
    /// Times the belt was found again by a search over the whole reach.
    pub found_again: usize,
    /// The predicted stretch whose speed most disagreed with the matched steps after it,
    /// if any disagreed by more than [`SPEED_DISAGREEMENT`].
    pub speed_disagreement: Option<SpeedDisagreement>,
}

/// A stretch of predicted frames placed at a speed the belt, matched after it, did not
/// have: its length on the belt is wrong by about the difference.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SpeedDisagreement {
    /// The stretch's first frame.
    pub first: usize,
    /// Its length, frames.
    pub frames: usize,
    /// Its mean placed step, rows a frame.
    pub predicted: f64,
    /// The median matched step after it, rows a frame.
    pub matched: f64,
}

impl SpeedDisagreement {
    /// The difference as a fraction of the matched speed.
    pub fn fraction(&self) -> f64 {
        (self.predicted - self.matched).abs() / self.matched.abs().max(1e-9)
    }
}

impl Summary {
    /// Why the placement cannot be trusted (empty: it can).
    pub fn doubts(&self, frames: usize) -> Vec<String> {
        let mut why = Vec::new();
        if frames > 1 && self.matched == 0 {
            why.push("no two frames matched: the belt's motion is unknown".to_string());
        }
        let (run, at) = self.longest_lost;
        if run >= LOST_RUN {
            why.push(format!(
                "the belt was lost for {run} textured frames from frame {at} (no match kept)"
            ));
        }
        let textured = self.matched + self.unmatched;
        if textured > 0 && self.unmatched * 5 > textured {
            why.push(format!(
                "{} of {textured} textured frames matched nothing",
                self.unmatched
            ));
        }
        if let Some(d) = &self.speed_disagreement {
            why.push(format!(
                "frames {}–{} were placed at {:.2} rows a frame, but the belt matched at {:.2} \
                 after them: that stretch's length rests on a wrong speed",
                d.first,
                d.first + d.frames - 1,
                d.predicted,
                d.matched
            ));
        }
        if self.matches > 0 && self.inconsistent * 5 > self.matches {
            why.push(format!(
                "{} of {} matches contradicted the others",
                self.inconsistent,
                self.matches + self.inconsistent
            ));
        }
        why
    }
}

/// A frame still being placed.
struct Held {
    features: Features,
    position: f64,
    commanded: Option<f64>,
    /// Belt column of the frame's column 0, to a fraction.
    col: f64,
    /// The best correlation found against any earlier frame.
    best_score: Option<f32>,
    textured: bool,
}

/// Travel over lag-1 matches between commanded frames.
#[derive(Debug, Clone, Copy, Default)]
struct Travel {
    /// Rows the matches measured…
    matched: f64,
    /// …the pull's share in them ([`Pull::share`])…
    pull_share: f64,
    /// …and rows commanded.
    commanded: f64,
}

/// A kept match between two frames (roll indices).
#[derive(Debug, Clone, Copy)]
struct Edge {
    from: usize,
    to: usize,
    rows: f64,
    sigma: f64,
    score: f32,
    /// How sharp the correlation's peak was.
    sharpness: f32,
    /// Kept before the roll's typical mismatch was known: judged again once it is.
    provisional: bool,
}

/// The running registration: feed it frames in acquisition order; it hands back each
/// frame's placement once [`WINDOW`] newer frames have been seen (the rest at
/// [`Tracker::finish`]).
pub struct Tracker {
    params: TrackParams,
    featurizer: Featurizer,
    /// Frames from roll index `first_held` on.
    held: VecDeque<Held>,
    first_held: usize,
    /// Frames handed back so far.
    placed: usize,
    edges: Vec<Edge>,
    /// The last placed frame's matched position (before anchoring to commanded rows) and
    /// whether it was matched.
    last_placed: Option<(f64, bool)>,
    /// The last measured steps between placed frames (for the speed).
    steps: VecDeque<f64>,
    /// The speed when the last frame was placed: kept when no measured step is left.
    last_speed: Option<f64>,
    /// Commanded row minus matched position, of the last placed commanded frames.
    anchor: VecDeque<f64>,
    /// Best lag-1 scores of recent frames.
    typical: VecDeque<f32>,
    /// Travel over lag-1 matches between commanded frames (for the apparent scale).
    travel: Travel,
    /// The matches' pull toward no motion.
    pull: Pull,
    /// The previous frame's gray levels, when sideways drift is allowed.
    previous_gray: Vec<f32>,
    /// Step standard deviations from the last solve, per held frame.
    step_sigma: Vec<f64>,
    summary: Summary,
    guess_run: (usize, usize),
    lost_run: (usize, usize),
    speed_check: SpeedCheck,
    width: usize,
}

/// Checks each stretch of predicted frames against the matched steps after it.
#[derive(Default)]
struct SpeedCheck {
    /// The stretch being placed.
    stretch: Stretch,
    /// A finished stretch waiting for matched steps, and those seen.
    pending: Option<(Stretch, Vec<f64>)>,
}

/// A run of frames placed by the prediction.
#[derive(Default, Clone, Copy)]
struct Stretch {
    first: usize,
    frames: usize,
    /// The steps into its frames, summed.
    rows: f64,
}

impl SpeedCheck {
    /// Takes frame `k`'s step (`None`: the first frame), whether it was guessed, and
    /// whether the step was measured (both ends matched); returns a disagreement once
    /// one is known.
    fn place(
        &mut self,
        k: usize,
        step: Option<f64>,
        guessed: bool,
        measured: bool,
    ) -> Option<SpeedDisagreement> {
        let step = step?;
        if guessed {
            if self.stretch.frames == 0 {
                self.stretch.first = k;
            }
            self.stretch.frames += 1;
            self.stretch.rows += step;
            return None;
        }
        let ended = std::mem::take(&mut self.stretch);
        if ended.frames >= SPEED_CHECK_FRAMES {
            self.pending = Some((ended, Vec::new()));
        }
        let (stretch, steps) = self.pending.as_mut()?;
        if measured {
            steps.push(step);
        }
        if steps.len() < SPEED_CHECK_STEPS {
            return None;
        }
        steps.sort_by(f64::total_cmp);
        let found = SpeedDisagreement {
            first: stretch.first,
            frames: stretch.frames,
            predicted: stretch.rows / stretch.frames as f64,
            matched: steps[steps.len() / 2],
        };
        self.pending = None;
        (found.fraction() > SPEED_DISAGREEMENT).then_some(found)
    }
}

impl Tracker {
    /// A tracker for frames of the profile's size.
    pub fn new(profile: &ContactProfile, params: TrackParams) -> Self {
        Self {
            params,
            featurizer: Featurizer::new(profile),
            held: VecDeque::new(),
            first_held: 0,
            placed: 0,
            edges: Vec::new(),
            last_placed: None,
            steps: VecDeque::new(),
            last_speed: None,
            anchor: VecDeque::new(),
            typical: VecDeque::new(),
            travel: Travel::default(),
            pull: Pull::default(),
            previous_gray: Vec::new(),
            step_sigma: Vec::new(),
            summary: Summary::default(),
            guess_run: (0, 0),
            lost_run: (0, 0),
            speed_check: SpeedCheck::default(),
            width: profile.width,
        }
    }

    /// Places `frames` (one size, in roll order, no commanded rows): the contact measured
    /// on the first [`MEASURE_FRAMES`] of them, then every frame tracked.
    pub fn place_all(frames: &[Planes], params: TrackParams) -> (Vec<Placement>, Summary) {
        let head: Vec<&Planes> = frames.iter().take(MEASURE_FRAMES).collect();
        let mut tracker = Self::new(&ContactProfile::measure(&head), params);
        let mut placed: Vec<Placement> =
            frames.iter().flat_map(|f| tracker.push(f, None)).collect();
        placed.extend(tracker.finish());
        (placed, tracker.summary)
    }

    /// The rows the frames are matched over: first row and count.
    pub fn band(&self) -> (usize, usize) {
        let b = self.featurizer.band();
        (b.top, b.rows())
    }

    /// What the placements so far rest on.
    pub fn summary(&self) -> &Summary {
        &self.summary
    }

    /// Roll index of the next frame pushed.
    fn next_index(&self) -> usize {
        self.first_held + self.held.len()
    }

    /// Takes the next frame (its commanded belt row, if a manifest gives one) and returns
    /// the placements it makes final, in roll order.
    pub fn push(&mut self, frame: &Planes, commanded: Option<f64>) -> Vec<Placement> {
        let gray = frame.gray();
        let features = self.featurizer.features(&gray);
        let k = self.next_index();
        let textured = features.content >= TEXTURE;
        let guess = match self.held.back() {
            None => commanded.unwrap_or(0.0),
            Some(prev) => prev.position + self.predicted_step(prev.commanded, commanded),
        };
        self.held.push_back(Held {
            features,
            position: guess,
            commanded,
            col: self.held.back().map_or(0.0, |p| p.col),
            best_score: None,
            textured,
        });
        if k > 0 {
            self.match_new(k);
            if self.params.max_drift_cols > 0 {
                self.follow_sideways(k, &gray);
            }
            self.solve();
        }
        if self.params.max_drift_cols > 0 {
            self.previous_gray = gray.into_owned();
        }
        // Until the motion is known from a few steps, frames wait (up to
        // [`HOLD_UNTIL_MOTION`]): the speed then places the bare frames before it.
        let known =
            self.held.iter().any(|h| h.commanded.is_some()) || self.settled_speed().is_some();
        let hold = if known { WINDOW } else { HOLD_UNTIL_MOTION };
        let mut out = Vec::new();
        while self.next_index() - self.placed > hold {
            out.push(self.place_oldest());
        }
        out
    }

    /// Places every frame still held.
    pub fn finish(&mut self) -> Vec<Placement> {
        let mut out = Vec::new();
        while self.placed < self.next_index() {
            out.push(self.place_oldest());
        }
        out
    }

    /// The held frame with roll index `k`.
    fn frame(&self, k: usize) -> Option<&Held> {
        k.checked_sub(self.first_held)
            .and_then(|i| self.held.get(i))
    }

    /// The robust mean of the last [`SPEED_STEPS`] measured steps (between consecutive
    /// frames a match joins, the newest frame left out; the middle 60 % averaged). It holds
    /// through a stretch with nothing to match, however long.
    fn speed(&self) -> Option<f64> {
        self.measured_speed().map(|(v, _)| v).or(self.last_speed)
    }

    /// The speed once [`SPEED_TO_START`] steps are measured: only then does it carry
    /// frames (a prior on every step), so that one wrong early match, which the search
    /// still centres on, cannot outweigh the right ones after it.
    fn settled_speed(&self) -> Option<f64> {
        match self.measured_speed() {
            Some((v, n)) if n >= SPEED_TO_START => Some(v),
            _ => self.last_speed,
        }
    }

    /// The speed from the measured steps at hand, and how many there are.
    fn measured_speed(&self) -> Option<(f64, usize)> {
        let newest = self.next_index().saturating_sub(1);
        // A step counts when a match joins its two frames: a frame matched only to
        // later ones says nothing of the step before it.
        let measured = |k: usize| self.edges.iter().any(|e| e.to == k && e.from + 1 == k);
        let unplaced = (self.placed.max(1)..newest).filter_map(|k| {
            let (a, b) = (self.frame(k - 1)?, self.frame(k)?);
            measured(k).then_some(b.position - a.position)
        });
        let mut steps: Vec<f64> = self.steps.iter().copied().chain(unplaced).collect();
        let keep = steps.len().saturating_sub(SPEED_STEPS);
        steps.drain(..keep);
        if steps.is_empty() {
            return None;
        }
        steps.sort_by(f64::total_cmp);
        let cut = steps.len() / 5;
        let middle = &steps[cut..steps.len() - cut];
        Some((
            middle.iter().sum::<f64>() / middle.len() as f64,
            steps.len(),
        ))
    }

    /// The predicted step to a frame commanded at `commanded` from one commanded at
    /// `previous`: the commanded step, else the speed, else 0.
    fn predicted_step(&self, previous: Option<f64>, commanded: Option<f64>) -> f64 {
        match (previous, commanded) {
            (Some(p), Some(c)) => c - p,
            _ => self.speed().unwrap_or(0.0),
        }
    }

    /// The typical mismatch (1 − score) of a good match on this roll: from the 75th
    /// percentile of recent best lag-1 scores.
    fn typical_mismatch(&self) -> Option<f32> {
        if self.typical.len() < 5 {
            return None;
        }
        let mut s: Vec<f32> = self.typical.iter().copied().collect();
        s.sort_by(f32::total_cmp);
        Some((1.0 - s[s.len() * 3 / 4]).max(MIN_TYPICAL_MISMATCH))
    }

    /// Whether a match is kept, and its standard deviation; `wide`: found over the whole
    /// reach, so it must also be unambiguous.
    fn judge(&self, m: &Match, wide: bool) -> Option<f64> {
        if m.score < self.params.min_score || m.sharpness <= 0.0 {
            return None;
        }
        if wide && m.score - m.runner_up < 0.1 {
            return None;
        }
        self.gated_sigma(m.score, m.sharpness)
    }

    /// The standard deviation of a match of `score` and peak `sharpness`, or `None` when
    /// its mismatch is past [`GATE`] times the roll's typical one.
    fn gated_sigma(&self, score: f32, sharpness: f32) -> Option<f64> {
        let mismatch = match self.typical_mismatch() {
            Some(t) => ((1.0 - score) / t).max(1.0),
            None => 1.0,
        };
        if mismatch > GATE {
            return None;
        }
        let from_score = 0.15 * f64::from(mismatch * mismatch);
        let from_peak = 0.005 / f64::from(sharpness.max(1e-6));
        Some(from_score.hypot(from_peak))
    }

    /// Matches frame `k` (just pushed) against the held frames before it: the frame just
    /// before near the prediction (over the whole reach while no motion is known), then
    /// the older ones near where that match puts it.
    fn match_new(&mut self, k: usize) {
        let motion_known =
            self.speed().is_some() || (self.frame(k).is_some_and(|f| f.commanded.is_some()));
        let mut kept = 0;
        let mut anchored: Option<f64> = None;
        for lag in LAGS {
            let Some(j) = k.checked_sub(lag) else { break };
            let (Some(later), Some(earlier)) = (self.frame(k), self.frame(j)) else {
                break;
            };
            let d = later.position - earlier.position;
            let reach = |spread: f64| {
                let r = spread.ceil() as i64;
                d.round() as i64 - r..=d.round() as i64 + r
            };
            let range = match (anchored, motion_known) {
                (Some(sigma), _) => reach((3.0 * sigma).clamp(3.0, 3.0 + 0.3 * d.abs())),
                (None, true) => reach(
                    self.params
                        .search_rows
                        .map_or(3.0 + 0.3 * d.abs(), |r| r as f64),
                ),
                (None, false) if lag == 1 => {
                    let r = self.params.first_search_rows as i64;
                    -r..=r
                }
                (None, false) => break,
            };
            let wide = !motion_known && anchored.is_none();
            if let Some(edge) = self.compare(k, j, range, wide) {
                if lag == 1 {
                    // The older frames are searched near where this match puts the frame.
                    let i = k - self.first_held;
                    self.held[i].position = self.held[i - 1].position + edge.rows;
                    anchored = Some(edge.sigma);
                }
                self.add_edge(edge, lag);
                kept += 1;
            }
        }
        let textured = self.frame(k).is_some_and(|f| f.textured);
        if kept == 0 && motion_known && textured && k > 0 {
            let r = self.params.first_search_rows as i64;
            if let Some(edge) = self.compare(k, k - 1, -r..=r, true) {
                self.add_edge(edge, 1);
                self.summary.found_again += 1;
            }
        }
    }

    /// Frame `k` against frame `j` over `shifts`: the match if it is kept.
    fn compare(
        &mut self,
        k: usize,
        j: usize,
        shifts: std::ops::RangeInclusive<i64>,
        wide: bool,
    ) -> Option<Edge> {
        let (later, earlier) = (self.frame(k)?, self.frame(j)?);
        let band = self.featurizer.band();
        let m = best_match(
            &later.features,
            &earlier.features,
            band,
            self.featurizer.groups(),
            shifts,
            self.params.subpixel,
        )?;
        let i = k - self.first_held;
        let best = &mut self.held[i].best_score;
        *best = Some(best.map_or(m.score, |b| b.max(m.score)));
        if k - j == 1 && m.score >= 0.5 {
            if self.typical.len() == TYPICAL_SCORES {
                self.typical.pop_front();
            }
            self.typical.push_back(m.score);
        }
        let sigma = self.judge(&m, wide)?;
        Some(Edge {
            from: j,
            to: k,
            rows: m.shift,
            sigma,
            score: m.score,
            sharpness: m.sharpness,
            provisional: self.typical_mismatch().is_none(),
        })
    }

    /// Keeps `edge`; a lag-1 edge between commanded frames adds to the travel the
    /// apparent scale is measured over.
    fn add_edge(&mut self, edge: Edge, lag: usize) {
        if lag == 1
            && let (Some(a), Some(b)) = (self.frame(edge.from), self.frame(edge.to))
            && let (Some(ca), Some(cb)) = (a.commanded, b.commanded)
        {
            self.travel.matched += edge.rows;
            self.travel.pull_share += Pull::share(edge.rows);
            self.travel.commanded += cb - ca;
        }
        self.edges.push(edge);
        self.summary.matches += 1;
    }

    /// Matched rows per commanded row, once enough has been commanded.
    fn apparent_scale(&self) -> f64 {
        let t = &self.travel;
        let (measured, commanded) = (t.matched + self.pull.rows() * t.pull_share, t.commanded);
        if commanded.abs() >= SCALE_AFTER {
            (measured / commanded).clamp(0.5, 2.0)
        } else {
            1.0
        }
    }

    /// The mean of commanded row minus matched position over the last placed frames (0
    /// before any).
    fn anchor_offset(&self) -> f64 {
        if self.anchor.is_empty() {
            return 0.0;
        }
        self.anchor.iter().sum::<f64>() / self.anchor.len() as f64
    }

    /// Follows the belt sideways from the frame before (lag-1 match kept, drift allowed).
    fn follow_sideways(&mut self, k: usize, gray: &[f32]) {
        let step = self
            .edges
            .iter()
            .rev()
            .find(|e| e.to == k && e.from + 1 == k)
            .map(|e| e.rows.round() as i64);
        let drift = match step {
            Some(step) if self.previous_gray.len() == gray.len() => sideways(
                gray,
                &self.previous_gray,
                self.width,
                self.featurizer.band(),
                step,
                self.params.max_drift_cols,
                self.params.min_score,
            ),
            _ => 0.0,
        };
        let i = k - self.first_held;
        self.held[i].col -= drift;
    }

    /// Judges again, once the roll's typical mismatch is known, the matches kept before it
    /// was: the first match of a roll, over the whole reach, may be a feature entering
    /// the contact band, which scores well only against nothing better.
    fn judge_provisional(&mut self) {
        if self.typical_mismatch().is_none() || !self.edges.iter().any(|e| e.provisional) {
            return;
        }
        let mut edges = std::mem::take(&mut self.edges);
        let before = edges.len();
        edges.retain_mut(|e| {
            if !e.provisional {
                return true;
            }
            e.provisional = false;
            match self.gated_sigma(e.score, e.sharpness) {
                Some(sigma) => {
                    e.sigma = sigma;
                    true
                }
                None => false,
            }
        });
        self.summary.matches -= before - edges.len();
        self.edges = edges;
    }

    /// Solves the free frames' positions and drops the matches that contradict the rest.
    fn solve(&mut self) {
        self.judge_provisional();
        let free_from = self.placed.max(1) - self.first_held;
        let positions: Vec<f64> = self.held.iter().map(|h| h.position).collect();
        let scale = self.apparent_scale();
        let at = |k: usize| k - self.first_held;
        let matches: Vec<Relation> = self
            .edges
            .iter()
            .map(|e| Relation {
                from: at(e.from),
                to: at(e.to),
                rows: self.pull.corrected(e.rows) / scale,
                sigma: e.sigma,
            })
            .collect();
        let speed = self.settled_speed();
        let mut priors = Vec::new();
        let mut anchors = Vec::new();
        let offset = self.anchor_offset();
        for i in free_from..self.held.len() {
            let (prev, cur) = (&self.held[i - 1], &self.held[i]);
            match (prev.commanded, cur.commanded) {
                (Some(p), Some(c)) => priors.push(Relation {
                    from: i - 1,
                    to: i,
                    rows: c - p,
                    sigma: COMMANDED_SIGMA * std::f64::consts::SQRT_2,
                }),
                _ => {
                    if let Some(v) = speed {
                        priors.push(Relation {
                            from: i - 1,
                            to: i,
                            rows: v,
                            sigma: prediction_sigma(v),
                        });
                    }
                }
            }
        }
        for (i, h) in self.held.iter().enumerate().skip(free_from) {
            if let Some(c) = h.commanded {
                // In the matched positions' frame: the commanded row less the offset the
                // placed frames settled at.
                anchors.push(Anchor {
                    frame: i,
                    row: c - offset,
                    sigma: COMMANDED_SIGMA,
                });
            }
        }
        let problem = Problem {
            positions,
            free_from,
            matches,
            priors,
            anchors,
        };
        let solution = problem.solve();
        let mut dropped = solution.dropped;
        dropped.sort_unstable();
        for &d in dropped.iter().rev() {
            self.edges.remove(d);
            self.summary.inconsistent += 1;
            self.summary.matches -= 1;
        }
        for (h, x) in self.held.iter_mut().zip(&solution.positions) {
            h.position = *x;
        }
        self.step_sigma = vec![0.0; free_from];
        self.step_sigma.extend(solution.step_sigma);
    }

    /// Hands back the oldest frame not yet placed, and lets go of what no frame to come
    /// can need.
    fn place_oldest(&mut self) -> Placement {
        let k = self.placed;
        self.observe_pull(k);
        let i = k - self.first_held;
        let kept = self.edges.iter().filter(|e| e.from == k || e.to == k);
        let best_kept = kept.map(|e| e.score).reduce(f32::max);
        let h = &self.held[i];
        let source = if k == 0 {
            Source::First
        } else if best_kept.is_some() {
            Source::Matched
        } else if h.textured && h.best_score.is_none_or(|s| s < self.params.min_score) {
            Source::Unmatched
        } else {
            Source::Predicted
        };
        let row = match h.commanded {
            Some(c) => {
                if self.anchor.len() == ANCHOR_FRAMES {
                    self.anchor.pop_front();
                }
                self.anchor.push_back(c - h.position);
                h.position + self.anchor_offset()
            }
            None => h.position,
        };
        let placement = Placement {
            frame: k,
            row,
            source,
            score: if k == 0 {
                None
            } else {
                best_kept.or(h.best_score)
            },
            sigma: self.step_sigma.get(i).copied().unwrap_or(0.0),
            col: h.col.round() as i64,
        };
        let position = h.position;
        let unkept = k > 0 && h.textured && best_kept.is_none();
        self.count(&placement, position, unkept);
        let matched = matches!(source, Source::Matched | Source::First);
        if let Some((previous, true)) = self.last_placed
            && matched
            && placement.sigma <= (SPEED_SIGMA * (position - previous).abs()).max(0.3)
        {
            if self.steps.len() == SPEED_STEPS {
                self.steps.pop_front();
            }
            self.steps.push_back(position - previous);
        }
        self.last_placed = Some((position, matched));
        self.last_speed = self.settled_speed();
        self.placed += 1;
        // Frames more than the longest lag before the oldest unplaced one are not matched
        // again.
        let keep_from = self.placed.saturating_sub(LAGS[LAGS.len() - 1]);
        while self.first_held < keep_from && self.held.len() > 1 {
            self.held.pop_front();
            if !self.step_sigma.is_empty() {
                self.step_sigma.remove(0);
            }
            self.first_held += 1;
        }
        let first = self.first_held;
        self.edges.retain(|e| e.from >= first);
        placement
    }

    /// Measures the pull on each long match ending at frame `k` that lag-1 matches
    /// also span.
    fn observe_pull(&mut self, k: usize) {
        let lag1 = |to: usize| {
            self.edges
                .iter()
                .find(|e| e.to == to && e.from + 1 == to)
                .map(|e| e.rows)
        };
        let chains: Vec<(f64, f64, usize)> = self
            .edges
            .iter()
            .filter(|e| e.to == k && e.from + 1 < k)
            .filter_map(|e| {
                let chain = (e.from + 1..=k).map(lag1).sum::<Option<f64>>()?;
                Some((e.rows, chain, k - e.from))
            })
            .collect();
        for (long, chain, lag) in chains {
            self.pull.observe(long, chain, lag);
        }
    }

    /// Adds a placed frame (at matched `position`; `unkept`: textured, but no match kept)
    /// to the summary.
    fn count(&mut self, p: &Placement, position: f64, unkept: bool) {
        let s = &mut self.summary;
        match p.source {
            Source::Matched => s.matched += 1,
            Source::Predicted => s.predicted += 1,
            Source::Unmatched => s.unmatched += 1,
            Source::First | Source::Manifest => {}
        }
        let guessed = matches!(p.source, Source::Predicted | Source::Unmatched);
        if let Some((previous, prev_matched)) = self.last_placed {
            let step = (position - previous).abs();
            s.travel_rows += step;
            if guessed || !prev_matched {
                s.predicted_rows += step;
            }
        }
        let step = self.last_placed.map(|(previous, _)| position - previous);
        let measured = !guessed && self.last_placed.is_some_and(|(_, m)| m);
        if let Some(d) = self.speed_check.place(p.frame, step, guessed, measured)
            && s.speed_disagreement
                .is_none_or(|w| d.fraction() > w.fraction())
        {
            s.speed_disagreement = Some(d);
        }
        let run = |run: &mut (usize, usize), on: bool, longest: &mut (usize, usize)| {
            if on {
                if run.0 == 0 {
                    run.1 = p.frame;
                }
                run.0 += 1;
                if run.0 > longest.0 {
                    *longest = *run;
                }
            } else {
                run.0 = 0;
            }
        };
        run(&mut self.guess_run, guessed, &mut s.longest_guess);
        run(&mut self.lost_run, unkept, &mut s.longest_lost);
    }
}

/// How much better than no shift a sideways shift must correlate.
const SIDEWAYS_GAIN: f64 = 0.05;

/// The sideways shift, columns (to a fraction), of `cur`'s content against `prev`'s,
/// `step` rows before it along the belt: the shift within `reach` whose column profiles
/// (summed horizontal differences over the band rows both frames hold) correlate best,
/// refined by a parabola, or 0 when none reaches `min_score`.
fn sideways(
    cur: &[f32],
    prev: &[f32],
    w: usize,
    band: &features::Band,
    step: i64,
    reach: usize,
    min_score: f32,
) -> f64 {
    let h = cur.len() / w.max(1);
    if w < 3 {
        return 0.0;
    }
    let rows: Vec<usize> = (band.top..band.top + band.rows())
        .filter(|&y| (0..h as i64).contains(&(y as i64 + step)))
        .collect();
    let profile = |img: &[f32], shift: i64| -> Vec<f64> {
        let mut p = vec![0f64; w];
        for &y in &rows {
            let row = &img[(y as i64 + shift) as usize * w..][..w];
            for x in 1..w - 1 {
                p[x] += f64::from(row[x + 1] - row[x - 1]);
            }
        }
        let mean = p.iter().sum::<f64>() / w as f64;
        p.iter().map(|v| v - mean).collect()
    };
    let (a, b) = (profile(cur, 0), profile(prev, step));
    // cur[x] shows what prev showed at x − s.
    let score = |s: i64| {
        let (mut ab, mut aa, mut bb) = (0f64, 0f64, 0f64);
        for x in 0..w as i64 {
            let xp = x - s;
            if !(0..w as i64).contains(&xp) {
                continue;
            }
            let (va, vb) = (a[x as usize], b[xp as usize]);
            ab += va * vb;
            aa += va * va;
            bb += vb * vb;
        }
        (aa > 0.0 && bb > 0.0).then(|| ab / (aa * bb).sqrt())
    };
    let reach = reach as i64;
    let scores: Vec<Option<f64>> = (-reach - 1..=reach + 1).map(score).collect();
    let at = |s: i64| scores[(s + reach + 1) as usize];
    let best = (-reach..=reach)
        .filter_map(|s| at(s).map(|v| (s, v)))
        .max_by(|x, y| x.1.total_cmp(&y.1));
    // A shift must correlate clearly better than none: a belt wanders slowly, and noise
    // alone moves the best shift now and then.
    let best = match (best, at(0)) {
        (Some((s, v)), Some(zero)) if s != 0 && v - zero < SIDEWAYS_GAIN => Some((0, zero)),
        (best, _) => best,
    };
    match best {
        Some((s, v)) if v >= f64::from(min_score) => {
            let (l, r) = (at(s - 1).unwrap_or(v), at(s + 1).unwrap_or(v));
            let curvature = l - 2.0 * v + r;
            let frac = if curvature < 0.0 {
                (0.5 * (l - r) / curvature).clamp(-0.5, 0.5)
            } else {
                0.0
            };
            s as f64 + frac
        }
        _ => 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Frame 0 first, frames 1–10 predicted at `predicted`, then matched frames at
    /// `matched` rows a frame.
    fn check(predicted: f64, matched: f64) -> Option<SpeedDisagreement> {
        let mut c = SpeedCheck::default();
        let mut found = c.place(0, None, false, false);
        for k in 1..=10 {
            found = found.or(c.place(k, Some(predicted), true, false));
        }
        // The step into the first matched frame joins it to a predicted one: not measured.
        found = found.or(c.place(11, Some(matched), false, false));
        for k in 12..=12 + SPEED_CHECK_STEPS {
            found = found.or(c.place(k, Some(matched), false, true));
        }
        found
    }

    #[test]
    fn a_stretch_at_a_speed_the_belt_did_not_have_is_found() {
        let d = check(1.35, 2.94).expect("a disagreement");
        assert_eq!((d.first, d.frames), (1, 10));
        assert!((d.predicted - 1.35).abs() < 1e-9 && (d.matched - 2.94).abs() < 1e-9);
    }

    #[test]
    fn a_stretch_within_the_belt_s_own_variation_is_not() {
        assert_eq!(check(2.5, 2.94), None);
        assert_eq!(check(3.4, 2.94), None);
    }
}
