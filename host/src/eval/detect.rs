//! `rollfuse eval --detect`: the paper's §IV.B comparison on held-out rolls. The detector
//! runs on every single frame and on the fused strip of the same stretch of belt, cut into
//! tiles of the frame's size:
//!
//! - a frame is asked for the defects in its contact band; defects it shows out of contact
//!   are neither to be found nor false alarms if found;
//! - a fused tile is asked for every defect whose centre it holds.
//!
//! A detection is right when it has the true kind and IoU ≥ [`MIN_IOU`] with the box.
//! Erroneous predictions are false alarms plus misses, per true defect.

use crate::detect::data::{Roll, RollShape, Sample, Style};
use crate::detect::targets::{Tally, share, tally_any_kind, tally_ignoring};
use crate::detect::train::{TRAIN_SEEDS, rolls};
use crate::detect::{Detector, UNKNOWN_FABRIC};
use crate::progress::Progress;
use crate::sim::textile::FABRICS;
use anyhow::ensure;
use serde::Serialize;

pub use crate::detect::targets::MIN_IOU;
/// First seed of the evaluation rolls (training uses [`TRAIN_SEEDS`] and above).
pub const EVAL_SEEDS: u64 = 1;

/// One row of the table: frames or fused tiles.
#[derive(Debug, Clone, Serialize)]
pub struct DetectRow {
    /// `single frames` or `fused tiles`.
    pub images: String,
    /// Images run.
    pub count: usize,
    /// Detections against the truth, summed.
    pub tally: Tally,
    /// The same with every kind taken as one (a defect boxed under another kind is a hit).
    pub any_kind: Tally,
    /// Images whose fabric was classified right.
    pub right_fabric: usize,
    /// Images called an unknown fabric (all of them known cloth: each is also wrong).
    pub unknown_fabric: usize,
    /// Mean probability given to the true fabric.
    pub mean_true_probability: f64,
}

impl DetectRow {
    /// Hits over detections.
    pub fn precision(&self) -> f64 {
        self.tally.precision()
    }

    /// Hits over true defects.
    pub fn recall(&self) -> f64 {
        self.tally.recall()
    }

    /// False alarms plus misses, per true defect.
    pub fn errors_per_defect(&self) -> f64 {
        share(
            self.tally.false_alarms + self.tally.misses,
            self.tally.hits + self.tally.misses,
        )
    }

    /// Share of images classified right.
    pub fn accuracy(&self) -> f64 {
        share(self.right_fabric, self.count)
    }
}

/// Runs `detector` over `samples` into one row.
fn row(detector: &Detector, images: &str, samples: &[&Sample]) -> anyhow::Result<DetectRow> {
    let mut r = DetectRow {
        images: images.to_string(),
        count: samples.len(),
        tally: Tally::default(),
        any_kind: Tally::default(),
        right_fabric: 0,
        unknown_fabric: 0,
        mean_true_probability: 0.0,
    };
    for s in samples {
        let d = detector.detect(&s.image)?;
        r.tally
            .add(tally_ignoring(&d.defects, &s.boxes, &s.blurred, MIN_IOU));
        r.any_kind
            .add(tally_any_kind(&d.defects, &s.boxes, &s.blurred, MIN_IOU));
        r.right_fabric += usize::from(d.fabric == FABRICS[s.class].name);
        r.unknown_fabric += usize::from(d.fabric == UNKNOWN_FABRIC);
        let p = d.probabilities.get(s.class).copied().unwrap_or(0.0);
        r.mean_true_probability += f64::from(p) / samples.len().max(1) as f64;
    }
    Ok(r)
}

/// Simulates `count` held-out rolls (seeds from [`EVAL_SEEDS`]) drawn in `style` and
/// measures `detector` on their frames and fused tiles; `progress` counts the rolls
/// simulated.
pub fn evaluate_detect(
    detector: &Detector,
    count: usize,
    shape: &RollShape,
    style: Style,
    progress: &dyn Progress,
) -> anyhow::Result<Vec<DetectRow>> {
    ensure!(count > 0, "--rolls must be at least 1");
    ensure!(
        count as u64 <= TRAIN_SEEDS - EVAL_SEEDS,
        "at most {} held-out rolls",
        TRAIN_SEEDS - EVAL_SEEDS
    );
    progress.start("simulating held-out rolls", Some(count as u64), "rolls");
    let done = |n: usize| progress.advance_to(n as u64);
    let held_out: Vec<Roll> = rolls(EVAL_SEEDS, count, shape, style, done)?;
    progress.finish();
    let frames: Vec<&Sample> = held_out.iter().flat_map(|r| &r.frames).collect();
    let fused: Vec<&Sample> = held_out.iter().flat_map(|r| &r.fused).collect();
    Ok(vec![
        row(detector, "single frames", &frames)?,
        row(detector, "fused tiles", &fused)?,
    ])
}

/// The rows as a Markdown table, with the change from frames to fused and the paper's.
pub fn markdown(rows: &[DetectRow]) -> String {
    let mut out = String::from(
        "| images | count | true defects | hits | false alarms | misses | precision | recall | erroneous / defect | fabric accuracy | called unknown | mean p(true fabric) |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let t = &r.tally;
        out += &format!(
            "| {} | {} | {} | {} | {} | {} | {:.3} | {:.3} | {:.3} | {:.3} | {} | {:.3} |\n",
            r.images,
            r.count,
            t.hits + t.misses,
            t.hits,
            t.false_alarms,
            t.misses,
            r.precision(),
            r.recall(),
            r.errors_per_defect(),
            r.accuracy(),
            r.unknown_fabric,
            r.mean_true_probability
        );
    }
    if let [frames, fused] = rows {
        let change = if frames.errors_per_defect() > 0.0 {
            100.0 * (fused.errors_per_defect() / frames.errors_per_defect() - 1.0)
        } else {
            0.0
        };
        out += &format!(
            "\nErroneous predictions per true defect, fused against single frames: {change:+.0} % \
             (the paper: −20 %). Fabric accuracy: {:.3} fused, {:.3} single frames (the paper: \
             fused fully correct).\n",
            fused.accuracy(),
            frames.accuracy()
        );
    }
    for r in rows {
        out += &format!(
            "\nAny kind (a defect boxed under any kind is found), {}: precision {:.3}, recall {:.3}.",
            r.images,
            r.any_kind.precision(),
            r.any_kind.recall()
        );
    }
    out + "\n"
}
