//! What the demo produced: its figures, for the report and the summary, and the names of
//! the files it writes.

use super::detection::DetectionDemo;
use crate::eval::depth::DepthRow;
use crate::eval::tables::Row;
use crate::fullres::window::ContactWindow;
use crate::stream::{StopReason, StreamRecord};
use crate::tradeoff::Measured;

/// One stage's name and wall time.
#[derive(Debug, Clone)]
pub struct Stage {
    /// Short name.
    pub name: &'static str,
    /// What it did, for the report.
    pub what: String,
    /// Wall time, seconds.
    pub secs: f64,
}

/// How the roll's alignment went.
#[derive(Debug, Clone)]
pub struct Alignment {
    /// Frames in the sequence.
    pub frames: usize,
    /// Frames placed by a match (all but the first, when every frame has texture).
    pub matched: usize,
    /// Frames placed at their prediction (nothing to match).
    pub predicted: usize,
    /// Largest difference, rows, between a frame's row on the strip and its belt travel
    /// by motion (relative to the first frame).
    pub max_motion_disagreement: i64,
    /// The contact window used, frame rows.
    pub window: ContactWindow,
}

/// Everything the demo produced. Images are written to the output folder under the names
/// in [`Files`]; the figures are kept here for the report and the summary.
pub struct Demo {
    /// The scenes' names.
    pub letters_name: String,
    /// Frames in the letters sequence and their size.
    pub frames: (usize, usize, usize),
    /// The frames shown in the report (indices; written as [`Files::frame`]).
    pub shown_frames: Vec<usize>,
    /// The streaming session's manifest (tiles, bytes, faults, device counters).
    pub stream: StreamRecord,
    /// Why the session ended ([`StopReason::DeviceStopped`] when the scene ran out).
    pub stream_stop: StopReason,
    /// The stitched strip's size.
    pub strip_size: (usize, usize),
    /// The template alignment.
    pub alignment: Alignment,
    /// The full-resolution strip's size.
    pub host_strip_size: (usize, usize),
    /// How many frames see each belt point: frame height over belt travel per frame.
    pub frames_per_point: f64,
    /// Tables II and III on the letters scene.
    pub eval: Vec<Row>,
    /// Table IV on the sphere scene.
    pub depth: Vec<DepthRow>,
    /// The defect detector on held-out textile rolls.
    pub detection: DetectionDemo,
    /// The trade-off study on the letters scene.
    pub tradeoff: Vec<Measured>,
    /// The bench build the MCU figures come from, if any.
    pub mcu_build: Option<String>,
    /// Stage timings, in order.
    pub stages: Vec<Stage>,
}

/// The files the demo writes, relative to its output folder.
pub struct Files;

impl Files {
    /// The device-fused strip (in the stream session's folder).
    pub const STRIP: &'static str = "stream/strip.png";
    /// The streaming session's manifest.
    pub const STREAM_MANIFEST: &'static str = "stream/manifest.json";
    /// The host's full-resolution strip (contact-window fusion of every frame).
    pub const HOST_STRIP: &'static str = "fused.png";
    /// The middle frame alone.
    pub const SINGLE: &'static str = "single.png";
    /// The mosaic over the middle frame's footprint.
    pub const FUSED_MIDDLE: &'static str = "fused_middle.png";
    /// Tables II and III.
    pub const EVAL_MD: &'static str = "eval.md";
    /// Tables II and III, CSV (the same file `rollfuse eval` writes).
    pub const EVAL_CSV: &'static str = "eval.csv";
    /// Table IV.
    pub const DEPTH_MD: &'static str = "depth.md";
    /// Table IV, CSV (the same file `rollfuse eval --depth` writes).
    pub const DEPTH_CSV: &'static str = "depth.csv";
    /// Depth maps, by method.
    pub const DEPTH_PNGS: [&'static str; 3] =
        ["depth_single.png", "depth_fused3.png", "depth_fused2.png"];
    /// The trade-off table.
    pub const TRADEOFF_MD: &'static str = "tradeoff.md";
    /// The trade-off CSV.
    pub const TRADEOFF_CSV: &'static str = "tradeoff.csv";
    /// The Pareto plot.
    pub const PARETO: &'static str = "pareto.svg";
    /// The report.
    pub const REPORT: &'static str = "report.html";

    /// Frame `k` of the sequence, as shown in the report.
    pub fn frame(k: usize) -> String {
        format!("frame_{k:02}.png")
    }
}
