//! The `f32` fusion path: the shared driver with the integer path's lifting steps run in
//! exact `f32` arithmetic, `f32` saliency and `f32` weights.

use crate::fusion::{Arith, FuseConfig, Join, LlWeight, Sequential, fuse_pair_checked};
use crate::lifting::{self, LevelBounds};
use crate::saliency::ll_gain_q16;
use crate::saliency::{SaliencyNorm, map_neighbourhood_row};
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

    fn saliency_rows(
        buf: &[f32],
        dims: Dims,
        norm: SaliencyNorm,
        wavelet: Wavelet,
        level: u8,
        row: &mut [f32],
        mut f: impl FnMut(usize, &[f32]),
    ) {
        let lap =
            |c: f32, [up, down, left, right]: [f32; 4]| (up + down + left + right - 4.0 * c).abs();
        let row = &mut row[..dims.width()];
        let max = match norm {
            SaliencyNorm::Local => (0..dims.height()).fold(0f32, |m, y| {
                map_neighbourhood_row(buf, dims, y, row, lap);
                max_of(row).max(m)
            }),
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
        for y in 0..dims.height() {
            // Sal/255 = |∇²I| / max, saturated at 1 for a Reference maximum.
            map_neighbourhood_row(buf, dims, y, row, lap);
            // A pass of its own: a plain map over the row, which vectorizes.
            for v in row.iter_mut() {
                *v = expm1_unit((*v * inv).min(1.0));
            }
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
            // No early exit, so the scan vectorizes; NaN fails the comparison.
            let in_range = row
                .iter()
                .fold(true, |ok, v| ok & (v.abs() <= MAX_SAMPLE_F32));
            if !in_range {
                return Err(Error::InvalidParameter {
                    name: "sample (NaN, infinite or beyond ±1e9)",
                });
            }
        }
        Ok(())
    }
}

/// The largest of `values` (all finite and ≥ 0), over eight lanes so that it vectorizes.
fn max_of(values: &[f32]) -> f32 {
    let mut lanes = [0f32; 8];
    let mut chunks = values.chunks_exact(8);
    for chunk in &mut chunks {
        for (m, &v) in lanes.iter_mut().zip(chunk) {
            *m = if v > *m { v } else { *m };
        }
    }
    let rest = chunks.remainder().iter();
    lanes.iter().chain(rest).fold(0f32, |m, &v| m.max(v))
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

/// Scratch length (in `f32`) that [`fuse_pair`] and [`fuse_pair_with`] need for `dims`:
/// as on the integer path ([`crate::fusion::fuse_scratch_len`]), plus a second transform
/// line so both images can be worked on at once.
pub fn fuse_scratch_len(dims: Dims) -> usize {
    crate::fusion::fuse_scratch_len(dims) + lifting::scratch_len(dims)
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
    fuse_pair_with(&Sequential, a, b, dims, cfg, ll_weight, scratch)
}

/// [`fuse_pair`] with each level's two independent halves (saliency and transform of
/// each image) run through `join`, e.g. on two threads. The result does not depend on it.
pub fn fuse_pair_with(
    join: &impl Join,
    a: &mut [f32],
    b: &mut [f32],
    dims: Dims,
    cfg: &FuseConfig,
    ll_weight: LlWeight,
    scratch: &mut [f32],
) -> Result<(), Error> {
    fuse_pair_checked(a, b, dims, cfg, ll_weight, scratch, 2, join)
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
