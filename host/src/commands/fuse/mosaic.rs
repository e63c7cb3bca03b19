//! `rollfuse fuse` on a few frames of one object: every frame fused over its whole
//! footprint into one image (the mosaic, paper Tables II–III).

use super::args::{AlignArg, Args};
use crate::commands::bars::{Bars, Show};
use crate::commands::check_writable;
use crate::commands::side_files::{self, Side};
use anyhow::bail;
use rollfuse::frames::{manifest_path, motion_offsets, refuse_overwriting_inputs};
use rollfuse::fullres::align::{Aligned, Match, Offset, TemplateParams, align_chain};
use rollfuse::fullres::fuse_mosaic_mut;
use rollfuse::image::{PixelLimit, Planes};
use rollfuse_core::FuseConfig;
use std::path::{Path, PathBuf};

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

/// Fuses every frame over its whole footprint into one image (a few frames of one object).
pub fn run(
    args: &Args,
    frames: Vec<Planes>,
    cfg: &FuseConfig,
    show: Show,
    limit: PixelLimit,
) -> anyhow::Result<()> {
    let offsets_path = Side::Offsets.path(&args.out);
    check_writable(&args.out)?;
    check_writable(&offsets_path)?;
    refuse_overwriting_inputs(
        &[&args.out, &offsets_path],
        &args.frames,
        args.manifest.as_deref(),
    )?;
    let _folder = rollfuse::files::NewFolder::for_file(&args.out)?;
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
    let fused = fuse_mosaic_mut(&mut placed, cfg, args.precision, limit)?;
    let took = started.elapsed().as_secs_f64();
    fused.save(&args.out, args.out_bits.bits())?;
    let json = serde_json::to_string_pretty(&record)? + "\n";
    rollfuse::files::write_bytes_atomic(&offsets_path, json.as_bytes())?;
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
