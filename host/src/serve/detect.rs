//! The defect detector on the live strip (`stream --serve --detect`): a thread of its own
//! runs the detector — or, with `--normal`, anomaly mode's model of one fabric — over the
//! strip's kept rows as they grow, window by window, and hands the boxes to the page. It reads the rows the server keeps anyway, at its own pace:
//! when the detector is slower than the stream it passes over the rows that have left
//! the server's memory (counted), and the stream never waits for it.

use super::events;
use super::findings::LiveBox;
use super::state::{Shared, lock};
use crate::detect::anomaly::NormalModel;
use crate::detect::{Detection, Detector, TILE_OVERLAP, TILE_ROWS};
use crate::image::Planes;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// How often the detector looks for new rows when it has none to work on.
const POLL: Duration = Duration::from_millis(100);

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
        Shared::broadcast(&mut clients, &event);
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
