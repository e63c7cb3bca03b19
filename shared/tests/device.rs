//! The device pipeline and command handling on the host: memory by the formula, the
//! tile model's observation counts, refused frames, and every command's validation.

use rollfuse_core::device::{
    Controller, Effect, FrameError, Pipeline, PipelineBuffers, PipelineConfig, Precision, Sensor,
};
use rollfuse_core::motion::MotionConfig;
use rollfuse_core::protocol::{
    self, Command, DeviceConfig, DeviceMessage, LedDuty, NakReason, PixelFormat, RollerCommand,
};

const QVGA: Sensor = Sensor {
    width: 320,
    height: 240,
    format: PixelFormat::Yuyv,
};

struct Storage {
    frame: Vec<u8>,
    tiles: Vec<u8>,
    work: Vec<i32>,
    profiles: Vec<i32>,
}

impl Storage {
    fn new(cfg: &PipelineConfig) -> Self {
        let m = cfg.memory();
        Self {
            frame: vec![0; m.frame_bytes],
            tiles: vec![0; m.tile_bytes],
            work: vec![0; m.work_words],
            profiles: vec![0; m.profile_words],
        }
    }
    fn buffers(&mut self) -> PipelineBuffers<'_> {
        PipelineBuffers {
            frame: &mut self.frame,
            tiles: &mut self.tiles,
            work: &mut self.work,
            profiles: &mut self.profiles,
        }
    }
}

/// The numbers docs/device.md states for the default configuration on a QVGA camera.
#[test]
fn the_default_configuration_needs_what_the_formula_says() {
    let cfg = PipelineConfig::from_wire(&DeviceConfig::default(), QVGA).unwrap();
    let (w, t) = (320, 16);
    // 16 camera px per frame at full resolution: 16 rows; window 4·16 + 16 − 1 = 79 rows,
    // the only rows converted and profiled.
    let h = 79;
    assert_eq!(cfg.window_rows(), h);
    let active = h.div_ceil(t) + 1;
    assert_eq!(cfg.active_tiles(), active);
    let m = cfg.memory();
    assert_eq!(m.frame_bytes, w * h);
    assert_eq!(m.tile_bytes, active * t * w);
    // Two work images, the transform's row of scratch, two maps, two saliency tables.
    assert_eq!(
        m.work_words,
        2 * t * w + w + 2 * (w / 2 + 1) * (t / 2 + 1) + 2 * 1024
    );
    // Four bands of columns a row.
    assert_eq!(m.profile_words, 2 * (h - 1) * 4);
    assert_eq!(m.total_bytes(), 120_520);

    // The firmware's buffers hold it, and the 2×-downsampled configurations users pick.
    assert!(m.fits(&rollfuse_core::device::MCU_CAPACITY));
    for (levels, tile_rows, frames_per_tile) in [(2, 16, 4), (3, 32, 6), (2, 8, 3)] {
        let wire = DeviceConfig {
            levels,
            downsample: 2,
            tile_rows,
            frames_per_tile,
            ..DeviceConfig::default()
        };
        let cfg = PipelineConfig::from_wire(&wire, QVGA).unwrap();
        assert!(
            cfg.memory().fits(&rollfuse_core::device::MCU_CAPACITY),
            "{wire:?}"
        );
    }

    // One element short anywhere is refused.
    let mut s = Storage::new(&cfg);
    assert!(Pipeline::new(cfg, s.buffers()).is_ok());
    for which in 0..4 {
        let mut s = Storage::new(&cfg);
        match which {
            0 => s.frame.pop().map(drop),
            1 => s.tiles.pop().map(drop),
            2 => s.work.pop().map(drop),
            _ => s.profiles.pop().map(drop),
        };
        assert!(Pipeline::new(cfg, s.buffers()).is_err(), "buffer {which}");
    }
}

/// The module's memory holds the camera's full resolution: every 1× configuration of the
/// trade-off study (both wavelets, 1–3 levels, either normalization) on the integer path,
/// and its fusion memory (tiles, work, profiles) fits the H743's 128 KiB DTCM, where the
/// firmware places it.
#[test]
fn full_resolution_fits_the_module() {
    use rollfuse_core::device::{MCU_CAPACITY, ModuleWork};
    use rollfuse_core::protocol::{NormMode, WaveletId};
    for wavelet in [WaveletId::Haar, WaveletId::Db2] {
        for levels in 1..=3 {
            for norm in [NormMode::PerFrame, NormMode::PerTile] {
                let wire = DeviceConfig {
                    wavelet,
                    levels,
                    norm,
                    downsample: 1,
                    ..DeviceConfig::default()
                };
                let cfg = PipelineConfig::from_wire(&wire, QVGA).unwrap();
                assert_eq!(cfg.precision(), Precision::Fixed);
                assert!(
                    cfg.memory().fits(&MCU_CAPACITY),
                    "{wire:?}: {:?}",
                    cfg.memory()
                );
            }
        }
    }
    assert!(core::mem::size_of::<ModuleWork>() <= 128 * 1024);
}

/// A gray belt with texture everywhere, as the camera sees it at belt row `offset`.
fn belt_frame(offset: usize, w: usize, h: usize) -> Vec<u8> {
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as u32, (i / w + offset) as u32);
            ((x * 7 + y * 13) ^ (y.wrapping_mul(2_654_435_761) >> 27)) as u8
        })
        .collect()
}

/// A pipeline for a 64×96 gray camera at full resolution: 8-row tiles of 3 frames,
/// `spacing` camera pixels between frames, refinement within `refine` rows.
fn small_gray(spacing: u16, refine: u8) -> PipelineConfig {
    let sensor = Sensor {
        width: 64,
        height: 96,
        format: PixelFormat::Gray8,
    };
    let wire = DeviceConfig {
        downsample: 1,
        tile_rows: 8,
        frames_per_tile: 3,
        frame_spacing_px: spacing,
        refine_rows: refine,
        ..DeviceConfig::default()
    };
    PipelineConfig::from_wire(&wire, sensor).unwrap()
}

#[test]
fn interior_tiles_get_exactly_their_observations_in_belt_order() {
    let cfg = small_gray(6, 2);
    let mut s = Storage::new(&cfg);
    let mut p = Pipeline::new(cfg, s.buffers()).unwrap();
    let mut seen = Vec::new();
    for k in 0..30 {
        let frame = belt_frame(6 * k, 64, 96);
        let report = p
            .push_frame(&frame, 6 * k as u64, |t| {
                seen.push((t.index, t.observations))
            })
            .unwrap();
        assert_eq!(
            report.offset,
            6 * k as u64,
            "refinement keeps the true shift"
        );
    }
    // A frame of the wrong size, or one from behind, is refused and changes nothing.
    assert!(matches!(
        p.push_frame(&[0; 10], 180, |_| {}),
        Err(FrameError::Size(_))
    ));
    let back = belt_frame(100, 64, 96);
    assert_eq!(
        p.push_frame(&back, 100, |_| panic!("no tile from a refused frame")),
        Err(FrameError::Backwards)
    );
    p.finish(|t| seen.push((t.index, t.observations)));
    let indices: Vec<u32> = seen.iter().map(|s| s.0).collect();
    assert!(indices.windows(2).all(|w| w[1] == w[0] + 1), "{indices:?}");
    // 3 frames × 6 rows = 18 consecutive window positions: each tile is seen 3 times,
    // except where the run starts and ends.
    let full = seen.iter().filter(|s| s.1 == 3).count();
    assert!(full >= seen.len() - 6, "{seen:?}");
    assert!(seen.iter().all(|s| (1..=3).contains(&s.1)));
}

/// A belt whose true position is off the commanded one by up to 2 rows a frame (the
/// motion system's unknown error): the offsets follow the true positions, not the
/// commanded ones, and do not drift along the run.
#[test]
fn offsets_follow_the_belt_where_the_commanded_motion_is_off() {
    let cfg = small_gray(7, 4);
    let mut s = Storage::new(&cfg);
    let mut p = Pipeline::new(cfg, s.buffers()).unwrap();
    // A fixed sequence of errors in −2..=2 averaging 0 (a mean error is indistinguishable
    // from where the run started).
    let error = |k: usize| [-2, 1, 0, 2, -1, 1, -2, 2, 0, -1][(k * 3 + k / 10) % 10];
    let (mut ours, mut told) = (0i64, 0i64);
    for k in 0..120 {
        let commanded = 7 * k as i64 + 10;
        let truth = commanded + error(k);
        let frame = belt_frame(truth as usize, 64, 96);
        let report = p.push_frame(&frame, commanded as u64, |_| {}).unwrap();
        // Offsets count from the first frame's commanded position.
        let want = truth - 10;
        if k >= 40 {
            ours += (report.offset as i64 - want).abs();
            told += (commanded - 10 - want).abs();
        }
        assert!(
            (report.offset as i64 - want).abs() <= 3,
            "frame {k}: offset {} for a belt at {want}",
            report.offset
        );
    }
    // Over the last 80 frames: mean error under half a row, where the commanded rows are
    // off by 1.2 on average.
    assert!(ours * 2 < 80, "mean error {:.2} rows", ours as f64 / 80.0);
    assert!(told > 80, "{told}");
}

/// Every tile a pipeline of `cfg` emits over a run of `frames` frames of a textured belt
/// moving `spacing` rows per frame, each frame with noise of its own (so a tile's
/// observations differ): (index, observations, pixels).
fn run_tiles(cfg: PipelineConfig, frames: usize, spacing: usize) -> Vec<(u32, u8, Vec<u8>)> {
    let (w, h) = (cfg.sensor().width, cfg.sensor().height);
    let mut s = Storage::new(&cfg);
    let mut p = Pipeline::new(cfg, s.buffers()).unwrap();
    let mut tiles = Vec::new();
    let mut keep = |t: protocol::Tile<'_>| tiles.push((t.index, t.observations, t.pixels.to_vec()));
    for k in 0..frames {
        let frame = noisy_belt_frame(k, spacing, w, h);
        p.push_frame(&frame, (spacing * k) as u64, &mut keep)
            .unwrap();
    }
    p.finish(&mut keep);
    tiles
}

/// Frame `k` of a textured belt moving `spacing` rows a frame, with noise of its own.
fn noisy_belt_frame(k: usize, spacing: usize, w: usize, h: usize) -> Vec<u8> {
    let mut frame = belt_frame(spacing * k, w, h);
    for (i, v) in frame.iter_mut().enumerate() {
        let noise = ((i * 2_654_435_761) ^ (k * 40_503)) >> 7 & 15;
        *v = v.saturating_add(noise as u8);
    }
    frame
}

/// A frame taken, then fused while the next capture overwrites the camera's buffer (as
/// the firmware overlaps them), gives the tiles of frames pushed whole; a fusion with no
/// frame taken is refused; a frame taken twice is fused once.
#[test]
fn fusing_a_taken_frame_needs_the_camera_buffer_no_more() {
    let gray = Sensor {
        format: PixelFormat::Gray8,
        ..QVGA
    };
    let cfg = PipelineConfig::from_wire(&DeviceConfig::default(), gray).unwrap();
    let spacing = cfg.spacing_px();
    let mut s = Storage::new(&cfg);
    let mut p = Pipeline::new(cfg, s.buffers()).unwrap();
    let mut tiles = Vec::new();
    let mut keep = |t: protocol::Tile<'_>| tiles.push((t.index, t.observations, t.pixels.to_vec()));
    assert_eq!(p.fuse_taken(0, &mut keep), Err(FrameError::NothingTaken));
    let mut camera = noisy_belt_frame(0, spacing, 320, 240);
    for k in 0..12 {
        p.take_frame(&camera).unwrap();
        if k == 3 {
            p.take_frame(&camera).unwrap();
        }
        camera = noisy_belt_frame(k + 1, spacing, 320, 240);
        p.fuse_taken((spacing * k) as u64, &mut keep).unwrap();
        assert_eq!(
            p.fuse_taken((spacing * k) as u64, &mut keep),
            Err(FrameError::NothingTaken)
        );
    }
    p.finish(&mut keep);
    assert!(tiles.len() > 4);
    assert_eq!(tiles, run_tiles(cfg, 12, spacing));
}

/// The `f32` fuse step in the pipeline: the same tiles, the same observations, pixels
/// within two gray levels of the integer path's (both round to 8 bits every step; the
/// integer path's lifting also rounds, so they are not identical — and must not be equal
/// everywhere either, or the precision switch would not be doing anything).
#[test]
fn the_f32_pipeline_emits_what_the_integer_one_does_up_to_rounding() {
    let sensor = Sensor {
        width: 64,
        height: 96,
        format: PixelFormat::Gray8,
    };
    let wire = DeviceConfig {
        downsample: 1,
        tile_rows: 8,
        frames_per_tile: 3,
        frame_spacing_px: 6,
        ..DeviceConfig::default()
    };
    let fixed = PipelineConfig::from_wire(&wire, sensor).unwrap();
    let float = fixed.with_precision(Precision::F32);
    assert!(
        float.memory().work_words > fixed.memory().work_words,
        "a second transform line"
    );
    let (a, b) = (run_tiles(fixed, 20, 6), run_tiles(float, 20, 6));
    assert_eq!(a.len(), b.len());
    let (mut worst, mut differing) = (0, 0);
    for ((ia, oa, pa), (ib, ob, pb)) in a.iter().zip(&b) {
        assert_eq!((ia, oa), (ib, ob));
        for (&x, &y) in pa.iter().zip(pb) {
            worst = worst.max(x.abs_diff(y));
            differing += usize::from(x != y);
        }
    }
    assert!(worst <= 2, "largest difference {worst} gray levels");
    assert!(differing > 0, "the f32 path changed nothing");
}

fn command(seq: u32, c: &Command) -> Vec<u8> {
    let mut buf = [0u8; 128];
    let n = protocol::encode(seq, c, &mut buf).unwrap();
    buf[..n].to_vec()
}

/// With the roller's mechanics, a speed the ramp cannot run (under one step a second) is
/// refused before it is acknowledged; the slowest it can run is accepted.
#[test]
fn a_device_with_a_roller_refuses_speeds_its_ramp_cannot_run() {
    let motion = MotionConfig {
        nm_per_step: 23_562,
        accel_um_s2: 100_000,
        timer_hz: 1_000_000,
    };
    let mut ctl = Controller::new(QVGA, [1, 2, 3], DeviceConfig::default())
        .unwrap()
        .with_motion(motion);
    let start = |speed_um_s| Command::Roller(RollerCommand::Start { speed_um_s });
    let speed = |speed_um_s| Command::Roller(RollerCommand::Speed { speed_um_s });
    for c in [start(1), start(23), speed(23)] {
        match ctl.handle(&command(3, &c)) {
            (
                DeviceMessage::Nak {
                    reason: NakReason::Speed,
                    ..
                },
                Effect::None,
            ) => {}
            other => panic!("{c:?} answered {other:?}"),
        }
        assert!(
            !ctl.counters().roller_running,
            "{c:?} marked the roller running"
        );
    }
    // 24 µm/s is one step a second: the ramp runs it.
    assert!(motion.check_speed(24).is_ok());
    match ctl.handle(&command(4, &start(24))) {
        (DeviceMessage::Ack { .. }, Effect::Roller(_)) => {}
        other => panic!("the slowest speed answered {other:?}"),
    }
    // Without the mechanics the controller cannot know: any speed from 1 µm/s is taken.
    let mut plain = Controller::new(QVGA, [1, 2, 3], DeviceConfig::default()).unwrap();
    assert!(matches!(
        plain.handle(&command(5, &start(1))).0,
        DeviceMessage::Ack { .. }
    ));
}

#[test]
fn every_command_is_validated_with_a_reason() {
    let mut ctl = Controller::new(QVGA, [1, 2, 3], DeviceConfig::default()).unwrap();
    let nak = |ctl: &mut Controller, c: Command| match ctl.handle(&command(5, &c)) {
        (
            DeviceMessage::Nak {
                reason,
                command_seq,
            },
            Effect::None,
        ) => {
            assert_eq!(command_seq, 5);
            reason
        }
        other => panic!("{c:?} accepted: {other:?}"),
    };
    let d = DeviceConfig::default();
    let bad_configs = [
        (DeviceConfig { levels: 0, ..d }, NakReason::Levels),
        (DeviceConfig { levels: 5, ..d }, NakReason::Levels),
        // Tiles so thin that more than the device holds would be in fusion at once.
        (DeviceConfig { tile_rows: 2, ..d }, NakReason::FramesPerTile),
        (DeviceConfig { downsample: 3, ..d }, NakReason::Downsample),
        (DeviceConfig { tile_rows: 0, ..d }, NakReason::TileRows),
        (
            DeviceConfig {
                tile_rows: 241,
                ..d
            },
            NakReason::TileRows,
        ),
        (
            DeviceConfig {
                frames_per_tile: 0,
                ..d
            },
            NakReason::FramesPerTile,
        ),
        (
            DeviceConfig {
                frames_per_tile: 15,
                ..d
            },
            NakReason::FramesPerTile,
        ),
        (
            DeviceConfig {
                frame_spacing_px: 0,
                ..d
            },
            NakReason::FrameSpacing,
        ),
        (
            DeviceConfig {
                frame_spacing_px: 241,
                ..d
            },
            NakReason::FrameSpacing,
        ),
        (
            DeviceConfig {
                refine_rows: 17,
                ..d
            },
            NakReason::RefineRows,
        ),
    ];
    for (cfg, reason) in bad_configs {
        assert_eq!(nak(&mut ctl, Command::Configure(cfg)), reason, "{cfg:?}");
    }
    let too_bright = LedDuty {
        red: 1001,
        ..LedDuty::default()
    };
    assert_eq!(nak(&mut ctl, Command::Leds(too_bright)), NakReason::LedDuty);
    for speed in [0, 500_001] {
        let c = Command::Roller(RollerCommand::Start { speed_um_s: speed });
        assert_eq!(nak(&mut ctl, c), NakReason::Speed);
    }
    for frames in [0, 9] {
        assert_eq!(
            nak(&mut ctl, Command::CaptureRaw { frames }),
            NakReason::RawFrames
        );
    }
    // Garbage is refused and counted.
    assert!(matches!(
        ctl.handle(&[1, 2, 3, 4, 5, 6, 7]).0,
        DeviceMessage::Nak {
            reason: NakReason::BadMessage,
            ..
        }
    ));
    assert_eq!(ctl.counters().bad_commands, 1);

    // Good commands: acked, with their effect.
    let ok = |ctl: &mut Controller, c: Command| {
        let (reply, effect) = ctl.handle(&command(9, &c));
        assert_eq!(reply, DeviceMessage::Ack { command_seq: 9 }, "{c:?}");
        effect
    };
    let smaller = DeviceConfig {
        levels: 1,
        downsample: 4,
        ..d
    };
    assert!(
        matches!(ok(&mut ctl, Command::Configure(smaller)), Effect::Configure(p) if p.downsample() == 4)
    );
    assert_eq!(
        ok(&mut ctl, Command::Leds(LedDuty::ALL_ON)),
        Effect::Leds(LedDuty::ALL_ON)
    );
    assert_eq!(ok(&mut ctl, Command::StreamStart), Effect::StreamStart);
    assert_eq!(nak(&mut ctl, Command::Configure(d)), NakReason::Busy);
    assert_eq!(nak(&mut ctl, Command::StreamStart), NakReason::Busy);
    assert_eq!(ok(&mut ctl, Command::StreamStop), Effect::StreamStop);
    // A device with fixed buffers refuses what would not fit them.
    let default_needs = PipelineConfig::from_wire(&d, QVGA).unwrap().memory();
    let mut small = Controller::new(QVGA, [1, 2, 3], d)
        .unwrap()
        .with_capacity(default_needs)
        .unwrap();
    let bigger = DeviceConfig { tile_rows: 32, ..d };
    assert_eq!(
        nak(&mut small, Command::Configure(bigger)),
        NakReason::Memory
    );
    assert!(matches!(
        ok(&mut small, Command::Configure(d)),
        Effect::Configure(_)
    ));
    let tiny = rollfuse_core::device::Memory {
        frame_bytes: 10,
        ..default_needs
    };
    assert!(
        Controller::new(QVGA, [0; 3], d)
            .unwrap()
            .with_capacity(tiny)
            .is_err()
    );
    match ctl.handle(&command(10, &Command::Hello)).0 {
        DeviceMessage::Info(info) => {
            assert_eq!(info.firmware, [1, 2, 3]);
            assert_eq!(info.config, smaller);
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn without_room_for_its_effect_a_command_is_refused_and_changes_nothing() {
    let mut ctl = Controller::new(QVGA, [1, 2, 3], DeviceConfig::default()).unwrap();
    let (reply, effect) = ctl.handle_when(&command(7, &Command::StreamStart), false);
    assert_eq!(
        reply,
        DeviceMessage::Nak {
            command_seq: 7,
            reason: NakReason::Busy
        }
    );
    assert_eq!(effect, Effect::None);
    assert!(
        !ctl.counters().streaming,
        "a refused start leaves streaming off"
    );
    // Stopping the roller and asking for status need no room.
    let stop = Command::Roller(rollfuse_core::protocol::RollerCommand::Stop);
    let (reply, effect) = ctl.handle_when(&command(8, &stop), false);
    assert_eq!(reply, DeviceMessage::Ack { command_seq: 8 });
    assert_eq!(
        effect,
        Effect::Roller(rollfuse_core::protocol::RollerCommand::Stop)
    );
    assert!(matches!(
        ctl.handle_when(&command(9, &Command::Status), false).0,
        DeviceMessage::Status(_)
    ));
    // With room, the same start is acknowledged and takes effect.
    let (reply, effect) = ctl.handle_when(&command(10, &Command::StreamStart), true);
    assert_eq!(reply, DeviceMessage::Ack { command_seq: 10 });
    assert_eq!(effect, Effect::StreamStart);
    assert!(ctl.host_lost(), "streaming was on");
    assert!(!ctl.counters().streaming && !ctl.host_lost());
}
