//! Orthonormal periodic filter-bank transforms (PyWavelets' `periodization` mode).

use crate::geometry::Line;
use crate::{Dims, Error, Wavelet};

/// Decomposition filters `(low, high)` as PyWavelets lists them (`dec_lo`, `dec_hi`).
fn filters(wavelet: Wavelet) -> (&'static [f32], &'static [f32]) {
    const H: f32 = core::f32::consts::FRAC_1_SQRT_2;
    const HAAR_LO: [f32; 2] = [H, H];
    const HAAR_HI: [f32; 2] = [-H, H];
    const DB2_LO: [f32; 4] = [-0.129_409_52, 0.224_143_87, 0.836_516_3, 0.482_962_9];
    const DB2_HI: [f32; 4] = [-0.482_962_9, 0.836_516_3, -0.224_143_87, -0.129_409_52];
    match wavelet {
        Wavelet::Haar => (&HAAR_LO, &HAAR_HI),
        Wavelet::Db2 => (&DB2_LO, &DB2_HI),
    }
}

/// Where a filter bank's taps sit on the signal: `cA[i] = Σₖ lo[k]·x[2i + lo_at − k]` and
/// `cD[i] = Σₖ hi[k]·x[2i + hi_at − k]`, indices taken modulo the (even) length.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Phase {
    lo_at: usize,
    hi_at: usize,
}

impl Phase {
    /// PyWavelets' `periodization` mode: both bands at `F/2`, so Haar's `cA[i]` covers
    /// `x[2i..=2i+1]` and db2's covers `x[2i−1..=2i+2]`.
    pub(crate) fn pywt(wavelet: Wavelet) -> Self {
        let f = filters(wavelet).0.len();
        Self {
            lo_at: f / 2,
            hi_at: f / 2,
        }
    }
}

/// Index `2i + at − k` wrapped into `0..n` (`2i < n`, `at ≤ 3`, `k < 4`).
#[inline(always)]
fn tap(i: usize, at: usize, k: usize, n: usize) -> usize {
    let j = 2 * i + at;
    // Only the first and last coefficients wrap; spare the others a division.
    if j >= k && j - k < n {
        j - k
    } else {
        (j + n - k) % n
    }
}

/// Forward analysis of one even-length line `x` into `out`: `cA` then `cD`.
fn analyze(wavelet: Wavelet, phase: Phase, x: &[f32], out: &mut [f32]) {
    let (lo, hi) = filters(wavelet);
    let n = x.len();
    let half = n / 2;
    for i in 0..half {
        let (mut a, mut d) = (0f32, 0f32);
        for (k, (&l, &h)) in lo.iter().zip(hi).enumerate() {
            a += l * x[tap(i, phase.lo_at, k, n)];
            d += h * x[tap(i, phase.hi_at, k, n)];
        }
        out[i] = a;
        out[half + i] = d;
    }
}

/// Inverse of [`analyze`] (its adjoint, the filter bank being orthonormal): `c` holds `cA`
/// then `cD`; the even-length signal is written to `x`.
fn synthesize(wavelet: Wavelet, phase: Phase, c: &[f32], x: &mut [f32]) {
    let (lo, hi) = filters(wavelet);
    let n = x.len();
    let half = n / 2;
    x.fill(0.0);
    for i in 0..half {
        let (a, d) = (c[i], c[half + i]);
        for (k, (&l, &h)) in lo.iter().zip(hi).enumerate() {
            x[tap(i, phase.lo_at, k, n)] += l * a;
            x[tap(i, phase.hi_at, k, n)] += h * d;
        }
    }
}

/// Runs `op(input, output)` on each line in turn: the line is copied into the first half
/// of `scratch`, and `op`'s result, in the second half, is written back in its place.
fn each_line(
    buf: &mut [f32],
    lines: impl Iterator<Item = Line>,
    scratch: &mut [f32],
    op: impl Fn(&[f32], &mut [f32]),
) {
    for line in lines {
        let (input, output) = scratch.split_at_mut(line.len);
        for (v, p) in input.iter_mut().zip(line.positions()) {
            *v = buf[p];
        }
        op(input, &mut output[..line.len]);
        for (p, &v) in line.positions().zip(output.iter()) {
            buf[p] = v;
        }
    }
}

/// Scratch (in `f32`) that one 2-D level on `dims` needs: a line pair for the rows and a
/// region-sized buffer for the columns, which are filtered a whole row at a time (column
/// by column, every sample would be a cache miss on wide images).
pub fn level_scratch_len(dims: Dims) -> usize {
    dims.pixels() + 2 * dims.width().max(dims.height())
}

/// Vertical analysis: output row `i` of the low band is `Σₖ lo[k]·row[2i + lo_at − k]`, a
/// whole row at a time; `tmp` (packed `w × h`) receives `cA` rows then `cD` rows, which
/// then replace the region's rows.
fn analyze_columns(wavelet: Wavelet, phase: Phase, buf: &mut [f32], dims: Dims, tmp: &mut [f32]) {
    let (lo, hi) = filters(wavelet);
    let (w, h) = (dims.width(), dims.height());
    let half = h / 2;
    let tmp = &mut tmp[..w * h];
    tmp.fill(0.0);
    let (low, high) = tmp.split_at_mut(half * w);
    for i in 0..half {
        let (a_row, d_row) = (&mut low[i * w..(i + 1) * w], &mut high[i * w..(i + 1) * w]);
        for (k, (&l, &g)) in lo.iter().zip(hi).enumerate() {
            let sa = dims.at(0, tap(i, phase.lo_at, k, h));
            let sd = dims.at(0, tap(i, phase.hi_at, k, h));
            for (o, &v) in a_row.iter_mut().zip(&buf[sa..sa + w]) {
                *o += l * v;
            }
            for (o, &v) in d_row.iter_mut().zip(&buf[sd..sd + w]) {
                *o += g * v;
            }
        }
    }
    for y in 0..h {
        buf[dims.at(0, y)..dims.at(0, y) + w].copy_from_slice(&tmp[y * w..(y + 1) * w]);
    }
}

/// Vertical synthesis, the adjoint of [`analyze_columns`], a whole row at a time.
fn synthesize_columns(
    wavelet: Wavelet,
    phase: Phase,
    buf: &mut [f32],
    dims: Dims,
    tmp: &mut [f32],
) {
    let (lo, hi) = filters(wavelet);
    let (w, h) = (dims.width(), dims.height());
    let half = h / 2;
    let tmp = &mut tmp[..w * h];
    tmp.fill(0.0);
    for i in 0..half {
        let (ra, rd) = (dims.at(0, i), dims.at(0, half + i));
        for (k, (&l, &g)) in lo.iter().zip(hi).enumerate() {
            let ta = tap(i, phase.lo_at, k, h) * w;
            for (o, &v) in tmp[ta..ta + w].iter_mut().zip(&buf[ra..ra + w]) {
                *o += l * v;
            }
            let td = tap(i, phase.hi_at, k, h) * w;
            for (o, &v) in tmp[td..td + w].iter_mut().zip(&buf[rd..rd + w]) {
                *o += g * v;
            }
        }
    }
    for y in 0..h {
        buf[dims.at(0, y)..dims.at(0, y) + w].copy_from_slice(&tmp[y * w..(y + 1) * w]);
    }
}

/// One forward 2-D level on an even-sized region, in place: rows then columns, Mallat
/// layout as in [`crate::geometry`]. `scratch` holds [`level_scratch_len`].
pub(crate) fn forward_level(
    wavelet: Wavelet,
    phase: Phase,
    buf: &mut [f32],
    dims: Dims,
    scratch: &mut [f32],
) {
    let rows = (0..dims.height()).map(|y| Line::row(dims, y));
    each_line(buf, rows, scratch, |x, out| analyze(wavelet, phase, x, out));
    analyze_columns(wavelet, phase, buf, dims, scratch);
}

/// One inverse 2-D level on an even-sized region, in place (columns, then rows).
pub(crate) fn inverse_level(
    wavelet: Wavelet,
    phase: Phase,
    buf: &mut [f32],
    dims: Dims,
    scratch: &mut [f32],
) {
    synthesize_columns(wavelet, phase, buf, dims, scratch);
    let rows = (0..dims.height()).map(|y| Line::row(dims, y));
    each_line(buf, rows, scratch, |c, x| synthesize(wavelet, phase, c, x));
}

/// Size of each subband of a single-level `dwt2` on a `w × h` image: `⌈w/2⌉ × ⌈h/2⌉`.
pub fn subband_dims(width: usize, height: usize) -> (usize, usize) {
    (width.div_ceil(2), height.div_ceil(2))
}

/// Single-level 2-D transform of the packed `dims` image `img`, as PyWavelets'
/// `dwt2(img, wavelet, mode='periodization')`. `out` receives the subbands in Mallat
/// layout on a packed `2⌈w/2⌉ × 2⌈h/2⌉` grid: `cA` top-left, `cV` (PyWavelets' vertical
/// detail = HL here) top-right, `cH` (LH) bottom-left, `cD` (HH) bottom-right. `scratch`
/// holds [`level_scratch_len`] of the `2⌈w/2⌉ × 2⌈h/2⌉` grid.
pub fn dwt2(
    wavelet: Wavelet,
    img: &[f32],
    dims: Dims,
    out: &mut [f32],
    scratch: &mut [f32],
) -> Result<(), Error> {
    dims.check_buffer("image", img.len())?;
    let (bw, bh) = subband_dims(dims.width(), dims.height());
    let padded = Dims::new(2 * bw, 2 * bh)?;
    check_len("output", out.len(), padded.pixels())?;
    check_len("scratch", scratch.len(), level_scratch_len(padded))?;
    for y in 0..padded.height() {
        let sy = y.min(dims.height() - 1);
        for x in 0..padded.width() {
            out[padded.at(x, y)] = img[dims.at(x.min(dims.width() - 1), sy)];
        }
    }
    forward_level(wavelet, Phase::pywt(wavelet), out, padded, scratch);
    Ok(())
}

/// Inverse of [`dwt2`]: `coeffs` is the `2⌈w/2⌉ × 2⌈h/2⌉` Mallat grid; the
/// reconstruction (as PyWavelets' `idwt2`, cropped to `w × h`) goes to `out`, packed.
/// `coeffs` is used as work space.
pub fn idwt2(
    wavelet: Wavelet,
    coeffs: &mut [f32],
    dims: Dims,
    out: &mut [f32],
    scratch: &mut [f32],
) -> Result<(), Error> {
    let (bw, bh) = subband_dims(dims.width(), dims.height());
    let padded = Dims::new(2 * bw, 2 * bh)?;
    check_len("coefficients", coeffs.len(), padded.pixels())?;
    check_len("output", out.len(), dims.pixels())?;
    check_len("scratch", scratch.len(), level_scratch_len(padded))?;
    inverse_level(wavelet, Phase::pywt(wavelet), coeffs, padded, scratch);
    for y in 0..dims.height() {
        for x in 0..dims.width() {
            out[y * dims.width() + x] = coeffs[padded.at(x, y)];
        }
    }
    Ok(())
}

pub(crate) fn check_len(which: &'static str, got: usize, needed: usize) -> Result<(), Error> {
    if got < needed {
        return Err(Error::BufferTooSmall { which, needed, got });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::lifting::forward_level;
    use std::{vec, vec::Vec};

    #[test]
    fn lifting_interior_matches_the_pywavelets_filter_bank() {
        // The lifting's low band is the filter bank's cA one pixel later, scaled by
        // √2/(√3 − 1); its high band is −cD one pixel earlier, scaled by √2/(√3 + 1).
        let n = 64;
        let x: Vec<f32> = (0..n)
            .map(|i| ((i * 37 % 23) as f32 - 11.0) * 3.5 + (i as f32 * 0.3).sin() * 20.0)
            .collect();
        let mut lifted = x.clone();
        let dims = Dims::new(n, 1).unwrap();
        forward_level(Wavelet::Db2, &mut lifted, dims, &mut vec![0f32; n]);
        let mut bank = vec![0f32; n];
        analyze(Wavelet::Db2, Phase { lo_at: 3, hi_at: 1 }, &x, &mut bank);
        let s3 = 3f32.sqrt();
        let (low_scale, high_scale) = (2f32.sqrt() / (s3 - 1.0), -(2f32.sqrt()) / (s3 + 1.0));
        let half = n / 2;
        for i in 2..half - 2 {
            assert!((lifted[i] - low_scale * bank[i]).abs() < 1e-3, "low {i}");
            assert!(
                (lifted[half + i] - high_scale * bank[half + i]).abs() < 1e-3,
                "high {i}"
            );
        }
    }
}
