//! What the records hold, as types.

use serde::Serialize;
use std::path::Path;

/// A roll as it starts: what it is and where its strip goes.
#[derive(Debug, Clone)]
pub struct RollStart {
    /// What the roll was made from, unique across the records: a re-run of the same source
    /// replaces its earlier record instead of adding a second (`device SERIAL at TIME`,
    /// `recording PATH`, `frames FOLDER`).
    pub source: String,
    /// The production line.
    pub line: String,
    /// The device's serial, or `host` for a strip fused on the host.
    pub device: String,
    /// The device's or the fusion's configuration, as JSON text.
    pub configuration: String,
    /// The strip's path (its segments are named beside it).
    pub out: String,
    /// Millimetres of belt a strip row, where known.
    pub mm_per_row: Option<f64>,
}

/// Where a roll is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Status {
    /// Being written by a live process.
    Running,
    /// Finished whole.
    Complete,
    /// Stopped by an error, with it.
    Failed(String),
    /// Its process ended without finishing it (killed, lost power), as found by a later
    /// start.
    Interrupted(String),
}

impl Status {
    /// The status in words, as stored.
    pub fn word(&self) -> &'static str {
        match self {
            Status::Running => "running",
            Status::Complete => "complete",
            Status::Failed(_) => "failed",
            Status::Interrupted(_) => "interrupted",
        }
    }

    /// The reason, for a failed or interrupted roll.
    pub fn reason(&self) -> Option<&str> {
        match self {
            Status::Failed(r) | Status::Interrupted(r) => Some(r),
            _ => None,
        }
    }
}

/// One strip segment, whole on disk when recorded.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct SegmentRecord {
    /// Its number in the roll, from 0.
    pub seq: i64,
    /// Its file name, beside the roll's `out`.
    pub file: String,
    /// The belt row of its first row.
    pub first_row: i64,
    /// Its rows.
    pub rows: i64,
    /// Its width, pixels (0 where the file is no PNG).
    pub width: i64,
    /// The file's size.
    pub bytes: i64,
    /// The file's CRC-32 (IEEE), to tell a file changed or cut short since.
    pub crc32: u32,
}

impl SegmentRecord {
    /// The record of segment `seq`, the file at `path` (read once for its checksum).
    pub fn of_file(
        seq: i64,
        path: &Path,
        first_row: i64,
        rows: i64,
    ) -> std::io::Result<SegmentRecord> {
        let bytes = std::fs::read(path)?;
        let file = path.file_name().unwrap_or_default().to_string_lossy();
        Ok(Self::of_bytes(seq, &file, first_row, rows, &bytes))
    }

    /// The record of segment `seq`, a file `file` that will hold `bytes`.
    pub fn of_bytes(seq: i64, file: &str, first_row: i64, rows: i64, bytes: &[u8]) -> Self {
        SegmentRecord {
            width: png_width(bytes).unwrap_or(0),
            seq,
            file: file.to_owned(),
            first_row,
            rows,
            bytes: bytes.len() as i64,
            crc32: crc32fast::hash(bytes),
        }
    }

    /// Whether the file at `path` is this segment, whole.
    pub fn matches_file(&self, path: &Path) -> bool {
        std::fs::read(path)
            .is_ok_and(|b| b.len() as i64 == self.bytes && crc32fast::hash(&b) == self.crc32)
    }
}

/// A PNG's width, from its header (the signature, then the IHDR chunk: its length and
/// type, then the width as a big-endian u32).
fn png_width(bytes: &[u8]) -> Option<i64> {
    const SIGNATURE: &[u8] = b"\x89PNG\r\n\x1a\n";
    if bytes.get(..8)? != SIGNATURE || bytes.get(12..16)? != b"IHDR" {
        return None;
    }
    let w: [u8; 4] = bytes.get(16..20)?.try_into().ok()?;
    Some(i64::from(u32::from_be_bytes(w)))
}

/// One defect found on a roll.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DefectRecord {
    /// The segment it was found in, if it was found on one.
    pub segment_seq: Option<i64>,
    /// Its kind (`hole`, `anomaly`, …).
    pub kind: String,
    /// The detector's score, higher is surer.
    pub score: f64,
    /// The belt row of its centre.
    pub belt_row: f64,
    /// Its centre across the belt, pixels from the strip's first column.
    pub across_px: f64,
    /// Its box in the segment's pixels: x, y, width, height.
    pub bbox: [i64; 4],
    /// A small PNG of it, if one was kept.
    #[serde(skip)]
    pub crop: Option<Vec<u8>>,
}

/// One line of `rolls list`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RollSummary {
    /// The roll's id.
    pub id: i64,
    /// The line.
    pub line: String,
    /// The device's serial, or `host`.
    pub device: String,
    /// What it was made from.
    pub source: String,
    /// `running`, `complete`, `failed` or `interrupted`.
    pub status: String,
    /// Why it failed or was interrupted.
    pub reason: Option<String>,
    /// When it started and ended (RFC 3339, UTC).
    pub started_at: String,
    /// When it ended, if it has.
    pub ended_at: Option<String>,
    /// Belt rows covered by its recorded segments.
    pub belt_rows: i64,
    /// Millimetres a row, where known.
    pub mm_per_row: Option<f64>,
    /// Belt length of its recorded segments in mm, where the scale is known.
    pub belt_mm: Option<f64>,
    /// Its strip's path.
    pub out: String,
    /// Recorded segments.
    pub segments: i64,
    /// Recorded defects.
    pub defects: i64,
}

/// A roll's whole record (`rolls show`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Roll {
    /// Its line in `rolls list`.
    #[serde(flatten)]
    pub summary: RollSummary,
    /// The configuration it ran with (JSON text).
    pub configuration: String,
    /// Its segments, in order.
    pub segment_list: Vec<SegmentRecord>,
    /// Its defects, along the belt.
    pub defect_list: Vec<DefectRecord>,
    /// Faults counted, by kind.
    pub faults: Vec<(String, i64)>,
}

impl Roll {
    /// A defect's position along the belt in mm from the roll's first row, where the scale
    /// is known.
    pub fn belt_mm(&self, d: &DefectRecord) -> Option<f64> {
        let first = self.segment_list.first().map_or(0, |s| s.first_row);
        self.summary
            .mm_per_row
            .map(|k| (d.belt_row - first as f64) * k)
    }
}

/// Which rolls `rolls list` shows.
#[derive(Debug, Clone, Default)]
pub struct Filter {
    /// Only this line's.
    pub line: Option<String>,
    /// Only those started at or after this time (RFC 3339).
    pub since: Option<String>,
    /// Only those with a defect of this kind.
    pub kind: Option<String>,
}
