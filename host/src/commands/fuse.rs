//! `rollfuse fuse`: full-resolution cyclic fusion of frames — a few frames of one object
//! into one image (the mosaic, paper Tables II–III), or a whole roll into a strip fused
//! over the contact window (docs/fusion.md, "Whole rolls").

use super::{
    AblationArg, LlWeightingArg, WaveletArg,
    bars::{Bars, Show},
    check_writable,
    side_files::{self, Side},
};
use crate::fullres::align::{Aligned, Match, Offset, TemplateParams, align_chain};
use crate::fullres::register::Tracker;
use crate::fullres::{Precision, fuse_mosaic_mut};
use crate::image::Planes;
use anyhow::{Context, bail, ensure};
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

/// `--mode`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ModeArg {
    /// A roll when the frames cannot all see one object (they span more than a frame
    /// height), otherwise a mosaic.
    Auto,
    /// Contact-window fusion of a roll into a strip, streamed.
    Roll,
    /// Every frame fused over its whole footprint into one image (a few frames of one
    /// object).
    Mosaic,
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

impl OutBits {
    /// Bits a sample.
    pub fn bits(self) -> u8 {
        match self {
            OutBits::Eight => 8,
            OutBits::Sixteen => 16,
        }
    }
}

/// Arguments of `rollfuse fuse`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The frames, in acquisition order (PNG, 8- or 16-bit, gray or RGB), or a folder:
    /// its `frame_*.png` files (if none, its `.png` files) in name order.
    #[arg(required = true)]
    pub frames: Vec<PathBuf>,
    /// The fused image (PNG). A roll longer than --segment-rows is written as numbered
    /// segments OUT_STEM.0000.png … listed with their belt rows in OUT_STEM.json.
    #[arg(long)]
    pub out: PathBuf,
    /// Roll or mosaic.
    #[arg(long, value_enum, default_value = "auto")]
    pub mode: ModeArg,
    /// Roll: rows of the contact window, centred on the middle row (default: from the
    /// manifest's roller geometry, else measured on the first frames).
    #[arg(long)]
    pub window_rows: Option<usize>,
    /// Roll: rows per fused band.
    #[arg(long, default_value_t = 32)]
    pub band_rows: usize,
    /// Roll: rows over which neighbouring bands are cross-faded (even, at most --band-rows).
    #[arg(long, default_value_t = 8)]
    pub blend_rows: usize,
    /// Roll: most rows per output segment.
    #[arg(long, default_value_t = crate::strip_file::DEFAULT_SEGMENT_ROWS)]
    pub segment_rows: usize,
    /// Roll, --align template: rows searched either side of the predicted position
    /// (default: 3 plus 30 % of the predicted step).
    #[arg(long)]
    pub search_rows: Option<usize>,
    /// Roll, --align template: whole-row positions only (no sub-pixel refinement).
    #[arg(long)]
    pub no_subpixel: bool,
    /// Roll, --align template: columns the belt may drift sideways between matched frames
    /// (default 0: the belt moves along the frame only).
    #[arg(long, default_value_t = 0)]
    pub max_drift_cols: usize,
    /// Roll, --align template: exit 0 even when the placement cannot be trusted (the belt
    /// lost, frames that matched nothing); the strip is written and marked either way.
    #[arg(long)]
    pub accept_untrusted: bool,
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
    /// Given with --align template on a roll, its commanded rows predict each position.
    #[arg(long)]
    pub manifest: Option<PathBuf>,
    /// With --align template: the template band, as fractions of the frame height.
    #[arg(long, value_delimiter = ',', default_values_t = [1.0 / 3.0, 2.0 / 3.0])]
    pub template_rows: Vec<f64>,
    /// With --align template: the largest shift searched along the belt, pixels (a roll:
    /// before the motion is known; default half a frame).
    #[arg(long)]
    pub max_shift: Option<usize>,
    /// With --align template: the lowest correlation accepted, 0..1 (default 0.5).
    #[arg(long)]
    pub min_score: Option<f32>,
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

/// Refuses outputs that are one of the input frames or the manifest (given, or the one
/// beside the frames).
pub fn refuse_overwriting_inputs(
    outputs: &[&Path],
    frames: &[PathBuf],
    manifest: Option<&Path>,
) -> anyhow::Result<()> {
    let manifest = manifest_path(manifest, frames);
    let inputs: Vec<(&str, &Path)> = frames
        .iter()
        .map(|p| ("input frame", p.as_path()))
        .chain([("manifest", manifest.as_path())])
        .collect();
    crate::files::refuse_overwriting(outputs, &inputs)
}

/// Loads every frame, checking they agree in size and colour.
pub fn load_frames(paths: &[PathBuf]) -> anyhow::Result<Vec<Planes>> {
    // Held together, the frames share the pixel limit: checked from their headers first.
    let limit = crate::image::max_pixels();
    let mut pixels = 0u64;
    for p in paths {
        let (w, h) = crate::image::dimensions(p)?;
        let one = u64::from(w) * u64::from(h);
        // One frame over the limit: no mode holds fewer than one frame.
        ensure!(
            one <= limit,
            "frame {} is {w}×{h} = {one} pixels, over the limit of {limit}: raise --max-pixels \
             to at least {one} to read it",
            p.display()
        );
        pixels = pixels.saturating_add(one);
    }
    ensure!(
        pixels <= limit,
        "{} frames of {pixels} pixels in all are over the limit of {limit} held at once \
         (--max-pixels): fuse a long sequence as a roll (--mode roll), which holds a few",
        paths.len()
    );
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
            let row = match &rec["strip_row"] {
                serde_json::Value::Null => {
                    anyhow::bail!("{}: frame {name} has no strip_row", manifest.display())
                }
                value => value.as_f64().filter(|r| r.is_finite()).with_context(|| {
                    format!(
                        "{}: frame {name} has strip_row {value}, not a number",
                        manifest.display()
                    )
                })?,
            };
            Ok(Offset {
                dy: row.round() as i64,
                dx: 0,
            })
        })
        .collect()
}

/// Frames an automatic choice of mode loads at once to find their span (a mosaic holds
/// them all anyway; more are always a roll).
const AUTO_LOAD_FRAMES: usize = 64;

/// The frames named on the command line: files as given, a folder as its `.png` files in
/// name order.
pub fn expand_frames(given: &[PathBuf]) -> anyhow::Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for p in given {
        if p.is_dir() {
            let mut pngs: Vec<PathBuf> = std::fs::read_dir(p)
                .with_context(|| format!("cannot list folder {}", p.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|f| {
                    f.extension().is_some_and(|e| e.eq_ignore_ascii_case("png"))
                        && !f
                            .file_name()
                            .is_some_and(|n| n.to_string_lossy().starts_with('.'))
                })
                .collect();
            pngs.sort();
            // A simulator's folder also holds a contact sheet: keep its frames only.
            let is_frame = |f: &PathBuf| {
                f.file_name()
                    .is_some_and(|n| n.to_string_lossy().starts_with("frame_"))
            };
            if pngs.iter().any(is_frame) {
                pngs.retain(is_frame);
            }
            if pngs.is_empty() {
                bail!("folder {} holds no .png frames", p.display());
            }
            out.extend(pngs);
        } else {
            out.push(p.clone());
        }
    }
    Ok(out)
}

/// What the command will do, with the frames it already loaded to decide.
enum Plan {
    Mosaic(Vec<Planes>),
    Roll(Option<Vec<Planes>>),
}

/// Runs the command, showing progress as `show` says.
pub fn run(mut args: Args, show: Show) -> anyhow::Result<()> {
    args.frames = expand_frames(&args.frames)?;
    if args.frames.len() < 2 {
        bail!(
            "fusion needs at least two frames, got {}",
            args.frames.len()
        );
    }
    if !(1..=4).contains(&args.levels) {
        bail!("--levels must be 1..=4, got {}", args.levels);
    }
    if let Some(m) = args.min_score.filter(|m| !(0.0..=1.0).contains(m)) {
        bail!("--min-score must be in 0..=1, got {m}");
    }
    crate::files::require_png_name(&args.out)?;
    match args.template_rows[..] {
        [t0, t1] if 0.0 <= t0 && t0 < t1 && t1 <= 1.0 => {}
        _ => bail!(
            "--template-rows must be two fractions 0 ≤ top < bottom ≤ 1, as A,B; got {:?}",
            args.template_rows
        ),
    }
    if args.window_rows == Some(0) {
        bail!("--window-rows must be at least 1");
    }
    if args.band_rows < 2 || !args.blend_rows.is_multiple_of(2) || args.blend_rows > args.band_rows
    {
        bail!(
            "bands of {} rows cannot be cross-faded over {} rows: --blend-rows must be even \
             and at most --band-rows (at least 2)",
            args.band_rows,
            args.blend_rows
        );
    }
    if args.segment_rows == 0 {
        bail!("--segment-rows must be at least 1");
    }
    check_reaches(&args)?;
    let cfg = FuseConfig {
        wavelet: args.wavelet.into(),
        levels: args.levels,
        ablation: args.ablation.into(),
        norm: SaliencyNorm::Local,
        ll_weighting: args.ll_weighting.into(),
    };
    let (plan, why) = plan(&args)?;
    if args.mode == ModeArg::Auto {
        println!("mode: {why}");
    }
    match plan {
        Plan::Mosaic(frames) => run_mosaic(&args, frames, &cfg, show),
        Plan::Roll(loaded) => super::fuse_roll::run(&args, loaded, &cfg, show),
    }
}

/// Refuses an aligner's reach past the frames
/// ([`crate::fullres::track::TrackParams::check`]); a mosaic's largest shift is bounded as
/// a roll's first search is.
fn check_reaches(args: &Args) -> anyhow::Result<()> {
    let (w, h) = crate::image::dimensions(&args.frames[0])?;
    let (w, h) = (w as usize, h as usize);
    super::fuse_roll::track_params(args, h).check(w, h)
}

/// Chooses roll or mosaic (`--mode auto`: a roll when the frames span more than a frame
/// height along the belt, so they cannot all see one object), with the reason in words.
fn plan(args: &Args) -> anyhow::Result<(Plan, &'static str)> {
    let auto = match (args.mode, args.align) {
        (ModeArg::Mosaic, _) => return Ok((Plan::Mosaic(load_frames(&args.frames)?), "mosaic")),
        (ModeArg::Auto, AlignArg::None) => {
            let frames = load_frames(&args.frames)?;
            return Ok((
                Plan::Mosaic(frames),
                "mosaic (--align none places no frame)",
            ));
        }
        (ModeArg::Roll, _) => return Ok((Plan::Roll(None), "roll")),
        (ModeArg::Auto, align) => align,
    };
    let (_, h) = crate::image::dimensions(&args.frames[0])?;
    let h = f64::from(h);
    let span = |rows: &mut dyn Iterator<Item = f64>| {
        let (lo, hi) = rows.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), r| {
            (a.min(r), b.max(r))
        });
        hi - lo
    };
    const ROLL: &str = "roll (the frames span a frame height or more along the belt)";
    const MOSAIC: &str = "mosaic (the frames span less than a frame height)";
    if auto == AlignArg::Motion {
        let manifest = manifest_path(args.manifest.as_deref(), &args.frames);
        let offsets = motion_offsets(&manifest, &args.frames)?;
        return Ok(if span(&mut offsets.iter().map(|o| o.dy as f64)) >= h {
            (Plan::Roll(None), ROLL)
        } else {
            (Plan::Mosaic(load_frames(&args.frames)?), MOSAIC)
        });
    }
    if args.frames.len() > AUTO_LOAD_FRAMES {
        return Ok((Plan::Roll(None), "roll (more than 64 frames)"));
    }
    let frames = load_frames(&args.frames)?;
    let params = super::fuse_roll::track_params(args, frames[0].height);
    let rows: Vec<f64> = Tracker::place_all(&frames, params)
        .0
        .iter()
        .map(|p| p.row)
        .collect();
    Ok(if span(&mut rows.into_iter()) >= h {
        (Plan::Roll(Some(frames)), ROLL)
    } else {
        (Plan::Mosaic(frames), MOSAIC)
    })
}

/// Fuses every frame over its whole footprint into one image (a few frames of one object).
fn run_mosaic(
    args: &Args,
    frames: Vec<Planes>,
    cfg: &FuseConfig,
    show: Show,
) -> anyhow::Result<()> {
    let offsets_path = Side::Offsets.path(&args.out);
    check_writable(&args.out)?;
    check_writable(&offsets_path)?;
    refuse_overwriting_inputs(
        &[&args.out, &offsets_path],
        &args.frames,
        args.manifest.as_deref(),
    )?;
    let _folder = crate::files::NewFolder::for_file(&args.out)?;
    let (placed, record) = match args.align {
        AlignArg::None => unaligned(&args.frames),
        AlignArg::Motion => by_motion(args)?,
        AlignArg::Template => by_template(args, &frames, show)?,
    };

    // Fusion may work in the frames (they are not needed afterwards): no copies.
    let mut frames: Vec<Option<Planes>> = frames.into_iter().map(Some).collect();
    let mut placed: Vec<(Planes, Offset)> = placed
        .into_iter()
        .filter_map(|(k, at)| Some((frames.get_mut(k)?.take()?, at)))
        .collect();
    let started = std::time::Instant::now();
    let fused = fuse_mosaic_mut(&mut placed, cfg, args.precision)?;
    let took = started.elapsed().as_secs_f64();
    fused.save_png_bits(&args.out, args.out_bits.bits())?;
    let json = serde_json::to_string_pretty(&record)? + "\n";
    crate::files::write_bytes_atomic(&offsets_path, json.as_bytes())?;
    side_files::remove_others(&args.out, &[Side::Offsets])?;
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

/// Frames placed by index, and the record of their offsets.
type Alignment<'a> = (Vec<(usize, Offset)>, OffsetsFile<'a>);

/// Every frame at the origin (`--align none`).
fn unaligned(files: &[PathBuf]) -> Alignment<'_> {
    let at = Offset { dy: 0, dx: 0 };
    let record = OffsetsFile {
        align: "none",
        frames: files
            .iter()
            .map(|file| FrameOffset {
                file,
                at,
                matched: None,
            })
            .collect(),
        skipped: Vec::new(),
    };
    ((0..files.len()).map(|k| (k, at)).collect(), record)
}

/// Every frame where the manifest's belt motion puts it (`--align motion`).
fn by_motion(args: &Args) -> anyhow::Result<Alignment<'_>> {
    let manifest = manifest_path(args.manifest.as_deref(), &args.frames);
    let offsets = motion_offsets(&manifest, &args.frames)?;
    let placed: Vec<(usize, Offset)> = offsets.into_iter().enumerate().collect();
    let record = OffsetsFile {
        align: "motion",
        frames: args
            .frames
            .iter()
            .zip(&placed)
            .map(|(file, &(_, at))| FrameOffset {
                file,
                at,
                matched: None,
            })
            .collect(),
        skipped: Vec::new(),
    };
    Ok((placed, record))
}

/// Every frame matched against the last one kept (`--align template`); a frame that does
/// not match is skipped, with a message.
fn by_template<'a>(args: &'a Args, frames: &[Planes], show: Show) -> anyhow::Result<Alignment<'a>> {
    let defaults = TemplateParams::default();
    let params = TemplateParams {
        rows: (args.template_rows[0], args.template_rows[1]),
        max_dy: args.max_shift.unwrap_or(defaults.max_dy),
        min_score: args.min_score.unwrap_or(defaults.min_score),
        ..defaults
    };
    let mut placed = Vec::new();
    let mut record = OffsetsFile {
        align: "template",
        frames: Vec::new(),
        skipped: Vec::new(),
    };
    let chain = align_chain(frames, &params, &Bars::new(show));
    for ((k, file), aligned) in args.frames.iter().enumerate().zip(chain) {
        match aligned {
            Aligned::Placed { at, matched } => {
                warn_of_doubtful_match(file, matched, params.max_dy);
                placed.push((k, at));
                record.frames.push(FrameOffset { file, at, matched });
            }
            Aligned::Skipped(reason) => {
                eprintln!("skipped {}: {reason}", file.display());
                record.skipped.push(Skipped { file, reason });
            }
        }
    }
    if placed.len() < 2 {
        bail!("only one frame could be aligned; nothing to fuse (see the messages above)");
    }
    Ok((placed, record))
}

/// Warns of a match that may be wrong: ambiguous (periodic texture), or at the edge of
/// the search (`max_dy` rows).
fn warn_of_doubtful_match(file: &Path, matched: Option<Match>, max_dy: usize) {
    for doubt in matched.iter().flat_map(|m| m.doubts(max_dy)) {
        eprintln!("warning: {} {doubt}", file.display());
    }
}
