//! The orthonormal Haar and db2 filter banks with periodic extension, reproducing
//! PyWavelets' `dwt2(x, w, mode='periodization')` and `idwt2` (checked against committed
//! vectors in `shared/tests/vectors/`). As in PyWavelets, a line of odd length is first
//! extended by repeating its last sample. In the interior the lifting's coefficients are
//! these, up to scale and a one-pixel shift of placement (test
//! `lifting_interior_matches_the_pywavelets_filter_bank`). A reference for tests, not part
//! of the fusion: built for the crate's tests and with the `pywt` feature.

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

/// Sample `j` of `x` (`tap` keeps `j` inside `x`; 0 if it were not).
#[inline(always)]
fn sample(x: &[f32], j: usize) -> f32 {
    x.get(j).copied().unwrap_or(0.0)
}

/// Forward analysis of one even-length line `x` into `out` (as long as `x`): `cA` then `cD`.
fn analyze(wavelet: Wavelet, phase: Phase, x: &[f32], out: &mut [f32]) {
    let (lo, hi) = filters(wavelet);
    let n = x.len();
    let half = n / 2;
    let Some((out_a, out_d)) = out.split_at_mut_checked(half) else {
        return;
    };
    for (i, (oa, od)) in out_a.iter_mut().zip(out_d.iter_mut()).enumerate() {
        let (mut a, mut d) = (0f32, 0f32);
        for (k, (&l, &h)) in lo.iter().zip(hi).enumerate() {
            a += l * sample(x, tap(i, phase.lo_at, k, n));
            d += h * sample(x, tap(i, phase.hi_at, k, n));
        }
        *oa = a;
        *od = d;
    }
}

/// Inverse of [`analyze`] (its adjoint, the filter bank being orthonormal): `c` holds `cA`
/// then `cD`; the even-length signal is written to `x` (as long as `c`).
fn synthesize(wavelet: Wavelet, phase: Phase, c: &[f32], x: &mut [f32]) {
    let (lo, hi) = filters(wavelet);
    let n = x.len();
    let half = n / 2;
    x.fill(0.0);
    let Some((c_a, c_d)) = c.split_at_checked(half) else {
        return;
    };
    for (i, (&a, &d)) in c_a.iter().zip(c_d).enumerate() {
        for (k, (&l, &h)) in lo.iter().zip(hi).enumerate() {
            // `tap` keeps the index inside `x`.
            if let Some(v) = x.get_mut(tap(i, phase.lo_at, k, n)) {
                *v += l * a;
            }
            if let Some(v) = x.get_mut(tap(i, phase.hi_at, k, n)) {
                *v += h * d;
            }
        }
    }
}

/// Runs `op(input, output)` on each row of the region in turn: the row is copied into the
/// first half of `scratch`, and `op`'s result, in the second half, is written back in its
/// place.
fn each_row(buf: &mut [f32], dims: Dims, scratch: &mut [f32], op: impl Fn(&[f32], &mut [f32])) {
    let w = dims.width();
    // The public entry points check `scratch` holds two rows and `buf` the region.
    let Some((input, output)) = scratch.split_at_mut_checked(w) else {
        return;
    };
    let Some(output) = output.get_mut(..w) else {
        return;
    };
    for y in 0..dims.height() {
        let Some(row) = dims.row_mut(buf, y) else {
            return;
        };
        input.copy_from_slice(row);
        op(input, output);
        row.copy_from_slice(output);
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
    // The public entry points check `tmp` holds the region and `buf` its rows.
    let Some(tmp) = tmp.get_mut(..w * h) else {
        return;
    };
    tmp.fill(0.0);
    let (low, high) = tmp.split_at_mut(half * w);
    let row_pairs = low.chunks_exact_mut(w).zip(high.chunks_exact_mut(w));
    for (i, (a_row, d_row)) in row_pairs.enumerate() {
        for (k, (&l, &g)) in lo.iter().zip(hi).enumerate() {
            let src_a = dims.row(buf, tap(i, phase.lo_at, k, h)).unwrap_or_default();
            let src_d = dims.row(buf, tap(i, phase.hi_at, k, h)).unwrap_or_default();
            for (o, &v) in a_row.iter_mut().zip(src_a) {
                *o += l * v;
            }
            for (o, &v) in d_row.iter_mut().zip(src_d) {
                *o += g * v;
            }
        }
    }
    copy_rows_back(buf, dims, tmp);
}

/// Replaces the region's rows in `buf` by the packed rows of `tmp`.
fn copy_rows_back(buf: &mut [f32], dims: Dims, tmp: &[f32]) {
    for (y, src) in tmp.chunks_exact(dims.width()).enumerate() {
        if let Some(dst) = dims.row_mut(buf, y) {
            dst.copy_from_slice(src);
        }
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
    // The public entry points check `tmp` holds the region and `buf` its rows.
    let Some(tmp) = tmp.get_mut(..w * h) else {
        return;
    };
    tmp.fill(0.0);
    for i in 0..half {
        let src_a = dims.row(buf, i).unwrap_or_default();
        let src_d = dims.row(buf, half + i).unwrap_or_default();
        for (k, (&l, &g)) in lo.iter().zip(hi).enumerate() {
            let ta = tap(i, phase.lo_at, k, h) * w;
            let dst_a = tmp.get_mut(ta..ta + w).unwrap_or_default();
            for (o, &v) in dst_a.iter_mut().zip(src_a) {
                *o += l * v;
            }
            let td = tap(i, phase.hi_at, k, h) * w;
            let dst_d = tmp.get_mut(td..td + w).unwrap_or_default();
            for (o, &v) in dst_d.iter_mut().zip(src_d) {
                *o += g * v;
            }
        }
    }
    copy_rows_back(buf, dims, tmp);
}

/// One forward 2-D level on an even-sized region, in place: rows then columns, in
/// Mallat's layout (PyWavelets' subbands as four quadrants, LL over LH; not the lifting's
/// interleaved rows of [`crate::geometry`]). `scratch` holds [`level_scratch_len`].
pub(crate) fn forward_level(
    wavelet: Wavelet,
    phase: Phase,
    buf: &mut [f32],
    dims: Dims,
    scratch: &mut [f32],
) {
    each_row(buf, dims, scratch, |x, out| analyze(wavelet, phase, x, out));
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
    each_row(buf, dims, scratch, |c, x| synthesize(wavelet, phase, c, x));
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
    // Odd sides are extended by repeating the last row and column.
    let out_rows = out.chunks_exact_mut(padded.width()).take(padded.height());
    for (y, out_row) in out_rows.enumerate() {
        let src = dims
            .row(img, y.min(dims.height() - 1))
            .ok_or(dims.too_small("image", img.len()))?;
        let (head, tail) = out_row.split_at_mut(dims.width());
        head.copy_from_slice(src);
        if let Some(&last) = src.last() {
            tail.fill(last);
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
    // The top-left `w × h` of the padded grid, packed: `coeffs` holds at least `ph ≥ h`
    // rows of `pw ≥ w`, `out` at least `h` rows of `w` (both checked above).
    let rows = coeffs
        .chunks_exact(padded.width())
        .zip(out.chunks_exact_mut(dims.width()));
    for (src, dst) in rows.take(dims.height()) {
        let (src, _) = src.split_at(dims.width());
        dst.copy_from_slice(src);
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
