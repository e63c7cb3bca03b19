//! `rollfuse eval --detect --normal`: anomaly mode measured as a user meets it — fitted on
//! a roll's own defect-free frames, then asked about the roll's other frames.
//!
//! - Of a roll's frames, every second one that shows no defect at all is a candidate to
//!   fit on; the first [`FIT_FRAMES`] of those fit the normal model, every other frame is
//!   scored.
//! - **Image AUROC**: the anomaly score of the frames with a defect in contact against the
//!   frames with none; frames showing a defect only out of contact (blurred: neither to be
//!   found nor clean) are left out.
//! - **Recall**: defects in contact overlapped by a region; **precision**: regions that
//!   overlap a defect in contact, of the regions that overlap none out of contact.
//!
//! A normal model learns one fabric at one contact, so each roll is fitted on its own
//! frames: the simulator presses the gel relative to the roll's tallest point, and a
//! model fitted on another roll would measure that, not anomaly mode.

use crate::detect::anomaly::NormalModel;
use crate::detect::data::{RollShape, Sample, class_of, frames, roll_scene};
use crate::detect::train::TRAIN_SEEDS;
use crate::progress::Progress;
use crate::sim::Simulator;
use crate::sim::textile::FABRICS;
use anyhow::ensure;
use serde::Serialize;

use super::detect::EVAL_SEEDS;

/// Defect-free frames a normal model is fitted on.
pub const FIT_FRAMES: usize = 20;

/// The rolls anomaly mode is measured on: the detector's 320 × 240 frames 0.6 mm apart,
/// long enough for [`FIT_FRAMES`] clean frames to fit on beside 6 defects (at 120 frames
/// a third of the held-out rolls had too few).
pub const ROLL: RollShape = RollShape {
    frames: 180,
    defects: 6,
    ..RollShape::STANDARD
};

/// Anomaly mode's figures on one roll.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Figures {
    /// Area under the ROC curve of the frames' anomaly scores.
    pub auroc: f64,
    /// Defects in contact found, of all in contact.
    pub recall: f64,
    /// Regions on a defect in contact, of the regions counted.
    pub precision: f64,
    /// Scored frames with a defect in contact.
    pub defective_frames: usize,
    /// Scored frames with no defect in view.
    pub clean_frames: usize,
    /// Defects in contact over the scored frames.
    pub defects: usize,
}

/// Fits anomaly mode on [`FIT_FRAMES`] of `frames`' defect-free frames and scores the
/// rest; refuses a roll with too few defect-free frames.
pub fn measure(frames: &[Sample]) -> anyhow::Result<Figures> {
    let clean =
        |k: usize, s: &Sample| s.boxes.is_empty() && s.blurred.is_empty() && k.is_multiple_of(2);
    let fit: Vec<usize> = (0..frames.len())
        .filter(|&k| clean(k, &frames[k]))
        .take(FIT_FRAMES)
        .collect();
    ensure!(
        fit.len() == FIT_FRAMES,
        "the roll has {} defect-free frames to fit on, not {FIT_FRAMES}",
        fit.len()
    );
    let images: Vec<_> = fit.iter().map(|&k| frames[k].image.clone()).collect();
    let model = NormalModel::fit(&images)?;
    let (mut positives, mut negatives) = (Vec::new(), Vec::new());
    let (mut found, mut defects, mut right, mut counted) = (0, 0, 0, 0);
    for (k, s) in frames.iter().enumerate() {
        if fit.contains(&k) {
            continue;
        }
        let a = model.detect(&s.image)?;
        if !s.boxes.is_empty() {
            positives.push(a.anomaly_score);
        } else if s.blurred.is_empty() {
            negatives.push(a.anomaly_score);
        }
        let on = |r: [f32; 4], set: &[crate::detect::targets::Labelled]| {
            set.iter().any(|d| overlaps(r, d.box_px))
        };
        defects += s.boxes.len();
        found += s
            .boxes
            .iter()
            .filter(|d| a.regions.iter().any(|r| overlaps(r.box_px, d.box_px)))
            .count();
        right += a.regions.iter().filter(|r| on(r.box_px, &s.boxes)).count();
        counted += a
            .regions
            .iter()
            .filter(|r| on(r.box_px, &s.boxes) || !on(r.box_px, &s.blurred))
            .count();
    }
    Ok(Figures {
        auroc: auroc(&positives, &negatives),
        recall: found as f64 / defects.max(1) as f64,
        precision: right as f64 / counted.max(1) as f64,
        defective_frames: positives.len(),
        clean_frames: negatives.len(),
        defects,
    })
}

fn overlaps(a: [f32; 4], b: [f32; 4]) -> bool {
    a[0] < b[2] && b[0] < a[2] && a[1] < b[3] && b[1] < a[3]
}

/// The area under the ROC curve of `positives` against `negatives` (ties count half).
pub fn auroc(positives: &[f32], negatives: &[f32]) -> f64 {
    let wins: f64 = positives
        .iter()
        .flat_map(|p| negatives.iter().map(move |n| (p, n)))
        .map(|(p, n)| match p.total_cmp(n) {
            std::cmp::Ordering::Greater => 1.0,
            std::cmp::Ordering::Equal => 0.5,
            std::cmp::Ordering::Less => 0.0,
        })
        .sum();
    wins / (positives.len() * negatives.len()).max(1) as f64
}

/// One held-out roll's line of the table.
#[derive(Debug, Clone, Serialize)]
pub struct AnomalyRow {
    /// The roll's seed.
    pub seed: u64,
    /// Its fabric.
    pub fabric: String,
    /// Anomaly mode's figures, if the roll could be measured.
    pub figures: Option<Figures>,
    /// Why it could not.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub not_measured: Option<String>,
}

/// Simulates `count` held-out rolls of [`ROLL`]'s shape (seeds from [`EVAL_SEEDS`]) and
/// measures anomaly mode on each; `progress` counts the rolls.
pub fn evaluate_anomaly(count: usize, progress: &dyn Progress) -> anyhow::Result<Vec<AnomalyRow>> {
    ensure!(count > 0, "--rolls must be at least 1");
    ensure!(
        count as u64 <= TRAIN_SEEDS - EVAL_SEEDS,
        "at most {} held-out rolls",
        TRAIN_SEEDS - EVAL_SEEDS
    );
    progress.start(
        "anomaly mode on held-out rolls",
        Some(count as u64),
        "rolls",
    );
    let mut rows = Vec::with_capacity(count);
    for (k, seed) in (EVAL_SEEDS..EVAL_SEEDS + count as u64).enumerate() {
        let sim = Simulator::new(&roll_scene(seed, &ROLL))?;
        let (frames, _) = frames(&sim, class_of(seed));
        let measured = measure(&frames);
        rows.push(AnomalyRow {
            seed,
            fabric: FABRICS[class_of(seed)].name.to_string(),
            not_measured: measured.as_ref().err().map(|e| e.to_string()),
            figures: measured.ok(),
        });
        progress.advance_to(k as u64 + 1);
    }
    progress.finish();
    Ok(rows)
}

/// The rows as a Markdown table, with the median of each figure over the rolls measured.
pub fn markdown(rows: &[AnomalyRow]) -> String {
    let mut out = String::from(
        "| roll | fabric | defective frames | clean frames | defects | image AUROC | recall | precision |\n\
         |---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        out += &match &r.figures {
            Some(f) => format!(
                "| {} | {} | {} | {} | {} | {:.3} | {:.2} | {:.2} |\n",
                r.seed,
                r.fabric,
                f.defective_frames,
                f.clean_frames,
                f.defects,
                f.auroc,
                f.recall,
                f.precision
            ),
            None => format!(
                "| {} | {} | {} | | | | | |\n",
                r.seed,
                r.fabric,
                r.not_measured.as_deref().unwrap_or("not measured")
            ),
        };
    }
    let measured: Vec<&Figures> = rows.iter().filter_map(|r| r.figures.as_ref()).collect();
    let median = |pick: fn(&Figures) -> f64| {
        let mut v: Vec<f64> = measured.iter().map(|f| pick(f)).collect();
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
    };
    out += &format!(
        "\nMedian over {} of {} rolls: image AUROC {:.3}, recall {:.2}, precision {:.2} \
         (each roll fitted on {FIT_FRAMES} of its own defect-free frames).\n",
        measured.len(),
        rows.len(),
        median(|f| f.auroc),
        median(|f| f.recall),
        median(|f| f.precision)
    );
    out
}
