//! A strip written as it grows: numbered PNG segments and a JSON index of their belt rows.
//!
//! A conveyor runs for hours, so a strip is never held whole: rows are collected into a
//! segment of at most `segment_rows` rows, which is written (whole, [`rollfuse_io::files`]) as
//! soon as it is full, and a new segment starts at every jump in the belt rows. A strip
//! that fits one segment is written as `OUT` itself; a longer one as `STEM.0000.EXT`,
//! `STEM.0001.EXT`, …; in both cases `STEM.json` lists the segments with their first belt
//! row and is written last, so it names only segments that are complete and of this run.
//!
//! An older strip of the same name stays whole until the new one is: each segment is
//! written as soon as it is full, beside its name under a hidden one that names the
//! process ([`rollfuse_io::files::temporary_beside`]), and moved into place when the strip
//! finishes. A strip that fails (or is dropped unfinished) removes what it wrote and
//! leaves the older strip, its index included, as it was; a run killed outright leaves
//! only its hidden files, which the next run writing to that folder removes.
//!
//! A strip kept in the inspection records is written [`StripWriter::in_place`] instead:
//! each segment goes to its numbered name as soon as it is full (a lone one too), so a
//! run killed midway leaves every full segment whole where the records say it is; an
//! older index is removed before the first segment lands, and its segments past this
//! strip's when it finishes. A full segment is first held encoded
//! ([`StripWriter::staged`]), so that its record can be announced with its checksum
//! before the file lands ([`StripWriter::new_segments`]).
//!
//! Memory: one segment, `segment_rows × width × channels` samples.

use rollfuse_io::files::{Batch, PngLayout, WriteError, add_png, write_bytes_atomic};
use std::path::{Path, PathBuf};

/// Default rows per segment.
pub const DEFAULT_SEGMENT_ROWS: usize = 4096;

/// One written segment, as the index lists it.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Segment {
    /// File name, beside the index.
    pub file: String,
    /// Belt row of its first row.
    pub first_row: i64,
    /// Rows.
    pub rows: usize,
}

/// The index `STEM.json`.
#[derive(Debug, Clone, serde::Serialize)]
pub struct StripIndex<T: serde::Serialize> {
    /// Strip width, pixels.
    pub width: usize,
    /// 1 (gray) or 3 (RGB).
    pub channels: usize,
    /// Bits per sample.
    pub bits: u8,
    /// The segments, in belt order.
    pub segments: Vec<Segment>,
    /// What the producer reports about the strip.
    pub details: T,
}

/// Refuses, before any work, an input (each named by what it is) that a strip written to
/// `out` could overwrite with a segment: one named `STEM.NNNN.EXT` beside `out`.
pub fn refuse_segment_names(out: &Path, inputs: &[(&str, &Path)]) -> crate::Result<()> {
    for (what, input) in inputs {
        rollfuse_io::require!(
            !is_segment_name(out, input),
            "{} would write segments named like the {what} {}: refusing to overwrite an input",
            out.display(),
            input.display()
        );
    }
    Ok(())
}

/// Whether `path` is named as a segment of a strip written to `out` (`STEM.NNNN.EXT`
/// beside it).
pub fn is_segment_name(out: &Path, path: &Path) -> bool {
    let stem = out.file_stem().unwrap_or_default().to_string_lossy();
    let ext = out.extension().unwrap_or_default().to_string_lossy();
    let at = rollfuse_io::files::resolved(path);
    let name = at.file_name().unwrap_or_default().to_string_lossy();
    let numbered = name
        .strip_prefix(&format!("{stem}."))
        .and_then(|r| r.strip_suffix(&format!(".{ext}")))
        .is_some_and(|n| n.len() == 4 && n.bytes().all(|b| b.is_ascii_digit()));
    numbered && at.parent() == rollfuse_io::files::resolved(out).parent()
}

/// Where a strip image lies on the belt, as its index says: the index's path and the belt
/// row of the image's first row, for a lone strip `OUT` (index `STEM.json`) or one of its
/// segments `STEM.NNNN.EXT`. None when no readable index beside it lists it.
pub fn first_row_of(image: &Path) -> Option<(PathBuf, i64)> {
    let name = image.file_name()?.to_str()?;
    let stem = image.file_stem()?.to_str()?;
    // `STEM.0003.png` has the stem `STEM.0003`; its index is `STEM.json`.
    let strip_stem = match stem.rsplit_once('.') {
        Some((s, n)) if n.len() == 4 && n.bytes().all(|b| b.is_ascii_digit()) => s,
        _ => stem,
    };
    let index = image.with_file_name(format!("{strip_stem}.json"));
    let segments = read_segments(&index).ok()?;
    let first = segments.iter().find(|s| s.file == name)?.first_row;
    Some((index, first))
}

/// The segments a strip's index (`STEM.json`) lists, in belt order.
pub fn read_segments(index: &Path) -> crate::Result<Vec<Segment>> {
    #[derive(serde::Deserialize)]
    struct Listed {
        segments: Vec<Segment>,
    }
    let text = std::fs::read_to_string(index).map_err(|source| crate::Error::Read {
        path: index.to_path_buf(),
        source,
    })?;
    let listed: Listed = serde_json::from_str(&text).map_err(|e| {
        crate::Error::Invalid(format!("{} is not a strip index: {e}", index.display()))
    })?;
    Ok(listed.segments)
}

/// Collects rows and writes segments.
pub struct StripWriter {
    out: PathBuf,
    width: usize,
    channels: usize,
    layout: PngLayout,
    bits: u8,
    segment_rows: usize,
    fill_gaps: usize,
    current_first: Option<i64>,
    current_rows: usize,
    data: Vec<u8>,
    /// Segments written, under their numbered names (`finish` renames a lone one).
    written: Vec<Segment>,
    /// Where each written segment is: in place, or beside an older file it will replace.
    files: Vec<Written>,
    /// Set once `finish` has put the strip in place: nothing to clean up.
    finished: bool,
    /// Each segment in place as it is written ([`StripWriter::in_place`]).
    in_place: bool,
    /// Segments written since [`StripWriter::new_segments`] last took them.
    unreported: usize,
    /// In [`StripWriter::in_place`] mode, the encoded segments not yet in place: the
    /// last `staged.len()` of `written`.
    staged: Vec<Vec<u8>>,
}

/// A full segment encoded and not yet at its name ([`StripWriter::staged`]).
pub struct StagedSegment<'a> {
    /// Its number in the strip.
    pub number: usize,
    /// As the index will list it.
    pub segment: &'a Segment,
    /// The file's bytes.
    pub png: &'a [u8],
}

/// Where a written segment lies until the strip finishes.
enum Written {
    /// At its own name (moved there as the strip finishes).
    InPlace(PathBuf),
    /// Under a hidden name beside `target`, until the strip finishes.
    Beside { hidden: PathBuf, target: PathBuf },
}

impl StripWriter {
    /// A writer of `width`-pixel rows of `channels` (1 or 3) to `out` (a `.png` path) at
    /// `bits` (8 or 16) per sample.
    pub fn new(
        out: &Path,
        width: usize,
        channels: usize,
        bits: u8,
        segment_rows: usize,
    ) -> crate::Result<Self> {
        rollfuse_io::require!(segment_rows >= 1, "segments need at least one row");
        rollfuse_io::require!(width >= 1, "a strip needs at least one column");
        Ok(Self {
            out: out.to_path_buf(),
            width,
            channels,
            layout: PngLayout::new(channels, bits)?,
            bits,
            segment_rows,
            fill_gaps: 0,
            current_first: None,
            current_rows: 0,
            data: Vec::new(),
            written: Vec::new(),
            files: Vec::new(),
            finished: false,
            in_place: false,
            unreported: 0,
            staged: Vec::new(),
        })
    }

    /// Puts each segment at its numbered name as soon as it is full, and keeps it there
    /// even if the strip fails: the mode of a strip whose segments are recorded as they
    /// are written (a lone segment keeps its number too).
    pub fn in_place(mut self) -> Self {
        self.in_place = true;
        self
    }

    /// The full segments held encoded until [`StripWriter::new_segments`] puts them in
    /// place ([`StripWriter::in_place`] mode; none otherwise).
    pub fn staged(&self) -> Vec<StagedSegment<'_>> {
        let from = self.written.len() - self.staged.len();
        (self.written[from..].iter().zip(&self.staged))
            .enumerate()
            .map(|(i, (segment, png))| StagedSegment {
                number: from + i,
                segment,
                png,
            })
            .collect()
    }

    /// Puts the staged segments in place, then returns the segments written since the
    /// last call, each whole at its name in [`StripWriter::in_place`] mode, with their
    /// numbers.
    pub fn new_segments(&mut self) -> crate::Result<Vec<(usize, Segment)>> {
        self.land_staged()?;
        let from = self.written.len() - self.unreported;
        self.unreported = 0;
        Ok((from..).zip(self.written[from..].iter().cloned()).collect())
    }

    /// Writes the segment being collected now, though it is not full (it is staged in
    /// [`StripWriter::in_place`] mode): the last one of a strip about to finish.
    pub fn end_segment(&mut self) -> crate::Result<()> {
        self.flush()
    }

    /// Writes each staged segment, whole, at its name; one that cannot be written stays
    /// staged with those after it (a strip dropped unfinished tries them again).
    fn land_staged(&mut self) -> crate::Result<()> {
        while let Some(png) = self.staged.first() {
            let n = self.written.len() - self.staged.len();
            write_bytes_atomic(&self.numbered(n), png)?;
            self.staged.remove(0);
        }
        Ok(())
    }

    /// Fills a jump of at most `rows` missing rows with zeros inside the segment instead
    /// of starting a new one (a stream's lost tiles show as black rows where they were).
    pub fn fill_gaps(mut self, rows: usize) -> Self {
        self.fill_gaps = rows;
        self
    }

    /// `STEM.NNNN.EXT` beside `out`.
    fn numbered(&self, n: usize) -> PathBuf {
        Self::segment_path(&self.out, n)
    }

    /// Segment `n`'s path, `STEM.NNNN.EXT` beside `out`.
    pub fn segment_path(out: &Path, n: usize) -> PathBuf {
        let stem = out.file_stem().unwrap_or_default().to_string_lossy();
        let ext = out.extension().unwrap_or_default().to_string_lossy();
        out.with_file_name(format!("{stem}.{n:04}.{ext}"))
    }

    /// Moves the segments written beside older files into place, the older index first
    /// removed so that no index describes a mix of two strips meanwhile.
    fn replace_older(&mut self) -> crate::Result<()> {
        remove_if_there(&Self::index_path(&self.out))?;
        for file in &mut self.files {
            if let Written::Beside { hidden, target } = file {
                std::fs::rename(&*hidden, &*target)
                    .map_err(WriteError::io("move into place", target))?;
                *file = Written::InPlace(target.clone());
            }
        }
        Ok(())
    }

    /// Removes what an older strip of the same name left that this one did not write:
    /// segments numbered past this one's, and the lone `out` when this one has segments.
    fn remove_stale(&self) -> crate::Result<()> {
        let mut stale = Self::segments_on_disk(&self.out, self.written.len());
        if (self.written.len() > 1 || self.in_place) && self.out.exists() {
            stale.push(self.out.clone());
        }
        Ok(rollfuse_io::files::remove_stale(stale)?)
    }

    /// The segments of a strip written to `out` that are on disk, numbered from `first` on
    /// without a gap.
    pub fn segments_on_disk(out: &Path, first: usize) -> Vec<PathBuf> {
        (first..)
            .map(|n| Self::segment_path(out, n))
            .take_while(|p| p.exists())
            .collect()
    }

    /// The index's path, `STEM.json`.
    pub fn index_path(out: &Path) -> PathBuf {
        out.with_extension("json")
    }

    /// Appends belt row `row` (one slice of `width` values per channel, 8-bit scale).
    pub fn push(&mut self, row: i64, channels: &[&[f32]]) -> crate::Result<()> {
        rollfuse_io::require!(
            channels.len() == self.channels && channels.iter().all(|c| c.len() == self.width),
            "a strip row must have {} channels of {} values",
            self.channels,
            self.width
        );
        let expected = self
            .current_first
            .map(|first| first + self.current_rows as i64);
        if let Some(next) = expected.filter(|&e| row > e && row - e <= self.fill_gaps as i64) {
            let zeros = vec![0f32; self.width];
            let blank: Vec<&[f32]> = (0..self.channels).map(|_| zeros.as_slice()).collect();
            for missing in next..row {
                self.push(missing, &blank)?;
            }
        }
        let continues = self
            .current_first
            .is_some_and(|first| first + self.current_rows as i64 == row);
        if !continues || self.current_rows == self.segment_rows {
            self.flush()?;
            self.current_first = Some(row);
        }
        for x in 0..self.width {
            for c in channels {
                let v = c[x];
                match self.bits {
                    8 => self.data.push(v.round().clamp(0.0, 255.0) as u8),
                    _ => {
                        let s = (v * (65535.0 / 255.0)).round().clamp(0.0, 65535.0) as u16;
                        self.data.extend_from_slice(&s.to_ne_bytes());
                    }
                }
            }
        }
        self.current_rows += 1;
        Ok(())
    }

    /// Writes the segment being collected, if any.
    fn flush(&mut self) -> crate::Result<()> {
        let Some(first) = self.current_first.take() else {
            return Ok(());
        };
        let path = self.numbered(self.written.len());
        let size = (self.width, self.current_rows);
        let written = if self.in_place {
            if self.written.is_empty() {
                // No index may describe a mix of the older strip and this one.
                remove_if_there(&Self::index_path(&self.out))?;
            }
            let mut png = Vec::new();
            rollfuse_io::files::encode_png(&mut png, &self.data, size, self.layout)?;
            self.staged.push(png);
            Written::InPlace(path.clone())
        } else {
            // Every segment waits under a hidden name, its owner's, until the strip
            // finishes: an older file at its name stays whole until then, and a run
            // killed midway leaves only hidden files that the next run in this folder
            // sweeps away.
            let hidden = rollfuse_io::files::temporary_beside(&path, "new");
            let hidden = hidden.with_file_name(format!(
                "{}.png",
                hidden.file_name().unwrap_or_default().to_string_lossy()
            ));
            let mut segment = Batch::new();
            add_png(&mut segment, &hidden, &self.data, size, self.layout)?;
            segment.commit()?;
            Written::Beside {
                hidden,
                target: path.clone(),
            }
        };
        self.files.push(written);
        self.written.push(Segment {
            file: path
                .file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned(),
            first_row: first,
            rows: self.current_rows,
        });
        self.unreported += 1;
        self.data.clear();
        self.current_rows = 0;
        Ok(())
    }

    /// Writes the last segment, renames a lone segment to `out` itself, and writes the
    /// index with `details`. Returns the segments written.
    pub fn finish<T: serde::Serialize>(mut self, details: T) -> crate::Result<Vec<Segment>> {
        self.flush()?;
        self.land_staged()?;
        rollfuse_io::require!(
            !self.written.is_empty(),
            "the strip has no rows: nothing was written"
        );
        self.replace_older()?;
        self.finished = true;
        self.remove_stale()?;
        if self.written.len() == 1 && !self.in_place {
            let lone = self.numbered(0);
            std::fs::rename(&lone, &self.out)
                .map_err(WriteError::io("move into place", &self.out))?;
            self.written[0].file = self
                .out
                .file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned();
        }
        let index = StripIndex {
            width: self.width,
            channels: self.channels,
            bits: self.bits,
            segments: self.written.clone(),
            details,
        };
        let json = serde_json::to_string_pretty(&index)
            .map_err(|e| crate::Error::Invalid(format!("the strip's index as JSON: {e}")))?
            + "\n";
        write_bytes_atomic(&Self::index_path(&self.out), json.as_bytes())?;
        Ok(std::mem::take(&mut self.written))
    }
}

impl Drop for StripWriter {
    /// A strip left unfinished (an error on the way) takes back what it wrote, except the
    /// segments it put in place ([`StripWriter::in_place`]); the older strip it would
    /// have replaced is as it was.
    fn drop(&mut self) {
        if self.finished {
            return;
        }
        // Full segments are kept in place (the records may have announced them).
        if self.in_place {
            let _ = self.land_staged();
        }
        for file in &self.files {
            match file {
                // In place as it was written: whole, and kept (the records list it).
                Written::InPlace(_) if self.in_place => {}
                Written::InPlace(p) | Written::Beside { hidden: p, .. } => {
                    let _ = std::fs::remove_file(p);
                }
            }
        }
    }
}

/// Removes `path` if it is there.
fn remove_if_there(path: &Path) -> crate::Result<()> {
    match std::fs::remove_file(path) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(WriteError::io("remove the old", path)(e).into()),
    }
}

impl crate::roll::StripSink for StripWriter {
    fn row(&mut self, row: i64, channels: &[&[f32]]) -> anyhow::Result<()> {
        Ok(self.push(row, channels)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_strips_are_cut_into_indexed_segments_and_jumps_start_new_ones() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("strip.png");
        let mut w = StripWriter::new(&out, 3, 1, 8, 4).unwrap();
        for row in (10..20).chain(30..32) {
            w.push(row, &[&[row as f32; 3]]).unwrap();
        }
        let segs = w.finish("test").unwrap();
        let firsts: Vec<(i64, usize)> = segs.iter().map(|s| (s.first_row, s.rows)).collect();
        assert_eq!(firsts, [(10, 4), (14, 4), (18, 2), (30, 2)]);
        let third = image::open(dir.path().join("strip.0002.png"))
            .unwrap()
            .to_luma8();
        assert_eq!(third.into_raw(), [18, 18, 18, 19, 19, 19]);
        let index = std::fs::read_to_string(dir.path().join("strip.json")).unwrap();
        assert!(index.contains("\"strip.0003.png\""), "{index}");
        assert!(!out.exists());
    }

    #[test]
    fn in_place_segments_land_as_they_fill_and_stay_when_the_strip_fails() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("strip.png");
        std::fs::write(StripWriter::index_path(&out), "{}").unwrap();
        let mut w = StripWriter::new(&out, 2, 1, 8, 3).unwrap().in_place();
        for row in 0..7 {
            w.push(row, &[&[row as f32; 2]]).unwrap();
        }
        let staged: Vec<(usize, Vec<u8>)> = (w.staged().iter())
            .map(|s| (s.number, s.png.to_vec()))
            .collect();
        assert_eq!(staged.iter().map(|s| s.0).collect::<Vec<_>>(), [0, 1]);
        assert!(
            !dir.path().join("strip.0000.png").exists(),
            "staged, not landed"
        );
        let landed: Vec<(usize, String)> = (w.new_segments().unwrap().into_iter())
            .map(|(n, s)| (n, s.file))
            .collect();
        assert_eq!(
            landed,
            [(0, "strip.0000.png".into()), (1, "strip.0001.png".into())]
        );
        assert!(w.staged().is_empty());
        assert!(
            w.new_segments().unwrap().is_empty(),
            "each segment is reported once"
        );
        for (n, png) in &staged {
            let file = std::fs::read(StripWriter::segment_path(&out, *n)).unwrap();
            assert_eq!(&file, png, "segment {n} landed as it was staged");
        }
        assert!(
            !StripWriter::index_path(&out).exists(),
            "the older index goes before the first segment lands"
        );
        w.push(7, &[&[7.0; 2]]).unwrap();
        w.end_segment().unwrap();
        assert_eq!(
            w.staged().len(),
            1,
            "a short last segment is staged on request"
        );
        drop(w);
        assert!(dir.path().join("strip.0000.png").exists());
        assert!(dir.path().join("strip.0001.png").exists());
        assert!(
            dir.path().join("strip.0002.png").exists(),
            "a staged segment lands when the strip fails"
        );
        assert!(!dir.path().join("strip.0003.png").exists());

        // A lone segment keeps its number: the records name it so from the start.
        std::fs::write(&out, "older").unwrap();
        let mut w = StripWriter::new(&out, 2, 1, 8, 3).unwrap().in_place();
        w.push(0, &[&[1.0; 2]]).unwrap();
        let segs = w.finish(()).unwrap();
        assert_eq!(segs[0].file, "strip.0000.png");
        assert!(!out.exists(), "the older lone strip is stale");
        assert!(!dir.path().join("strip.0001.png").exists());
    }

    #[test]
    fn short_jumps_are_filled_with_zeros_and_long_ones_start_a_segment() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("g.png");
        let mut w = StripWriter::new(&out, 1, 1, 8, 100).unwrap().fill_gaps(2);
        for row in [0, 1, 4, 5, 9] {
            w.push(row, &[&[7.0]]).unwrap();
        }
        let segs = w.finish(()).unwrap();
        let spans: Vec<(i64, usize)> = segs.iter().map(|s| (s.first_row, s.rows)).collect();
        assert_eq!(spans, [(0, 6), (9, 1)]);
        let first = image::open(dir.path().join("g.0000.png"))
            .unwrap()
            .to_luma8();
        assert_eq!(first.into_raw(), [7, 7, 0, 0, 7, 7]);
    }

    #[test]
    fn a_short_strip_is_one_file_named_as_asked() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("s.png");
        let mut w = StripWriter::new(&out, 2, 3, 16, 100).unwrap();
        w.push(-5, &[&[1.0, 2.0], &[3.0, 4.0], &[5.0, 6.0]])
            .unwrap();
        let segs = w.finish(()).unwrap();
        assert_eq!(segs[0].file, "s.png");
        assert_eq!(image::open(&out).unwrap().to_rgb16().len(), 6);
        assert!(!dir.path().join("s.0000.png").exists());
        let empty = StripWriter::new(&dir.path().join("e.png"), 2, 1, 8, 10).unwrap();
        assert!(empty.finish(()).is_err());
    }

    /// Every file in `dir` with its bytes.
    fn files(dir: &Path) -> std::collections::BTreeMap<String, Vec<u8>> {
        std::fs::read_dir(dir)
            .unwrap()
            .map(|e| {
                let e = e.unwrap();
                let name = e.file_name().to_string_lossy().into_owned();
                (name, std::fs::read(e.path()).unwrap())
            })
            .collect()
    }

    #[test]
    fn an_older_strip_stays_whole_until_the_new_one_is_and_its_leftovers_go() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("strip.png");
        let mut old = StripWriter::new(&out, 2, 1, 8, 2).unwrap();
        for row in 0..6 {
            old.push(row, &[&[9.0; 2]]).unwrap();
        }
        assert_eq!(old.finish("old").unwrap().len(), 3);
        let older = files(dir.path());
        // A new strip longer than the old one, cut off midway: its segments are written
        // as they fill, each hidden beside its name, a free name too; the old strip and
        // its index stay as they were, and the cut strip takes back all it wrote.
        let mut cut = StripWriter::new(&out, 2, 1, 8, 2).unwrap();
        for row in 0..9 {
            cut.push(row, &[&[1.0; 2]]).unwrap();
        }
        assert!(
            !dir.path().join("strip.0003.png").exists(),
            "a free name is taken before the strip is whole"
        );
        let hidden = std::fs::read_dir(dir.path())
            .unwrap()
            .filter(|e| {
                let name = e.as_ref().unwrap().file_name();
                rollfuse_io::files::temporary_owner(&name.to_string_lossy())
                    == Some(std::process::id())
            })
            .count();
        assert_eq!(hidden, 4, "the full segments are on disk, hidden");
        for (name, bytes) in &older {
            assert_eq!(
                std::fs::read(dir.path().join(name)).unwrap(),
                *bytes,
                "{name}"
            );
        }
        drop(cut);
        assert_eq!(files(dir.path()), older, "the cut strip left something");
        // A short strip finishing: one file, the older segments removed.
        let mut short = StripWriter::new(&out, 2, 1, 8, 10).unwrap();
        short.push(0, &[&[5.0; 2]]).unwrap();
        short.finish("new").unwrap();
        let names: Vec<String> = files(dir.path()).into_keys().collect();
        assert_eq!(names, ["strip.json", "strip.png"]);
        assert_eq!(image::open(&out).unwrap().to_luma8().into_raw(), [5, 5]);
        // A longer one over it: its first segment replaces nothing at its numbered name,
        // and the lone older file goes once it finishes.
        let mut long = StripWriter::new(&out, 2, 1, 8, 2).unwrap();
        for row in 0..4 {
            long.push(row, &[&[3.0; 2]]).unwrap();
        }
        long.finish("long").unwrap();
        let names: Vec<String> = files(dir.path()).into_keys().collect();
        assert_eq!(names, ["strip.0000.png", "strip.0001.png", "strip.json"]);
    }
}
