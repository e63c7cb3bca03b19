//! What the live detector has found, as the server keeps it for the page: the boxes on the
//! strip and the summary `/status.json` gives.

use crate::detect::Detection;
use serde::Serialize;
use std::collections::{BTreeMap, VecDeque};

/// Boxes the server keeps for pages that connect later (older ones are dropped).
pub const KEPT_BOXES: usize = 1024;

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
    pub(super) fn failed(&mut self, why: &str) {
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
    /// Whether the boxes go to the inspection records too (`--records`).
    pub recording: bool,
    /// Boxes not yet handed to the records, with `recording` (the session takes them as
    /// it goes, so this stays short).
    pub unrecorded: Vec<LiveBox>,
    /// Every fabric's probability summed over the rows checked, weighted by rows.
    weights: Vec<f64>,
}

impl Findings {
    /// Nothing found yet; the boxes go to the records too when `recording`.
    pub fn new(recording: bool) -> Self {
        Self {
            recording,
            ..Self::default()
        }
    }

    /// Counts a window's boxes and weighs its fabric probabilities by its `rows`.
    pub(super) fn take(
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
            if self.recording {
                self.unrecorded.push(*b);
            }
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

impl LiveBox {
    /// As the records take it.
    pub fn strip_box(&self) -> crate::records::StripBox {
        (self.kind, self.score, self.strip_box)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::{Detection, UNKNOWN_FABRIC};

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
