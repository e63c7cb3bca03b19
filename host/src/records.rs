//! What the commands put in the inspection records (`--records DB`, [`rollfuse_records`]):
//! a fused strip's segments, a streamed strip's segments as they are written
//! ([`RollKeeper`]), and defects found on a recorded strip's segments with their belt
//! positions and a small crop of each.

use crate::image::{PixelLimit, Planes};
use crate::strip_file::{Segment, StripWriter};
use anyhow::Context;
use rollfuse_records::{DefectRecord, Records, RollStart, SegmentRecord, Status};
use std::path::Path;

/// A defect found on a strip: its kind, score and box (`[x0, row0, x1, row1]`: strip
/// columns and belt rows).
pub type StripBox = (&'static str, f32, [f32; 4]);

/// The largest crop kept of a defect, pixels a side (a larger box keeps its middle).
pub const CROP_SIDE: usize = 96;
/// Pixels of cloth kept around a defect's box in its crop.
const CROP_MARGIN: f32 = 8.0;

/// Where a streamed roll is kept in the records.
#[derive(Debug, Clone)]
pub struct KeepRoll {
    /// The records: a SQLite file's path or a `postgres://` URL.
    pub records: String,
    /// The roll's record as it starts; its `out` is set to the strip's path.
    pub start: RollStart,
    /// Belt millimetres a camera pixel: the roll's scale once the device's downsampling
    /// is known.
    pub mm_per_px: Option<f64>,
}

/// A streamed roll being recorded: each strip segment as soon as it is whole on disk, the
/// faults and the status when the session ends.
pub struct RollKeeper {
    records: Records,
    roll: i64,
    folder: std::path::PathBuf,
    /// The recorded segments: number, first belt row, rows, file name.
    segments: Vec<(i64, Segment)>,
    /// Defects on the strip whose segment is not recorded yet.
    waiting: Vec<StripBox>,
    /// The defects recorded on each segment (recording one again replaces them all).
    found: std::collections::BTreeMap<i64, Vec<DefectRecord>>,
    /// Belt millimetres a camera pixel, until the scale is set.
    mm_per_px: Option<f64>,
}

impl RollKeeper {
    /// Opens the records and starts the roll of a strip written to `strip`. Refuses a
    /// strip already at `strip` unless it is this source's own (a recording streamed
    /// again): segments land in place as they are written, and would overwrite it.
    pub fn start(keep: &KeepRoll, strip: &Path) -> anyhow::Result<RollKeeper> {
        let mut records = Records::open(&keep.records)?;
        let out = std::path::absolute(strip).unwrap_or_else(|_| strip.to_path_buf());
        let earlier = [
            crate::strip_file::StripWriter::index_path(strip),
            strip.to_path_buf(),
            crate::strip_file::StripWriter::segment_path(strip, 0),
        ];
        let own = records
            .roll_of_source(&keep.start.source)?
            .is_some_and(|r| r.out == out.display().to_string());
        if let Some(there) = earlier.iter().find(|p| p.exists()).filter(|_| !own) {
            anyhow::bail!(
                "{} holds a strip already ({}): with --records a roll's segments land as they \
                 are written and would replace it; choose a new --out or move it away",
                crate::files::folder_of(strip).display(),
                there.display()
            );
        }
        let start = RollStart {
            out: out.display().to_string(),
            ..keep.start.clone()
        };
        let roll = records.begin_roll(&start)?;
        Ok(RollKeeper {
            records,
            roll,
            folder: crate::files::folder_of(strip).to_path_buf(),
            segments: Vec::new(),
            waiting: Vec::new(),
            found: Default::default(),
            mm_per_px: keep.mm_per_px,
        })
    }

    /// The device's tiles are downsampled `downsample`×: the roll's scale follows from the
    /// camera's (the first configuration's; set once).
    pub fn configured(&mut self, downsample: u8) -> anyhow::Result<()> {
        if let Some(k) = self.mm_per_px.take() {
            self.records
                .set_scale(self.roll, k * f64::from(downsample.max(1)))?;
        }
        Ok(())
    }

    /// The roll's id.
    pub fn roll(&self) -> i64 {
        self.roll
    }

    /// Lands `writer`'s full segments ([`StripWriter::new_segments`]): each is announced to
    /// the records before its file is written and recorded once it is, so a roll cut off
    /// between the two still lists it if it is whole.
    pub fn land(&mut self, writer: &mut StripWriter) -> anyhow::Result<()> {
        let mut announced = Vec::new();
        for s in writer.staged() {
            let seg = s.segment;
            let (seq, first, rows) = (s.number as i64, seg.first_row, seg.rows as i64);
            let record = SegmentRecord::of_bytes(seq, &seg.file, first, rows, s.png);
            self.records.announce_segment(self.roll, &record)?;
            announced.push((record, seg.clone()));
        }
        writer.new_segments()?;
        for (record, segment) in announced {
            self.records.add_segment(self.roll, &record, &[])?;
            self.segments.push((record.seq, segment));
        }
        self.place_waiting()
    }

    /// Records `found` on the segments they lie on; those on a segment not written yet
    /// wait for it.
    pub fn defects(&mut self, found: Vec<StripBox>) -> anyhow::Result<()> {
        self.waiting.extend(found);
        self.place_waiting()
    }

    /// Records the waiting defects whose segment is recorded, each segment's whole list
    /// in one transaction.
    fn place_waiting(&mut self) -> anyhow::Result<()> {
        let placed = place(&self.segments, std::mem::take(&mut self.waiting));
        self.waiting = placed.waiting;
        for (seq, boxes) in placed.by_segment {
            let Some((_, segment)) = self.segments.iter().find(|(n, _)| *n == seq) else {
                continue;
            };
            let image = Planes::load(&self.folder.join(&segment.file), PixelLimit::OWN)?;
            let list = self.found.entry(seq).or_default();
            list.extend(on_segment(&boxes, segment, &image));
            self.records.replace_defects(self.roll, seq, list)?;
        }
        Ok(())
    }

    /// Ends the roll: its `faults` counted, complete or failed.
    pub fn finish(mut self, faults: &[(&str, u64)], status: &Status) -> anyhow::Result<()> {
        self.records.set_faults(self.roll, faults)?;
        self.records.finish_roll(self.roll, status)?;
        Ok(())
    }
}

/// Records `found`, defects the detector reported after roll `roll` was finished (its
/// last windows), on the roll's segments beside those recorded before; a defect on no
/// recorded segment is left out. Returns how many were recorded.
pub fn record_late_defects(target: &str, roll: i64, found: Vec<StripBox>) -> anyhow::Result<usize> {
    if found.is_empty() {
        return Ok(0);
    }
    let mut records = Records::open(target)?;
    let record = records.roll(roll)?;
    let folder = crate::files::folder_of(Path::new(&record.summary.out)).to_path_buf();
    let segments: Vec<(i64, Segment)> = (record.segment_list.iter())
        .map(|s| {
            let segment = Segment {
                file: s.file.clone(),
                first_row: s.first_row,
                rows: s.rows as usize,
            };
            (s.seq, segment)
        })
        .collect();
    let placed = place(&segments, found);
    let mut recorded = 0;
    for (seq, boxes) in placed.by_segment {
        let Some((_, segment)) = segments.iter().find(|(n, _)| *n == seq) else {
            continue;
        };
        let image = Planes::load(&folder.join(&segment.file), PixelLimit::OWN)?;
        let mut list: Vec<DefectRecord> = (record.defect_list.iter())
            .filter(|d| d.segment_seq == Some(seq))
            .cloned()
            .collect();
        recorded += boxes.len();
        list.extend(on_segment(&boxes, segment, &image));
        records.replace_defects(roll, seq, &list)?;
    }
    Ok(recorded)
}

/// `boxes` (strip columns and belt rows) as defects of `segment`, whose file is `image`:
/// their boxes in the segment's pixels, their crops cut from it.
fn on_segment<'a>(
    boxes: &'a [StripBox],
    segment: &'a Segment,
    image: &'a Planes,
) -> impl Iterator<Item = DefectRecord> + 'a {
    let first = segment.first_row as f32;
    boxes.iter().map(move |&(kind, score, [x0, y0, x1, y1])| {
        let in_segment = [x0, y0 - first, x1, y1 - first];
        defect(kind, score, in_segment, image, segment.first_row)
    })
}

/// Defects sorted onto segments.
struct Placed {
    /// By segment number.
    by_segment: std::collections::BTreeMap<i64, Vec<StripBox>>,
    /// On no segment yet.
    waiting: Vec<StripBox>,
}

/// Sorts `boxes` onto the `segments` holding their centre rows.
fn place(segments: &[(i64, Segment)], boxes: Vec<StripBox>) -> Placed {
    let mut placed = Placed {
        by_segment: Default::default(),
        waiting: Vec::new(),
    };
    for b in boxes {
        let centre = f64::from(b.2[1] + b.2[3]) / 2.0;
        let on = segments.iter().find(|(_, s)| {
            (s.first_row as f64..(s.first_row + s.rows as i64) as f64).contains(&centre)
        });
        match on {
            Some((seq, _)) => placed.by_segment.entry(*seq).or_default().push(b),
            None => placed.waiting.push(b),
        }
    }
    placed
}

/// Records a strip written whole (`rollfuse fuse`): the roll `start`, each of `segments`
/// (files beside `out`, read for their checksums) and the roll's end, `status`. A roll of
/// the same source recorded before is replaced. Returns the roll's id.
pub fn record_strip(
    records: &mut Records,
    start: &RollStart,
    out: &Path,
    segments: &[Segment],
    status: &Status,
) -> anyhow::Result<i64> {
    let roll = records.begin_roll(start)?;
    let folder = crate::files::folder_of(out);
    for (seq, s) in segments.iter().enumerate() {
        let path = folder.join(&s.file);
        let record = SegmentRecord::of_file(seq as i64, &path, s.first_row, s.rows as i64)
            .with_context(|| format!("cannot read {} to record it", path.display()))?;
        records.add_segment(roll, &record, &[])?;
    }
    records.finish_roll(roll, status)?;
    Ok(roll)
}

/// A defect of `kind` found at `box_px` (`[x0, y0, x1, y1]`) in `image`, a segment whose
/// first row is belt row `first_row`; its crop cut from `image`.
pub fn defect(
    kind: &str,
    score: f32,
    box_px: [f32; 4],
    image: &Planes,
    first_row: i64,
) -> DefectRecord {
    let [x0, y0, x1, y1] = box_px;
    DefectRecord {
        segment_seq: None,
        kind: kind.to_owned(),
        score: f64::from(score),
        belt_row: first_row as f64 + f64::from(y0 + y1) / 2.0,
        across_px: f64::from(x0 + x1) / 2.0,
        bbox: [
            x0.round() as i64,
            y0.round() as i64,
            (x1 - x0).round() as i64,
            (y1 - y0).round() as i64,
        ],
        crop: crop_png(image, box_px),
    }
}

/// The box with a margin, at most [`CROP_SIDE`] a side around its middle, of the first
/// plane as an 8-bit gray PNG; none for a box outside the image.
pub fn crop_png(image: &Planes, [x0, y0, x1, y1]: [f32; 4]) -> Option<Vec<u8>> {
    use image::ImageEncoder;
    let span = |a: f32, b: f32, size: usize| -> Option<(usize, usize)> {
        let (lo, hi) = (
            (a - CROP_MARGIN).max(0.0),
            (b + CROP_MARGIN).min(size as f32),
        );
        let (mid, half) = (
            (lo + hi) / 2.0,
            ((hi - lo) / 2.0).min(CROP_SIDE as f32 / 2.0),
        );
        let (lo, hi) = (
            (mid - half).floor().max(0.0),
            (mid + half).ceil().min(size as f32),
        );
        (hi > lo).then_some((lo as usize, hi as usize))
    };
    let (cx0, cx1) = span(x0, x1, image.width)?;
    let (cy0, cy1) = span(y0, y1, image.height)?;
    let plane = image.planes.first()?;
    let pixels: Vec<u8> = (cy0..cy1)
        .flat_map(|y| (cx0..cx1).map(move |x| (y, x)))
        .map(|(y, x)| plane[y * image.width + x].round().clamp(0.0, 255.0) as u8)
        .collect();
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(
            &pixels,
            (cx1 - cx0) as u32,
            (cy1 - cy0) as u32,
            image::ExtendedColorType::L8,
        )
        .ok()?;
    Some(png)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_defect_lies_where_its_box_is_on_the_belt_with_a_bounded_crop() {
        let image = Planes {
            width: 300,
            height: 400,
            planes: vec![(0..120_000).map(|i| (i % 256) as f32).collect()],
        };
        let d = defect("hole", 0.9, [10.0, 20.0, 30.0, 60.0], &image, 5000);
        assert_eq!(d.belt_row, 5040.0);
        assert_eq!(d.across_px, 20.0);
        assert_eq!(d.bbox, [10, 20, 20, 40]);
        let crop = image::load_from_memory(d.crop.as_ref().unwrap()).unwrap();
        // 8 px of margin each side, cut at the image's left edge: x 2..38, y 12..68.
        assert_eq!((crop.width(), crop.height()), (36, 56));
        let big = crop_png(&image, [0.0, 0.0, 300.0, 400.0]).unwrap();
        let big = image::load_from_memory(&big).unwrap();
        assert_eq!((big.width(), big.height()), (96, 96));
        assert!(crop_png(&image, [500.0, 0.0, 600.0, 10.0]).is_none());
    }
}
