//! The `f32` fusion path: the shared driver with orthonormal periodic transforms, `f32`
//! saliency (`exp` from libm) and `f32` weights.

use super::dwt::{self, Phase, check_len};
use crate::fusion::{
    Arith, BandOffsets, FuseConfig, LlWeight, fuse_generic, maps_len, split_scratch,
};
use crate::geometry::{Roi, mirror};
use crate::saliency::{SaliencyNorm, for_each_neighbourhood};
use crate::{Dims, Error, Wavelet};

impl Arith for f32 {
    fn forward_level(wavelet: Wavelet, buf: &mut [f32], dims: Dims, scratch: &mut [f32]) {
        dwt::forward_level(wavelet, Phase::lifting(wavelet), buf, dims, scratch);
    }

    fn inverse(wavelet: Wavelet, buf: &mut [f32], dims: Dims, levels: u8, scratch: &mut [f32]) {
        let mut sizes = [dims; 4];
        for k in 1..levels as usize {
            sizes[k] = sizes[k - 1].low_band();
        }
        for d in sizes[..levels as usize].iter().rev() {
            dwt::inverse_level(wavelet, Phase::lifting(wavelet), buf, *d, scratch);
        }
    }

    fn band_offsets(wavelet: Wavelet) -> BandOffsets {
        // The fusion transform sits where the integer lifting does (Phase::lifting).
        <i32 as Arith>::band_offsets(wavelet)
    }

    fn for_each_saliency(
        buf: &[f32],
        dims: Dims,
        roi: Roi,
        norm: SaliencyNorm,
        _wavelet: Wavelet,
        level: u8,
        mut f: impl FnMut(usize, usize, f32),
    ) {
        let lap = |c: f32, around: [f32; 4]| (around.iter().sum::<f32>() - 4.0 * c).abs();
        let max = match norm {
            SaliencyNorm::Local => {
                let mut m = 0f32;
                for_each_neighbourhood(buf, dims, |x, y, c, a| {
                    if roi.contains(x, y) {
                        m = m.max(lap(c, a));
                    }
                });
                m
            }
            // Orthonormal 2-D transforms double the LL band's DC level per level.
            SaliencyNorm::Reference(r) => r as f32 * (1u32 << (level - 1)) as f32,
        };
        if max <= 0.0 || !max.is_finite() {
            return;
        }
        let inv = 1.0 / max;
        for_each_neighbourhood(buf, dims, |x, y, c, a| {
            // Sal/255 = |∇²I| / max, saturated at 1 for a Reference maximum.
            f(x, y, expm1_unit((lap(c, a) * inv).min(1.0)));
        });
    }

    fn weight(s1: f32, s2: f32) -> f32 {
        let total = s1 + s2;
        if total > 0.0 { s1 / total } else { 0.5 }
    }

    #[inline(always)]
    fn blend(h1: f32, h2: f32, w1: f32) -> f32 {
        w1 * h1 + (1.0 - w1) * h2
    }

    #[inline(always)]
    fn mix(a: f32, b: f32, w: LlWeight) -> f32 {
        let w = w.as_f32();
        (1.0 - w) * a + w * b
    }

    #[inline(always)]
    fn abs_ge(a: f32, b: f32) -> bool {
        a.abs() >= b.abs()
    }
}

/// `eˣ − 1` for `x` in `0..=1`: its Taylor series to degree 9 in Horner form, exact to
/// below 1e-6 there (the remainder is at most e/10! ≈ 7.5e-7; test
/// `expm1_unit_matches_libm`). A per-pixel libm `exp` took a fifth of a fuse step.
#[inline(always)]
fn expm1_unit(x: f32) -> f32 {
    const INV: [f32; 8] = [
        1.0 / 2.0,
        1.0 / 3.0,
        1.0 / 4.0,
        1.0 / 5.0,
        1.0 / 6.0,
        1.0 / 7.0,
        1.0 / 8.0,
        1.0 / 9.0,
    ];
    let mut acc = 1.0f32;
    for c in INV.iter().rev() {
        acc = 1.0 + x * c * acc;
    }
    x * acc
}

/// The frame the float path fuses a `width × height` image in: the image at `(margin,
/// margin)` inside a region whose sides are multiples of `2^levels`, the margins filled by
/// whole-sample symmetric reflection of the image.
///
/// Periodization treats a line as a ring; without margins the first and last rows (and
/// columns) would be filtered together. The reflected margin, `3 · 2^levels` pixels (the
/// reach of a level-`levels` db2 basis function), puts that seam far from the image, and
/// gives the float path the same kind of border as the integer path.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Padded {
    dims: Dims,
    margin: usize,
    width: usize,
    height: usize,
    levels: u8,
}

impl Padded {
    /// The padded frame for a `width × height` image fused `levels` deep.
    pub fn new(width: usize, height: usize, levels: u8) -> Result<Self, Error> {
        if levels == 0 || levels > crate::MAX_LEVELS {
            return Err(Error::LevelsOutOfRange { levels });
        }
        Dims::new(width, height)?;
        let m = 1usize << levels;
        let margin = 3 * m;
        let dims = Dims::new(
            (width + 2 * margin).next_multiple_of(m),
            (height + 2 * margin).next_multiple_of(m),
        )?;
        Ok(Self {
            dims,
            margin,
            width,
            height,
            levels,
        })
    }

    /// The padded region (packed): the size of the buffers [`fuse_pair`] takes.
    pub fn dims(&self) -> Dims {
        self.dims
    }

    /// Offset of the image inside the padded region, on both axes.
    pub fn margin(&self) -> usize {
        self.margin
    }

    /// The most levels a fuse step in this frame may use.
    pub fn levels(&self) -> u8 {
        self.levels
    }

    /// Fills `buf` (the padded region) from the packed image `get(x, y)`, reflecting it
    /// into the margins.
    pub fn fill(&self, buf: &mut [f32], get: impl Fn(usize, usize) -> f32) -> Result<(), Error> {
        self.dims.check_buffer("padded image", buf.len())?;
        let m = self.margin as isize;
        for y in 0..self.dims.height() {
            let sy = mirror(y as isize - m, self.height);
            for x in 0..self.dims.width() {
                let sx = mirror(x as isize - m, self.width);
                buf[self.dims.at(x, y)] = get(sx, sy);
            }
        }
        Ok(())
    }

    /// Index of the image's pixel `(x, y)` in the padded buffer, `None` outside the image.
    pub fn index(&self, x: usize, y: usize) -> Option<usize> {
        (x < self.width && y < self.height).then(|| self.dims.at(x + self.margin, y + self.margin))
    }
}

/// The largest sample magnitude the float path accepts: far beyond any image (16-bit data
/// is 65535), far enough below `f32::MAX` that Laplacians and sums stay finite.
pub const MAX_SAMPLE_F32: f32 = 1e9;

/// Scratch length (in `f32`) that [`fuse_pair`] needs for the padded region `dims`.
pub fn fuse_scratch_len(dims: Dims) -> usize {
    dwt::level_scratch_len(dims) + maps_len(dims)
}

/// One `f32` fuse step in a [`Padded`] frame (`frame.dims` for both buffers; saliency is
/// normalized over the image, not its margins): the fused image replaces `a`, `b` is used
/// as work space. `cfg.levels` must not exceed the levels the frame was made for, and
/// samples must be finite with `|x| ≤` [`MAX_SAMPLE_F32`].
pub fn fuse_pair(
    a: &mut [f32],
    b: &mut [f32],
    frame: &Padded,
    cfg: &FuseConfig,
    ll_weight: LlWeight,
    scratch: &mut [f32],
) -> Result<(), Error> {
    let dims = frame.dims;
    dims.check_buffer("first image", a.len())?;
    dims.check_buffer("second image", b.len())?;
    dims.check_levels(cfg.levels)?;
    if cfg.levels > frame.levels {
        return Err(Error::InvalidParameter {
            name: "frame (made for fewer levels than cfg.levels)",
        });
    }
    if ll_weight.0 > 1 << 15 {
        return Err(Error::InvalidParameter { name: "ll_weight" });
    }
    for buf in [&*a, &*b] {
        if buf[..dims.buffer_len()]
            .iter()
            .any(|v| v.is_nan() || v.abs() > MAX_SAMPLE_F32)
        {
            return Err(Error::InvalidParameter {
                name: "sample (NaN, infinite or beyond ±1e9)",
            });
        }
    }
    check_len("scratch", scratch.len(), fuse_scratch_len(dims))?;
    let line = dwt::level_scratch_len(dims);
    let work = split_scratch(scratch, line, dims)?;
    let roi = Roi {
        x0: frame.margin,
        y0: frame.margin,
        width: frame.width,
        height: frame.height,
    };
    fuse_generic(a, b, dims, roi, cfg, ll_weight, work);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::expm1_unit;

    #[test]
    fn expm1_unit_matches_libm() {
        let worst = (0..=10_000)
            .map(|i| {
                let x = i as f32 / 10_000.0;
                (expm1_unit(x) as f64 - libm::expm1(x as f64)).abs()
            })
            .fold(0.0, f64::max);
        assert!(worst < 1e-6, "max error {worst}");
    }
}
