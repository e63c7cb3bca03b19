//! Alignment of a roll that does not drift: each frame's belt row predicted from the
//! motion, then matched near the prediction against everything aligned so far.
//!
//! - **Features.** Each frame is reduced to row profiles: the summed gradient magnitude
//!   of each row in each of up to 16 column groups, high-passed along the rows (minus the
//!   mean of the 13 rows around) so that smooth patterns fixed to the frame — vignetting,
//!   the defocus that smooths noise away from the focal line — cannot pull a match toward
//!   "no motion". Cost: one pass over the frame.
//! - **Reference.** The profiles of every frame aligned so far, accumulated at their belt
//!   rows (sub-pixel positions split between two rows) in a ring of 4 frame heights: the
//!   strip as aligned, not the previous frame alone, so one poor match does not carry
//!   into every later position.
//! - **Prediction.** The manifest's commanded position when given, else the last
//!   position plus the median of the last five measured steps. With commanded positions,
//!   matches fix each frame's place relative to its neighbours and the commanded rows fix
//!   where the whole run of them lies (see [`Anchor`]).
//! - **Match.** Normalized correlation of the frame's profiles with the reference over
//!   their overlap, at every whole row within `search_rows` of the prediction; the best
//!   refined to sub-pixel by a parabola through its neighbours. Accepted when the score
//!   reaches `min_score`; otherwise (no texture where the frame overlaps the strip) the
//!   prediction is kept and the frame is reported as predicted.
//!
//! Columns are searched only when the user allows a drift (`max_drift_cols`): the belt does
//! not move across the frame unless the conveyor's tracking is off, and a sideways search
//! in texture-free stretches only finds shifts that never happened. When allowed, each
//! matched frame's column profiles (summed horizontal differences of its middle rows) are
//! correlated with those of the same belt rows in the chain's newest frame.

use crate::image::Planes;
use std::collections::VecDeque;

/// Alignment settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackParams {
    /// Rows searched either side of the prediction; `None`: 3 plus 30 % of the predicted
    /// step (a belt whose speed varies by ±25 % stays inside).
    pub search_rows: Option<usize>,
    /// Rows searched either side of the previous frame before any motion is known.
    pub first_search_rows: usize,
    /// Lowest normalized correlation accepted as a match.
    pub min_score: f32,
    /// Refine matches to a fraction of a row.
    pub subpixel: bool,
    /// Columns the belt may drift sideways from one matched frame to the next (0: none).
    pub max_drift_cols: usize,
}

impl TrackParams {
    /// The defaults for frames `height` rows high: the first search spans half a frame.
    pub fn for_height(height: usize) -> Self {
        Self {
            search_rows: None,
            first_search_rows: height / 2,
            min_score: 0.3,
            subpixel: true,
            max_drift_cols: 0,
        }
    }

    /// Refuses a reach past frames of `width × height`: the search around a prediction
    /// (`--search-rows`) from 1 to the height, the first search (`--max-shift`, 0: the
    /// frames taken as they lie) and the sideways drift (`--max-drift-cols`) at most the
    /// height and the width. A search past the frame finds nothing more, and costs time
    /// and memory in proportion.
    pub fn check(&self, width: usize, height: usize) -> anyhow::Result<()> {
        if let Some(r) = self.search_rows {
            anyhow::ensure!(
                (1..=height).contains(&r),
                "--search-rows must be from 1 to the frames' height ({height} rows), got {r}"
            );
        }
        anyhow::ensure!(
            self.first_search_rows <= height,
            "--max-shift must be at most the frames' height ({height} rows), got {}",
            self.first_search_rows
        );
        anyhow::ensure!(
            self.max_drift_cols <= width,
            "--max-drift-cols must be at most the frames' width ({width}), got {}",
            self.max_drift_cols
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
    /// Matched against the aligned strip.
    Matched,
    /// No match good enough (no texture): the prediction kept.
    Predicted,
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
            Source::Manifest => "manifest",
        }
    }
}

/// Where a frame lies: the belt row of its top row.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Placement {
    /// Belt row of the frame's row 0 (fractional with sub-pixel matching).
    pub row: f64,
    /// How it was found.
    pub source: Source,
    /// The best correlation found (absent for the first frame and manifest rows).
    pub score: Option<f32>,
    /// Belt column of the frame's column 0 (always 0 unless sideways drift is allowed).
    pub col: i64,
}

/// Half-width of the high-pass box along the rows.
const HIGH_PASS: usize = 6;
/// Most column groups of the profiles.
const MAX_GROUPS: usize = 16;
/// Recent steps (and command biases) the prediction takes its median of.
const HISTORY: usize = 5;

/// The running aligner: feed it frames in acquisition order.
pub struct Tracker {
    width: usize,
    height: usize,
    groups: usize,
    params: TrackParams,
    /// The current frame's high-passed profiles, `height × groups`.
    profile: Vec<f32>,
    raw: Vec<f32>,
    gray: Vec<f32>,
    /// The reference ring: per slot the belt row it holds, its profile sums and weight.
    slot_row: Vec<i64>,
    sums: Vec<f32>,
    weights: Vec<f32>,
    last: Option<f64>,
    steps: VecDeque<f64>,
    anchor: Anchor,
    /// Frames placed so far.
    frame: usize,
    /// The newest frame of the chain in the reference: its row, commanded row, number.
    chain_end: (f64, Option<f64>, usize),
    /// Whether the chain has a matched link.
    linked: bool,
    /// Belt column of the newest frame's column 0.
    col: i64,
    /// The chain's newest frame, gray, when sideways drift is allowed.
    drift_reference: Vec<f32>,
}

/// Frames of a chain over which its place is averaged against the commanded rows.
const ANCHOR_FRAMES: usize = 40;

/// Commanded motion as the long-term reference, matches as the short-term one.
///
/// Matching links each frame to the frames before it: a run of matched frames (a chain)
/// has a shape known to a fraction of a pixel, but its place inherits every error before
/// it. The commanded rows have no drift but carry the belt's unknown error of a few pixels
/// per frame. So a chain's shape comes from its matched steps and its place from the
/// commanded rows, averaged over its last [`ANCHOR_FRAMES`] frames.
///
/// Matched steps are in the images' apparent scale, which is not the belt's: the gel
/// pulls each feature toward the apex a little more the farther it is from it, so on the
/// simulator's letters geometry every step measures about 1 % short (20 px: 19.8). Each
/// step is rescaled by the ratio of all matched to all commanded travel so far.
#[derive(Debug, Default)]
struct Anchor {
    measured: f64,
    commanded: f64,
    /// The chain's newest frame's place along it.
    along: f64,
    /// Commanded row minus place along the chain, for the chain's newest frames.
    offsets: VecDeque<f64>,
}

impl Anchor {
    /// Commanded travel after which the matched-to-commanded ratio is used, rows.
    const SCALE_AFTER: f64 = 100.0;

    /// Starts a chain with a frame commanded at `commanded`.
    fn start(&mut self, commanded: f64) {
        self.along = 0.0;
        self.offsets.clear();
        self.offsets.push_back(commanded);
    }

    /// Links a frame commanded at `commanded` to the chain: matched `step` rows after the
    /// chain's newest frame, which was commanded `told` rows before. Returns its row.
    fn link(&mut self, step: f64, told: f64, commanded: f64) -> f64 {
        self.measured += step;
        self.commanded += told;
        let scale = if self.commanded.abs() >= Self::SCALE_AFTER {
            (self.measured / self.commanded).clamp(0.5, 2.0)
        } else {
            1.0
        };
        self.along += step / scale;
        if self.offsets.len() == ANCHOR_FRAMES {
            self.offsets.pop_front();
        }
        self.offsets.push_back(commanded - self.along);
        self.along + self.offsets.iter().sum::<f64>() / self.offsets.len() as f64
    }
}

/// `values` minus the mean of the 13 around each, after a [1 2 1] / 4 smoothing.
fn high_pass(values: &[f32]) -> Vec<f32> {
    let n = values.len();
    let at = |i: isize| values[i.clamp(0, n as isize - 1) as usize];
    let smooth: Vec<f32> = (0..n as isize)
        .map(|i| 0.25 * (at(i - 1) + 2.0 * at(i) + at(i + 1)))
        .collect();
    (0..n)
        .map(|i| {
            let (lo, hi) = (i.saturating_sub(HIGH_PASS), (i + HIGH_PASS + 1).min(n));
            smooth[i] - smooth[lo..hi].iter().sum::<f32>() / (hi - lo) as f32
        })
        .collect()
}

fn median(values: &VecDeque<f64>) -> Option<f64> {
    let mut v: Vec<f64> = values.iter().copied().collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    Some(v[v.len() / 2])
}

fn push_bounded(q: &mut VecDeque<f64>, v: f64) {
    if q.len() == HISTORY {
        q.pop_front();
    }
    q.push_back(v);
}

impl Tracker {
    /// An aligner for frames of `width × height`.
    pub fn new(width: usize, height: usize, params: TrackParams) -> Self {
        let groups = (width / 20).clamp(1, MAX_GROUPS);
        let slots = (4 * height).next_power_of_two();
        Self {
            width,
            height,
            groups,
            params,
            profile: vec![0.0; height * groups],
            raw: vec![0.0; height * groups],
            gray: Vec::new(),
            slot_row: vec![i64::MIN; slots],
            sums: vec![0.0; slots * groups],
            weights: vec![0.0; slots],
            last: None,
            steps: VecDeque::new(),
            anchor: Anchor::default(),
            frame: 0,
            chain_end: (0.0, None, 0),
            linked: false,
            col: 0,
            drift_reference: Vec::new(),
        }
    }

    /// Places the next frame; `commanded` is its commanded belt row from a manifest, if
    /// any. The frame must be `width × height`.
    ///
    /// Frames form chains: each matched frame is linked to the chain the reference holds
    /// and joins it. A frame without a match is placed at its prediction and left out of
    /// the reference, unless the chain has no link yet or the frame no longer overlaps it:
    /// then it starts a new chain, alone in the reference. So the reference only ever
    /// holds frames placed consistently with each other.
    pub fn place(&mut self, frame: &Planes, commanded: Option<f64>) -> Placement {
        self.compute_profile(frame);
        self.frame += 1;
        let Some(last) = self.last else {
            let row = commanded.unwrap_or(0.0);
            self.start_chain(row, commanded);
            self.keep_for_drift(frame);
            return Placement {
                row,
                source: Source::First,
                score: None,
                col: 0,
            };
        };
        let (pred, reach) = self.predict(last, commanded);
        let (matched, score) = self.match_near(pred, reach);
        let row = match matched {
            Some(m) => {
                let (prev_row, prev_commanded, prev_frame) = self.chain_end;
                let frames = (self.frame - prev_frame).max(1) as f64;
                push_bounded(&mut self.steps, (m - prev_row) / frames);
                let row = match (commanded, prev_commanded) {
                    (Some(c), Some(pc)) => self.anchor.link(m - prev_row, c - pc, c),
                    _ => m,
                };
                if self.params.max_drift_cols > 0 {
                    self.col -= self.sideways(frame, (m - prev_row).round() as i64);
                    self.keep_for_drift(frame);
                }
                self.accumulate(row);
                self.chain_end = (row, commanded, self.frame);
                self.linked = true;
                row
            }
            None => {
                let row = commanded.unwrap_or(pred);
                if !self.linked || score.is_none() {
                    self.start_chain(row, commanded);
                    self.keep_for_drift(frame);
                }
                row
            }
        };
        self.last = Some(row);
        Placement {
            row,
            source: if matched.is_some() {
                Source::Matched
            } else {
                Source::Predicted
            },
            score,
            col: self.col,
        }
    }

    /// Keeps `frame`'s gray levels as the chain's newest, for the sideways search.
    fn keep_for_drift(&mut self, frame: &Planes) {
        if self.params.max_drift_cols > 0 {
            let mut scratch = Vec::new();
            let gray = Self::gray_of(&mut scratch, frame).to_vec();
            self.drift_reference = gray;
        }
    }

    /// The sideways shift, columns, of `frame`'s content against the chain's newest frame,
    /// `step` rows before it along the belt: the shift within `max_drift_cols` whose column
    /// profiles correlate best, or 0 when none reaches `min_score`.
    fn sideways(&self, frame: &Planes, step: i64) -> i64 {
        let (w, h) = (self.width, self.height);
        let mut scratch = Vec::new();
        let cur = Self::gray_of(&mut scratch, frame);
        let prev = &self.drift_reference;
        if prev.len() != w * h || w < 3 {
            return 0;
        }
        // Rows of the middle half that the previous frame saw too (at row y + step).
        let rows: Vec<usize> = (h / 4..h - h / 4)
            .filter(|&y| (0..h as i64).contains(&(y as i64 + step)))
            .collect();
        let profile = |img: &[f32], shift: i64| -> Vec<f32> {
            let mut p = vec![0f32; w];
            for &y in &rows {
                let row = &img[(y as i64 + shift) as usize * w..][..w];
                for x in 1..w - 1 {
                    p[x] += row[x + 1] - row[x - 1];
                }
            }
            high_pass(&p)
        };
        let (a, b) = (profile(cur, 0), profile(prev, step));
        let reach = self.params.max_drift_cols as i64;
        let mut best = (0i64, self.params.min_score);
        for s in -reach..=reach {
            // cur[x] shows what prev showed at x − s.
            let (mut ab, mut aa, mut bb) = (0f64, 0f64, 0f64);
            for x in 0..w as i64 {
                let xp = x - s;
                if !(0..w as i64).contains(&xp) {
                    continue;
                }
                let (va, vb) = (f64::from(a[x as usize]), f64::from(b[xp as usize]));
                ab += va * vb;
                aa += va * va;
                bb += vb * vb;
            }
            if aa > 0.0 && bb > 0.0 {
                let score = (ab / (aa * bb).sqrt()) as f32;
                if score > best.1 {
                    best = (s, score);
                }
            }
        }
        best.0
    }

    /// Clears the reference and starts a chain with the current frame at `row`.
    fn start_chain(&mut self, row: f64, commanded: Option<f64>) {
        self.slot_row.fill(i64::MIN);
        self.anchor.start(commanded.unwrap_or(row));
        self.accumulate(row);
        self.chain_end = (row, commanded, self.frame);
        self.linked = false;
        self.last = Some(row);
    }

    /// The predicted row and the rows to search either side of it.
    fn predict(&self, last: f64, commanded: Option<f64>) -> (f64, usize) {
        let (pred, known) = match (commanded, median(&self.steps)) {
            (Some(c), _) => (c, true),
            (None, Some(step)) => (last + step, true),
            (None, None) => (last, false),
        };
        let reach = match (self.params.search_rows, known) {
            (_, false) => self.params.first_search_rows,
            (Some(r), true) => r,
            (None, true) => 3 + (0.3 * (pred - last).abs()).ceil() as usize,
        };
        (pred, reach)
    }

    /// The best match within `reach` rows of `pred` if it reaches the minimum score, and
    /// the best score found.
    fn match_near(&self, pred: f64, reach: usize) -> (Option<f64>, Option<f32>) {
        let centre = pred.round() as i64;
        let reach = reach as i64;
        let scores: Vec<Option<f32>> = (centre - reach..=centre + reach)
            .map(|d| self.score_at(d))
            .collect();
        let best = scores
            .iter()
            .enumerate()
            .filter_map(|(i, s)| s.map(|s| (i, s)))
            .max_by(|a, b| a.1.total_cmp(&b.1));
        let Some((i, score)) = best else {
            return (None, None);
        };
        if score < self.params.min_score {
            return (None, Some(score));
        }
        let mut row = (centre - reach + i as i64) as f64;
        if self.params.subpixel {
            let at = |j: Option<usize>| j.and_then(|j| scores.get(j).copied().flatten());
            if let (Some(a), Some(c)) = (at(i.checked_sub(1)), at(Some(i + 1))) {
                let curvature = a - 2.0 * score + c;
                if curvature < 0.0 {
                    row += f64::from((0.5 * (a - c) / curvature).clamp(-0.5, 0.5));
                }
            }
        }
        (Some(row), Some(score))
    }

    /// Gray levels of `frame` (the mean of its channels).
    fn gray_of<'a>(gray: &'a mut Vec<f32>, frame: &'a Planes) -> &'a [f32] {
        if frame.planes.len() == 1 {
            return &frame.planes[0];
        }
        let n = frame.planes.len() as f32;
        gray.clear();
        gray.extend(
            (0..frame.width * frame.height)
                .map(|i| frame.planes.iter().map(|p| p[i]).sum::<f32>() / n),
        );
        gray
    }

    /// The frame's high-passed row profiles into `self.profile`.
    fn compute_profile(&mut self, frame: &Planes) {
        let (w, h, g) = (self.width, self.height, self.groups);
        let mut gray = std::mem::take(&mut self.gray);
        let img = Self::gray_of(&mut gray, frame);
        self.raw.fill(0.0);
        for y in 1..h.saturating_sub(1) {
            let (up, mid, down) = (
                &img[(y - 1) * w..y * w],
                &img[y * w..(y + 1) * w],
                &img[(y + 1) * w..(y + 2) * w],
            );
            let out = &mut self.raw[y * g..(y + 1) * g];
            let _ = mid;
            for x in 0..w {
                out[x * g / w] += down[x] - up[x];
            }
        }
        // Rows 0 and h − 1 have no gradient: copy their neighbours' so the box below sees
        // no step at the frame's edges.
        if h >= 3 {
            self.raw.copy_within(g..2 * g, 0);
            self.raw.copy_within((h - 2) * g..(h - 1) * g, (h - 1) * g);
        }
        // Smoothed along the rows ([1 2 1] / 4: the row differences of sensor noise
        // alternate in sign, the gel's smooth features do not) and high-passed.
        let mut column = vec![0f32; h];
        for k in 0..g {
            for (y, v) in column.iter_mut().enumerate() {
                *v = self.raw[y * g + k];
            }
            for (y, v) in high_pass(&column).into_iter().enumerate() {
                self.profile[y * g + k] = v;
            }
        }
        self.gray = gray;
    }

    fn slot(&self, belt_row: i64) -> usize {
        belt_row.rem_euclid(self.slot_row.len() as i64) as usize
    }

    /// The reference's mean profile at `belt_row`, if any frame covered it.
    fn reference(&self, belt_row: i64) -> Option<&[f32]> {
        let s = self.slot(belt_row);
        (self.slot_row[s] == belt_row && self.weights[s] > 0.0).then(|| {
            let g = self.groups;
            &self.sums[s * g..(s + 1) * g]
        })
    }

    /// Normalized correlation of the frame's profiles with the reference, the frame's top
    /// at belt row `top`; `None` when they overlap by fewer than a quarter of the frame.
    fn score_at(&self, top: i64) -> Option<f32> {
        let g = self.groups;
        let (mut fr, mut ff, mut rr, mut rows) = (0f64, 0f64, 0f64, 0usize);
        // The middle half of the frame: the rows in contact, where features stand out.
        let (ylo, yhi) = (self.height / 4, self.height - self.height / 4);
        for y in ylo..yhi {
            let s = self.slot(top + y as i64);
            let Some(sum) = self.reference(top + y as i64) else {
                continue;
            };
            let wgt = self.weights[s];
            rows += 1;
            for (f, r) in self.profile[y * g..(y + 1) * g].iter().zip(sum) {
                let (f, r) = (f64::from(*f), f64::from(*r / wgt));
                fr += f * r;
                ff += f * f;
                rr += r * r;
            }
        }
        if rows < ((yhi - ylo) / 4).max(4) || ff <= 0.0 || rr <= 0.0 {
            return None;
        }
        Some((fr / (ff * rr).sqrt()) as f32)
    }

    /// Adds the frame's profiles to the reference at belt row `row` (split between the
    /// two nearest rows).
    fn accumulate(&mut self, row: f64) {
        let g = self.groups;
        let base = row.floor();
        let frac = (row - base) as f32;
        let base = base as i64;
        for y in 0..self.height {
            for (dy, wgt) in [(0, 1.0 - frac), (1, frac)] {
                if wgt <= 0.0 {
                    continue;
                }
                let belt = base + (y + dy) as i64;
                let s = self.slot(belt);
                if self.slot_row[s] != belt {
                    self.slot_row[s] = belt;
                    self.weights[s] = 0.0;
                    self.sums[s * g..(s + 1) * g].fill(0.0);
                }
                self.weights[s] += wgt;
                for (acc, v) in self.sums[s * g..(s + 1) * g]
                    .iter_mut()
                    .zip(&self.profile[y * g..(y + 1) * g])
                {
                    *acc += wgt * v;
                }
            }
        }
    }
}
