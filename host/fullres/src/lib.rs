//! Full-resolution fusion on the host: frames placed on a common canvas (the mosaic) and
//! fused cyclically where they overlap, per colour channel, on the `f32` path of
//! `rollfuse-core` (or its integer MCU path, for comparison).
//!
//! Frame `k` is fused into the running mosaic over its own footprint: pixels of the
//! footprint the mosaic has not seen yet take the frame's own values first (fusing an
//! image with itself returns it), so the first frame over any region passes through and
//! later frames fuse with what is there.
//!
//! A whole roll is fused as it arrives ([`roll`]) and written as it grows, in indexed PNG
//! segments ([`strip_file`]).
//!
//! Every fallible function returns [`Error`]: input that cannot be fused, a strip file
//! that could not be read or written, or the error of a frame, sink or callback the
//! caller handed in.

pub mod align;
pub mod contact;
mod error;
pub mod register;
pub mod roll;
pub mod strip;
pub mod strip_file;
pub mod window;

use align::Offset;
pub use error::{Error, Result};
use rayon::prelude::*;
use rollfuse_core::fusion::{
    Join, LlWeight, Sequential, U8Pair, U8Work, fuse_scratch_len, fuse_u8,
};
use rollfuse_core::{Dims, FuseConfig, float};
use rollfuse_io::image::{PixelLimit, Planes};

/// Which arithmetic fuses: the core's [`Precision`](rollfuse_core::device::Precision), here
/// on frames of any size (the integer path rounds 16-bit input to 8 bits).
pub use rollfuse_core::device::Precision;

/// A frame and where it lies on the canvas.
#[derive(Debug, Clone, Copy)]
pub struct Placed<'a> {
    /// The frame.
    pub image: &'a Planes,
    /// Its pixel (0, 0) on the canvas.
    pub at: Offset,
}

/// The canvas covering every frame: its origin (smallest offsets) and size, refused when
/// larger than `limit`: a wrong offset in a manifest is an error, not gigabytes allocated.
fn canvas(
    offsets: &[Offset],
    w: usize,
    h: usize,
    limit: PixelLimit,
) -> crate::Result<(i64, i64, usize, usize)> {
    let span = |f: fn(&Offset) -> i64| {
        let (lo, hi) = offsets
            .iter()
            .map(f)
            .fold((i64::MAX, i64::MIN), |(a, b), v| (a.min(v), b.max(v)));
        hi.checked_sub(lo)
            .and_then(|d| usize::try_from(d).ok())
            .map(|d| (lo, d))
    };
    let ((min_x, dx), (min_y, dy)) = match (span(|at| at.dx), span(|at| at.dy)) {
        (Some(x), Some(y)) => (x, y),
        _ => rollfuse_io::invalid!("frame offsets span more than the canvas can hold"),
    };
    let (cw, ch) = (dx.saturating_add(w), dy.saturating_add(h));
    rollfuse_io::require!(
        cw.checked_mul(ch)
            .is_some_and(|n| u64::try_from(n).is_ok_and(|n| limit.admits(n))),
        "a canvas of {cw}×{ch} pixels is larger than the limit of {} (--max-pixels; \
         Python's max_pixels): are the offsets right?",
        limit.pixels()
    );
    Ok((min_x, min_y, cw, ch))
}

/// Fuses `frames`, in order, into one mosaic covering all of them. All frames must have
/// the same size and the same number of channels. The frames are left as they are; see
/// [`fuse_mosaic_mut`] to let fusion work in them and save a copy of each.
///
/// ```
/// use rollfuse_fullres::{Placed, Precision, align::Offset, fuse_mosaic};
/// use rollfuse_io::image::{PixelLimit, Planes};
/// use rollfuse_core::FuseConfig;
///
/// // Two 64×48 gray frames of a ramp, the second 16 rows further along.
/// let frame = |top: usize| Planes {
///     width: 64,
///     height: 48,
///     planes: vec![(0..64 * 48).map(|i| ((top + i / 64) * 2) as f32).collect()],
/// };
/// let (a, b) = (frame(0), frame(16));
/// let frames = [
///     Placed { image: &a, at: Offset { dy: 0, dx: 0 } },
///     Placed { image: &b, at: Offset { dy: 16, dx: 0 } },
/// ];
/// let mosaic = fuse_mosaic(&frames, &FuseConfig::default(), Precision::F32, PixelLimit::default())?;
/// assert_eq!((mosaic.width, mosaic.height), (64, 64));
/// // Where only one frame lies, the mosaic is that frame.
/// assert_eq!(mosaic.planes[0][..64], a.planes[0][..64]);
/// # anyhow::Ok(())
/// ```
pub fn fuse_mosaic(
    frames: &[Placed],
    cfg: &FuseConfig,
    precision: Precision,
    limit: PixelLimit,
) -> crate::Result<Planes> {
    let frames = frames
        .iter()
        .map(|f| (FrameRef::Kept(f.image), f.at))
        .collect();
    fuse_frames(frames, cfg, precision, limit)
}

/// [`fuse_mosaic`] that may work in the frames: each frame's planes serve as the fuse
/// step's work space where its rows lie as on the canvas (no horizontal offsets), and the
/// first frame's become the mosaic when every frame covers the same pixels. That saves a
/// copy of each frame and the first touch of as much fresh memory: a sixth of the fusion
/// time of six 1280×960 frames (`bash host/bench/compare.sh`). On return the frames'
/// planes hold unspecified values (or none).
pub fn fuse_mosaic_mut(
    frames: &mut [(Planes, Offset)],
    cfg: &FuseConfig,
    precision: Precision,
    limit: PixelLimit,
) -> crate::Result<Planes> {
    let frames = frames
        .iter_mut()
        .map(|(image, at)| (FrameRef::Spent(image), *at))
        .collect();
    fuse_frames(frames, cfg, precision, limit)
}

/// A frame, or a plane of one, that fusion must leave as it is, or may overwrite.
enum FrameRef<'a, T: ?Sized> {
    Kept(&'a T),
    Spent(&'a mut T),
}

impl<T: ?Sized> std::ops::Deref for FrameRef<'_, T> {
    type Target = T;
    fn deref(&self) -> &T {
        match self {
            FrameRef::Kept(v) => v,
            FrameRef::Spent(v) => v,
        }
    }
}

/// Frames that fusion reads one channel plane at a time, into a buffer it reuses: input
/// held in another type or layout (a numpy array of uint8) is converted frame by frame,
/// as fusion reaches it, instead of all at once, so it costs one frame's memory, not all
/// of them.
pub trait FrameSource: Sync {
    /// How many frames there are.
    fn frames(&self) -> usize;
    /// Every frame's width, height and number of channels (1 gray, 3 RGB).
    fn shape(&self) -> (usize, usize, usize);
    /// Writes channel `channel` of frame `frame` into `out` (`width × height`, row-major,
    /// on the 8-bit scale). Called only with `frame < frames()` and `channel` below the
    /// number of channels.
    fn read(&self, frame: usize, channel: usize, out: &mut [f32]);
}

/// [`fuse_mosaic`] of the frames of `source`, frame `k` at `offsets[k]`, each read when
/// fusion reaches it. The result is the same as that of [`fuse_mosaic`] on the frames.
pub fn fuse_mosaic_from(
    source: &dyn FrameSource,
    offsets: &[Offset],
    cfg: &FuseConfig,
    precision: Precision,
    limit: PixelLimit,
) -> crate::Result<Planes> {
    rollfuse_io::require!(
        offsets.len() == source.frames(),
        "{} offsets for {} frames",
        offsets.len(),
        source.frames()
    );
    rollfuse_io::require!(!offsets.is_empty(), "no frames to fuse");
    let (w, h, channels) = source.shape();
    let per_channel = (0..channels)
        .map(|c| {
            (0..offsets.len())
                .map(|k| Plane::Read(source, k, c))
                .collect()
        })
        .collect();
    fuse_planes(per_channel, offsets, (w, h), cfg, precision, limit)
}

fn fuse_frames(
    frames: Vec<(FrameRef<Planes>, Offset)>,
    cfg: &FuseConfig,
    precision: Precision,
    limit: PixelLimit,
) -> crate::Result<Planes> {
    let Some((first, _)) = frames.first() else {
        rollfuse_io::invalid!("no frames to fuse");
    };
    let (w, h, channels) = (first.width, first.height, first.planes.len());
    for (k, (image, _)) in frames.iter().enumerate() {
        if (image.width, image.height) != (w, h) {
            rollfuse_io::invalid!(
                "frame {k} is {}×{}, frame 0 is {w}×{h}: all frames must have one size",
                image.width,
                image.height
            );
        }
        if image.planes.len() != channels {
            rollfuse_io::invalid!(
                "frame {k} has {} channels, frame 0 has {channels}: mix of gray and RGB",
                image.planes.len()
            );
        }
    }
    let offsets: Vec<Offset> = frames.iter().map(|(_, at)| *at).collect();
    // One list of planes per channel, each kept or spent as its frame is.
    let mut per_channel: Vec<Vec<Plane>> = (0..channels)
        .map(|_| Vec::with_capacity(frames.len()))
        .collect();
    for (image, _) in frames {
        match image {
            FrameRef::Kept(image) => {
                for (list, plane) in per_channel.iter_mut().zip(&image.planes) {
                    list.push(Plane::Kept(plane));
                }
            }
            FrameRef::Spent(image) => {
                for (list, plane) in per_channel.iter_mut().zip(&mut image.planes) {
                    list.push(Plane::Spent(plane));
                }
            }
        }
    }
    fuse_planes(per_channel, &offsets, (w, h), cfg, precision, limit)
}

/// One channel of one frame, as fusion gets it.
enum Plane<'a> {
    /// To be left as it is.
    Kept(&'a Vec<f32>),
    /// Fusion may overwrite it.
    Spent(&'a mut Vec<f32>),
    /// Read from a source (frame, channel) into a buffer fusion owns.
    Read(&'a dyn FrameSource, usize, usize),
}

/// Fuses `w × h` planes, one list per channel, frame `k` at `offsets[k]`.
fn fuse_planes(
    per_channel: Vec<Vec<Plane>>,
    offsets: &[Offset],
    (w, h): (usize, usize),
    cfg: &FuseConfig,
    precision: Precision,
    limit: PixelLimit,
) -> crate::Result<Planes> {
    Dims::new(w, h)?.check_levels(cfg.levels)?;
    let (min_x, min_y, cw, ch) = canvas(offsets, w, h, limit)?;
    let starts: Vec<usize> = offsets
        .iter()
        .map(|at| (at.dy - min_y) as usize * cw + (at.dx - min_x) as usize)
        .collect();
    // Channels are independent: fuse them in parallel (results do not depend on threads).
    let planes: Vec<Vec<f32>> = per_channel
        .into_par_iter()
        .map(|planes| fuse_channel(planes, &starts, (w, h), (cw, ch), cfg, precision))
        .collect::<crate::Result<_>>()?;
    Ok(Planes {
        width: cw,
        height: ch,
        planes,
    })
}

/// Fuses one channel's planes (`w × h`, packed), frame `k` at `starts[k]` on the canvas.
fn fuse_channel(
    planes: Vec<Plane>,
    starts: &[usize],
    (w, h): (usize, usize),
    (cw, ch): (usize, usize),
    cfg: &FuseConfig,
    precision: Precision,
) -> crate::Result<Vec<f32>> {
    let mut fuser = Fuser::new(w, h, cw, cfg, precision)?;
    let mut frames = planes.into_iter().zip(starts).enumerate();
    // When every frame covers the whole canvas the first passes through as the mosaic
    // (what the general case below makes of it) and no pixel needs tracking.
    let (mut mosaic, mut seen) = if (cw, ch) == (w, h) {
        let first = frames.next().map(|(_, (plane, _))| match plane {
            Plane::Kept(plane) => plane.clone(),
            Plane::Spent(plane) => std::mem::take(plane),
            Plane::Read(source, k, c) => {
                let mut plane = vec![0.0; w * h];
                source.read(k, c, &mut plane);
                plane
            }
        });
        (first.unwrap_or_default(), None)
    } else {
        (vec![0f32; cw * ch], Some(vec![false; cw * ch]))
    };
    // Where planes are read from a source, one buffer takes each in turn.
    let mut read = Vec::new();
    for (k, (plane, &start)) in frames {
        let frame = match plane {
            Plane::Kept(plane) => FrameRef::Kept(plane),
            Plane::Spent(plane) => FrameRef::Spent(plane),
            Plane::Read(source, k, c) => {
                read.resize(w * h, 0.0);
                source.read(k, c, &mut read);
                FrameRef::Spent(&mut read)
            }
        };
        // The footprint's holes take the frame's own values: fusing them with themselves
        // gives them back, so the first frame over any region passes through.
        let mut any_seen = true;
        if let Some(seen) = seen.as_mut() {
            any_seen = false;
            for (y, frame_row) in frame.chunks_exact(w).enumerate() {
                let span = start + y * cw..start + y * cw + w;
                any_seen |= fill_holes(&mut mosaic[span.clone()], &mut seen[span], frame_row);
            }
        }
        if any_seen {
            let ll = LlWeight::for_frame(cfg.ll_weighting, k as u32 + 1);
            fuser.fuse_into(&mut mosaic[start..], frame, ll)?;
        }
    }
    Ok(mosaic)
}

/// Gives the pixels of a mosaic row that no frame has covered yet (`seen` false) the
/// frame's values, marks the whole row seen, and returns whether any pixel was seen
/// before. Rows wholly seen or wholly new (the usual cases: frames overlap in bands) take
/// one scan and at most one copy instead of a branch per pixel.
fn fill_holes(mosaic: &mut [f32], seen: &mut [bool], frame: &[f32]) -> bool {
    if !seen.contains(&false) {
        return true;
    }
    if !seen.contains(&true) {
        mosaic.copy_from_slice(frame);
        seen.fill(true);
        return false;
    }
    for ((m, s), &v) in mosaic.iter_mut().zip(seen.iter_mut()).zip(frame) {
        if !*s {
            *m = v;
        }
        *s = true;
    }
    true
}

/// `rayon::join` for the core: a fuse step's two images on two threads when the pool has
/// them (gray frames have no channels to spread over). The result does not depend on it.
struct RayonJoin;

impl Join for RayonJoin {
    fn join(&self, a: impl FnOnce() + Send, b: impl FnOnce() + Send) {
        rayon::join(a, b);
    }
}

/// Fuses frames into a region of the mosaic, in place, with buffers allocated once per
/// channel.
struct Fuser {
    /// The frame's footprint on the mosaic (rows `cw` apart).
    region: Dims,
    cfg: FuseConfig,
    precision: Precision,
    /// The incoming frame laid out like the region, for frames the fuse step may not work
    /// in (borrowed, or with rows shorter than the region's stride); allocated on first use.
    b: Vec<f32>,
    scratch: Vec<f32>,
    a8: Vec<u8>,
    b8: Vec<u8>,
    ia: Vec<i32>,
    ib: Vec<i32>,
    iscratch: Vec<i32>,
}

impl Fuser {
    fn new(
        w: usize,
        h: usize,
        cw: usize,
        cfg: &FuseConfig,
        precision: Precision,
    ) -> crate::Result<Self> {
        let region = Dims::with_stride(w, h, cw)?;
        let packed = Dims::new(w, h)?;
        let n = w * h;
        let fixed = usize::from(precision == Precision::Fixed);
        Ok(Self {
            region,
            cfg: *cfg,
            precision,
            b: Vec::new(),
            scratch: vec![0.0; (1 - fixed) * float::fuse_scratch_len(region)],
            a8: vec![0; fixed * n],
            b8: vec![0; fixed * n],
            ia: vec![0; fixed * n],
            ib: vec![0; fixed * n],
            iscratch: vec![0; fixed * fuse_scratch_len(packed)],
        })
    }

    /// Fuses `frame` (packed) into the region at the start of `mosaic`, in place; an owned
    /// frame it may spend, laid out like the region, is the step's work space.
    fn fuse_into(
        &mut self,
        mosaic: &mut [f32],
        mut frame: FrameRef<Vec<f32>>,
        ll: LlWeight,
    ) -> crate::Result<()> {
        let region = self.region;
        let (w, stride) = (region.width(), region.stride());
        match self.precision {
            Precision::F32 => {
                let b: &mut [f32] = match &mut frame {
                    FrameRef::Spent(plane) if stride == w => plane,
                    _ => {
                        if self.b.is_empty() {
                            self.b = vec![0.0; region.buffer_len()];
                        }
                        for (dst, src) in self.b.chunks_mut(stride).zip(frame.chunks_exact(w)) {
                            dst[..w].copy_from_slice(src);
                        }
                        &mut self.b
                    }
                };
                let (cfg, scratch) = (&self.cfg, &mut self.scratch);
                // With one thread, rayon's job machinery only costs time.
                if rayon::current_num_threads() > 1 {
                    float::fuse_pair_with(&RayonJoin, mosaic, b, region, cfg, ll, scratch)?;
                } else {
                    float::fuse_pair_with(&Sequential, mosaic, b, region, cfg, ll, scratch)?;
                }
            }
            Precision::Fixed => {
                let to8 = |v: f32| v.round().clamp(0.0, 255.0) as u8;
                let rows = mosaic.chunks(stride).zip(frame.chunks_exact(w));
                for ((a8, b8), (a, b)) in self
                    .a8
                    .chunks_exact_mut(w)
                    .zip(self.b8.chunks_exact_mut(w))
                    .zip(rows)
                {
                    for (d, &v) in a8.iter_mut().zip(a) {
                        *d = to8(v);
                    }
                    for (d, &v) in b8.iter_mut().zip(b) {
                        *d = to8(v);
                    }
                }
                let packed = Dims::new(w, region.height())?;
                let work = U8Work {
                    a: &mut self.ia,
                    b: &mut self.ib,
                    scratch: &mut self.iscratch,
                };
                fuse_u8(
                    U8Pair::same(&mut self.a8, &self.b8, packed),
                    &self.cfg,
                    ll,
                    work,
                )?;
                for (dst, src) in mosaic.chunks_mut(stride).zip(self.a8.chunks_exact(w)) {
                    for (d, &v) in dst.iter_mut().zip(src) {
                        *d = f32::from(v);
                    }
                }
            }
        }
        Ok(())
    }
}

/// The time-splicing baseline (paper Tables I and III): every canvas row comes from the
/// frame whose centre row (the roller's apex) is nearest to it, and neighbouring frames'
/// strips are blended linearly over `blend` rows either side of each seam. Columns are
/// not shifted. All frames must agree in size and channels, as for [`fuse_mosaic`].
pub fn splice(frames: &[Placed], blend: usize, limit: PixelLimit) -> crate::Result<Planes> {
    rollfuse_io::require!(!frames.is_empty(), "no frames to splice");
    let first = frames[0].image;
    let (w, h, channels) = (first.width, first.height, first.planes.len());
    for (k, f) in frames.iter().enumerate() {
        rollfuse_io::require!(
            (f.image.width, f.image.height, f.image.planes.len()) == (w, h, channels),
            "frame {k} differs in size or channels from frame 0"
        );
    }
    let offsets: Vec<Offset> = frames.iter().map(|f| f.at).collect();
    let (_, min_y, _, ch) = canvas(&offsets, w, h, limit)?;
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A textured `w × h` frame with `channels` planes, different for each `seed`.
    fn frame(w: usize, h: usize, channels: usize, seed: u32) -> Planes {
        let value = |c: usize, i: usize| {
            let x = (i as u32)
                .wrapping_mul(2_654_435_761)
                .wrapping_add(seed.wrapping_mul(40_503) + c as u32 * 977);
            ((x >> 16) % 256) as f32
        };
        Planes {
            width: w,
            height: h,
            planes: (0..channels)
                .map(|c| (0..w * h).map(|i| value(c, i)).collect())
                .collect(),
        }
    }

    /// Frames read through [`FrameSource`].
    struct Frames<'a>(&'a [Planes]);

    impl FrameSource for Frames<'_> {
        fn frames(&self) -> usize {
            self.0.len()
        }
        fn shape(&self) -> (usize, usize, usize) {
            let f = &self.0[0];
            (f.width, f.height, f.planes.len())
        }
        fn read(&self, frame: usize, channel: usize, out: &mut [f32]) {
            out.copy_from_slice(&self.0[frame].planes[channel]);
        }
    }

    #[test]
    fn working_in_the_frames_or_reading_them_gives_the_same_mosaic() {
        let (w, h) = (37, 23);
        // Same footprint (the first frame becomes the mosaic), rows only (frames are the
        // work space), rows and columns (frames are copied): gray and RGB, both precisions.
        let layouts: [&[(i64, i64)]; 3] = [
            &[(0, 0), (0, 0), (0, 0)],
            &[(0, 0), (5, 0), (9, 0), (-3, 0)],
            &[(0, 0), (4, 2), (7, -1)],
        ];
        for offsets in layouts {
            for channels in [1, 3] {
                for precision in [Precision::F32, Precision::Fixed] {
                    let frames: Vec<Planes> = (0..offsets.len())
                        .map(|k| frame(w, h, channels, k as u32))
                        .collect();
                    let at = |&(dy, dx): &(i64, i64)| Offset { dy, dx };
                    let placed: Vec<Placed> = frames
                        .iter()
                        .zip(offsets)
                        .map(|(image, o)| Placed { image, at: at(o) })
                        .collect();
                    let cfg = FuseConfig::default();
                    let kept =
                        fuse_mosaic(&placed, &cfg, precision, PixelLimit::default()).unwrap();
                    let mut spent: Vec<(Planes, Offset)> =
                        frames.iter().cloned().zip(offsets.iter().map(at)).collect();
                    let worked =
                        fuse_mosaic_mut(&mut spent, &cfg, precision, PixelLimit::default())
                            .unwrap();
                    assert_eq!(
                        kept, worked,
                        "{offsets:?}, {channels} channels, {precision:?}"
                    );
                    let source = Frames(&frames);
                    let offsets: Vec<Offset> = offsets.iter().map(at).collect();
                    let read =
                        fuse_mosaic_from(&source, &offsets, &cfg, precision, PixelLimit::default())
                            .unwrap();
                    assert_eq!(
                        kept, read,
                        "{offsets:?}, {channels} channels, {precision:?}"
                    );
                    // A real fusion: the mosaic is no frame's copy.
                    assert!(frames.iter().all(|f| f.planes != kept.planes));
                }
            }
        }
    }

    #[test]
    fn no_frames_and_mixed_frames_are_refused() {
        let cfg = FuseConfig::default();
        let err =
            fuse_mosaic_mut(&mut [], &cfg, Precision::F32, PixelLimit::default()).unwrap_err();
        assert_eq!(err.to_string(), "no frames to fuse");
        let origin = Offset { dy: 0, dx: 0 };
        let mut mixed = vec![(frame(8, 8, 1, 0), origin), (frame(8, 8, 3, 1), origin)];
        let err =
            fuse_mosaic_mut(&mut mixed, &cfg, Precision::F32, PixelLimit::default()).unwrap_err();
        assert!(err.to_string().contains("mix of gray and RGB"), "{err}");
        // Refused before any work: the frames are as they were.
        assert_eq!(mixed[0].0, frame(8, 8, 1, 0));
        assert_eq!(mixed[1].0, frame(8, 8, 3, 1));
        let one = [frame(8, 8, 1, 0)];
        let err = fuse_mosaic_from(
            &Frames(&one),
            &[],
            &cfg,
            Precision::F32,
            PixelLimit::default(),
        )
        .unwrap_err();
        assert_eq!(err.to_string(), "0 offsets for 1 frames");
        let err = fuse_mosaic_from(
            &Frames(&[]),
            &[],
            &cfg,
            Precision::F32,
            PixelLimit::default(),
        )
        .unwrap_err();
        assert_eq!(err.to_string(), "no frames to fuse");
    }
}
