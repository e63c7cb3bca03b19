//! The streaming tile model: camera frames in, fused tiles out, in fixed memory.
//!
//! Belt space (downsampled rows, 0 = the first frame's top row) is cut into tiles of
//! `tile_rows` rows across the whole belt width; tile `t` covers belt rows
//! `t·T .. (t+1)·T`. Frame `k` lies at belt offset `o_k` (its row `y` shows belt row
//! `o_k + y`), found from the commanded motion and refined ([`super::refine`]).
//!
//! Only the middle of each frame is used: the *observation window* of
//! `n·s + T − 1` rows centred on the roller's apex, `n` being the frames per tile and `s`
//! the nominal frame spacing in rows. Only the window is downsampled, and the shift
//! refinement's row profile and the per-frame saliency normalization (the largest
//! Laplacian) are taken over it: the camera rows outside it are never read (at the default
//! configuration the window is 47 of 120 rows). A tile is observed by a frame when it lies
//! wholly in that window — with exact motion, by exactly `n` consecutive frames, from below
//! the apex to above it. Each observation is fused into the tile's running result on the
//! integer path ([`crate::fusion::fuse_u8`], the LL band weighted as configured); the
//! tile is emitted, with its belt index and observation count, as soon as a frame
//! arrives in which it has left the window (offsets only grow, so none can see it again),
//! or when the run ends ([`Pipeline::finish`]).
//!
//! Memory is the caller's ([`PipelineBuffers`]), sized by [`PipelineConfig::memory`].

use super::downsample::{downsample_rows_profiled, downsampled_dims};
use super::refine::{SUBROWS, profile_len, refine_shift};
use crate::float;
use crate::fusion::{ImagePair, LlWeight, U8Pair, U8Work, fuse_scratch_words, fuse_u8};
use crate::protocol::{DeviceConfig, NakReason, NormMode, PixelFormat, Tile, WaveletId};
use crate::saliency::laplacian_max_u8;
use crate::{Ablation, Dims, Error, FuseConfig, LlWeighting, SaliencyNorm, Wavelet};

/// Tiles in fusion at once, at most.
pub const MAX_ACTIVE_TILES: usize = 16;

/// The most observations a tile may be configured to fuse.
pub const MAX_FRAMES_PER_TILE: usize = 16;

/// The largest refinement search, rows either side.
pub const MAX_REFINE_ROWS: usize = 16;

/// The arithmetic that fuses: on the device (whose tiles are 8-bit either way) and on the
/// host's full-resolution path alike.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Precision {
    /// The integer path ([`crate::fusion::fuse_u8`]) on 8-bit data: what the firmware runs.
    #[default]
    Fixed,
    /// The `f32` path ([`crate::float::fuse_pair`]): the host's default, and on the MCU its
    /// FPU.
    F32,
}

/// The camera: frame size and pixel format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Sensor {
    /// Frame width, pixels.
    pub width: usize,
    /// Frame height, pixels.
    pub height: usize,
    /// Pixel format.
    pub format: PixelFormat,
}

impl Sensor {
    /// Bytes of one camera frame.
    pub const fn frame_bytes(&self) -> usize {
        self.width * self.height * self.format.bytes_per_pixel()
    }
}

/// A validated pipeline configuration: made only by [`PipelineConfig::from_wire`], read
/// through its getters, so every value in it is one that validation accepted and no
/// computation on it (memory, schedule) can divide by zero or underflow.
///
/// ```
/// use rollfuse_core::device::{CAMERA, PipelineConfig};
/// use rollfuse_core::protocol::DeviceConfig;
///
/// let cfg = PipelineConfig::from_wire(&DeviceConfig::default(), CAMERA).unwrap();
/// assert_eq!(cfg.downsample(), 1);
/// assert_eq!(cfg.memory().total_bytes(), 120_520);
/// ```
///
/// A validated configuration cannot be changed out of range afterwards:
///
/// ```compile_fail,E0616
/// use rollfuse_core::device::{CAMERA, PipelineConfig};
/// use rollfuse_core::protocol::DeviceConfig;
///
/// let mut cfg = PipelineConfig::from_wire(&DeviceConfig::default(), CAMERA).unwrap();
/// cfg.downsample = 0;
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PipelineConfig {
    /// The camera.
    sensor: Sensor,
    /// Wavelet, levels, LL weighting (normalization is set per frame or per tile).
    fuse: FuseConfig,
    /// Saliency normalized per frame (else per tile).
    per_frame_norm: bool,
    /// Box downsampling factor: 1, 2 or 4.
    downsample: usize,
    /// Tile height, downsampled rows.
    tile_rows: usize,
    /// Observations per tile.
    frames_per_tile: usize,
    /// Nominal belt travel between frames, camera pixels.
    spacing_px: usize,
    /// Refinement search, ± downsampled rows.
    refine_rows: usize,
    /// The arithmetic of the fuse step. The wire has no field for it: a device runs
    /// [`Precision::Fixed`]; the host's trade-off study and the Cortex-M7 bench set
    /// [`Precision::F32`] to measure the alternative.
    precision: Precision,
    /// The downsampled frame.
    frame: Dims,
    /// One tile.
    tile: Dims,
}

/// The caller-owned memory a pipeline needs, by [`PipelineConfig::memory`]:
///
/// - `frame`: the downsampled observation window, `W·(n·s + T − 1)` bytes;
/// - `tiles`: the tiles in fusion, `A·T·W` bytes with `A` = [`PipelineConfig::active_tiles`]
///   `= ⌈(n·s + T − 1)/T⌉ + 1`;
/// - `work`: two fusion work images and the fusion scratch, `2·T·W +`
///   [`fuse_scratch_words`]`(W, T)` words;
/// - `profiles`: this frame's and the previous frame's row profiles (of the window),
///   `2·(n·s + T − 2)·B` words, `B` = [`PROFILE_BANDS`](super::refine::PROFILE_BANDS).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Memory {
    /// Bytes of `frame`.
    pub frame_bytes: usize,
    /// Bytes of `tiles`.
    pub tile_bytes: usize,
    /// Words (`i32`) of `work`.
    pub work_words: usize,
    /// Words (`i32`) of `profiles`.
    pub profile_words: usize,
}

impl Memory {
    /// Whether every buffer this much memory needs fits in `capacity`'s.
    pub const fn fits(&self, capacity: &Memory) -> bool {
        self.frame_bytes <= capacity.frame_bytes
            && self.tile_bytes <= capacity.tile_bytes
            && self.work_words <= capacity.work_words
            && self.profile_words <= capacity.profile_words
    }

    /// Everything, in bytes.
    pub const fn total_bytes(&self) -> usize {
        self.frame_bytes + self.tile_bytes + 4 * (self.work_words + self.profile_words)
    }
}

impl PipelineConfig {
    /// Validates a configuration from the host for `sensor`; a value out of range is
    /// refused with the reason the device sends back.
    pub fn from_wire(cfg: &DeviceConfig, sensor: Sensor) -> Result<Self, NakReason> {
        let frame = downsampled_dims(sensor.width, sensor.height, usize::from(cfg.downsample))
            .map_err(|_| NakReason::Downsample)?;
        let (w, h) = (frame.width(), frame.height());
        let t = usize::from(cfg.tile_rows);
        if t == 0 || t > h || w * t > crate::protocol::MAX_TILE_BYTES {
            return Err(NakReason::TileRows);
        }
        let tile = Dims::new(w, t).map_err(|_| NakReason::TileRows)?;
        tile.check_levels(cfg.levels)
            .map_err(|_| NakReason::Levels)?;
        let spacing = usize::from(cfg.frame_spacing_px);
        if spacing == 0 || spacing > sensor.height {
            return Err(NakReason::FrameSpacing);
        }
        if usize::from(cfg.refine_rows) > MAX_REFINE_ROWS {
            return Err(NakReason::RefineRows);
        }
        let out = Self {
            sensor,
            fuse: FuseConfig {
                wavelet: match cfg.wavelet {
                    WaveletId::Haar => Wavelet::Haar,
                    WaveletId::Db2 => Wavelet::Db2,
                },
                levels: cfg.levels,
                ablation: Ablation::None,
                norm: SaliencyNorm::Local,
                // The paper's pairwise mean, as `rollfuse fuse` does by default.
                ll_weighting: LlWeighting::Paper,
            },
            per_frame_norm: cfg.norm == NormMode::PerFrame,
            downsample: usize::from(cfg.downsample),
            tile_rows: t,
            frames_per_tile: usize::from(cfg.frames_per_tile),
            spacing_px: spacing,
            refine_rows: usize::from(cfg.refine_rows),
            precision: Precision::Fixed,
            frame,
            tile,
        };
        let n = out.frames_per_tile;
        if n == 0 || n > MAX_FRAMES_PER_TILE || out.window_rows() > h {
            return Err(NakReason::FramesPerTile);
        }
        if out.active_tiles() > MAX_ACTIVE_TILES {
            return Err(NakReason::FramesPerTile);
        }
        Ok(out)
    }

    /// The same configuration with the fuse step's arithmetic set to `precision` (the
    /// wire's configurations run [`Precision::Fixed`]). The memory it needs changes with
    /// it: [`Self::memory`].
    pub fn with_precision(self, precision: Precision) -> Self {
        Self { precision, ..self }
    }

    /// The camera.
    pub fn sensor(&self) -> Sensor {
        self.sensor
    }

    /// Wavelet, levels, LL weighting (normalization is set per frame or per tile).
    pub fn fuse(&self) -> FuseConfig {
        self.fuse
    }

    /// Saliency normalized per frame (else per tile).
    pub fn per_frame_norm(&self) -> bool {
        self.per_frame_norm
    }

    /// Box downsampling factor: 1, 2 or 4.
    pub fn downsample(&self) -> usize {
        self.downsample
    }

    /// Tile height, downsampled rows (at least 1).
    pub fn tile_rows(&self) -> usize {
        self.tile_rows
    }

    /// Observations per tile (1 to [`MAX_FRAMES_PER_TILE`]).
    pub fn frames_per_tile(&self) -> usize {
        self.frames_per_tile
    }

    /// Nominal belt travel between frames, camera pixels (1 to the sensor's height).
    pub fn spacing_px(&self) -> usize {
        self.spacing_px
    }

    /// Refinement search, ± downsampled rows (at most [`MAX_REFINE_ROWS`]).
    pub fn refine_rows(&self) -> usize {
        self.refine_rows
    }

    /// The arithmetic of the fuse step.
    pub fn precision(&self) -> Precision {
        self.precision
    }

    /// The downsampled frame size.
    pub fn frame_dims(&self) -> Dims {
        self.frame
    }

    /// The observation window's band of the downsampled frame: its width by
    /// [`Self::window_rows`] (what the pipeline downsamples, profiles and normalizes by).
    pub fn window_dims(&self) -> Dims {
        // `from_wire` checked the window fits the frame; the fallback is never taken.
        Dims::new(self.frame.width(), self.window_rows()).unwrap_or(self.frame)
    }

    /// The size of one tile: the frame's width by `tile_rows`.
    pub fn tile_dims(&self) -> Dims {
        self.tile
    }

    /// Nominal frame spacing in downsampled rows (at least 1).
    pub fn spacing_rows(&self) -> usize {
        (self.spacing_px / self.downsample).max(1)
    }

    /// Which tiles each frame observes.
    pub fn schedule(&self) -> Schedule {
        Schedule::new(
            self.frame_dims().height(),
            self.tile_rows,
            self.frames_per_tile,
            self.spacing_rows(),
        )
    }

    /// Height of the observation window, rows: `n·s + T − 1`.
    pub fn window_rows(&self) -> usize {
        self.schedule().window_rows
    }

    /// Tiles in fusion at once, at most: `⌈(n·s + T − 1)/T⌉ + 1` (tiles are emitted
    /// before a frame's observations, so only tiles starting inside the window are held).
    pub fn active_tiles(&self) -> usize {
        self.window_rows().div_ceil(self.tile_rows) + 1
    }

    /// The memory a pipeline of this configuration needs.
    pub fn memory(&self) -> Memory {
        let d = self.window_dims();
        let (w, h, t) = (d.width(), d.height(), self.tile_rows);
        Memory {
            frame_bytes: w * h,
            tile_bytes: self.active_tiles() * t * w,
            work_words: 2 * t * w
                + match self.precision {
                    Precision::Fixed => fuse_scratch_words(w, t),
                    Precision::F32 => float::fuse_scratch_len(self.tile),
                },
            profile_words: 2 * profile_len(h),
        }
    }
}

/// The tile schedule: which tiles of belt space a frame at belt offset `o` observes (those
/// wholly inside its observation window, rows `o + top .. o + top + window`), at any
/// resolution — the pipeline's, or full resolution for the host's reference fusion.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Schedule {
    /// Tile height `T`, rows.
    pub tile_rows: usize,
    /// First frame row of the window.
    pub window_top: usize,
    /// Window height `n·s + T − 1`, rows. It may exceed the frame's height; then the
    /// window starts at row 0 and the tiles beyond the frame are not observable
    /// ([`PipelineConfig::from_wire`] refuses such configurations).
    pub window_rows: usize,
}

impl Schedule {
    /// The window of `frames_per_tile` (`n`) frames `spacing_rows` (`s`) apart, centred on
    /// a frame of `frame_rows`; `tile_rows` is raised to 1 at least.
    pub fn new(
        frame_rows: usize,
        tile_rows: usize,
        frames_per_tile: usize,
        spacing_rows: usize,
    ) -> Self {
        let tile_rows = tile_rows.max(1);
        let window_rows = frames_per_tile
            .saturating_mul(spacing_rows)
            .saturating_add(tile_rows - 1);
        Self {
            tile_rows,
            window_top: frame_rows.saturating_sub(window_rows) / 2,
            window_rows,
        }
    }

    /// Tiles a frame at belt `offset` observes: `t·T ≥ top` and `t·T + T ≤ bottom`.
    pub fn observed(&self, offset: u64) -> core::ops::Range<u64> {
        let t = self.tile_rows as u64;
        let top = offset + self.window_top as u64;
        let first = top.div_ceil(t);
        first..((top + self.window_rows as u64) / t).max(first)
    }

    /// Whether tile `index` starts above the window of a frame at `offset` (offsets only
    /// grow, so no later frame observes it).
    pub fn is_done(&self, index: u64, offset: u64) -> bool {
        index * (self.tile_rows as u64) < offset + self.window_top as u64
    }

    /// The frame rows the tiles a frame at `offset` observes cover (they are adjacent: one
    /// band; empty if it observes none). Per-frame normalization takes the maximum
    /// Laplacian over these rows: the window's others are fused into nothing that frame.
    pub fn observed_rows(&self, offset: u64) -> core::ops::Range<usize> {
        let tiles = self.observed(offset);
        self.frame_row(tiles.start, offset)..self.frame_row(tiles.end, offset)
    }

    /// The frame row where tile `index` (one of [`Self::observed`]) starts.
    pub fn frame_row(&self, index: u64, offset: u64) -> usize {
        (index * self.tile_rows as u64).saturating_sub(offset) as usize
    }
}

/// The caller's memory for a [`Pipeline`]; see [`Memory`] for the sizes.
pub struct PipelineBuffers<'a> {
    /// The downsampled frame.
    pub frame: &'a mut [u8],
    /// The tiles in fusion.
    pub tiles: &'a mut [u8],
    /// Fusion work images and scratch.
    pub work: &'a mut [i32],
    /// Row profiles.
    pub profiles: &'a mut [i32],
}

impl PipelineBuffers<'_> {
    /// Fails, naming the first buffer too small, unless each holds what `needed` says.
    fn check(&self, needed: &Memory) -> Result<(), Error> {
        for (which, needed, got) in [
            ("frame", needed.frame_bytes, self.frame.len()),
            ("tiles", needed.tile_bytes, self.tiles.len()),
            ("work", needed.work_words, self.work.len()),
            ("profiles", needed.profile_words, self.profiles.len()),
        ] {
            if got < needed {
                return Err(Error::BufferTooSmall { which, needed, got });
            }
        }
        Ok(())
    }
}

/// A tile in fusion.
#[derive(Debug, Clone, Copy)]
struct Slot {
    index: u64,
    observations: u8,
}

/// What one frame did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameReport {
    /// The frame's belt offset, downsampled rows.
    pub offset: u64,
    /// The shift from the previous frame that refinement chose.
    pub shift: i64,
    /// Tiles this frame observed.
    pub observed: usize,
    /// Tiles it completed.
    pub emitted: usize,
}

/// Why a frame was refused (the pipeline's state is unchanged).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameError {
    /// The frame buffer is not one camera frame.
    Size(Error),
    /// The belt moved backwards.
    Backwards,
    /// [`Pipeline::fuse_taken`] without a frame taken since the last fusion.
    NothingTaken,
}

/// Variance of a matched step's error, 1/1024 row²: about 0.1 row (root mean square) on
/// the built-in scenes rolled as `rollfuse eval --roll` rolls them.
pub const STEP_VARIANCE: u64 = 10;

/// Variance of a commanded position's error, 1/1024 camera pixel²: the belt's unknown
/// error of up to ±2 px a frame, uniform (4/3 px²), that the simulator's `jitter` models.
pub const COMMANDED_VARIANCE_PX: u64 = 1365;

/// Where the frames lie on the belt: each frame's place predicted from the last by the
/// matched step, then drawn toward its commanded position by how sure each is (a
/// Kalman filter of one state: the matched steps carry no error of the belt's own but
/// add up theirs, [`STEP_VARIANCE`] a step; the commanded positions carry the belt's
/// error, [`COMMANDED_VARIANCE_PX`], but do not drift). A frame no match refines is
/// placed where commanded. A frame's offset is its commanded row moved by the filter's
/// correction (place minus commanded position) in whole rows, never moving back.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Track {
    /// The first frame's commanded position, camera pixels.
    origin_px: u64,
    /// The last frame's commanded position, camera pixels.
    commanded_at: u64,
    /// The last frame's place, sixteenths of a row.
    place: i64,
    /// Its variance, 1/1024 row².
    variance: u64,
    /// A commanded position's variance, 1/1024 row².
    commanded_variance: u64,
    /// Camera pixels a row.
    downsample: u64,
    /// The last offset handed out, rows.
    offset: u64,
}

impl Track {
    /// The first frame, at `position_px`, rows `downsample` camera pixels tall: where
    /// commanded.
    fn start(position_px: u64, downsample: u64) -> Self {
        let commanded_variance = COMMANDED_VARIANCE_PX / (downsample * downsample).max(1);
        Self {
            origin_px: position_px,
            commanded_at: position_px,
            place: 0,
            variance: commanded_variance,
            commanded_variance: commanded_variance.max(1),
            downsample: downsample.max(1),
            offset: 0,
        }
    }

    /// The next frame, `step` sixteenths of a row after the last if a match measured it,
    /// commanded to `position_px`, `commanded_rows` whole rows from the first: its offset
    /// and the rows it moved on from the last.
    fn follow(&mut self, step: Option<i64>, commanded_rows: i64, position_px: u64) -> (u64, i64) {
        // The commanded position itself, unrounded: sixteenths are whole for every factor.
        let since_start_px = (position_px as i64).saturating_sub(self.origin_px as i64);
        let commanded = since_start_px.saturating_mul(SUBROWS) / self.downsample as i64;
        (self.place, self.variance) = match step {
            Some(step) => {
                let predicted = self.place.saturating_add(step);
                let variance = self.variance.saturating_add(STEP_VARIANCE);
                let total = variance.saturating_add(self.commanded_variance);
                // The gain `variance / total` in 1/1024: the correction's product stays
                // far inside i64 (an innovation of a few rows, in sixteenths).
                let gain = ((variance << 10) / total) as i64;
                let innovation = commanded.saturating_sub(predicted);
                // Rounded to the nearest sixteenth: rounded down, every frame would lose
                // half a sixteenth, which the small gain lets add up to half a row.
                let correction = innovation
                    .saturating_mul(gain)
                    .saturating_add(1 << 9)
                    .div_euclid(1 << 10);
                let left = variance.saturating_mul(self.commanded_variance) / total;
                (predicted.saturating_add(correction), left)
            }
            None => (commanded, self.commanded_variance),
        };
        // The commanded row moved by the filter's correction in whole rows: where the
        // filter agrees with the command, the command's own rounding of a fractional
        // spacing (2.5 rows: 0, 3, 5, 8, …) stays, so the tiles see the frames the
        // schedule plans.
        let correction = self
            .place
            .saturating_sub(commanded)
            .saturating_add(SUBROWS / 2)
            .div_euclid(SUBROWS);
        let rows = commanded_rows.saturating_add(correction).max(0) as u64;
        let offset = rows.max(self.offset);
        let moved = (offset - self.offset) as i64;
        self.offset = offset;
        self.commanded_at = position_px;
        (offset, moved)
    }
}

/// The device pipeline: frames in, fused tiles out.
pub struct Pipeline<'a> {
    cfg: PipelineConfig,
    bufs: PipelineBuffers<'a>,
    slots: [Option<Slot>; MAX_ACTIVE_TILES],
    /// Where the frames so far lie ([`Track`]).
    track: Option<Track>,
    /// Which half of `profiles` holds the previous frame's.
    previous_profile_first: bool,
    /// The size of the band [`Pipeline::take_frame`] took and no fusion used yet.
    taken: Option<Dims>,
}

impl<'a> Pipeline<'a> {
    /// A pipeline on the caller's buffers; fails if one is smaller than
    /// [`PipelineConfig::memory`] says.
    pub fn new(cfg: PipelineConfig, bufs: PipelineBuffers<'a>) -> Result<Self, Error> {
        bufs.check(&cfg.memory())?;
        Ok(Self {
            cfg,
            bufs,
            slots: [None; MAX_ACTIVE_TILES],
            track: None,
            previous_profile_first: true,
            taken: None,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &PipelineConfig {
        &self.cfg
    }

    /// Serves `cfg` from now on, on the same memory, as a new pipeline would: tiles still
    /// in fusion are dropped, so [`Self::finish`] first. Fails, keeping the configuration
    /// in force, if a buffer is smaller than `cfg` needs.
    pub fn reconfigure(&mut self, cfg: PipelineConfig) -> Result<(), Error> {
        self.bufs.check(&cfg.memory())?;
        self.cfg = cfg;
        self.slots = [None; MAX_ACTIVE_TILES];
        self.track = None;
        self.previous_profile_first = true;
        self.taken = None;
        Ok(())
    }

    /// Gives the caller's memory back (e.g. to build a pipeline of another configuration
    /// on it); tiles still in fusion are dropped, so [`Self::finish`] first.
    pub fn into_buffers(self) -> PipelineBuffers<'a> {
        self.bufs
    }

    /// Takes one camera frame, taken when the commanded belt position was `position_px`
    /// camera pixels from the start of the run, and calls `emit` for every tile it
    /// completes, in belt order: [`Self::take_frame`] then [`Self::fuse_taken`].
    pub fn push_frame(
        &mut self,
        camera: &[u8],
        position_px: u64,
        emit: impl FnMut(Tile<'_>),
    ) -> Result<FrameReport, FrameError> {
        self.take_frame(camera)?;
        self.fuse_taken(position_px, emit)
    }

    /// The first half of [`Self::push_frame`]: converts the frame's window band (and its
    /// row profile) out of `camera` into the pipeline's memory. From its return on the
    /// camera's buffer is not read again, so the next capture may fill it while
    /// [`Self::fuse_taken`] runs. A frame taken and not fused is replaced by the next.
    pub fn take_frame(&mut self, camera: &[u8]) -> Result<(), FrameError> {
        self.taken = None;
        let cfg = self.cfg;
        let schedule = cfg.schedule();
        let window = schedule.window_top..schedule.window_top + schedule.window_rows;
        let p = profile_len(window.len());
        let (_, current) = profile_halves(self.bufs.profiles, p, self.previous_profile_first)?;
        // The band and its row profile, the profile's sums taken while converting at 1×;
        // `downsample_rows_profiled` checks the band fits the frame.
        let dims = downsample_rows_profiled(
            camera,
            cfg.sensor.format,
            (cfg.sensor.width, cfg.sensor.height),
            cfg.downsample,
            window,
            self.bufs.frame,
            current,
        )
        .map_err(FrameError::Size)?;
        self.taken = Some(dims);
        Ok(())
    }

    /// The second half of [`Self::push_frame`]: fuses the frame [`Self::take_frame`] took,
    /// at commanded belt position `position_px`, calling `emit` for every tile it
    /// completes, in belt order.
    pub fn fuse_taken(
        &mut self,
        position_px: u64,
        mut emit: impl FnMut(Tile<'_>),
    ) -> Result<FrameReport, FrameError> {
        let dims = self.taken.take().ok_or(FrameError::NothingTaken)?;
        let cfg = self.cfg;
        let schedule = cfg.schedule();
        let f = cfg.downsample as u64;
        let p = profile_len(schedule.window_rows);
        let (previous, current) =
            profile_halves(self.bufs.profiles, p, self.previous_profile_first)?;
        let (offset, shift) = match &mut self.track {
            None => {
                self.track = Some(Track::start(position_px, f));
                (0, 0)
            }
            Some(track) => {
                // Commanded rows since the last frame, rounded on the absolute positions
                // so rounding does not accumulate.
                let rows = |px: u64| (px + f / 2) / f;
                let commanded = rows(position_px) as i64 - rows(track.commanded_at) as i64;
                let refined = (cfg.refine_rows > 0)
                    .then(|| refine_shift(previous, current, commanded, cfg.refine_rows as u32))
                    .flatten();
                let step = match refined {
                    // Within a quarter row of the commanded shift is the sensor's noise:
                    // exact motion stays exact.
                    Some(step) if (step - commanded * SUBROWS).abs() <= SUBROWS / 4 => {
                        Some(commanded * SUBROWS)
                    }
                    Some(step) => Some(step.max(0)),
                    None if commanded >= 0 => None,
                    None => return Err(FrameError::Backwards),
                };
                let since_start = rows(position_px) as i64 - rows(track.origin_px) as i64;
                track.follow(step, since_start, position_px)
            }
        };
        self.previous_profile_first = !self.previous_profile_first;

        // Tiles above the window are done: no later frame can see them. Emitting them
        // first bounds the tiles held to those starting inside the window.
        let emitted = self.emit_where(|index| schedule.is_done(index, offset), &mut emit);
        let observed = schedule.observed(offset);
        // Rows of the window band: each observed tile lies wholly in the window.
        let band_row = |index| {
            schedule
                .frame_row(index, offset)
                .saturating_sub(schedule.window_top)
        };
        let norm = if cfg.per_frame_norm {
            let rows = schedule.observed_rows(offset);
            let top = schedule.window_top;
            let rows = rows.start.saturating_sub(top)..rows.end.saturating_sub(top);
            let w = dims.width();
            let covered = Dims::new(w, rows.len()).ok();
            let band = covered.zip(self.bufs.frame.get(rows.start * w..rows.end * w));
            SaliencyNorm::Reference(band.map_or(0, |(d, band)| laplacian_max_u8(band, d)))
        } else {
            SaliencyNorm::Local
        };
        let fuse_cfg = FuseConfig { norm, ..cfg.fuse };
        for index in observed.clone() {
            self.observe(index, band_row(index), &fuse_cfg);
        }
        Ok(FrameReport {
            offset,
            shift,
            observed: (observed.end - observed.start) as usize,
            emitted,
        })
    }

    /// Emits every tile still in fusion, in belt order (the end of a run).
    pub fn finish(&mut self, mut emit: impl FnMut(Tile<'_>)) -> usize {
        let n = self.emit_where(|_| true, &mut emit);
        self.track = None;
        self.taken = None;
        n
    }

    /// Fuses rows `row ..` of the current window band into tile `index`.
    fn observe(&mut self, index: u64, row: usize, cfg: &FuseConfig) {
        let (t, dims) = (self.cfg.tile_rows, self.cfg.tile);
        let w = dims.width();
        let n = t * w;
        let slot_no = match self
            .slots
            .iter()
            .position(|s| s.is_some_and(|s| s.index == index))
        {
            Some(k) => k,
            None => match self.slots.iter().position(Option::is_none) {
                Some(k) => k,
                // Cannot happen: the window holds at most `active_tiles` tiles, and a
                // tile leaves before a new frame's tiles arrive. Dropping it is safe.
                None => return,
            },
        };
        let Some(tile) = self.bufs.tiles.get_mut(slot_no * n..(slot_no + 1) * n) else {
            return;
        };
        let Some(src) = self.bufs.frame.get(row * w..(row + t) * w) else {
            return;
        };
        let Some(slot) = self.slots.get_mut(slot_no) else {
            return;
        };
        let observations = slot.map_or(0, |s| s.observations);
        if observations == 0 {
            tile.copy_from_slice(src);
        } else {
            let ll = LlWeight::for_frame(cfg.ll_weighting, u32::from(observations) + 1);
            // Sizes were validated with the configuration; should this fail, the tile
            // keeps its previous observations.
            let fused = match self.cfg.precision {
                Precision::Fixed => fuse_tile_fixed(tile, src, dims, cfg, ll, self.bufs.work),
                Precision::F32 => fuse_tile_f32(tile, src, dims, cfg, ll, self.bufs.work),
            };
            if fused.is_err() {
                return;
            }
        }
        *slot = Some(Slot {
            index,
            observations: observations.saturating_add(1),
        });
    }

    /// Emits, in belt order, and frees every tile whose index passes `done`.
    fn emit_where(&mut self, done: impl Fn(u64) -> bool, emit: &mut impl FnMut(Tile<'_>)) -> usize {
        let w = self.cfg.frame_dims().width();
        let t = self.cfg.tile_rows;
        let mut count = 0;
        loop {
            let next = self
                .slots
                .iter()
                .enumerate()
                .filter_map(|(k, s)| s.filter(|s| done(s.index)).map(|s| (k, s)))
                .min_by_key(|(_, s)| s.index);
            let Some((k, slot)) = next else {
                return count;
            };
            // `k` came from enumerating the slots.
            let Some(freed) = self.slots.get_mut(k) else {
                return count;
            };
            *freed = None;
            if let Some(pixels) = self.bufs.tiles.get(k * t * w..(k + 1) * t * w) {
                emit(Tile {
                    index: slot.index as u32,
                    width: w as u16,
                    height: t as u16,
                    observations: slot.observations,
                    pixels,
                });
                count += 1;
            }
        }
    }
}

/// The previous frame's row profile and the current frame's, `p` words each, in the halves
/// of `profiles` that `previous_first` names.
fn profile_halves(
    profiles: &mut [i32],
    p: usize,
    previous_first: bool,
) -> Result<(&mut [i32], &mut [i32]), FrameError> {
    // `Pipeline::new` checked the profiles hold two of `p` words (`cfg.memory()`).
    let error = FrameError::Size(Error::BufferTooSmall {
        which: "profiles",
        needed: 2 * p,
        got: profiles.len(),
    });
    let (first, second) = profiles.split_at_mut_checked(p).ok_or(error)?;
    let second = second.get_mut(..p).ok_or(error)?;
    Ok(if previous_first {
        (first, second)
    } else {
        (second, first)
    })
}

/// Fuses observation `src` into `tile` on the integer path; `work` holds the two work
/// images and the scratch ([`PipelineConfig::memory`]).
fn fuse_tile_fixed(
    tile: &mut [u8],
    src: &[u8],
    dims: Dims,
    cfg: &FuseConfig,
    ll: LlWeight,
    work: &mut [i32],
) -> Result<(), Error> {
    let n = dims.pixels();
    let (wa, rest) = work.split_at_mut(n.min(work.len()));
    let (wb, scratch) = rest.split_at_mut(n.min(rest.len()));
    let work = U8Work {
        a: wa,
        b: wb,
        scratch,
    };
    fuse_u8(U8Pair::same(tile, src, dims), cfg, ll, work)
}

/// [`fuse_tile_fixed`] on the `f32` path: the tiles stay 8-bit, the step runs in `f32`
/// on the same work words (an `f32` is one word) and rounds back.
fn fuse_tile_f32(
    tile: &mut [u8],
    src: &[u8],
    dims: Dims,
    cfg: &FuseConfig,
    ll: LlWeight,
    work: &mut [i32],
) -> Result<(), Error> {
    let n = dims.pixels();
    let work: &mut [f32] = bytemuck::cast_slice_mut(work);
    let (fa, rest) = work.split_at_mut(n.min(work.len()));
    let (fb, scratch) = rest.split_at_mut(n.min(rest.len()));
    for (dst, src) in [(&mut *fa, &*tile), (&mut *fb, src)] {
        for (d, &v) in dst.iter_mut().zip(src) {
            *d = f32::from(v);
        }
    }
    let images = ImagePair {
        a: &mut *fa,
        b: fb,
        dims,
    };
    float::fuse_pair_of_bytes(images, cfg, ll, scratch)?;
    for (d, &v) in tile.iter_mut().zip(fa.iter()) {
        *d = round_to_byte(v);
    }
    Ok(())
}

/// `v` rounded half up to a byte, saturating: `as` truncates toward zero and saturates
/// (below 0 and NaN to 0, above 255 to 255), so adding ½ first rounds, with no clamp
/// needed (`f32::round` needs std).
#[inline(always)]
fn round_to_byte(v: f32) -> u8 {
    (v + 0.5) as u8
}

#[cfg(test)]
mod tests {
    use super::round_to_byte;

    /// Rounding half up needs no clamp: `as` saturates, so every value gives the byte
    /// clamping first would, from far below 0 to far above 255, the halves, NaN and the
    /// infinities included.
    #[test]
    fn rounding_to_a_byte_saturates_as_a_clamp_would() {
        let clamped = |v: f32| (v.clamp(0.0, 255.0) + 0.5) as u8;
        let mut v = -300.0f32;
        while v <= 600.0 {
            assert_eq!(round_to_byte(v), clamped(v), "{v}");
            v += 0.0625;
        }
        let edges = [
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            -0.5,
            -0.49,
            -0.0,
            254.49,
            254.5,
            255.49,
            255.5,
            1e9,
            -1e9,
        ];
        for v in edges {
            assert_eq!(round_to_byte(v), clamped(v), "{v}");
        }
        let rounded = [0.5, 1.49, -3.0, 300.0].map(round_to_byte);
        assert_eq!(rounded, [1, 1, 0, 255]);
    }
}
