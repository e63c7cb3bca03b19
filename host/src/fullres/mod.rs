//! Full-resolution fusion on the host: frames placed on a common canvas (the mosaic) and
//! fused cyclically where they overlap, per colour channel, on the `f32` path of
//! `rollfuse-core` (or its integer MCU path, for comparison).
//!
//! Frame `k` is fused into the running mosaic over its own footprint: pixels of the
//! footprint the mosaic has not seen yet take the frame's own values first (fusing an
//! image with itself returns it), so the first frame over any region passes through and
//! later frames fuse with what is there.

pub mod align;

use crate::image::Planes;
use align::Offset;
use anyhow::{bail, ensure};
use rayon::prelude::*;
use rollfuse_core::fusion::{LlWeight, U8Work, fuse_scratch_len, fuse_u8};
use rollfuse_core::{Dims, FuseConfig, float};

/// Which arithmetic fuses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
pub enum Precision {
    /// `f32` (the host's full-resolution path).
    F32,
    /// The MCU's integer path on 8-bit data (16-bit input is rounded to 8 bits).
    Fixed,
}

/// A frame and where it lies on the canvas.
#[derive(Debug, Clone, Copy)]
pub struct Placed<'a> {
    /// The frame.
    pub image: &'a Planes,
    /// Its pixel (0, 0) on the canvas.
    pub at: Offset,
}

/// Largest mosaic, in pixels per channel.
pub const MAX_MOSAIC_PIXELS: usize = 1 << 28;

/// The canvas covering every frame: its origin (smallest offsets) and size, refused when
/// larger than [`MAX_MOSAIC_PIXELS`].
fn canvas(frames: &[Placed], w: usize, h: usize) -> anyhow::Result<(i64, i64, usize, usize)> {
    let span = |f: fn(&Placed) -> i64| {
        let (lo, hi) = frames
            .iter()
            .map(f)
            .fold((i64::MAX, i64::MIN), |(a, b), v| (a.min(v), b.max(v)));
        hi.checked_sub(lo)
            .and_then(|d| usize::try_from(d).ok())
            .map(|d| (lo, d))
    };
    let ((min_x, dx), (min_y, dy)) = match (span(|f| f.at.dx), span(|f| f.at.dy)) {
        (Some(x), Some(y)) => (x, y),
        _ => bail!("frame offsets span more than the canvas can hold"),
    };
    let (cw, ch) = (dx.saturating_add(w), dy.saturating_add(h));
    ensure!(
        cw.checked_mul(ch).is_some_and(|n| n <= MAX_MOSAIC_PIXELS),
        "a mosaic of {cw}×{ch} pixels is larger than {MAX_MOSAIC_PIXELS}: are the offsets right?"
    );
    Ok((min_x, min_y, cw, ch))
}

/// Fuses `frames`, in order, into one mosaic covering all of them. All frames must have
/// the same size and the same number of channels.
pub fn fuse_mosaic(
    frames: &[Placed],
    cfg: &FuseConfig,
    precision: Precision,
) -> anyhow::Result<Planes> {
    ensure!(!frames.is_empty(), "no frames to fuse");
    let first = frames[0].image;
    let (w, h, channels) = (first.width, first.height, first.planes.len());
    for (k, f) in frames.iter().enumerate() {
        if (f.image.width, f.image.height) != (w, h) {
            bail!(
                "frame {k} is {}×{}, frame 0 is {w}×{h}: all frames must have one size",
                f.image.width,
                f.image.height
            );
        }
        if f.image.planes.len() != channels {
            bail!(
                "frame {k} has {} channels, frame 0 has {channels}: mix of gray and RGB",
                f.image.planes.len()
            );
        }
    }
    Dims::new(w, h)?.check_levels(cfg.levels)?;
    let min_y = frames.iter().map(|f| f.at.dy).min().unwrap_or(0);
    let min_x = frames.iter().map(|f| f.at.dx).min().unwrap_or(0);
    let cw = (frames.iter().map(|f| f.at.dx).max().unwrap_or(0) - min_x) as usize + w;
    let ch = (frames.iter().map(|f| f.at.dy).max().unwrap_or(0) - min_y) as usize + h;
    ensure!(
        cw <= 4 * rollfuse_core::MAX_DIMENSION && ch <= 4 * rollfuse_core::MAX_DIMENSION,
        "mosaic of {cw}×{ch} is too large"
    );
    // Channels are independent: fuse them in parallel (results do not depend on threads).
    let planes: Vec<Vec<f32>> = (0..channels)
        .into_par_iter()
        .map(|c| fuse_channel(frames, c, (min_x, min_y), (cw, ch), cfg, precision))
        .collect::<anyhow::Result<_>>()?;
    Ok(Planes {
        width: cw,
        height: ch,
        planes,
    })
}

fn fuse_channel(
    frames: &[Placed],
    c: usize,
    (min_x, min_y): (i64, i64),
    (cw, ch): (usize, usize),
    cfg: &FuseConfig,
    precision: Precision,
) -> anyhow::Result<Vec<f32>> {
    let (w, h) = (frames[0].image.width, frames[0].image.height);
    let mut mosaic = vec![0f32; cw * ch];
    let mut seen = vec![false; cw * ch];
    let mut fuser = Fuser::new(w, h, cfg, precision)?;
    for (k, f) in frames.iter().enumerate() {
        let (ox, oy) = ((f.at.dx - min_x) as usize, (f.at.dy - min_y) as usize);
        let frame = &f.image.planes[c];
        // The mosaic under this footprint, holes filled from the frame.
        let mut under = vec![0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                let i = (oy + y) * cw + ox + x;
                under[y * w + x] = if seen[i] { mosaic[i] } else { frame[y * w + x] };
            }
        }
        let ll = LlWeight::for_frame(cfg.ll_weighting, k as u32 + 1);
        let fused = if k == 0 {
            under
        } else {
            fuser.fuse(&under, frame, ll)?
        };
        for y in 0..h {
            for x in 0..w {
                let i = (oy + y) * cw + ox + x;
                mosaic[i] = fused[y * w + x];
                seen[i] = true;
            }
        }
    }
    Ok(mosaic)
}

/// One fuse step's buffers, allocated once per channel.
struct Fuser {
    dims: Dims,
    cfg: FuseConfig,
    precision: Precision,
    a: Vec<f32>,
    b: Vec<f32>,
    scratch: Vec<f32>,
    ia: Vec<i32>,
    ib: Vec<i32>,
    iscratch: Vec<i32>,
}

impl Fuser {
    fn new(w: usize, h: usize, cfg: &FuseConfig, precision: Precision) -> anyhow::Result<Self> {
        let dims = Dims::new(w, h)?;
        let (f, i) = match precision {
            Precision::F32 => (1, 0),
            Precision::Fixed => (0, 1),
        };
        Ok(Self {
            dims,
            cfg: *cfg,
            precision,
            a: vec![0.0; f * w * h],
            b: vec![0.0; f * w * h],
            scratch: vec![0.0; f * float::fuse_scratch_len(dims)],
            ia: vec![0; i * w * h],
            ib: vec![0; i * w * h],
            iscratch: vec![0; i * fuse_scratch_len(dims)],
        })
    }

    fn fuse(&mut self, a: &[f32], b: &[f32], ll: LlWeight) -> anyhow::Result<Vec<f32>> {
        let dims = self.dims;
        match self.precision {
            Precision::F32 => {
                self.a.copy_from_slice(a);
                self.b.copy_from_slice(b);
                float::fuse_pair(
                    &mut self.a,
                    &mut self.b,
                    dims,
                    &self.cfg,
                    ll,
                    &mut self.scratch,
                )?;
                Ok(self.a.clone())
            }
            Precision::Fixed => {
                let to8 = |v: &[f32]| {
                    v.iter()
                        .map(|x| x.round().clamp(0.0, 255.0) as u8)
                        .collect::<Vec<u8>>()
                };
                let (a8, b8) = (to8(a), to8(b));
                let work = U8Work {
                    a: &mut self.ia,
                    b: &mut self.ib,
                    scratch: &mut self.iscratch,
                };
                fuse_u8((&a8, dims), (&b8, dims), &self.cfg, ll, work)?;
                Ok(self.ia.iter().map(|&v| v as f32).collect())
            }
        }
    }
}

/// The time-splicing baseline (paper Tables I and III): every canvas row comes from the
/// frame whose centre row (the roller's apex) is nearest to it, and neighbouring frames'
/// strips are blended linearly over `blend` rows either side of each seam. Columns are
/// not shifted. All frames must agree in size and channels, as for [`fuse_mosaic`].
pub fn splice(frames: &[Placed], blend: usize) -> anyhow::Result<Planes> {
    ensure!(!frames.is_empty(), "no frames to splice");
    let first = frames[0].image;
    let (w, h, channels) = (first.width, first.height, first.planes.len());
    for (k, f) in frames.iter().enumerate() {
        ensure!(
            (f.image.width, f.image.height, f.image.planes.len()) == (w, h, channels),
            "frame {k} differs in size or channels from frame 0"
        );
    }
    let (_, min_y, _, ch) = canvas(frames, w, h)?;
    // Apex rows on the canvas, in canvas order.
    let mut apexes: Vec<(f64, usize)> = frames
        .iter()
        .enumerate()
        .map(|(k, f)| ((f.at.dy - min_y) as f64 + h as f64 / 2.0, k))
        .collect();
    apexes.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut planes = vec![vec![0f32; w * ch]; channels];
    let blend = blend as f64;
    for y in 0..ch {
        let yc = y as f64 + 0.5;
        // Weights: each frame that covers the row, by a tent around its strip's seams.
        let mut weights: Vec<(usize, f64)> = Vec::new();
        for (i, &(apex, k)) in apexes.iter().enumerate() {
            let top = (frames[k].at.dy - min_y) as f64;
            if yc < top || yc >= top + h as f64 {
                continue;
            }
            let lo = if i == 0 {
                f64::NEG_INFINITY
            } else {
                (apexes[i - 1].0 + apex) / 2.0
            };
            let hi = if i + 1 == apexes.len() {
                f64::INFINITY
            } else {
                (apex + apexes[i + 1].0) / 2.0
            };
            // Signed distance into the strip: the weight is ½ at a seam, 1 from `blend`
            // rows inside, 0 from `blend` rows outside.
            let into = (yc - lo).min(hi - yc);
            let wgt = if blend > 0.0 {
                (0.5 + into / (2.0 * blend)).clamp(0.0, 1.0)
            } else {
                f64::from(into >= 0.0)
            };
            if wgt > 0.0 {
                weights.push((k, wgt));
            }
        }
        let total: f64 = weights.iter().map(|(_, w)| w).sum();
        if total <= 0.0 {
            continue;
        }
        for (c, plane) in planes.iter_mut().enumerate() {
            for x in 0..w {
                let v: f64 = weights
                    .iter()
                    .map(|&(k, wgt)| {
                        let fy = (y as i64 - (frames[k].at.dy - min_y)) as usize;
                        wgt * f64::from(frames[k].image.planes[c][fy * w + x])
                    })
                    .sum();
                plane[y * w + x] = (v / total) as f32;
            }
        }
    }
    Ok(Planes {
        width: w,
        height: ch,
        planes,
    })
}
