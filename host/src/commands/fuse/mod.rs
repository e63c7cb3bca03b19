//! `rollfuse fuse`: full-resolution cyclic fusion of frames — a few frames of one object
//! into one image (the mosaic, paper Tables II–III), or a whole roll into a strip fused
//! over the contact window (docs/fusion.md, "Whole rolls").

mod args;
mod mosaic;
mod roll;

pub use args::{AlignArg, Args, ModeArg};

use crate::commands::bars::Show;
use anyhow::bail;
use rollfuse::frames::{self, manifest_path, motion_offsets};
use rollfuse::fullres::register::{LOST_RUN, Tracker};
use rollfuse::image::{ImageFormat, PixelLimit, Planes};
use rollfuse_core::{FuseConfig, SaliencyNorm};

/// Frames an automatic choice of mode loads at once to find their span (a mosaic holds
/// them all anyway; more are always a roll).
const AUTO_LOAD_FRAMES: usize = 64;

/// What the command will do, with the frames it already loaded to decide.
enum Plan {
    Mosaic(Vec<Planes>),
    Roll(Option<Vec<Planes>>),
}

/// Runs the command, showing progress as `show` says.
pub fn run(mut args: Args, show: Show, limit: PixelLimit) -> anyhow::Result<()> {
    args.frames = frames::expand(&args.frames)?;
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
    let format = ImageFormat::of(&args.out)?;
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
        wavelet: args.wavelet,
        levels: args.levels,
        ablation: args.ablation,
        norm: SaliencyNorm::Local,
        ll_weighting: args.ll_weighting,
    };
    let (plan, why) = plan(&args, limit)?;
    if args.mode == ModeArg::Auto {
        println!("mode: {why}");
    }
    if matches!(plan, Plan::Mosaic(_)) && args.record.records.is_some() {
        bail!(
            "--records keeps rolls: a mosaic of a few frames is not one (--mode roll fuses a roll)"
        );
    }
    if matches!(plan, Plan::Roll(_)) && format != ImageFormat::Png {
        bail!(
            "{}: a roll's strip is written as it grows, in PNG segments; name it .png (a \
             mosaic may be any image format)",
            args.out.display()
        );
    }
    match plan {
        Plan::Mosaic(frames) => mosaic::run(&args, frames, &cfg, show, limit),
        Plan::Roll(loaded) => roll::run(&args, loaded, &cfg, show, limit),
    }
}

/// Refuses an aligner's reach past the frames
/// ([`rollfuse::fullres::track::TrackParams::check`]); a mosaic's largest shift is bounded as
/// a roll's first search is.
fn check_reaches(args: &Args) -> anyhow::Result<()> {
    let (w, h) = rollfuse::image::dimensions(&args.frames[0])?;
    let (w, h) = (w as usize, h as usize);
    Ok(args.track_params(h).check(w, h)?)
}

/// Chooses roll or mosaic (`--mode auto`: a roll when the frames span more than a frame
/// height along the belt, so they cannot all see one object), with the reason in words.
fn plan(args: &Args, limit: PixelLimit) -> anyhow::Result<(Plan, &'static str)> {
    let auto = match (args.mode, args.align) {
        (ModeArg::Mosaic, _) => {
            return Ok((Plan::Mosaic(frames::load(&args.frames, limit)?), "mosaic"));
        }
        (ModeArg::Auto, AlignArg::None) => {
            let frames = frames::load(&args.frames, limit)?;
            return Ok((
                Plan::Mosaic(frames),
                "mosaic (--align none places no frame)",
            ));
        }
        (ModeArg::Roll, _) => return Ok((Plan::Roll(None), "roll")),
        (ModeArg::Auto, align) => align,
    };
    let (_, h) = rollfuse::image::dimensions(&args.frames[0])?;
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
            (Plan::Mosaic(frames::load(&args.frames, limit)?), MOSAIC)
        });
    }
    if args.frames.len() > AUTO_LOAD_FRAMES {
        return Ok((Plan::Roll(None), "roll (more than 64 frames)"));
    }
    let frames = frames::load(&args.frames, limit)?;
    let params = args.track_params(frames[0].height);
    let (placed, summary) = Tracker::place_all(&frames, params);
    if summary.longest_lost.0 >= LOST_RUN {
        // A run of textured frames that matched nothing: their span is as unknown as
        // their placement, so they are fused as a roll, which says so.
        return Ok((
            Plan::Roll(Some(frames)),
            "roll (textured frames matched nothing: their span is unknown)",
        ));
    }
    Ok(if span(&mut placed.iter().map(|p| p.row)) >= h {
        (Plan::Roll(Some(frames)), ROLL)
    } else {
        (Plan::Mosaic(frames), MOSAIC)
    })
}
