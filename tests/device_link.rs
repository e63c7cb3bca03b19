//! The device path end to end, without hardware: the virtual device (the core's device
//! pipeline on simulated frames) streams over the protocol's bytes into the host's strip,
//! which must equal a reference built here independently — downsampling, belt offsets,
//! the observation window and the cyclic integer fusion of each tile's frames — bit for
//! bit. A recording of the stream, played back, must give byte-identical files.

use rollfuse::link::replay::Replay;
use rollfuse::link::sim::{SimDevice, camera_bytes};
use rollfuse::progress::Silent;
use rollfuse::sim::{Scene, Simulator};
use rollfuse::stream::{self, Options};
use rollfuse_core::fusion::{LlWeight, U8Pair, U8Work, fuse_scratch_len, fuse_u8};
use rollfuse_core::protocol::{DeviceConfig, NormMode, WaveletId};
use rollfuse_core::{Dims, FuseConfig, LlWeighting, SaliencyNorm, Wavelet};
use std::path::Path;

fn letters(frames: usize) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../host/scenes/letters.toml");
    let mut scene = Scene::load(&path).unwrap();
    scene.sensor.frames = frames;
    scene
}

/// `factor × factor` box means, rounded, written plainly.
fn box_downsample(gray: &[u8], w: usize, h: usize, f: usize) -> Vec<u8> {
    let (ow, oh) = (w / f, h / f);
    let mut out = vec![0u8; ow * oh];
    for y in 0..oh {
        for x in 0..ow {
            let mut sum = 0u32;
            for dy in 0..f {
                for dx in 0..f {
                    sum += u32::from(gray[(y * f + dy) * w + x * f + dx]);
                }
            }
            let area = (f * f) as u32;
            out[y * ow + x] = ((sum + area / 2) / area) as u8;
        }
    }
    out
}

/// The largest 4-neighbour |Laplacian| with mirrored borders, written plainly.
fn laplacian_max(img: &[u8], w: usize, h: usize) -> u32 {
    let m = |i: isize, n: usize| -> usize {
        if i < 0 {
            (-i) as usize
        } else if i as usize >= n {
            2 * (n - 1) - i as usize
        } else {
            i as usize
        }
    };
    let at = |x: isize, y: isize| i32::from(img[m(y, h) * w + m(x, w)]);
    let mut max = 0;
    for y in 0..h as isize {
        for x in 0..w as isize {
            let l = at(x - 1, y) + at(x + 1, y) + at(x, y - 1) + at(x, y + 1) - 4 * at(x, y);
            max = max.max(l.unsigned_abs());
        }
    }
    max
}

/// Every tile the device should send for `scene` under `cfg`: index → (observations,
/// pixels), fused here from the frames whose observation window holds the tile.
fn reference_tiles(
    scene: &Scene,
    cfg: &DeviceConfig,
) -> std::collections::BTreeMap<u64, (u8, Vec<u8>)> {
    let sim = Simulator::new(scene).unwrap();
    let (w, h) = (scene.sensor.width_px, scene.sensor.height_px);
    let f = usize::from(cfg.downsample);
    let (dw, dh) = (w / f, h / f);
    let t = usize::from(cfg.tile_rows);
    let n = usize::from(cfg.frames_per_tile);
    let s = usize::from(cfg.frame_spacing_px) / f;
    let window = n * s + t - 1;
    let top = (dh - window) / 2;
    let tile_dims = Dims::new(dw, t).unwrap();
    let mut tiles = std::collections::BTreeMap::new();
    let origin = sim.strip_row_of_top(sim.frame(0).offset_mm);
    for k in 0..sim.frames() {
        let frame = sim.frame(k);
        let gray = camera_bytes(&frame.image);
        let small = box_downsample(&gray, w, h, f);
        let position = (sim.strip_row_of_top(frame.offset_mm) - origin).round() as usize;
        let offset = (position + f / 2) / f;
        let fuse_cfg = FuseConfig {
            wavelet: match cfg.wavelet {
                WaveletId::Haar => Wavelet::Haar,
                WaveletId::Db2 => Wavelet::Db2,
            },
            levels: cfg.levels,
            norm: match cfg.norm {
                // The largest Laplacian of the rows the frame's tiles cover: those wholly
                // inside the window, adjacent.
                NormMode::PerFrame => {
                    let first = (offset + top).div_ceil(t) * t - offset;
                    let end = (offset + top + window) / t * t - offset;
                    SaliencyNorm::Reference(if end > first {
                        laplacian_max(&small[first * dw..end * dw], dw, end - first)
                    } else {
                        0 // no tile observed: nothing is fused
                    })
                }
                NormMode::PerTile => SaliencyNorm::Local,
            },
            ll_weighting: LlWeighting::Paper,
            ..FuseConfig::default()
        };
        for index in 0..(offset + dh) / t + 1 {
            let start = index * t;
            if start < offset + top || start + t > offset + top + window {
                continue;
            }
            let rows = &small[(start - offset) * dw..(start - offset + t) * dw];
            let entry = tiles.entry(index as u64).or_insert((0u8, Vec::new()));
            if entry.0 == 0 {
                entry.1 = rows.to_vec();
            } else {
                let (mut a, mut b) = (vec![0i32; dw * t], vec![0i32; dw * t]);
                let mut scratch = vec![0i32; fuse_scratch_len(tile_dims)];
                let ll = LlWeight::for_frame(LlWeighting::Paper, u32::from(entry.0) + 1);
                let work = U8Work {
                    a: &mut a,
                    b: &mut b,
                    scratch: &mut scratch,
                };
                fuse_u8(
                    U8Pair::same(&mut entry.1, rows, tile_dims),
                    &fuse_cfg,
                    ll,
                    work,
                )
                .unwrap();
            }
            entry.0 += 1;
        }
    }
    tiles
}

fn options(out: &Path, config: Option<DeviceConfig>, record: Option<&Path>) -> Options {
    Options {
        config,
        record: record.map(Path::to_path_buf),
        ..Options::into_folder(out)
    }
}

/// A change to the device's default configuration.
type Adjust = fn(DeviceConfig) -> DeviceConfig;

#[test]
fn the_streamed_strip_matches_the_reference_tile_by_tile_and_replays_identically() {
    let scene = letters(14);
    let tmp = std::env::temp_dir().join(format!("rollfuse-link-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    // The device's default both ways of normalizing, and at the camera's full resolution
    // (where the offset refinement meets the sensor's noise undamped by downsampling).
    let full_resolution = |d: DeviceConfig| DeviceConfig {
        levels: 1,
        downsample: 1,
        ..d
    };
    let runs: [(NormMode, Adjust); 3] = [
        (NormMode::PerFrame, |d| d),
        (NormMode::PerTile, |d| d),
        (NormMode::PerFrame, full_resolution),
    ];
    for (k, (norm, config)) in runs.into_iter().enumerate() {
        let (live, replayed) = (tmp.join(format!("live{k}")), tmp.join(format!("replay{k}")));
        let recording = tmp.join(format!("stream{k}.bin"));
        let mut dev = SimDevice::start(&scene).unwrap();
        let cfg = DeviceConfig {
            norm,
            ..config(dev.default_config())
        };
        let out = stream::run(
            &mut dev,
            &options(&live, Some(cfg), Some(&recording)),
            &Silent,
        )
        .unwrap();
        assert!(out.manifest.device_stopped);
        assert_eq!(out.manifest.faults.total(), 0);

        let expected = reference_tiles(&scene, &cfg);
        assert_eq!(out.manifest.tiles_received, expected.len() as u64);
        let strip = image::open(live.join("strip.png")).unwrap().to_luma8();
        let first = *expected.keys().next().unwrap();
        let tile_bytes = strip.width() as usize * usize::from(cfg.tile_rows);
        for (index, (obs, pixels)) in &expected {
            let at = (index - first) as usize * tile_bytes;
            assert_eq!(
                &strip.as_raw()[at..at + tile_bytes],
                &pixels[..],
                "tile {index} ({obs} observations) differs from the reference ({cfg:?})"
            );
        }
        // Interior tiles have all their observations.
        assert_eq!(
            out.manifest.observations.get(&cfg.frames_per_tile).copied(),
            Some(
                expected
                    .values()
                    .filter(|(o, _)| *o == cfg.frames_per_tile)
                    .count() as u64
            )
        );

        let mut replay = Replay::open(&recording).unwrap();
        stream::run(&mut replay, &options(&replayed, None, None), &Silent).unwrap();
        for file in ["strip.png", "manifest.json"] {
            assert_eq!(
                std::fs::read(live.join(file)).unwrap(),
                std::fs::read(replayed.join(file)).unwrap(),
                "{file} differs after replay"
            );
        }
    }
    let _ = std::fs::remove_dir_all(&tmp);
}
