//! `rollfuse demo`: the whole system on simulated data, end to end, and a report.
//!
//! The stages, each timed:
//!
//! 1. **acquire** — the letters scene rolled under the sensor: its camera frames (8-bit).
//! 2. **device** — the same scene streamed through the virtual device (the shared device
//!    pipeline, real message bytes) and its fused tiles stitched into a strip, exactly as
//!    `rollfuse stream --device sim` does.
//! 3. **full-res fusion** — the raw frames aligned by template matching and fused at full
//!    resolution on the host, as `rollfuse fuse` does.
//! 4. **evaluation** — Tables II and III on the letters scene's frames from stage 1, as
//!    `rollfuse eval` computes them.
//! 5. **depth** — the three-sphere RGB scene: depth from single and fused frames (Table IV,
//!    as `rollfuse eval --depth`).
//! 6. **detection** — the built-in defect detector on a held-out textile roll, and frames
//!    against fused tiles over one roll of each fabric ([`detection`]).
//! 7. **trade-off** — every device configuration against the f64 reference on the letters
//!    scene (`rollfuse tradeoff`, one repeat): the accuracy/time Pareto plot.
//! 8. **report** — `report.html`, one self-contained page ([`html`]).
//!
//! Every figure comes from the same functions the single-purpose commands use, so the
//! demo's tables are the ones those commands print for the same scenes.

pub mod detection;
pub mod html;
pub mod markup;
mod results;

pub use results::{Alignment, Demo, Files, Stage};

use crate::eval::depth::{self as depth_eval, DepthRow};
use crate::eval::tables::{self, Acquisition, Row, acquire, evaluate_acquired};
use crate::fullres::align::Offset;
use crate::fullres::roll::StripInMemory;
use crate::fullres::strip::{StripOptions, fuse_strip};
use crate::fullres::{Placed, Precision, fuse_mosaic};
use crate::image::{PixelLimit, Planes};
use crate::link::sim::SimDevice;
use crate::progress::{Progress, Silent};
use crate::sim::{Scene, built_in};
use crate::stream::{self, Outcome};
use crate::tradeoff::{self, Measured, bench::McuTable, report as tradeoff_report};
use anyhow::{Context, ensure};
use rollfuse_core::FuseConfig;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What the demo runs on and where it writes.
#[derive(Debug, Clone)]
pub struct Options {
    /// Output folder.
    pub out: PathBuf,
    /// The gray scene rolled under the sensor (none: the built-in letters).
    pub letters: Option<PathBuf>,
    /// The RGB three-sphere scene for depth (none: the built-in one).
    pub spheres: Option<PathBuf>,
    /// The Cortex-M7 bench results, if measured (instruction counts in the trade-off).
    pub bench: Option<PathBuf>,
}

/// Frames of the sequence shown in the report.
const SHOWN_FRAMES: usize = 6;

/// Runs every stage; `progress` counts the [`STAGES`] as they start, each named in its
/// message.
pub fn run(opts: &Options, progress: &dyn Progress) -> anyhow::Result<Demo> {
    progress.start("demo", Some(STAGES.len() as u64), "stages");
    let demo = run_stages(opts, progress);
    progress.finish();
    demo
}

/// The stages in order, then the report.
fn run_stages(opts: &Options, progress: &dyn Progress) -> anyhow::Result<Demo> {
    std::fs::create_dir_all(&opts.out)
        .with_context(|| format!("cannot create {}", opts.out.display()))?;
    crate::files::check_writable(&opts.out.join(Files::REPORT))?;
    let letters = built_in::scene_or(opts.letters.as_deref(), "letters")?;
    let spheres = built_in::scene_or(opts.spheres.as_deref(), "spheres")?;
    let out = opts.out.as_path();
    let mut clock = Clock::new(progress);

    let (acq, shown) = clock.stage(0, || show_frames(&letters, out))?;
    let (streamed, strip) = clock.stage(1, || stream_device(&letters, out))?;
    let (host_strip, alignment) = clock.stage(2, || fuse_roll(&letters, &acq, out))?;
    let eval = clock.stage(3, || evaluate(&letters, &acq, out))?;
    let depth = clock.stage(4, || measure_depth(&spheres, out))?;
    let detection = clock.stage(5, || detect_defects(out))?;
    let (measured, mcu_build) =
        clock.stage(6, || trade_off(&letters, opts.bench.as_deref(), out))?;

    let n = acq.frames.len();
    let (fw, fh) = (acq.frames[0].width, acq.frames[0].height);
    clock.announce(7);
    let demo = Demo {
        letters_name: letters.name.clone(),
        frames: (n, fw, fh),
        shown_frames: shown,
        strip_size: (strip.width, strip.height),
        stream: streamed.manifest,
        stream_stop: streamed.stop,
        alignment,
        host_strip_size: (host_strip.width, host_strip.height),
        frames_per_point: fh as f64 * (n - 1) as f64
            / (acq.rows[n - 1] - acq.rows[0]).max(1) as f64,
        eval,
        depth,
        detection,
        tradeoff: measured,
        mcu_build,
        stages: clock.stages,
    };
    // The report's own time cannot be in the report: the command prints it.
    let page = html::report(&demo, out)?;
    write(&out.join(Files::REPORT), &page)?;
    Ok(demo)
}

/// Stage 1: the letters scene's frames, a few of them written for the report; the
/// indices of those.
fn show_frames(letters: &Scene, out: &Path) -> Timed<(Acquisition, Vec<usize>)> {
    let acq = acquire(letters)?;
    let n = acq.frames.len();
    ensure!(
        n >= 7,
        "scene {} has {n} frames; the demo needs at least 7",
        letters.name
    );
    let (fw, fh) = (acq.frames[0].width, acq.frames[0].height);
    // Evenly spread over the roll, first and last included.
    let shown: Vec<usize> = (0..SHOWN_FRAMES)
        .map(|k| k * (n - 1) / (SHOWN_FRAMES - 1))
        .collect();
    for &i in &shown {
        acq.frames[i].save_png(&out.join(Files::frame(i)))?;
    }
    let what = format!("{n} frames of {fw}×{fh} rendered from {}", letters.name);
    Ok(((acq, shown), what))
}

/// Stage 2: the scene streamed through the virtual device; the session and its strip.
fn stream_device(letters: &Scene, out: &Path) -> Timed<(Outcome, Planes)> {
    let mut device = SimDevice::start(letters)?;
    let session = stream::Options {
        config: Some(device.default_config()),
        ..stream::Options::into_folder(&out.join("stream"))
    };
    let streamed = stream::run(&mut device, &session, &Silent)?;
    let strip = Planes::load(&out.join(Files::STRIP), PixelLimit::OWN)?;
    let m = &streamed.manifest;
    let what = format!(
        "{} tiles, {} bytes in {} messages through the virtual device",
        m.tiles_received, m.bytes, m.messages
    );
    Ok(((streamed, strip), what))
}

/// Stage 3: the roll fused at full resolution; the strip and how the alignment went.
fn fuse_roll(letters: &Scene, acq: &Acquisition, out: &Path) -> Timed<(Planes, Alignment)> {
    let (host_strip, alignment, middle) = fuse_full_resolution(letters, &acq.frames, &acq.rows)?;
    host_strip.save_png(&out.join(Files::HOST_STRIP))?;
    let n = acq.frames.len();
    acq.frames[(n - 1) / 2].save_png(&out.join(Files::SINGLE))?;
    middle.save_png(&out.join(Files::FUSED_MIDDLE))?;
    let what = format!(
        "{} of {n} frames matched, the roll fused over the contact window (db2, 1 level, f32)",
        alignment.matched + 1
    );
    Ok(((host_strip, alignment), what))
}

/// Stage 4: Tables II and III on the letters scene's frames.
fn evaluate(letters: &Scene, acq: &Acquisition, out: &Path) -> Timed<Vec<Row>> {
    let eval = evaluate_acquired(letters, acq, &FuseConfig::default(), 10)?;
    write(&out.join(Files::EVAL_MD), &tables::markdown(&eval))?;
    write(&out.join(Files::EVAL_CSV), &tables::csv(&eval))?;
    let what = format!("{} methods measured against the ideal contact", eval.len());
    Ok((eval, what))
}

/// Stage 5: Table IV on the sphere scene, and its height maps.
fn measure_depth(spheres: &Scene, out: &Path) -> Timed<Vec<DepthRow>> {
    let depth = depth_eval::evaluate_depth(spheres)?;
    let mut pictures = crate::files::Batch::new();
    for (r, name) in depth.iter().zip(Files::DEPTH_PNGS) {
        crate::depth::output::write_png(&r.depth, &mut pictures, &out.join(name))?;
    }
    pictures.commit()?;
    write(&out.join(Files::DEPTH_MD), &depth_eval::markdown(&depth))?;
    write(&out.join(Files::DEPTH_CSV), &depth_eval::csv(&depth))?;
    let what = format!("{} height maps from {}", depth.len(), spheres.name);
    Ok((depth, what))
}

/// Stage 6: the defect detector on textile rolls.
fn detect_defects(out: &Path) -> Timed<detection::DetectionDemo> {
    let detection = detection::run(out)?;
    let what = format!(
        "the detector on a {} roll and on {} held-out rolls",
        detection.fabric,
        crate::sim::textile::FABRICS.len()
    );
    Ok((detection, what))
}

/// Stage 7: every device configuration on the letters scene; the measurements and the
/// bench build their MCU figures come from.
fn trade_off(
    letters: &Scene,
    bench: Option<&Path>,
    out: &Path,
) -> Timed<(Vec<Measured>, Option<String>)> {
    let mcu = match bench {
        Some(p) if p.exists() => McuTable::load(p)?,
        _ => McuTable::empty(),
    };
    let setups = tradeoff::sweep();
    let study_scene = tradeoff::acquire(letters)?;
    let measured = tradeoff::study(&[study_scene], &setups, 1, &mcu, &Silent)?;
    let names = [letters.name.clone()];
    write(
        &out.join(Files::TRADEOFF_MD),
        &tradeoff_report::markdown(&measured, &names, mcu.build.as_deref()),
    )?;
    write(
        &out.join(Files::TRADEOFF_CSV),
        &tradeoff_report::csv(&measured),
    )?;
    write(
        &out.join(Files::PARETO),
        &tradeoff_report::pareto_svg(&measured)?,
    )?;
    let what = format!(
        "{} device configurations against the f64 reference",
        setups.len()
    );
    Ok(((measured, mcu.build), what))
}

/// The stages' names, in order.
pub const STAGES: [&str; 8] = [
    "acquire",
    "device",
    "full-res fusion",
    "evaluation",
    "depth",
    "detection",
    "trade-off",
    "report",
];

/// A stage's result, and what it did (a line of the report).
type Timed<T> = anyhow::Result<(T, String)>;

/// Times the stages and announces each to the progress.
struct Clock<'p> {
    stages: Vec<Stage>,
    progress: &'p dyn Progress,
}

impl<'p> Clock<'p> {
    fn new(progress: &'p dyn Progress) -> Self {
        Self {
            stages: Vec::new(),
            progress,
        }
    }

    /// Stage `k` of [`STAGES`] starts.
    fn announce(&self, k: usize) {
        self.progress.advance_to(k as u64);
        self.progress.message(STAGES[k]);
    }

    /// Runs stage `k`, which returns its result and what it did, and times it.
    fn stage<T>(&mut self, k: usize, run: impl FnOnce() -> Timed<T>) -> anyhow::Result<T> {
        self.announce(k);
        let since = Instant::now();
        let (value, what) = run()?;
        self.stages.push(Stage {
            name: STAGES[k],
            what,
            secs: since.elapsed().as_secs_f64(),
        });
        Ok(value)
    }
}

fn write(path: &Path, text: &str) -> anyhow::Result<()> {
    Ok(crate::files::write_bytes_atomic(path, text.as_bytes())?)
}

/// The roll at full resolution: `frames` aligned by matching (their belt rows by motion,
/// `rows`, as the prediction) and fused over the contact window of `scene`'s roller (the
/// host's defaults: db2, one level, f32). Returns the strip, how the alignment went, and
/// the fusion of the four frames around the middle one (Table III's "fusion of 4") over
/// the middle frame's footprint.
fn fuse_full_resolution(
    scene: &Scene,
    frames: &[Planes],
    rows: &[i64],
) -> anyhow::Result<(Planes, Alignment, Planes)> {
    let opts = StripOptions::tracked(
        scene.sensor.roller_geometry(),
        rows.iter().map(|&r| r as f64).collect(),
    );
    let mut disagreement = 0i64;
    let (sink, report) = fuse_strip(
        frames.iter().cloned().map(Ok),
        &opts,
        |_, _| Ok(StripInMemory::default()),
        |p| {
            disagreement = disagreement.max((p.row.round() as i64 - rows[p.frame]).abs());
            Ok(())
        },
    )?;
    let strip = sink.image.context("the roll gave an empty strip")?;
    let alignment = Alignment {
        frames: frames.len(),
        matched: report.placement.as_ref().map_or(0, |p| p.matched),
        predicted: report
            .placement
            .as_ref()
            .map_or(0, |p| p.predicted + p.unmatched),
        max_motion_disagreement: disagreement,
        window: report.window,
    };
    let placed: Vec<(usize, Placed)> = frames
        .iter()
        .zip(rows)
        .enumerate()
        .map(|(k, (image, &dy))| {
            (
                k,
                Placed {
                    image,
                    at: Offset { dy, dx: 0 },
                },
            )
        })
        .collect();
    // Frames m − 1 ..= m + 2, as the evaluation fuses them.
    let m = (frames.len() - 1) / 2;
    let four: Vec<Placed> = placed
        .iter()
        .filter(|(k, _)| (m.saturating_sub(1)..=m + 2).contains(k))
        .map(|(_, p)| *p)
        .collect();
    ensure!(
        four.len() == 4,
        "the frames around the middle one could not all be aligned"
    );
    let around = fuse_mosaic(
        &four,
        &FuseConfig::default(),
        Precision::F32,
        PixelLimit::OWN,
    )?;
    let middle = &four[1];
    let top = four.iter().map(|p| p.at.dy).min().unwrap_or(0);
    let left = four.iter().map(|p| p.at.dx).min().unwrap_or(0);
    let over_middle = around.crop(
        usize::try_from(middle.at.dy - top)?,
        usize::try_from(middle.at.dx - left)?,
        middle.image.height,
        middle.image.width,
    )?;
    Ok((strip, alignment, over_middle))
}
