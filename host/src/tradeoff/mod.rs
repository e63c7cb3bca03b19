//! The trade-off study: what each device configuration buys in accuracy and costs in time.
//!
//! For every configuration of the sweep (wavelet × levels × downsampling × fixed/`f32` fuse
//! step × per-tile/per-frame normalization, [`sweep`]) the core's device pipeline — the code
//! the firmware runs — fuses a simulated acquisition into tiles. Each configuration is
//! compared with the **reference**: the same tile schedule (the same observations of the
//! same belt rows, in the same order) fused in `f64` at full resolution, normalized per
//! frame ([`reference`]). So the figures measure what downsampling, the integer or `f32`
//! arithmetic and per-tile normalization lose, not the tiling itself. A configuration's
//! tiles are upsampled to full resolution by repeating each pixel (what a downsampled pixel
//! stands for) before comparing.
//!
//! Time comes from two places: host nanoseconds per camera pixel (a frame's time over its
//! pixels before downsampling), measured here in the same run, and Cortex-M7 instructions per frame, read from the bench's CSV
//! ([`bench`], written by `tests/mcu-bench/run.sh`).

pub mod bench;
pub mod report;
mod setup;

pub use setup::{Setup, sweep};

use crate::eval::metrics::{Gray, entropy, ms_ssim};
use crate::link::sim::{camera_bytes, sensor_for};
use crate::pipeline_memory::PipelineMemory;
use crate::progress::Progress;
use crate::sim::{Scene, Simulator};
use anyhow::{Context, bail, ensure};
use rollfuse_core::device::downsample::downsample;
use rollfuse_core::device::{Pipeline, PipelineConfig, Schedule, Sensor};
use rollfuse_core::fusion::LlWeight;
use rollfuse_core::protocol::DeviceConfig;
use rollfuse_core::saliency::laplacian_max_u8;
use rollfuse_core::{Dims, FuseConfig, SaliencyNorm, float};
use std::collections::BTreeMap;
use std::time::Instant;

/// A scene's frames as the virtual device's camera delivers them.
pub struct Acquisition {
    /// Scene name.
    pub name: String,
    /// The camera.
    pub sensor: Sensor,
    /// The device configuration the virtual device starts with for this scene (its frame
    /// spacing; tile rows and frames per tile are the product's).
    pub base: DeviceConfig,
    /// Camera frames and their commanded belt positions, camera pixels from the first.
    pub frames: Vec<(Vec<u8>, u64)>,
}

/// Renders every frame of `scene` as [`crate::link::sim`]'s virtual device would.
pub fn acquire(scene: &Scene) -> anyhow::Result<Acquisition> {
    let sim = Simulator::new(scene)?;
    let (sensor, base) = sensor_for(scene, &sim);
    let mut frames = Vec::with_capacity(sim.frames());
    let mut origin = None;
    for k in 0..sim.frames() {
        let f = sim.frame(k);
        let at = sim.strip_row_of_top(f.offset_mm);
        let origin = *origin.get_or_insert(at);
        frames.push((
            camera_bytes(&f.image),
            (at - origin).round().max(0.0) as u64,
        ));
    }
    Ok(Acquisition {
        name: scene.name.clone(),
        sensor,
        base,
        frames,
    })
}

/// Fused tiles by belt index: observations and samples (row-major, `width` wide).
#[derive(Debug, Clone)]
pub struct Tiles<T> {
    /// Tile width, pixels.
    pub width: usize,
    /// Tile height, rows.
    pub rows: usize,
    /// Index → (observations, samples).
    pub tiles: BTreeMap<u64, (u8, Vec<T>)>,
}

/// What one configuration's device run gave.
#[derive(Debug, Clone)]
pub struct DeviceRun {
    /// The emitted tiles.
    pub tiles: Tiles<u8>,
    /// Each frame's belt offset as the pipeline placed it (after refinement),
    /// downsampled rows.
    pub offsets: Vec<u64>,
    /// Host time per frame, seconds: the best of the timed runs, rendering excluded.
    pub secs_per_frame: f64,
}

/// Runs the device pipeline of `setup` over the acquisition, `repeats` times.
pub fn run_device(acq: &Acquisition, setup: &Setup, repeats: usize) -> anyhow::Result<DeviceRun> {
    let wire = setup.wire(&acq.base);
    let cfg = PipelineConfig::from_wire(&wire, acq.sensor)
        .map_err(|r| anyhow::anyhow!("{}: the device refuses it ({r:?})", setup.label()))?
        .with_precision(setup.precision);
    let mut memory = PipelineMemory::new(&cfg.memory());
    let tile = cfg.tile_dims();
    let mut best = f64::INFINITY;
    let mut offsets = Vec::with_capacity(acq.frames.len());
    let mut out = Tiles {
        width: tile.width(),
        rows: tile.height(),
        tiles: BTreeMap::new(),
    };
    for _ in 0..repeats.max(1) {
        let mut pipe = Pipeline::new(cfg, memory.buffers())?;
        let mut emitted = Vec::new();
        let mut keep = |t: rollfuse_core::protocol::Tile<'_>| {
            emitted.push((u64::from(t.index), t.observations, t.pixels.to_vec()))
        };
        offsets.clear();
        let start = Instant::now();
        for (k, (bytes, at)) in acq.frames.iter().enumerate() {
            let report = pipe
                .push_frame(bytes, *at, &mut keep)
                .map_err(|e| anyhow::anyhow!("frame {k}: {e:?}"))?;
            offsets.push(report.offset);
        }
        pipe.finish(&mut keep);
        best = best.min(start.elapsed().as_secs_f64());
        out.tiles = emitted
            .into_iter()
            .map(|(i, obs, px)| (i, (obs, px)))
            .collect();
    }
    Ok(DeviceRun {
        tiles: out,
        offsets,
        secs_per_frame: best / acq.frames.len().max(1) as f64,
    })
}

/// The reference for configurations of `setup`'s wavelet, levels and downsampling: the
/// same schedule at full resolution (tiles `d` times taller, so each covers the same belt
/// rows; frames at the belt offsets the device placed them at, `offsets` in its
/// downsampled rows), fused in `f64`, normalized per frame (over the rows its tiles cover).
pub fn reference(acq: &Acquisition, setup: &Setup, offsets: &[u64]) -> anyhow::Result<Tiles<f64>> {
    let wire = setup.wire(&acq.base);
    let d = usize::from(setup.downsample);
    let (w, h) = (acq.sensor.width, acq.sensor.height);
    let t = usize::from(wire.tile_rows) * d;
    let n = usize::from(wire.frames_per_tile);
    let dev = PipelineConfig::from_wire(&wire, acq.sensor)
        .map_err(|r| anyhow::anyhow!("{}: the device refuses it ({r:?})", setup.label()))?;
    // The device's spacing in whole downsampled rows, so a spacing that is not a multiple
    // of `d` plans the same observations here as there.
    let schedule = Schedule::new(h, t, n, dev.spacing_rows() * d);
    ensure!(
        schedule.window_rows <= h,
        "the reference's observation window ({} rows) is taller than the frame ({h})",
        schedule.window_rows
    );
    let tile = Dims::new(w, t)?;
    ensure!(
        offsets.len() == acq.frames.len(),
        "{} offsets for {} frames",
        offsets.len(),
        acq.frames.len()
    );
    let mut gray = vec![0u8; w * h];
    let mut b = vec![0f64; tile.pixels()];
    let mut scratch = vec![0f64; float::fuse_scratch_len(tile)];
    let mut tiles: BTreeMap<u64, (u8, Vec<f64>)> = BTreeMap::new();
    for ((bytes, _), &offset) in acq.frames.iter().zip(offsets) {
        let at = offset * d as u64;
        downsample(bytes, acq.sensor.format, (w, h), 1, &mut gray)
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        // Normalized over the rows the frame's tiles cover, as the device does (inside
        // the window, and `window_rows <= h` was checked above).
        let rows = schedule.observed_rows(at);
        let band = &gray[rows.start * w..rows.end * w];
        let norm = match Dims::new(w, rows.len()) {
            Ok(band_dims) => laplacian_max_u8(band, band_dims),
            Err(_) => 0, // no tile observed: nothing is fused
        };
        let cfg = FuseConfig {
            norm: SaliencyNorm::Reference(norm),
            ..dev.fuse()
        };
        for index in schedule.observed(at) {
            let row = schedule.frame_row(index, at);
            let Some(src) = gray.get(row * w..(row + t) * w) else {
                bail!("tile {index} lies outside frame rows {row}..{}", row + t);
            };
            match tiles.get_mut(&index) {
                None => {
                    tiles.insert(index, (1, src.iter().map(|&v| f64::from(v)).collect()));
                }
                Some((obs, a)) => {
                    for (d, &v) in b.iter_mut().zip(src) {
                        *d = f64::from(v);
                    }
                    let ll = LlWeight::for_frame(cfg.ll_weighting, u32::from(*obs) + 1);
                    float::fuse_pair(a, &mut b, tile, &cfg, ll, &mut scratch)?;
                    *obs += 1;
                }
            }
        }
    }
    Ok(Tiles {
        width: w,
        rows: t,
        tiles,
    })
}

/// How close a configuration's output is to the reference.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Accuracy {
    /// Peak signal-to-noise ratio, dB (peak 255).
    pub psnr_db: f64,
    /// MS-SSIM (gray-normalized, as `rollfuse metrics`).
    pub ms_ssim: f64,
    /// Largest absolute difference, gray levels.
    pub max_abs: f64,
    /// Information entropy against the reference's, percent.
    pub ie_change_pct: f64,
    /// Full-resolution pixels compared.
    pub pixels: usize,
}

/// Compares `tiles` (downsampled `d`×) with `reference` over the tiles both have with the
/// most observations any tile got: the run's first and last tiles see fewer frames, and a
/// spacing that is not a whole number of downsampled rows (10 px at 4×) may give every
/// tile fewer than the frames per tile.
pub fn compare(tiles: &Tiles<u8>, reference: &Tiles<f64>, d: usize) -> anyhow::Result<Accuracy> {
    ensure!(
        tiles.width * d == reference.width && tiles.rows * d == reference.rows,
        "tiles of {}×{} at {d}× do not cover the reference's {}×{}",
        tiles.width,
        tiles.rows,
        reference.width,
        reference.rows
    );
    let w = reference.width;
    let observations = tiles.tiles.values().map(|(obs, _)| *obs).max().unwrap_or(0);
    let (mut ours, mut theirs) = (Vec::new(), Vec::new());
    for (index, (obs, px)) in &tiles.tiles {
        let Some((ref_obs, ref_px)) = reference.tiles.get(index) else {
            continue;
        };
        if *obs != observations || *ref_obs != observations {
            continue;
        }
        // Each downsampled pixel repeated over the d×d pixels it stands for.
        for y in 0..reference.rows {
            let row = &px[(y / d) * tiles.width..(y / d + 1) * tiles.width];
            ours.extend((0..w).map(|x| f64::from(row[x / d])));
        }
        theirs.extend_from_slice(ref_px);
    }
    ensure!(
        !ours.is_empty(),
        "no tile got the same {observations} observations in both runs: the scene is too short"
    );
    let n = ours.len();
    let (mut sq, mut max_abs) = (0.0, 0f64);
    for (a, b) in ours.iter().zip(&theirs) {
        let e = a - b;
        sq += e * e;
        max_abs = max_abs.max(e.abs());
    }
    let mse = sq / n as f64;
    let psnr_db = 10.0 * (255.0 * 255.0 / mse).log10();
    let to8 = |v: &[f64]| -> Vec<u8> {
        v.iter()
            .map(|x| x.round().clamp(0.0, 255.0) as u8)
            .collect()
    };
    let (ie, ie_ref) = (entropy(&to8(&ours)), entropy(&to8(&theirs)));
    let height = n / w;
    let ms = ms_ssim(&Gray::new(w, height, ours)?, &Gray::new(w, height, theirs)?)?;
    Ok(Accuracy {
        psnr_db,
        ms_ssim: ms,
        max_abs,
        ie_change_pct: if ie_ref > 0.0 {
            100.0 * (ie - ie_ref) / ie_ref
        } else {
            0.0
        },
        pixels: n,
    })
}

/// One configuration's figures over the study's scenes.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Measured {
    /// The configuration.
    #[serde(skip)]
    pub setup: Setup,
    /// Accuracy, averaged over the scenes (`max_abs`: the largest).
    pub accuracy: Accuracy,
    /// Host time per frame over its camera pixels, ns per pixel (mean over the scenes):
    /// comparable across downsampling factors.
    pub host_ns_per_px: f64,
    /// Cortex-M7 instructions per frame and whether it fits the firmware's RAM, when the
    /// bench measured this configuration.
    pub mcu: Option<bench::McuCost>,
}

/// Runs the study on `scenes` for `setups`; `progress` counts the configurations measured.
pub fn study(
    scenes: &[Acquisition],
    setups: &[Setup],
    repeats: usize,
    mcu: &bench::McuTable,
    progress: &dyn Progress,
) -> anyhow::Result<Vec<Measured>> {
    ensure!(!scenes.is_empty(), "no scenes to study");
    // References depend on wavelet, levels and downsampling only: one per scene each.
    let mut references: BTreeMap<(String, u8, u8, u8), Tiles<f64>> = BTreeMap::new();
    let mut out = Vec::with_capacity(setups.len());
    progress.start("measuring", Some(setups.len() as u64), "configurations");
    for (k, setup) in setups.iter().enumerate() {
        let mut per_scene = Vec::new();
        let mut ns = 0.0;
        for acq in scenes {
            let key = (
                acq.name.clone(),
                setup.wavelet as u8,
                setup.levels,
                setup.downsample,
            );
            let run = run_device(acq, setup, repeats)
                .with_context(|| format!("{} on {}", setup.label(), acq.name))?;
            if !references.contains_key(&key) {
                // Refinement sees the downsampled frames only, so every configuration of
                // one downsampling places the frames alike.
                let r = reference(acq, setup, &run.offsets)
                    .with_context(|| format!("reference for {} on {}", setup.label(), acq.name))?;
                references.insert(key.clone(), r);
            }
            let camera_px = acq.sensor.width * acq.sensor.height;
            ns += run.secs_per_frame * 1e9 / camera_px as f64;
            per_scene.push(
                compare(&run.tiles, &references[&key], usize::from(setup.downsample))
                    .with_context(|| format!("{} on {}", setup.label(), acq.name))?,
            );
        }
        let m = per_scene.len() as f64;
        let mean = |f: fn(&Accuracy) -> f64| per_scene.iter().map(f).sum::<f64>() / m;
        out.push(Measured {
            setup: *setup,
            accuracy: Accuracy {
                psnr_db: mean(|a| a.psnr_db),
                ms_ssim: mean(|a| a.ms_ssim),
                max_abs: per_scene.iter().map(|a| a.max_abs).fold(0.0, f64::max),
                ie_change_pct: mean(|a| a.ie_change_pct),
                pixels: per_scene.iter().map(|a| a.pixels).sum(),
            },
            host_ns_per_px: ns / m,
            mcu: mcu.get(setup),
        });
        progress.advance_to(k as u64 + 1);
    }
    progress.finish();
    Ok(out)
}
