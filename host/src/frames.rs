//! A sequence of frames on disk: a folder's frames in order, loaded within the pixel
//! limit, and where their motion record says each one lies on the belt.

use crate::fullres::align::Offset;
use crate::image::{PixelLimit, Planes};
use crate::sim::Manifest;
use anyhow::{Context, bail, ensure};
use std::path::{Path, PathBuf};

/// The frames named on the command line: files as given, a folder as its `.png` files in
/// name order.
pub fn expand(given: &[PathBuf]) -> anyhow::Result<Vec<PathBuf>> {
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
    Ok(crate::files::refuse_overwriting(outputs, &inputs)?)
}

/// Loads every frame, checking they agree in size and colour; held together, they share
/// `max` (checked from their headers before any is decoded).
pub fn load(paths: &[PathBuf], max: PixelLimit) -> anyhow::Result<Vec<Planes>> {
    let limit = max.pixels();
    let mut pixels = 0u64;
    for p in paths {
        let (w, h) = crate::image::dimensions(p)?;
        let one = u64::from(w) * u64::from(h);
        // One frame over the limit: no mode holds fewer than one frame.
        ensure!(
            max.admits(one),
            "frame {} is {w}×{h} = {one} pixels, over the limit of {limit}: raise --max-pixels \
             to at least {one} to read it",
            p.display()
        );
        pixels = pixels.saturating_add(one);
    }
    ensure!(
        max.admits(pixels),
        "{} frames of {pixels} pixels in all are over the limit of {limit} held at once \
         (--max-pixels): fuse a long sequence as a roll (--mode roll), which holds a few",
        paths.len()
    );
    let frames: Vec<Planes> = paths
        .iter()
        .map(|p| Ok(Planes::load(p, max)?))
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

/// Commanded belt offsets of `paths` from a manifest ([`Manifest`]), as canvas rows.
pub fn motion_offsets(manifest: &Path, paths: &[PathBuf]) -> anyhow::Result<Vec<Offset>> {
    let record = Manifest::read(manifest)?;
    paths
        .iter()
        .map(|p| {
            let name = p.file_name().and_then(|n| n.to_str()).unwrap_or_default();
            let frame = record
                .frame(name)
                .with_context(|| format!("{} is not in {}", p.display(), manifest.display()))?;
            Ok(Offset {
                dy: frame.strip_row.round() as i64,
                dx: 0,
            })
        })
        .collect()
}
