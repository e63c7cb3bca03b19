//! The `f32` fusion path: the shared driver with the integer path's lifting steps run in
//! exact `f32` arithmetic, `f32` saliency and `f32` weights.

use crate::fusion::{Arith, BandOffsets, FuseConfig, LlWeight, fuse_pair_checked};
use crate::lifting::{self, LevelBounds};
use crate::saliency::ll_gain_q16;
use crate::saliency::{SaliencyNorm, for_each_neighbourhood, neighbourhood_row};
use crate::{Dims, Error, Wavelet};

impl Arith for f32 {
    fn forward_level(wavelet: Wavelet, buf: &mut [f32], dims: Dims, scratch: &mut [f32]) {
        lifting::forward_level(wavelet, buf, dims, scratch);
    }

    fn inverse(wavelet: Wavelet, buf: &mut [f32], dims: Dims, levels: u8, scratch: &mut [f32]) {
        // Floats need no saturation: the bounds are only passed along.
        let bounds = LevelBounds::default();
        let mut sizes = [dims; 4];
        for k in 1..levels as usize {
            sizes[k] = sizes[k - 1].low_band();
        }
        for d in sizes[..levels as usize].iter().rev() {
            lifting::inverse_level(wavelet, buf, *d, scratch, &bounds);
        }
    }

    fn band_offsets(wavelet: Wavelet) -> BandOffsets {
        // The same lifting as the integer path, so the same coefficient placement.
        <i32 as Arith>::band_offsets(wavelet)
    }

    fn saliency_rows(
        buf: &[f32],
        dims: Dims,
        norm: SaliencyNorm,
        wavelet: Wavelet,
        level: u8,
        row: &mut [f32],
        mut f: impl FnMut(usize, &[f32]),
    ) {
        let lap = |c: f32, around: [f32; 4]| (around.iter().sum::<f32>() - 4.0 * c).abs();
        let max = match norm {
            SaliencyNorm::Local => {
                let mut m = 0f32;
                for_each_neighbourhood(buf, dims, |_, _, c, a| m = m.max(lap(c, a)));
                m
            }
            // The LL band's DC gain per level, as on the integer path.
            SaliencyNorm::Reference(r) => {
                let gain = ll_gain_q16(wavelet) as f32 / 65536.0;
                (1..level).fold(r as f32, |m, _| m * gain)
            }
        };
        if max <= 0.0 || !max.is_finite() {
            return;
        }
        let inv = 1.0 / max;
        let row = &mut row[..dims.width()];
        for y in 0..dims.height() {
            // Sal/255 = |∇²I| / max, saturated at 1 for a Reference maximum.
            neighbourhood_row(buf, dims, y, |x, c, a| {
                row[x] = expm1_unit((lap(c, a) * inv).min(1.0))
            });
            f(y, row);
        }
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

    fn check_samples(buf: &[f32], dims: Dims) -> Result<(), Error> {
        for y in 0..dims.height() {
            let row = &buf[dims.at(0, y)..dims.at(dims.width(), y)];
            if row.iter().any(|v| v.is_nan() || v.abs() > MAX_SAMPLE_F32) {
                return Err(Error::InvalidParameter {
                    name: "sample (NaN, infinite or beyond ±1e9)",
                });
            }
        }
        Ok(())
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

/// The largest sample magnitude the float path accepts: far beyond any image (16-bit data
/// is 65535), far enough below `f32::MAX` that Laplacians and sums stay finite.
pub const MAX_SAMPLE_F32: f32 = 1e9;

/// Scratch length (in `f32`) that [`fuse_pair`] needs for `dims`: as on the integer path
/// ([`crate::fusion::fuse_scratch_len`]), a transform line and the saliency maps.
pub fn fuse_scratch_len(dims: Dims) -> usize {
    crate::fusion::fuse_scratch_len(dims)
}

/// One `f32` fuse step on the `dims` region of `a` and `b`: the fused image replaces `a`,
/// `b` is used as work space. Any size from 1 up, as on the integer path; samples must be
/// finite with `|x| ≤` [`MAX_SAMPLE_F32`].
pub fn fuse_pair(
    a: &mut [f32],
    b: &mut [f32],
    dims: Dims,
    cfg: &FuseConfig,
    ll_weight: LlWeight,
    scratch: &mut [f32],
) -> Result<(), Error> {
    fuse_pair_checked(a, b, dims, cfg, ll_weight, scratch)
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
