//! Contact-window fusion of a whole roll, streamed: frames in, strip rows out.
//!
//! Belt rows are cut into bands of `band_rows`. Band `b` (rows `b·B .. (b+1)·B`, centre
//! `c`) is fused cyclically from the frames whose contact window held `c` (the device
//! fuses a tile the same way, from the frames that saw it near the apex), in order of
//! their distance from the apex, farthest first: the last frame of a cyclic fusion
//! weighs most in the LL band, and that should be the deepest contact. Each band is fused over its rows plus a margin either side — half the blend
//! zone, and enough rows that the wavelet's boundary extension does not reach the rows
//! kept — and neighbouring bands are cross-faded linearly over `blend_rows` rows around
//! their boundary, so the change of frames from one band to the next leaves no seam.
//!
//! A band is fused as soon as a frame arrives whose window starts below its centre: the
//! belt moves one way, so no later frame can hold it. Frames are dropped once no band
//! to come can use them. Memory: the frames of one window plus two, and two bands.
//!
//! A band that no window held (the belt jumped farther than the window between two
//! frames) is fused from the held frame whose window centre is nearest, and counted; a
//! band that no frame covers at all is written as a gap of zeros and counted.

use super::window::ContactWindow;
use super::{FrameRef, Fuser, Precision};
use rollfuse_core::FuseConfig;
use rollfuse_core::fusion::LlWeight;
use rollfuse_io::image::Planes;
use std::collections::VecDeque;

/// Band layout of a roll.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Bands {
    /// Rows per band.
    pub band_rows: usize,
    /// Rows over which two neighbouring bands are cross-faded (even, at most `band_rows`).
    pub blend_rows: usize,
}

impl Default for Bands {
    fn default() -> Self {
        Self {
            band_rows: 32,
            blend_rows: 8,
        }
    }
}

/// Receives the strip's rows, top to bottom, as they are finished.
pub trait StripSink {
    /// Belt row `row`: one slice of `width` values per channel.
    fn row(&mut self, row: i64, channels: &[&[f32]]) -> anyhow::Result<()>;
}

/// A sink that keeps every row: the whole strip in memory (tests, evaluation, short rolls).
#[derive(Debug, Default)]
pub struct StripInMemory {
    /// Belt row of the first row kept.
    pub first_row: Option<i64>,
    /// The rows so far.
    pub image: Option<Planes>,
}

impl StripSink for StripInMemory {
    fn row(&mut self, row: i64, channels: &[&[f32]]) -> anyhow::Result<()> {
        let first = *self.first_row.get_or_insert(row);
        let image = self.image.get_or_insert_with(|| Planes {
            width: channels[0].len(),
            height: 0,
            planes: vec![Vec::new(); channels.len()],
        });
        anyhow::ensure!(
            row == first + image.height as i64,
            "strip rows out of order: row {row} after {} rows from {first}",
            image.height
        );
        for (plane, values) in image.planes.iter_mut().zip(channels) {
            plane.extend_from_slice(values);
        }
        image.height += 1;
        Ok(())
    }
}

/// What a finished roll reports.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct RollSummary {
    /// Frames received.
    pub frames: usize,
    /// Bands fused.
    pub bands: usize,
    /// Bands no contact window held, fused from the nearest frame.
    pub bands_outside_window: usize,
    /// Bands no frame covered, written as zeros.
    pub gap_bands: usize,
    /// Bands passed over without writing where the belt jumped (after
    /// [`MAX_GAP_BANDS`] bands no frame covered).
    pub bands_skipped: u64,
    /// Strip rows written.
    pub rows: usize,
    /// Frames whose contact window lay wholly behind the bands already fused, so they
    /// added nothing: frames out of belt order, or a belt that ran backwards.
    pub frames_behind: usize,
}

/// Bands no frame covers written as zeros in a row before the fuser passes over the rest
/// of a jump: the strip then resumes at the first band a frame covers, and a sink sees the
/// jump in its rows (a file sink starts a new segment there).
pub const MAX_GAP_BANDS: usize = 8;

struct Held {
    index: usize,
    top: i64,
    /// Belt column of the frame's column 0.
    left: i64,
    image: Planes,
}

/// What lies before the band being fused.
enum Before {
    /// Nothing: the strip starts with it.
    Start,
    /// A band no frame covered.
    Gap,
    /// The band before it, fused.
    Band(Band),
}

/// A fused band's region: its first row and its values per channel (`rows × width`).
struct Band {
    top: i64,
    planes: Vec<Vec<f32>>,
}

/// The streaming contact-window fuser.
pub struct RollFuser<S: StripSink> {
    sink: S,
    window: ContactWindow,
    bands: Bands,
    /// Rows fused either side of a band beyond the rows kept.
    margin: usize,
    width: usize,
    height: usize,
    channels: usize,
    cfg: FuseConfig,
    fuser: Fuser,
    frames: VecDeque<Held>,
    next_band: Option<i64>,
    previous: Before,
    summary: RollSummary,
    last_top: Option<i64>,
    /// Bands in a row no frame covered.
    gap_run: usize,
}

impl<S: StripSink> RollFuser<S> {
    /// A fuser for frames of `width × height` with `channels` planes. The window is
    /// clipped so that every band it holds, with its margins, lies inside the frame.
    pub fn new(
        sink: S,
        (width, height, channels): (usize, usize, usize),
        window: ContactWindow,
        bands: Bands,
        cfg: &FuseConfig,
        precision: Precision,
    ) -> crate::Result<Self> {
        rollfuse_io::require!(
            bands.band_rows >= 2
                && bands.blend_rows.is_multiple_of(2)
                && bands.blend_rows <= bands.band_rows,
            "bands of {} rows cannot be cross-faded over {} rows (an even number, at most the band)",
            bands.band_rows,
            bands.blend_rows
        );
        // db2's boundary extension reaches about three rows per level, doubling per level.
        let margin = bands.blend_rows / 2 + (3usize << cfg.levels);
        let region = bands.band_rows + 2 * margin;
        let reach = bands.band_rows / 2 + margin;
        if region > height {
            rollfuse_io::invalid!(
                "frames of {height} rows are too short for bands of {} rows with {} levels: \
                 use fewer levels or --band-rows",
                bands.band_rows,
                cfg.levels
            );
        }
        let top = window.top.max(reach).min(height - reach);
        let bottom = (window.top + window.rows).min(height - reach).max(top + 1);
        let window = ContactWindow {
            top,
            rows: bottom - top,
        };
        let dims = rollfuse_core::Dims::new(width, region)?;
        dims.check_levels(cfg.levels)?;
        Ok(Self {
            sink,
            window,
            bands,
            margin,
            width,
            height,
            channels,
            cfg: *cfg,
            fuser: Fuser::new(width, region, width, cfg, precision)?,
            frames: VecDeque::new(),
            next_band: None,
            previous: Before::Start,
            summary: RollSummary::default(),
            last_top: None,
            gap_run: 0,
        })
    }

    /// The window in use (after clipping).
    pub fn window(&self) -> ContactWindow {
        self.window
    }

    fn centre(&self, band: i64) -> i64 {
        band * self.bands.band_rows as i64 + self.bands.band_rows as i64 / 2
    }

    /// Belt row where the window of a frame at `top` starts.
    fn window_start(&self, top: i64) -> i64 {
        top + self.window.top as i64
    }

    /// Adds frame `index` with its pixel (0, 0) at belt row `top`, column `left` (the
    /// strip's columns are the first frame's; a frame shifted sideways is read with its
    /// edge columns repeated); fuses and writes every band it completes.
    pub fn push(
        &mut self,
        index: usize,
        (top, left): (i64, i64),
        image: Planes,
    ) -> crate::Result<()> {
        rollfuse_io::require!(
            (image.width, image.height, image.planes.len())
                == (self.width, self.height, self.channels),
            "frame {index} is {}×{} with {} channels; the roll's frames are {}×{} with {}",
            image.width,
            image.height,
            image.planes.len(),
            self.width,
            self.height,
            self.channels
        );
        self.summary.frames += 1;
        let band_rows = self.bands.band_rows as i64;
        if self.next_band.is_none() {
            // The first band whose centre the first window holds.
            let start = self.window_start(top) - band_rows / 2;
            self.next_band =
                Some(start.div_euclid(band_rows) + i64::from(start.rem_euclid(band_rows) != 0));
        }
        // A frame that went back along the belt still serves the bands to come, unless its
        // whole window is behind them.
        if let Some(b) = self.next_band
            && self.window_start(top) + self.window.rows as i64 <= self.centre(b)
        {
            self.summary.frames_behind += 1;
        }
        self.last_top = Some(self.last_top.map_or(top, |t| t.max(top)));
        self.frames.push_back(Held {
            index,
            top,
            left,
            image,
        });
        let ready_below = self.window_start(self.last_top.unwrap_or(top));
        while let Some(b) = self.next_band {
            if self.centre(b) >= ready_below {
                break;
            }
            self.fuse_band(b)?;
            self.next_band = Some(self.after(b));
            self.drop_spent();
        }
        Ok(())
    }

    /// Fuses the bands the last windows hold, writes the rest of the strip and returns the
    /// sink and the summary.
    pub fn finish(mut self) -> crate::Result<(S, RollSummary)> {
        if let (Some(mut b), Some(last)) = (self.next_band, self.last_top) {
            let end = self.window_start(last) + self.window.rows as i64;
            while self.centre(b) < end {
                self.fuse_band(b)?;
                b = self.after(b);
            }
            self.next_band = Some(b);
        }
        let half = (self.bands.blend_rows / 2) as i64;
        if let Some(b) = self.next_band.filter(|_| self.summary.bands > 0) {
            let end = b * self.bands.band_rows as i64;
            match std::mem::replace(&mut self.previous, Before::Start) {
                Before::Band(last) => self.write_from(Some(&last), end - half..end)?,
                Before::Gap => self.write_from(None, end - half..end)?,
                Before::Start => {}
            }
        }
        Ok((self.sink, self.summary))
    }

    /// The band to fuse after band `b`: the next, unless `b` ended a run of
    /// [`MAX_GAP_BANDS`] bands no frame covered; then the first band a held frame covers.
    fn after(&mut self, b: i64) -> i64 {
        if !matches!(self.previous, Before::Gap) {
            self.gap_run = 0;
            return b + 1;
        }
        self.gap_run += 1;
        let band_rows = self.bands.band_rows as i64;
        let margin = self.margin as i64;
        let resume = self
            .frames
            .iter()
            .map(|f| (f.top + margin).div_euclid(band_rows) + 1)
            .filter(|&r| r > b)
            .min();
        match resume {
            Some(r) if self.gap_run >= MAX_GAP_BANDS && r > b + 1 => {
                self.summary.bands_skipped += (r - b - 1) as u64;
                self.previous = Before::Start;
                self.gap_run = 0;
                r
            }
            _ => b + 1,
        }
    }

    /// Drops the frames no band to come can use, keeping the newest two for bands the
    /// windows skip.
    fn drop_spent(&mut self) {
        let Some(next) = self.next_band else { return };
        let c = self.centre(next);
        while self.frames.len() > 2 {
            let f = &self.frames[0];
            if self.window_start(f.top) + self.window.rows as i64 > c {
                break;
            }
            self.frames.pop_front();
        }
    }

    fn fuse_band(&mut self, b: i64) -> crate::Result<()> {
        let band_rows = self.bands.band_rows as i64;
        let c = self.centre(b);
        let region_top = b * band_rows - self.margin as i64;
        let region_rows = self.bands.band_rows + 2 * self.margin;
        let covers = |f: &Held| {
            f.top <= region_top && region_top + region_rows as i64 <= f.top + self.height as i64
        };
        let (start, rows) = (self.window.top as i64, self.window.rows as i64);
        let mut chosen: Vec<usize> = (0..self.frames.len())
            .filter(|&i| {
                let f = &self.frames[i];
                covers(f) && (f.top + start..f.top + start + rows).contains(&c)
            })
            .collect();
        if chosen.is_empty() {
            let centre_of = |f: &Held| f.top + start + rows / 2;
            if let Some(i) = (0..self.frames.len())
                .filter(|&i| covers(&self.frames[i]))
                .min_by_key(|&i| (centre_of(&self.frames[i]) - c).abs())
            {
                chosen.push(i);
                self.summary.bands_outside_window += 1;
            }
        }
        // From the window's edges toward its centre: the newest frame of a cyclic fusion
        // weighs most in the LL band (½ with the paper's weighting), so it is the one that
        // saw the band nearest the apex, deepest in contact. Ties in acquisition order.
        let from_apex = |f: &Held| (f.top + start + rows / 2 - c).abs();
        chosen.sort_by_key(|&i| {
            let f = &self.frames[i];
            (std::cmp::Reverse(from_apex(f)), f.index)
        });
        let band = if chosen.is_empty() {
            self.summary.gap_bands += 1;
            None
        } else {
            Some(Band {
                top: region_top,
                planes: self.fuse_region(region_top, &chosen)?,
            })
        };
        self.summary.bands += 1;
        let half = (self.bands.blend_rows / 2) as i64;
        let (band_top, band_end) = (b * band_rows, (b + 1) * band_rows);
        let zone = band_top - half..band_top + half;
        match (std::mem::replace(&mut self.previous, Before::Gap), &band) {
            (Before::Start, _) => self.write_from(band.as_ref(), band_top..zone.end)?,
            (Before::Band(prev), Some(cur)) => self.write_blend(&prev, cur, zone.clone())?,
            (Before::Band(prev), None) => {
                self.write_from(Some(&prev), zone.start..band_top)?;
                self.write_from(None, band_top..zone.end)?;
            }
            (Before::Gap, _) => {
                self.write_from(None, zone.start..band_top)?;
                self.write_from(band.as_ref(), band_top..zone.end)?;
            }
        }
        self.write_from(band.as_ref(), zone.end..band_end - half)?;
        self.previous = band.map_or(Before::Gap, Before::Band);
        Ok(())
    }

    /// Fuses the frames `chosen` (indices into `self.frames`, in acquisition order) over
    /// the `region_rows` rows from belt row `region_top`.
    fn fuse_region(&mut self, region_top: i64, chosen: &[usize]) -> crate::Result<Vec<Vec<f32>>> {
        let w = self.width;
        let region_rows = self.bands.band_rows + 2 * self.margin;
        let rows_of = |f: &Held, c: usize| -> Vec<f32> {
            let y0 = (region_top - f.top) as usize;
            let rows = &f.image.planes[c][y0 * w..(y0 + region_rows) * w];
            if f.left == 0 {
                return rows.to_vec();
            }
            // Strip column X is the frame's column X − left, edges repeated.
            let last = w as i64 - 1;
            rows.chunks_exact(w)
                .flat_map(|row| {
                    (0..w as i64).map(move |x| row[(x - f.left).clamp(0, last) as usize])
                })
                .collect()
        };
        let mut planes = Vec::with_capacity(self.channels);
        for c in 0..self.channels {
            let mut acc = rows_of(&self.frames[chosen[0]], c);
            for (n, &i) in chosen.iter().enumerate().skip(1) {
                let mut next = rows_of(&self.frames[i], c);
                let ll = LlWeight::for_frame(self.cfg.ll_weighting, n as u32 + 1);
                self.fuser
                    .fuse_into(&mut acc, FrameRef::Spent(&mut next), ll)?;
            }
            planes.push(acc);
        }
        Ok(planes)
    }

    /// Writes belt rows `range` from `band`, or zeros where there is none (a gap).
    fn write_from(
        &mut self,
        band: Option<&Band>,
        range: std::ops::Range<i64>,
    ) -> crate::Result<()> {
        let w = self.width;
        let zeros = vec![0f32; w];
        for row in range {
            let views: Vec<&[f32]> = match band {
                Some(band) => {
                    let o = (row - band.top) as usize * w;
                    band.planes.iter().map(|p| &p[o..o + w]).collect()
                }
                None => (0..self.channels).map(|_| zeros.as_slice()).collect(),
            };
            self.sink.row(row, &views)?;
            self.summary.rows += 1;
        }
        Ok(())
    }

    /// Writes belt rows `zone` cross-faded from `band` into `next`, the weight of `next`
    /// rising linearly across the zone.
    fn write_blend(
        &mut self,
        band: &Band,
        next: &Band,
        zone: std::ops::Range<i64>,
    ) -> crate::Result<()> {
        let w = self.width;
        let blend = (zone.end - zone.start) as f32;
        let mut mixed = vec![vec![0f32; w]; self.channels];
        for row in zone.clone() {
            let t = ((row - zone.start) as f32 + 0.5) / blend;
            let (oa, ob) = ((row - band.top) as usize * w, (row - next.top) as usize * w);
            for (c, out) in mixed.iter_mut().enumerate() {
                let (a, b) = (&band.planes[c][oa..oa + w], &next.planes[c][ob..ob + w]);
                for ((o, &a), &b) in out.iter_mut().zip(a).zip(b) {
                    *o = a + t * (b - a);
                }
            }
            let views: Vec<&[f32]> = mixed.iter().map(Vec::as_slice).collect();
            self.sink.row(row, &views)?;
            self.summary.rows += 1;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Records the belt rows it is given.
    #[derive(Default)]
    struct Rows(Vec<i64>);

    impl StripSink for Rows {
        fn row(&mut self, row: i64, _: &[&[f32]]) -> anyhow::Result<()> {
            self.0.push(row);
            Ok(())
        }
    }

    fn flat(w: usize, h: usize) -> Planes {
        Planes {
            width: w,
            height: h,
            planes: vec![vec![100.0; w * h]],
        }
    }

    #[test]
    fn a_jump_of_the_belt_is_passed_over_not_filled() {
        let (w, h) = (16, 96);
        let window = ContactWindow { top: 28, rows: 40 };
        let mut fuser = RollFuser::new(
            Rows::default(),
            (w, h, 1),
            window,
            Bands::default(),
            &FuseConfig::default(),
            Precision::F32,
        )
        .unwrap();
        let tops = [0i64, 4, 8, 1_000_000_000, 1_000_000_004];
        for (k, &top) in tops.iter().enumerate() {
            fuser.push(k, (top, 0), flat(w, h)).unwrap();
        }
        let (rows, summary) = fuser.finish().unwrap();
        // A few hundred rows, in two runs, none of the billion between.
        assert!(rows.0.len() < 1000, "{} rows", rows.0.len());
        assert!(summary.bands_skipped > 1000, "{summary:?}");
        let jumps = rows.0.windows(2).filter(|p| p[1] != p[0] + 1).count();
        assert_eq!(jumps, 1, "{:?}", rows.0);
        assert!(
            rows.0.windows(2).all(|p| p[1] > p[0]),
            "rows only go forward"
        );
    }
}
