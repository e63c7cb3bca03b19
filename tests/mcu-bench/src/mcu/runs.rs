//! What is measured: the device pipeline per frame over the trade-off sweep (wavelet ×
//! levels × downsampling × normalization × fixed/`f32` fuse step), the fuse step per tile on the integer and the
//! `f32` path for each of those, and the pipeline's kernels at the default configuration.

use super::clock::Clock;
use super::frames::{self, FRAME_BYTES, HEIGHT, SPACING_PX, WIDTH};
use core::fmt;
use cortex_m_semihosting::hprintln;
use rollfuse_core::device::downsample::{downsample, downsample_rows};
use rollfuse_core::device::refine::{PROFILE_BANDS, profile_len, refine_shift, row_profile};
use rollfuse_core::device::{
    CAMERA, MCU_CAPACITY, Pipeline, PipelineBuffers, PipelineConfig, Precision, Sensor,
};
use rollfuse_core::fusion::{LlWeight, U8Pair, U8Work, fuse_u8};
use rollfuse_core::lifting::{forward_2d, inverse_2d};
use rollfuse_core::protocol::{DeviceConfig, NormMode, WaveletId};
use rollfuse_core::saliency::laplacian_max_u8;
use rollfuse_core::{Ablation, Dims, FuseConfig, SaliencyNorm, Wavelet, float};

/// The CSV columns.
pub const HEADER: &str = "section,name,wavelet,levels,downsample,norm,pixels,calls,\
                          instructions,per_call,per_pixel,observed_per_call,fits_firmware_ram";

/// Frames pushed before measuring, so the pipeline holds its full set of tiles.
const WARMUP: usize = 8;
/// Frames measured per configuration.
const MEASURED: usize = 8;
/// Calls averaged per fuse-step measurement.
const FUSE_CALLS: usize = 4;

/// The camera the firmware has.
const SENSOR: Sensor = CAMERA;

/// One configuration of the sweep.
#[derive(Clone, Copy)]
pub struct Setup {
    wavelet: WaveletId,
    levels: u8,
    downsample: u8,
    per_frame: bool,
}

impl Setup {
    fn wire(self) -> DeviceConfig {
        DeviceConfig {
            wavelet: self.wavelet,
            levels: self.levels,
            downsample: self.downsample,
            norm: if self.per_frame {
                NormMode::PerFrame
            } else {
                NormMode::PerTile
            },
            frame_spacing_px: SPACING_PX as u16,
            ..DeviceConfig::default()
        }
    }

    /// The validated pipeline configuration for the bench's camera.
    fn config(self) -> Option<PipelineConfig> {
        PipelineConfig::from_wire(&self.wire(), SENSOR).ok()
    }
}

/// One CSV line.
pub struct Row {
    section: &'static str,
    name: &'static str,
    setup: Setup,
    pixels: usize,
    calls: u64,
    instructions: u64,
    /// Tile observations fused, and whether the configuration fits the memory the
    /// firmware reserves ([`MCU_CAPACITY`]); pipeline rows only.
    pipeline: Option<(u64, bool)>,
}

impl fmt::Display for Row {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = self.setup;
        let wavelet = match s.wavelet {
            WaveletId::Haar => "haar",
            WaveletId::Db2 => "db2",
        };
        let norm = if s.per_frame { "frame" } else { "tile" };
        let calls = self.calls.max(1) as f64;
        let per_call = self.instructions as f64 / calls;
        write!(
            f,
            "{},{},{},{},{},{},{},{},{},{:.1},{:.2},",
            self.section,
            self.name,
            wavelet,
            s.levels,
            s.downsample,
            norm,
            self.pixels,
            self.calls,
            self.instructions,
            per_call,
            per_call / self.pixels.max(1) as f64,
        )?;
        match self.pipeline {
            Some((observed, fits)) => {
                write!(f, "{:.2},{}", observed as f64 / calls, u8::from(fits))
            }
            None => write!(f, ","),
        }
    }
}

/// Every buffer the runs need, sized for the largest configuration (QVGA, no
/// downsampling): QEMU's board has 4 MB of RAM, so all of it lives on the stack.
struct Buffers {
    camera: [u8; FRAME_BYTES],
    frame: [u8; WIDTH * HEIGHT],
    tiles: [u8; 16 * 16 * WIDTH],
    work: [i32; 32 * 1024],
    profiles: [i32; 2 * HEIGHT * PROFILE_BANDS],
    ints: [i32; 16 * WIDTH],
    fa: [f32; 16 * WIDTH],
    fb: [f32; 16 * WIDTH],
    fscratch: [f32; 8 * 1024],
}

impl Buffers {
    const fn new() -> Self {
        Self {
            camera: [0; FRAME_BYTES],
            frame: [0; WIDTH * HEIGHT],
            tiles: [0; 16 * 16 * WIDTH],
            work: [0; 32 * 1024],
            profiles: [0; 2 * HEIGHT * PROFILE_BANDS],
            ints: [0; 16 * WIDTH],
            fa: [0.0; 16 * WIDTH],
            fb: [0.0; 16 * WIDTH],
            fscratch: [0.0; 8 * 1024],
        }
    }
}

/// Runs everything, handing each row to `out`. False if any measurement could not run.
pub fn all(clock: &Clock, out: &mut impl FnMut(&Row)) -> bool {
    let mut b = Buffers::new();
    let mut ok = kernels(clock, &mut b, DEFAULT, out) && kernels(clock, &mut b, HALF, out);
    for wavelet in [WaveletId::Haar, WaveletId::Db2] {
        for levels in 1..=3 {
            for downsample in [1, 2, 4] {
                for per_frame in [false, true] {
                    let setup = Setup {
                        wavelet,
                        levels,
                        downsample,
                        per_frame,
                    };
                    ok &= pipeline(clock, &mut b, setup, Precision::Fixed, out)
                        && pipeline(clock, &mut b, setup, Precision::F32, out)
                        && tile_fuse(clock, &mut b, setup, out);
                }
            }
        }
    }
    ok
}

/// The device pipeline fusing with `precision`, instructions per frame in steady state.
fn pipeline(
    clock: &Clock,
    b: &mut Buffers,
    setup: Setup,
    precision: Precision,
    out: &mut impl FnMut(&Row),
) -> bool {
    let Some(cfg) = setup.config() else {
        return false;
    };
    let cfg = cfg.with_precision(precision);
    let mem = cfg.memory();
    let bufs = PipelineBuffers {
        frame: &mut b.frame[..mem.frame_bytes],
        tiles: &mut b.tiles[..mem.tile_bytes],
        work: &mut b.work[..mem.work_words],
        profiles: &mut b.profiles[..mem.profile_words],
    };
    let Ok(mut pipe) = Pipeline::new(cfg, bufs) else {
        return false;
    };
    let (mut instructions, mut observed) = (0, 0);
    for k in 0..WARMUP + MEASURED {
        frames::draw(k, &mut b.camera);
        let position = (k * SPACING_PX) as u64;
        // Emitted tiles are dropped: queueing them for USB is the firmware's, not measured.
        let (report, n) = clock.instructions(|| pipe.push_frame(&b.camera, position, |_| {}));
        let Ok(report) = report else {
            return false;
        };
        if k >= WARMUP {
            instructions += n;
            observed += report.observed as u64;
        }
    }
    out(&Row {
        section: "pipeline",
        name: match precision {
            Precision::Fixed => "frame_fixed",
            Precision::F32 => "frame_f32",
        },
        setup,
        pixels: cfg.frame_dims().pixels(),
        calls: MEASURED as u64,
        instructions,
        pipeline: Some((observed, mem.fits(&MCU_CAPACITY))),
    });
    true
}

/// One tile's fuse step on both paths at the configuration's tile size, on two tiles cut
/// from a downsampled frame.
fn tile_fuse(clock: &Clock, b: &mut Buffers, setup: Setup, out: &mut impl FnMut(&Row)) -> bool {
    let Some(cfg) = setup.config() else {
        return false;
    };
    frames::draw(0, &mut b.camera);
    let ds = usize::from(setup.downsample);
    let Ok(frame) = downsample(&b.camera, SENSOR.format, (WIDTH, HEIGHT), ds, &mut b.frame) else {
        return false;
    };
    let tile = cfg.tile_dims();
    let n = tile.pixels();
    let norm = if setup.per_frame {
        SaliencyNorm::Reference(laplacian_max_u8(&b.frame, frame))
    } else {
        SaliencyNorm::Local
    };
    let fuse = FuseConfig { norm, ..cfg.fuse() };
    let (ta, tb) = (&b.frame[..n], &b.frame[n..2 * n]);
    let mut fixed = 0;
    for _ in 0..FUSE_CALLS {
        let (work_a, rest) = b.work.split_at_mut(n);
        let (work_b, scratch) = rest.split_at_mut(n);
        let work = U8Work {
            a: work_a,
            b: work_b,
            scratch,
        };
        // The result replaces the first tile: each call starts from a copy of it.
        let fused = &mut b.tiles[..n];
        fused.copy_from_slice(ta);
        let (r, i) = clock
            .instructions(|| fuse_u8(U8Pair::same(fused, tb, tile), &fuse, LlWeight::HALF, work));
        if r.is_err() {
            return false;
        }
        fixed += i;
    }
    let mut real = 0;
    for _ in 0..FUSE_CALLS {
        for ((a, b), (&x, &y)) in b.fa.iter_mut().zip(b.fb.iter_mut()).zip(ta.iter().zip(tb)) {
            *a = f32::from(x);
            *b = f32::from(y);
        }
        let (fa, fb, scratch) = (&mut b.fa[..n], &mut b.fb[..n], &mut b.fscratch[..]);
        let (r, i) =
            clock.instructions(|| float::fuse_pair(fa, fb, tile, &fuse, LlWeight::HALF, scratch));
        if r.is_err() {
            return false;
        }
        real += i;
    }
    for (name, instructions) in [("fuse_fixed", fixed), ("fuse_f32", real)] {
        out(&Row {
            section: "tile",
            name,
            setup,
            pixels: n,
            calls: FUSE_CALLS as u64,
            instructions,
            pipeline: None,
        });
    }
    true
}

/// The default configuration: db2, 1 level, the camera's full resolution, per-frame
/// normalization.
const DEFAULT: Setup = Setup {
    wavelet: WaveletId::Db2,
    levels: 1,
    downsample: 1,
    per_frame: true,
};

/// Half resolution for comparison: db2, 2 levels, 2× downsampling, per frame.
const HALF: Setup = Setup {
    wavelet: WaveletId::Db2,
    levels: 2,
    downsample: 2,
    per_frame: true,
};

/// The pipeline's parts at `setup` (normalized per frame), each on the data it sees there.
fn kernels(clock: &Clock, b: &mut Buffers, setup: Setup, out: &mut impl FnMut(&Row)) -> bool {
    let Some(cfg) = setup.config() else {
        return false;
    };
    let mut row = |name, pixels, instructions| {
        out(&Row {
            section: "kernel",
            name,
            setup,
            pixels,
            calls: 1,
            instructions,
            pipeline: None,
        })
    };
    frames::draw(0, &mut b.camera);
    // The pipeline reads only the observation window: its band is what each kernel sees.
    let schedule = cfg.schedule();
    let window = schedule.window_top..schedule.window_top + schedule.window_rows;
    let (band, i) = clock.instructions(|| {
        downsample_rows(
            &b.camera,
            SENSOR.format,
            (WIDTH, HEIGHT),
            usize::from(setup.downsample),
            window,
            &mut b.frame,
        )
    });
    let Ok(band) = band else {
        return false;
    };
    row("downsample", band.pixels(), i);
    let p = profile_len(band.height());
    let (previous, current) = b.profiles.split_at_mut(p);
    row_profile(&b.frame, band, previous);
    let ((), i) = clock.instructions(|| row_profile(&b.frame, band, &mut current[..p]));
    row("row_profile", band.pixels(), i);
    let radius = u32::from(DeviceConfig::default().refine_rows);
    let (_, i) = clock.instructions(|| refine_shift(previous, &current[..p], 8, radius));
    row("refine_shift", band.pixels(), i);
    // Over the rows the frame's tiles cover, as the pipeline takes it.
    let rows = schedule.observed_rows(0);
    let top = schedule.window_top;
    let covered = &b.frame[(rows.start - top) * band.width()..(rows.end - top) * band.width()];
    let Ok(covered_dims) = Dims::new(band.width(), rows.len()) else {
        return false;
    };
    let (_, i) = clock.instructions(|| laplacian_max_u8(covered, covered_dims));
    row("laplacian_max", covered_dims.pixels(), i);
    let tile = cfg.tile_dims();
    let n = tile.pixels();
    for (v, &p) in b.ints.iter_mut().zip(&b.frame[..n]) {
        *v = i32::from(p);
    }
    let (ints, scratch) = (&mut b.ints[..n], &mut b.work[..]);
    let (r, i) = clock.instructions(|| forward_2d(Wavelet::Db2, ints, tile, setup.levels, scratch));
    if r.is_err() {
        return false;
    }
    row("forward_2d", n, i);
    let (r, i) = clock.instructions(|| inverse_2d(Wavelet::Db2, ints, tile, setup.levels, scratch));
    if r.is_err() {
        return false;
    }
    row("inverse_2d", n, i);
    // The fuse step of two tiles of the band with max-|coefficient| selection (no saliency
    // maps, weights or blend); the `tile` rows have the full step on the same tiles.
    let fuse = FuseConfig {
        ablation: Ablation::MaxHigh,
        ..cfg.fuse()
    };
    let (a, rest) = b.work.split_at_mut(n);
    let (b_work, scratch) = rest.split_at_mut(n);
    let work = U8Work {
        a,
        b: b_work,
        scratch,
    };
    let (ta, tb) = (&b.frame[..n], &b.frame[n..2 * n]);
    let fused = &mut b.tiles[..n];
    fused.copy_from_slice(ta);
    let (r, i) =
        clock.instructions(|| fuse_u8(U8Pair::same(fused, tb, tile), &fuse, LlWeight::HALF, work));
    if r.is_err() {
        return false;
    }
    row("fuse_max_high", n, i);
    true
}

/// The device pipeline at one configuration only (what `tests/mcu-bench/profile.sh`
/// traces): its warm-up and measured frames, each a timed section.
pub fn one(clock: &Clock, setup: Setup, precision: Precision, out: &mut impl FnMut(&Row)) -> bool {
    if setup.config().is_none() {
        hprintln!("# the device refuses this configuration (PipelineConfig::from_wire)");
        return false;
    }
    pipeline(clock, &mut Buffers::new(), setup, precision, out)
}

/// The configuration `ROLLFUSE_PROFILE` names at build time, as
/// `wavelet,levels,downsample,norm,precision` (`db2,1,1,frame,fixed` if unset); `None` if
/// it names none.
pub fn profiled() -> Option<(Setup, Precision)> {
    let spec = option_env!("ROLLFUSE_PROFILE").unwrap_or("db2,1,1,frame,fixed");
    let mut parts = spec.split(',');
    let mut next = || parts.next().map(str::trim);
    let wavelet = match next()? {
        "haar" => WaveletId::Haar,
        "db2" => WaveletId::Db2,
        _ => return None,
    };
    let levels = next()?.parse().ok()?;
    let downsample = next()?.parse().ok()?;
    let per_frame = match next()? {
        "frame" => true,
        "tile" => false,
        _ => return None,
    };
    let precision = match next()? {
        "fixed" => Precision::Fixed,
        "f32" => Precision::F32,
        _ => return None,
    };
    if next().is_some() {
        return None;
    }
    let setup = Setup {
        wavelet,
        levels,
        downsample,
        per_frame,
    };
    Some((setup, precision))
}
