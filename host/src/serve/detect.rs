//! The defect detector on the live strip (`stream --serve --detect`): a thread of its own
//! runs the detector — or, with `--normal`, anomaly mode's model of one fabric — over the
//! strip's kept rows as they grow, window by window, and hands the boxes to the page. It reads the rows the server keeps anyway, at its own pace:
//! when the detector is slower than the stream it passes over the rows that have left
//! the server's memory (counted), and the stream never waits for it.

use super::events;
use super::state::{Shared, lock};
use crate::detect::anomaly::NormalModel;
use crate::detect::{Detection, Detector, TILE_OVERLAP, TILE_ROWS};
use crate::image::Planes;
use serde::Serialize;
use std::collections::{BTreeMap, VecDeque};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// Boxes the server keeps for pages that connect later (older ones are dropped).
pub const KEPT_BOXES: usize = 1024;

/// How often the detector looks for new rows when it has none to work on.
const POLL: Duration = Duration::from_millis(100);

/// A defect on the strip, in strip pixels (belt rows down, columns across).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LiveBox {
    /// Its kind: `hole`, `snag`, `slub`, or `anomaly` from anomaly mode.
    pub kind: &'static str,
    /// The detector's heatmap peak (0..1), or anomaly mode's score (above 1).
    pub score: f32,
    /// `[x0, row0, x1, row1]`: columns and belt rows of the strip.
    pub strip_box: [f32; 4],
}

/// What the detector has said so far, as `/status.json` and the page show it.
#[derive(Debug, Clone, Default, Serialize)]
pub struct DetectorStatus {
    /// Anomaly mode's model runs (`--normal`): every region is of kind `anomaly` and no
    /// fabric is named.
    pub anomaly_mode: bool,
    /// The most probable fabric over the rows checked (their probabilities averaged), or
    /// [`crate::detect::UNKNOWN_FABRIC`] when most of those rows were unlike every fabric
    /// the model knows.
    pub fabric: Option<String>,
    /// The most probable fabric's mean probability.
    pub probability: f64,
    /// Rows checked in windows unlike every fabric the model knows.
    pub unknown_rows: u64,
    /// Defects found, by kind.
    pub defects: BTreeMap<String, u64>,
    /// Strip rows the detector has looked at.
    pub rows_checked: u64,
    /// Strip rows it passed over, having fallen behind the stream.
    pub rows_skipped: u64,
    /// Windows the detector failed on (an error or a panic): their rows are not checked.
    pub failures: u64,
    /// The last failure, in a line.
    pub last_failure: Option<String>,
}

impl DetectorStatus {
    /// Counts a failure on a window, for the reason given.
    fn failed(&mut self, why: &str) {
        self.failures += 1;
        self.last_failure = Some(format!("the detector failed: {why}"));
    }
}

/// The detector's findings, shared with the server's threads.
#[derive(Default)]
pub struct Findings {
    /// The summary.
    pub status: DetectorStatus,
    /// The newest boxes, oldest first.
    pub boxes: VecDeque<LiveBox>,
    /// Every fabric's probability summed over the rows checked, weighted by rows.
    weights: Vec<f64>,
}

/// What the live detector runs over the strip.
pub enum LiveModel {
    /// The defect detector: kinds, scores and the fabric.
    Defects(Box<Detector>),
    /// Anomaly mode's model of one fabric (`stream --normal`): regions of kind
    /// `anomaly`, no fabric.
    Normal(NormalModel),
}

/// A box the model found: its kind, score and `[x0, y0, x1, y1]` in the window's pixels.
type Found = (&'static str, f32, [f32; 4]);

impl LiveModel {
    /// The model's findings in a window `image` downsampled by `d` from its scale: boxes
    /// in the window's pixels, and the detector's detection (fabric and all) if it ran.
    fn find(&self, image: &Planes, d: usize) -> anyhow::Result<(Vec<Found>, Option<Detection>)> {
        Ok(match self {
            Self::Defects(detector) => {
                let found = detector.detect_at_scale(image, d)?;
                let boxes = found
                    .defects
                    .iter()
                    .map(|f| (f.kind.name(), f.score, f.box_px))
                    .collect();
                (boxes, Some(found))
            }
            Self::Normal(model) => {
                let found = model.detect_at_scale(image, d)?;
                let boxes = found
                    .regions
                    .iter()
                    .map(|r| (crate::detect::anomaly::KIND, r.score, r.box_px))
                    .collect();
                (boxes, None)
            }
        })
    }

    /// The fabric names the detector's probabilities are over (none for anomaly mode).
    fn fabrics(&self) -> &[String] {
        match self {
            Self::Defects(detector) => &detector.about().fabrics,
            Self::Normal(_) => &[],
        }
    }
}

/// The running detector: stops when dropped.
pub struct LiveDetector {
    ended: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl LiveDetector {
    /// Starts the detector's thread on `shared`'s strip.
    pub fn start(shared: Arc<Shared>, detector: LiveModel) -> anyhow::Result<Self> {
        let ended = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&ended);
        let thread = std::thread::Builder::new()
            .name("serve-detect".into())
            .spawn(move || Windows::new(detector).run(&shared, &flag))?;
        Ok(Self {
            ended,
            thread: Some(thread),
        })
    }

    /// The stream is over: the detector checks the rows left and stops; this waits for
    /// it, so the page has every box before it is told the stream ended.
    pub fn finish(&mut self) {
        self.ended.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for LiveDetector {
    fn drop(&mut self) {
        self.finish();
    }
}

/// The detector walking down the strip: each window's own rows are those whose defects
/// it reports, with context rows either side so a defect on the edge is seen whole.
pub(super) struct Windows {
    detector: LiveModel,
    /// The first strip row not yet reported on.
    next: Option<u64>,
}

/// A window: rows `own` reported on, rows `seen` given to the detector.
pub(super) struct Window {
    pub(super) own: std::ops::Range<u64>,
    pub(super) seen: std::ops::Range<u64>,
}

impl Windows {
    pub(super) fn new(detector: LiveModel) -> Self {
        Self {
            detector,
            next: None,
        }
    }

    pub(super) fn run(mut self, shared: &Shared, ended: &AtomicBool) {
        lock(&shared.findings).status.anomaly_mode = matches!(self.detector, LiveModel::Normal(_));
        loop {
            // Read before looking at the rows, so rows that came before the end are seen.
            let last = ended.load(Ordering::Relaxed);
            let Some(upsample) = downsample_of(shared) else {
                if last {
                    return;
                }
                std::thread::sleep(POLL);
                continue;
            };
            match self.next_window(shared, upsample, last) {
                Some(w) => {
                    let checked = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                        self.check(shared, w, upsample)
                    }));
                    if let Err(panic) = checked {
                        let why = panic
                            .downcast_ref::<&str>()
                            .map(|s| s.to_string())
                            .or_else(|| panic.downcast_ref::<String>().cloned())
                            .unwrap_or_else(|| "a panic".into());
                        lock(&shared.findings).status.failed(&why);
                    }
                }
                None if last => return,
                None => std::thread::sleep(POLL),
            }
        }
    }

    /// The next window whose rows are all in (or the rest of the strip once it has
    /// ended), passing over rows the server no longer keeps.
    pub(super) fn next_window(
        &mut self,
        shared: &Shared,
        upsample: usize,
        last: bool,
    ) -> Option<Window> {
        let ring = lock(&shared.ring);
        let span = ring.span()?;
        let context = (TILE_OVERLAP / upsample / 2) as u64;
        let own_rows = (TILE_ROWS / upsample) as u64 - 2 * context;
        let mut next = *self.next.get_or_insert(span.start);
        if next < span.start {
            lock(&shared.findings).status.rows_skipped += span.start - next;
            next = span.start;
        }
        // Rows of tiles that never came (a jump of the belt index) are no strip to check:
        // a window ends where its run of tiles does, and the next starts at the next tile.
        next = ring.kept_row_from(next).map_or(next, |k| k.max(next));
        self.next = Some(next);
        let run_end = ring.kept_run_end(next)?;
        drop(ring);
        let own_end = (next + own_rows).min(run_end);
        let ready = span.end >= own_end + context || own_end == run_end && run_end < span.end;
        if !(ready || last && span.end > next) {
            return None;
        }
        let own = next..own_end;
        let seen =
            own.start.saturating_sub(context).max(span.start)..(own.end + context).min(run_end);
        Some(Window { own, seen })
    }

    /// Marks a window's own rows as reported on.
    pub(super) fn done(&mut self, w: &Window) {
        self.next = Some(w.own.end);
    }

    /// Runs the detector on a window and hands its boxes on.
    fn check(&mut self, shared: &Shared, w: Window, upsample: usize) {
        self.done(&w);
        let Some((width, start, rows, pixels)) = lock(&shared.ring).rows(w.seen.clone()) else {
            return;
        };
        let image = Planes {
            width,
            height: rows,
            planes: vec![pixels.iter().map(|&v| f32::from(v)).collect()],
        };
        // A window too small for the detector (a short tail) is counted as checked; any
        // other error is a failure, counted and shown.
        let small = width.min(rows) * upsample.max(1) < crate::detect::MIN_SIDE;
        let (found, detection) = match self.detector.find(&image, upsample) {
            Ok(found) => found,
            Err(_) if small => (Vec::new(), None),
            Err(e) => {
                let why = crate::detect::model::first_line(&e);
                lock(&shared.findings).status.failed(&why);
                return;
            }
        };
        let top = start as f32;
        let boxes: Vec<LiveBox> = found
            .into_iter()
            .map(|(kind, score, [x0, y0, x1, y1])| LiveBox {
                kind,
                score,
                strip_box: [x0, y0 + top, x1, y1 + top],
            })
            .filter(|b| {
                w.own
                    .contains(&(((b.strip_box[1] + b.strip_box[3]) / 2.0) as u64))
            })
            .collect();
        let status = {
            let mut findings = lock(&shared.findings);
            findings.take(
                &boxes,
                detection.as_ref(),
                w.own.end - w.own.start,
                self.detector.fabrics(),
            );
            findings.status.clone()
        };
        let event = events::defects_event(&boxes, &status);
        let mut clients = lock(&shared.clients);
        super::state::Shared::broadcast(&mut clients, &event);
    }
}

impl Findings {
    /// Counts a window's boxes and weighs its fabric probabilities by its `rows`.
    fn take(
        &mut self,
        boxes: &[LiveBox],
        found: Option<&Detection>,
        rows: u64,
        fabrics: &[String],
    ) {
        self.status.rows_checked += rows;
        for b in boxes {
            *self.status.defects.entry(b.kind.to_string()).or_default() += 1;
            self.boxes.push_back(*b);
        }
        while self.boxes.len() > KEPT_BOXES {
            self.boxes.pop_front();
        }
        let Some(found) = found else {
            return;
        };
        if found.fabric == crate::detect::UNKNOWN_FABRIC {
            self.status.unknown_rows += rows;
        }
        self.weights.resize(found.probabilities.len(), 0.0);
        for (w, &p) in self.weights.iter_mut().zip(&found.probabilities) {
            *w += f64::from(p) * rows as f64;
        }
        let total: f64 = self.weights.iter().sum();
        if let Some((class, &w)) = self
            .weights
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .filter(|_| total > 0.0)
        {
            self.status.fabric = if 2 * self.status.unknown_rows > self.status.rows_checked {
                Some(crate::detect::UNKNOWN_FABRIC.to_string())
            } else {
                fabrics.get(class).cloned()
            };
            self.status.probability = w / total;
        }
    }
}

/// The device's downsampling (the detector works at the camera's scale), once the
/// device has said its configuration.
fn downsample_of(shared: &Shared) -> Option<usize> {
    let status = lock(&shared.status);
    status
        .device
        .map(|d| usize::from(d.config.downsample.max(1)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::UNKNOWN_FABRIC;

    fn window(fabric: &str) -> Detection {
        Detection {
            fabric: fabric.to_string(),
            most_like: "canvas".to_string(),
            probability: 0.9,
            unfamiliarity: Some(if fabric == UNKNOWN_FABRIC { 2.0 } else { 0.2 }),
            probabilities: vec![0.1, 0.9],
            defects: Vec::new(),
        }
    }

    #[test]
    fn the_fabric_is_unknown_while_most_rows_checked_were() {
        let fabrics = ["plain".to_string(), "canvas".to_string()];
        let mut f = Findings::default();
        f.take(&[], Some(&window(UNKNOWN_FABRIC)), 300, &fabrics);
        f.take(&[], Some(&window("canvas")), 100, &fabrics);
        assert_eq!(f.status.fabric.as_deref(), Some(UNKNOWN_FABRIC));
        assert_eq!((f.status.unknown_rows, f.status.rows_checked), (300, 400));
        f.take(&[], Some(&window("canvas")), 300, &fabrics);
        assert_eq!(f.status.fabric.as_deref(), Some("canvas"));
    }
}
