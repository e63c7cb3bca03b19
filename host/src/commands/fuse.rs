//! `rollfuse fuse`: full-resolution cyclic fusion of a folder's worth of frames.

use super::{AblationArg, LlWeightingArg, WaveletArg, check_writable, simulate::progress};
use crate::fullres::align::{Aligned, Match, Offset, TemplateParams, align_chain};
use crate::fullres::{Precision, fuse_mosaic_mut};
use crate::image::Planes;
use anyhow::{Context, bail};
use rollfuse_core::{FuseConfig, SaliencyNorm};
use std::path::{Path, PathBuf};

/// `--align`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum AlignArg {
    /// Frames are already aligned: all at the same place.
    None,
    /// Each frame matched against the previous one (normalized cross-correlation).
    Template,
    /// Belt offsets from the acquisition's manifest.json (commanded motion).
    Motion,
}

/// `--out-bits`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum OutBits {
    /// 8-bit PNG.
    #[value(name = "8")]
    Eight,
    /// 16-bit PNG (the 8-bit scale times 257).
    #[value(name = "16")]
    Sixteen,
}

/// Arguments of `rollfuse fuse`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The frames, in acquisition order (PNG, 8- or 16-bit, gray or RGB).
    #[arg(required = true)]
    pub frames: Vec<PathBuf>,
    /// The fused image (PNG).
    #[arg(long)]
    pub out: PathBuf,
    /// Bits per sample of the output PNG: 8, or 16 to keep the fused values' fractions.
    #[arg(long, value_enum, default_value = "8")]
    pub out_bits: OutBits,
    /// Wavelet.
    #[arg(long, value_enum, default_value = "db2")]
    pub wavelet: WaveletArg,
    /// Decomposition levels, 1..=4.
    #[arg(long, default_value_t = 1)]
    pub levels: u8,
    /// How frames are placed on the common canvas.
    #[arg(long, value_enum, default_value = "template")]
    pub align: AlignArg,
    /// With --align motion: the manifest (default: manifest.json beside the first frame).
    #[arg(long)]
    pub manifest: Option<PathBuf>,
    /// With --align template: the template band, as fractions of the frame height.
    #[arg(long, value_delimiter = ',', num_args = 2, default_values_t = [1.0 / 3.0, 2.0 / 3.0])]
    pub template_rows: Vec<f64>,
    /// With --align template: the largest shift searched along the belt, pixels.
    #[arg(long, default_value_t = 200)]
    pub max_shift: usize,
    /// With --align template: the lowest correlation accepted (0..1).
    #[arg(long, default_value_t = 0.5)]
    pub min_score: f32,
    /// Remove one part of the method (paper Table II).
    #[arg(long, value_enum, default_value = "none")]
    pub ablation: AblationArg,
    /// f32 (host) or fixed (the MCU's integer path, on 8-bit data).
    #[arg(long, value_enum, default_value = "f32")]
    pub precision: Precision,
    /// How the LL band weighs each frame.
    #[arg(long, value_enum, default_value = "paper")]
    pub ll_weighting: LlWeightingArg,
}

/// What `FUSED.offsets.json` records.
#[derive(Debug, serde::Serialize)]
struct OffsetsFile<'a> {
    align: &'static str,
    frames: Vec<FrameOffset<'a>>,
    skipped: Vec<Skipped<'a>>,
}

#[derive(Debug, serde::Serialize)]
struct FrameOffset<'a> {
    file: &'a Path,
    at: Offset,
    #[serde(skip_serializing_if = "Option::is_none")]
    matched: Option<Match>,
}

#[derive(Debug, serde::Serialize)]
struct Skipped<'a> {
    file: &'a Path,
    reason: String,
}

/// Refuses an output path that is one of the inputs.
pub fn refuse_overwriting_inputs(out: &Path, inputs: &[PathBuf]) -> anyhow::Result<()> {
    let canon = |p: &Path| std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf());
    let out_c = canon(out);
    if let Some(same) = inputs.iter().find(|p| canon(p) == out_c) {
        bail!(
            "--out {} is one of the input frames ({})",
            out.display(),
            same.display()
        );
    }
    Ok(())
}

/// Loads every frame, checking they agree in size and colour.
pub fn load_frames(paths: &[PathBuf]) -> anyhow::Result<Vec<Planes>> {
    let frames: Vec<Planes> = paths
        .iter()
        .map(|p| Planes::load(p))
        .collect::<anyhow::Result<_>>()?;
    if let Some(first) = frames.first() {
        for (p, f) in paths.iter().zip(&frames) {
            if (f.width, f.height) != (first.width, first.height) {
                bail!(
                    "{} is {}×{} but {} is {}×{}: all frames must have one size",
                    p.display(),
                    f.width,
                    f.height,
                    paths[0].display(),
                    first.width,
                    first.height
                );
            }
            if f.is_rgb() != first.is_rgb() {
                bail!(
                    "{} and {} mix gray and RGB",
                    paths[0].display(),
                    p.display()
                );
            }
        }
    }
    Ok(frames)
}

/// The manifest to read motion from: the one given, or `manifest.json` beside the first
/// frame (where `rollfuse simulate` writes it).
pub fn manifest_path(given: Option<&Path>, frames: &[PathBuf]) -> PathBuf {
    match given {
        Some(m) => m.to_path_buf(),
        None => frames
            .first()
            .and_then(|f| f.parent())
            .unwrap_or(Path::new("."))
            .join("manifest.json"),
    }
}

/// Commanded belt offsets of `paths` from a simulator manifest, as canvas rows.
pub fn motion_offsets(manifest: &Path, paths: &[PathBuf]) -> anyhow::Result<Vec<Offset>> {
    let text = std::fs::read_to_string(manifest)
        .with_context(|| format!("cannot read manifest {}", manifest.display()))?;
    let doc: serde_json::Value = serde_json::from_str(&text)
        .with_context(|| format!("{} is not valid JSON", manifest.display()))?;
    let frames = doc["frames"]
        .as_array()
        .with_context(|| format!("{}: no `frames` list", manifest.display()))?;
    paths
        .iter()
        .map(|p| {
            let name = p.file_name().and_then(|n| n.to_str()).unwrap_or_default();
            let rec = frames
                .iter()
                .find(|f| f["file"].as_str() == Some(name))
                .with_context(|| format!("{} is not in {}", p.display(), manifest.display()))?;
            let row = rec["strip_row"].as_f64().with_context(|| {
                format!("{}: frame {name} has no strip_row", manifest.display())
            })?;
            Ok(Offset {
                dy: row.round() as i64,
                dx: 0,
            })
        })
        .collect()
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    if args.frames.len() < 2 {
        bail!(
            "fusion needs at least two frames, got {}",
            args.frames.len()
        );
    }
    if !(1..=4).contains(&args.levels) {
        bail!("--levels must be 1..=4, got {}", args.levels);
    }
    if !(0.0..=1.0).contains(&args.min_score) {
        bail!("--min-score must be in 0..=1, got {}", args.min_score);
    }
    let (t0, t1) = (args.template_rows[0], args.template_rows[1]);
    if !(0.0 <= t0 && t0 < t1 && t1 <= 1.0) {
        bail!("--template-rows must be two fractions 0 ≤ top < bottom ≤ 1, got {t0},{t1}");
    }
    let offsets_path = args.out.with_extension("offsets.json");
    check_writable(&args.out)?;
    check_writable(&offsets_path)?;
    refuse_overwriting_inputs(&args.out, &args.frames)?;
    refuse_overwriting_inputs(&offsets_path, &args.frames)?;
    let frames = load_frames(&args.frames)?;
    let cfg = FuseConfig {
        wavelet: args.wavelet.into(),
        levels: args.levels,
        ablation: args.ablation.into(),
        norm: SaliencyNorm::Local,
        ll_weighting: args.ll_weighting.into(),
    };

    let mut placed = Vec::new();
    let mut record = OffsetsFile {
        align: "",
        frames: Vec::new(),
        skipped: Vec::new(),
    };
    match args.align {
        AlignArg::None => {
            record.align = "none";
            for (k, p) in args.frames.iter().enumerate() {
                placed.push((k, Offset { dy: 0, dx: 0 }));
                record.frames.push(FrameOffset {
                    file: p,
                    at: Offset { dy: 0, dx: 0 },
                    matched: None,
                });
            }
        }
        AlignArg::Motion => {
            record.align = "motion";
            let manifest = manifest_path(args.manifest.as_deref(), &args.frames);
            let offsets = motion_offsets(&manifest, &args.frames)?;
            for ((k, p), at) in args.frames.iter().enumerate().zip(offsets) {
                placed.push((k, at));
                record.frames.push(FrameOffset {
                    file: p,
                    at,
                    matched: None,
                });
            }
        }
        AlignArg::Template => {
            record.align = "template";
            let params = TemplateParams {
                rows: (t0, t1),
                max_dy: args.max_shift,
                max_dx: 8,
                min_score: args.min_score,
            };
            let bar = progress(frames.len(), "frames", "aligning".into());
            let chain = align_chain(&frames, &params, |k| bar.set_position(k as u64));
            for ((k, file), aligned) in args.frames.iter().enumerate().zip(chain) {
                match aligned {
                    Aligned::Placed { at, matched } => {
                        if let Some(m) = matched.filter(Match::is_ambiguous) {
                            eprintln!(
                                "warning: {} matches ambiguously (score {:.3}, runner-up {:.3}): periodic texture?",
                                file.display(),
                                m.score,
                                m.runner_up
                            );
                        }
                        placed.push((k, at));
                        record.frames.push(FrameOffset { file, at, matched });
                    }
                    Aligned::Skipped(reason) => {
                        eprintln!("skipped {}: {reason}", file.display());
                        record.skipped.push(Skipped { file, reason });
                    }
                }
            }
            bar.finish_and_clear();
            if placed.len() < 2 {
                bail!("only one frame could be aligned; nothing to fuse (see the messages above)");
            }
        }
    }

    // Fusion may work in the frames (they are not needed afterwards): no copies.
    let mut frames: Vec<Option<Planes>> = frames.into_iter().map(Some).collect();
    let mut placed: Vec<(Planes, Offset)> = placed
        .into_iter()
        .filter_map(|(k, at)| Some((frames.get_mut(k)?.take()?, at)))
        .collect();
    let started = std::time::Instant::now();
    let fused = fuse_mosaic_mut(&mut placed, &cfg, args.precision)?;
    let took = started.elapsed().as_secs_f64();
    let bits = match args.out_bits {
        OutBits::Eight => 8,
        OutBits::Sixteen => 16,
    };
    fused.save_png_bits(&args.out, bits)?;
    std::fs::write(&offsets_path, serde_json::to_string_pretty(&record)? + "\n")
        .with_context(|| format!("cannot write {}", offsets_path.display()))?;
    println!("offsets (rows, columns) on the canvas:");
    for f in &record.frames {
        println!("  {:>6} {:>4}  {}", f.at.dy, f.at.dx, f.file.display());
    }
    println!(
        "fused {} of {} frames ({}×{}) → {} (offsets in {}); fusion took {took:.4} s",
        record.frames.len(),
        args.frames.len(),
        fused.width,
        fused.height,
        args.out.display(),
        offsets_path.display()
    );
    Ok(())
}
