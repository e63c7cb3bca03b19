//! `rollfuse splice`: the time-splicing baseline (central strips placed by motion offsets,
//! seams blended).

use super::check_writable;
use anyhow::bail;
use rollfuse::frames::{self, manifest_path, motion_offsets, refuse_overwriting_inputs};
use rollfuse::fullres::{Placed, splice};
use rollfuse::image::PixelLimit;
use std::path::PathBuf;

/// Arguments of `rollfuse splice`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The frames, in acquisition order.
    #[arg(required = true)]
    pub frames: Vec<PathBuf>,
    /// The spliced image: an 8-bit PNG, or .npy (f32, the values unrounded).
    #[arg(long)]
    pub out: PathBuf,
    /// The acquisition's manifest (default: manifest.json beside the first frame).
    #[arg(long)]
    pub manifest: Option<PathBuf>,
    /// Rows blended either side of each seam.
    #[arg(long, default_value_t = 4)]
    pub blend: usize,
}

/// Runs the command, reading and building images within `limit`.
pub fn run(args: Args, limit: PixelLimit) -> anyhow::Result<()> {
    if args.frames.len() < 2 {
        bail!(
            "splicing needs at least two frames, got {}",
            args.frames.len()
        );
    }
    rollfuse::image::ImageFormat::of(&args.out)?;
    check_writable(&args.out)?;
    refuse_overwriting_inputs(&[&args.out], &args.frames, args.manifest.as_deref())?;
    let _folder = rollfuse::files::NewFolder::for_file(&args.out)?;
    let frames = frames::load(&args.frames, limit)?;
    let manifest = manifest_path(args.manifest.as_deref(), &args.frames);
    let offsets = motion_offsets(&manifest, &args.frames)?;
    let placed: Vec<Placed> = frames
        .iter()
        .zip(offsets)
        .map(|(image, at)| Placed { image, at })
        .collect();
    let out = splice(&placed, args.blend, limit)?;
    out.save(&args.out, 8)?;
    super::side_files::remove_others(&args.out, &[])?;
    println!(
        "spliced {} frames ({}×{}) → {}",
        placed.len(),
        out.width,
        out.height,
        args.out.display()
    );
    Ok(())
}
