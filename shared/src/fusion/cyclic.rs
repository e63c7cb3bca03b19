//! Cyclic fusion over a sequence: `F₁ = fuse(I₁, I₂)`, `Fₖ = fuse(Fₖ₋₁, Iₖ₊₁)`, with the
//! running result kept as an 8-bit image between cycles (clamped to 0..=255, as the camera's
//! own range).

use super::config::{FuseConfig, LlWeight};
use super::integer::{U8Pair, U8Work, fuse_scratch_len, fuse_u8};
use crate::{Dims, Error};

/// The caller-owned memory of a [`CyclicFuser`] for a `w × h` image:
/// `fused` ≥ `w·h` bytes, `work_a` and `work_b` ≥ `w·h` words each, `scratch` ≥
/// [`super::fuse_scratch_len`] words.
pub struct CyclicBuffers<'a> {
    /// The running fused image, packed `w × h`.
    pub fused: &'a mut [u8],
    /// Transform work for the running image.
    pub work_a: &'a mut [i32],
    /// Transform work for the incoming frame.
    pub work_b: &'a mut [i32],
    /// Lines and saliency maps.
    pub scratch: &'a mut [i32],
}

/// Fuses frames one at a time into a running result held in caller-owned buffers.
///
/// ```
/// use rollfuse_core::fusion::{CyclicBuffers, fuse_scratch_len};
/// use rollfuse_core::{CyclicFuser, Dims, FuseConfig};
///
/// let (w, h) = (16, 12);
/// let mut fused = vec![0u8; w * h];
/// let (mut work_a, mut work_b) = (vec![0i32; w * h], vec![0i32; w * h]);
/// let mut scratch = vec![0i32; fuse_scratch_len(Dims::new(w, h)?)];
/// let bufs = CyclicBuffers {
///     fused: &mut fused,
///     work_a: &mut work_a,
///     work_b: &mut work_b,
///     scratch: &mut scratch,
/// };
/// let mut fuser = CyclicFuser::new(FuseConfig::default(), w, h, bufs)?;
/// for k in 1..=3u8 {
///     let frame: Vec<u8> = (0..w * h).map(|i| (i as u8).wrapping_mul(k)).collect();
///     fuser.push(&frame, w)?; // packed rows: `w` apart
/// }
/// assert_eq!(fuser.frames(), 3);
/// assert_eq!(fuser.fused().len(), w * h);
/// # Ok::<(), rollfuse_core::Error>(())
/// ```
pub struct CyclicFuser<'a> {
    cfg: FuseConfig,
    dims: Dims,
    bufs: CyclicBuffers<'a>,
    frames: u32,
}

impl<'a> CyclicFuser<'a> {
    /// A fuser for `width × height` frames. Fails if the configuration is invalid for the
    /// size or a buffer is too small.
    pub fn new(
        cfg: FuseConfig,
        width: usize,
        height: usize,
        bufs: CyclicBuffers<'a>,
    ) -> Result<Self, Error> {
        let dims = Dims::new(width, height)?;
        dims.check_levels(cfg.levels)?;
        let n = dims.pixels();
        for (which, len) in [
            ("fused", bufs.fused.len()),
            ("work_a", bufs.work_a.len()),
            ("work_b", bufs.work_b.len()),
        ] {
            if len < n {
                return Err(Error::BufferTooSmall {
                    which,
                    needed: n,
                    got: len,
                });
            }
        }
        let needed = fuse_scratch_len(dims);
        if bufs.scratch.len() < needed {
            return Err(Error::BufferTooSmall {
                which: "scratch",
                needed,
                got: bufs.scratch.len(),
            });
        }
        Ok(Self {
            cfg,
            dims,
            bufs,
            frames: 0,
        })
    }

    /// Fuses the next frame (`width × height` bytes, rows `stride` apart) into the result.
    /// The first frame becomes the result as it is.
    pub fn push(&mut self, frame: &[u8], stride: usize) -> Result<(), Error> {
        let (w, h) = (self.dims.width(), self.dims.height());
        let src = Dims::with_stride(w, h, stride)?;
        src.check_buffer("frame", frame.len())?;
        let n = self.dims.pixels();
        let fused_error = Error::BufferTooSmall {
            which: "fused",
            needed: n,
            got: self.bufs.fused.len(),
        };
        if self.frames == 0 {
            // `new` checked `fused` holds `h` rows of `w`, and `frame` was checked above.
            for (row, dst) in src.rows(frame).zip(self.bufs.fused.chunks_exact_mut(w)) {
                dst.copy_from_slice(row);
            }
            self.frames = 1;
            return Ok(());
        }
        let frame_no = self.frames.saturating_add(1);
        let ll_weight = LlWeight::for_frame(self.cfg.ll_weighting, frame_no);
        let bufs = &mut self.bufs;
        let images = U8Pair {
            a: bufs.fused.get_mut(..n).ok_or(fused_error)?,
            a_dims: self.dims,
            b: frame,
            b_dims: src,
        };
        fuse_u8(
            images,
            &self.cfg,
            ll_weight,
            U8Work {
                a: bufs.work_a,
                b: bufs.work_b,
                scratch: bufs.scratch,
            },
        )?;
        self.frames = frame_no;
        Ok(())
    }

    /// The fused image so far, packed `width × height` (empty before the first frame).
    pub fn fused(&self) -> &[u8] {
        if self.frames == 0 {
            &[]
        } else {
            // `new` checked `fused` holds the image.
            self.bufs
                .fused
                .get(..self.dims.pixels())
                .unwrap_or_default()
        }
    }

    /// Frames fused so far.
    pub fn frames(&self) -> u32 {
        self.frames
    }

    /// Starts a new sequence, keeping the configuration and buffers.
    pub fn reset(&mut self) {
        self.frames = 0;
    }

    /// The configuration.
    pub fn config(&self) -> &FuseConfig {
        &self.cfg
    }
}
