//! Level 1 of db2 or Haar on 8-bit rows in 16-bit lanes ([`I16x2`]): the row pass from
//! bytes and the inverse row pass to bytes, four samples a word, for rows whose length is
//! a multiple of 4 (the device's tiles: 320, 160 or 80 pixels). The column passes run on
//! the same words through the generic sweeps ([`super::db2`], [`super::haar`]), two
//! columns a word.
//!
//! A row of `4q` bytes is `q` words, each giving the lanes of its even samples
//! `(e₂ₖ, e₂ₖ₊₁)` and of its odd ones `(o₂ₖ, o₂ₖ₊₁)` (pairs `2k` and `2k + 1`). The
//! lifting steps run on those pairs of pairs. db2: `s¹ = e + ⌊√3·o⌋`,
//! `d¹ₗ = o − (⌊a·s¹ₗ⌋ + ⌊b·s¹ₗ₋₁⌋)`, `s²ₗ = s¹ₗ − d¹ₗ₊₁`, with `s¹₋₁` and `d¹ₙₕ` mirrored
//! as in [`super::db2`] (whole-sample symmetric extension), which at a row's ends is a
//! swap of a word's lanes. Haar: `d = o − e`, `s = ⌊(e + o)/2⌋` (`SSUB16`, `SHADD16`),
//! the integer path's arithmetic exactly. The output words hold the low band's
//! coefficients two a word, then the high band's: the layout of the generic line
//! passes, packed.
//!
//! Same bits as the generic one-sample sweeps run on `I16x2` words holding one sample
//! (test `lane_rows_are_the_generic_sweep_two_pairs_a_word`).

use super::lift::Lift;
use super::rows::{ColumnBounds, RowsPrepared, RowsReady, Unsaturated};
use super::{db2, haar};
use crate::lanes::I16x2;
use crate::{Dims, Wavelet};

/// db2's forward row pass of `src` (a multiple of 4 bytes, at least 4) into `dst`: the
/// low band's `len/2` coefficients then the high band's, two a word (`len/2` words). The
/// bytes take the fusion's guard bits (`GUARD`). Other lengths, or a short `dst`, write
/// nothing and return `false`.
#[inline(always)]
pub(crate) fn db2_forward_row<const GUARD: u32>(src: &[u8], dst: &mut [I16x2]) -> bool {
    let k = <I16x2 as Lift>::constants();
    let Some((words, low, high)) = forward_halves(src, dst) else {
        return false;
    };
    let Some((first, rest)) = words.split_first() else {
        return false;
    };
    let pairs = |w: &[u8; 4]| {
        let [e, o] = I16x2::from_bytes(u32::from_le_bytes(*w));
        (e.shl_small(GUARD), o.shl_small(GUARD))
    };
    let s1 = |(e, o): (I16x2, I16x2)| e + o.mul_q16(k.sqrt3);
    let d1 = |o: I16x2, s: I16x2, s_prev: I16x2| o - s.mul_q16_add(k.a, s_prev, k.b);
    // Word 0: s¹₋₁ is s¹₁, the other lane of the same word.
    let (e, o) = pairs(first);
    let mut s = s1((e, o));
    let mut d = d1(o, s, s.swap());
    for ((w, lo), hi) in rest.iter().zip(low.iter_mut()).zip(high.iter_mut()) {
        let (e, o) = pairs(w);
        let s_next = s1((e, o));
        let d_next = d1(o, s_next, I16x2::straddle(s, s_next));
        *lo = s - I16x2::straddle(d, d_next);
        *hi = d;
        (s, d) = (s_next, d_next);
    }
    // The last word: d¹ past the end is its mirror d¹ₙₕ₋₂, the other lane.
    if let (Some(lo), Some(hi)) = (low.last_mut(), high.last_mut()) {
        *lo = s - d.swap();
        *hi = d;
    }
    true
}

/// Inverse of [`db2_forward_row`]: `src` holds the low band's words then the high
/// band's (`len/4` each), `dst` (a multiple of 4 bytes, at least 4) gets the samples
/// rounded from the guard bits and clamped to bytes ([`I16x2::to_bytes`]). Other lengths,
/// or a short `src`, write nothing and return `false`.
#[inline(always)]
pub(crate) fn db2_inverse_row<const GUARD: u32>(src: &[I16x2], dst: &mut [u8]) -> bool {
    let k = <I16x2 as Lift>::constants();
    let Some((low, high, words)) = inverse_halves(src, dst) else {
        return false;
    };
    let unlift = |s: I16x2, s_prev: I16x2, d: I16x2| {
        let o = d + s.mul_q16_add(k.a, s_prev, k.b);
        I16x2::to_bytes::<GUARD>(s - o.mul_q16(k.sqrt3), o).to_le_bytes()
    };
    // s¹ₗ = s²ₗ + d¹ₗ₊₁. Past the last word d¹ₙₕ is its mirror d¹ₙₕ₋₂, and before the
    // first s¹₋₁ is s¹₁: each the other lane of the same word.
    let (Some((first, inner_out)), Some((&l_first, low_rest)), Some((&d_first, high_rest))) = (
        words.split_first_mut(),
        low.split_first(),
        high.split_first(),
    ) else {
        return false;
    };
    let d_after = high_rest
        .first()
        .map_or(d_first.swap(), |&n| I16x2::straddle(d_first, n));
    let mut s_prev = l_first + d_after;
    *first = unlift(s_prev, s_prev.swap(), d_first);
    let Some((last, inner_out)) = inner_out.split_last_mut() else {
        return true;
    };
    // Words 1 … q − 2, each with the next word's d¹.
    let ahead = low_rest
        .iter()
        .zip(high_rest.iter().zip(high_rest.get(1..).unwrap_or_default()));
    for (out, (&l, (&d, &d_next))) in inner_out.iter_mut().zip(ahead) {
        let s = l + I16x2::straddle(d, d_next);
        *out = unlift(s, I16x2::straddle(s_prev, s), d);
        s_prev = s;
    }
    if let (Some(&l), Some(&d)) = (low_rest.last(), high_rest.last()) {
        let s = l + d.swap();
        *last = unlift(s, I16x2::straddle(s_prev, s), d);
    }
    true
}

/// Haar's forward row pass, as [`db2_forward_row`]: `d = o − e`, `s = ⌊(e + o)/2⌋`.
#[inline(always)]
pub(crate) fn haar_forward_row<const GUARD: u32>(src: &[u8], dst: &mut [I16x2]) -> bool {
    let Some((words, low, high)) = forward_halves(src, dst) else {
        return false;
    };
    for ((w, s), d) in words.iter().zip(low).zip(high) {
        let [e, o] = I16x2::from_bytes(u32::from_le_bytes(*w));
        let (e, o) = (e.shl_small(GUARD), o.shl_small(GUARD));
        *d = o - e;
        *s = e.halving_add(o);
    }
    true
}

/// Inverse of [`haar_forward_row`], as [`db2_inverse_row`]: `e = s − ⌊d/2⌋`, `o = e + d`.
#[inline(always)]
pub(crate) fn haar_inverse_row<const GUARD: u32>(src: &[I16x2], dst: &mut [u8]) -> bool {
    let Some((low, high, words)) = inverse_halves(src, dst) else {
        return false;
    };
    for ((out, &s), &d) in words.iter_mut().zip(low).zip(high) {
        let even = s - d.halving_add(I16x2::default());
        *out = I16x2::to_bytes::<GUARD>(even, d + even).to_le_bytes();
    }
    true
}

/// A row of bytes as words, and the low and high bands' words ([`forward_halves`]).
type ForwardRow<'r> = (&'r [[u8; 4]], &'r mut [I16x2], &'r mut [I16x2]);

/// The low and high bands' words, and a row of bytes as words ([`inverse_halves`]).
type InverseRow<'r> = (&'r [I16x2], &'r [I16x2], &'r mut [[u8; 4]]);

/// A forward row pass's operands: the row of `4q` bytes as its `q` words, and the low
/// and high bands' `q` words each at the front of `dst`. `None` for a row that is not a
/// multiple of 4 bytes or is empty, or a `dst` too short.
#[inline(always)]
fn forward_halves<'r>(src: &'r [u8], dst: &'r mut [I16x2]) -> Option<ForwardRow<'r>> {
    let (words, []) = src.as_chunks::<4>() else {
        return None;
    };
    let q = words.len();
    let (low, high) = dst.get_mut(..2 * q)?.split_at_mut(q);
    (q > 0).then_some((words, low, high))
}

/// An inverse row pass's operands, as [`forward_halves`]: the low and high bands' `q`
/// words each at the front of `src`, and the row of `4q` bytes as its `q` words.
#[inline(always)]
fn inverse_halves<'r>(src: &'r [I16x2], dst: &'r mut [u8]) -> Option<InverseRow<'r>> {
    let (words, []) = dst.as_chunks_mut::<4>() else {
        return None;
    };
    let q = words.len();
    let (low, high) = src.get(..2 * q)?.split_at(q);
    (q > 0).then_some((low, high, words))
}

/// The words region of the `w × h` level-1 image laid out as `dims` says in a buffer of
/// `image_len` bytes, in lanes: `w/2` words a row. `None` unless `w` is a multiple of 4,
/// the image's buffer holds it and the lanes' buffer (`words_len`) holds the region.
fn word_region(dims: Dims, image_len: usize, words_len: usize) -> Option<Dims> {
    let w = dims.width();
    if !w.is_multiple_of(4) || dims.check_buffer("image", image_len).is_err() {
        return None;
    }
    Dims::new(w / 2, dims.height())
        .ok()
        .filter(|region| words_len >= region.pixels())
}

/// Forward level 1 of `wavelet` of the 8-bit image in `src` (laid out as `src_dims` says;
/// its width a multiple of 4) into `buf`: `h` rows of `w/2` words, in the layout of
/// [`crate::geometry`] two coefficients a word (rows `2l` the column-low band: LL words,
/// then HL; rows `2l + 1` LH, then HH). Each row is lifted from its bytes just before the
/// column sweep first reads it. Returns `false`, writing nothing, for another width or a
/// `buf` too short.
pub(crate) fn forward_from_bytes<const GUARD: u32>(
    wavelet: Wavelet,
    (src, src_dims): (&[u8], Dims),
    buf: &mut [I16x2],
) -> bool {
    let Some(region) = word_region(src_dims, src.len(), buf.len()) else {
        return false;
    };
    let mut row_pass = |y: usize, row: &mut [I16x2]| {
        if let Some(bytes) = src_dims.row(src, y) {
            match wavelet {
                Wavelet::Db2 => db2_forward_row::<GUARD>(bytes, row),
                Wavelet::Haar => haar_forward_row::<GUARD>(bytes, row),
            };
        }
    };
    let ready = &mut RowsReady::new(&mut row_pass);
    match wavelet {
        Wavelet::Db2 => db2::forward_columns(buf, region, ready),
        Wavelet::Haar => haar::forward_columns(buf, region, ready),
    }
    true
}

/// Inverse of [`forward_from_bytes`] into the 8-bit image in `dst` (laid out as
/// `dst_dims` says), rounded from the guard bits and clamped; `prepare(y, row y)` runs on
/// each row of `buf` before the sweep first reads it (the fusion blends the bands there).
/// Nothing saturates: the level's values all fit a lane (`docs/numerics.md`). Returns
/// `false`, writing nothing, for another width or a buffer too short.
pub(crate) fn inverse_to_bytes<const GUARD: u32>(
    wavelet: Wavelet,
    buf: &mut [I16x2],
    (dst, dst_dims): (&mut [u8], Dims),
    mut prepare: impl FnMut(usize, &mut [I16x2]),
) -> bool {
    let Some(region) = word_region(dst_dims, dst.len(), buf.len()) else {
        return false;
    };
    let mut done = |y: usize, row: &mut [I16x2]| {
        if let Some(bytes) = dst_dims.row_mut(dst, y) {
            match wavelet {
                Wavelet::Db2 => db2_inverse_row::<GUARD>(row, bytes),
                Wavelet::Haar => haar_inverse_row::<GUARD>(row, bytes),
            };
        }
    };
    let bounds = ColumnBounds::split_at_half(region.width(), [0, 0], Unsaturated);
    let mut prepared = RowsPrepared::new(&mut prepare, buf, region);
    match wavelet {
        Wavelet::Db2 => db2::inverse_columns(buf, region, bounds, &mut prepared, &mut done),
        Wavelet::Haar => haar::inverse_columns(buf, region, bounds, &mut prepared, &mut done),
    }
    true
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::lifting::q16::CONSTANTS;
    use crate::lifting::{GUARD_BITS, Lift};
    use std::vec::Vec;

    /// A deterministic row of bytes with edges, flats and noise.
    fn row(len: usize, seed: u32) -> Vec<u8> {
        let mut x = seed.wrapping_mul(2_654_435_761).max(1);
        (0..len)
            .map(|i| {
                x ^= x << 13;
                x ^= x >> 17;
                x ^= x << 5;
                match (i / 7 + seed as usize) % 4 {
                    0 => 0,
                    1 => 255,
                    _ => x as u8,
                }
            })
            .collect()
    }

    /// Both wavelets' lane row passes, forward and inverse.
    const ROWS: [(Wavelet, Forward, Inverse); 2] = [
        (
            Wavelet::Db2,
            db2_forward_row::<GUARD_BITS>,
            db2_inverse_row::<GUARD_BITS>,
        ),
        (
            Wavelet::Haar,
            haar_forward_row::<GUARD_BITS>,
            haar_inverse_row::<GUARD_BITS>,
        ),
    ];
    type Forward = fn(&[u8], &mut [I16x2]) -> bool;
    type Inverse = fn(&[I16x2], &mut [u8]) -> bool;

    #[test]
    fn lane_rows_are_the_generic_sweep_two_pairs_a_word() {
        for (wavelet, forward, inverse) in ROWS {
            for len in (4..=64).step_by(4).chain([160, 320]) {
                for seed in 0..20 {
                    let src = row(len, seed);
                    let what = std::format!("{wavelet:?}, length {len}, seed {seed}");
                    // The generic sweep, one sample a word (both lanes alike).
                    let mut generic = std::vec![I16x2::default(); len];
                    let mut scratch = std::vec![I16x2::default(); len];
                    super::super::forward_row_from_bytes(wavelet, &src, &mut generic, &mut scratch);
                    let mut packed = std::vec![I16x2::default(); len / 2];
                    assert!(forward(&src, &mut packed));
                    let unpacked: Vec<i16> = packed.iter().flat_map(|w| [w.lo(), w.hi()]).collect();
                    let expected: Vec<i16> = generic.iter().map(|w| w.lo()).collect();
                    assert_eq!(unpacked, expected, "forward, {what}");
                    // Back: the generic inverse, and the lanes' to bytes.
                    let mut generic_bytes = std::vec![0u8; len];
                    let put = |v: I16x2| v.to_byte();
                    match wavelet {
                        Wavelet::Db2 => db2::inverse_line_into(&generic, &mut generic_bytes, put),
                        Wavelet::Haar => haar::inverse_line_into(&generic, &mut generic_bytes, put),
                    }
                    let mut bytes = std::vec![0u8; len];
                    assert!(inverse(&packed, &mut bytes));
                    assert_eq!(bytes, generic_bytes, "inverse, {what}");
                    assert_eq!(bytes, src, "round trip, {what}");
                }
            }
        }
    }

    /// A `w × h` tile of [`row`]s, with a smooth ramp under some of them.
    fn tile(w: usize, h: usize, seed: u32) -> Vec<u8> {
        (0..h as u32)
            .flat_map(|y| {
                let mut r = row(w, seed * 31 + y);
                if y % 3 == 0 {
                    for (x, v) in r.iter_mut().enumerate() {
                        *v = ((x * 255) / w.max(1)) as u8;
                    }
                }
                r
            })
            .collect()
    }

    #[test]
    fn a_lane_level_is_the_generic_level_and_comes_back_exactly() {
        use crate::lifting::{
            Coefficients, Saturation, forward_level_from_bytes, inverse_level, level_bounds,
        };
        for (wavelet, w) in [Wavelet::Db2, Wavelet::Haar]
            .into_iter()
            .flat_map(|wl| [4, 8, 12, 20, 80, 160].map(|w| (wl, w)))
        {
            for h in 1..=18 {
                let dims = Dims::new(w, h).unwrap();
                let src = tile(w, h, (w * 100 + h) as u32);
                let mut packed = std::vec![I16x2::default(); w * h / 2];
                assert!(forward_from_bytes::<GUARD_BITS>(
                    wavelet,
                    (&src, dims),
                    &mut packed
                ));
                // The generic level, one sample a word.
                let mut generic = std::vec![I16x2::default(); w * h];
                let mut scratch = std::vec![I16x2::default(); w];
                forward_level_from_bytes(wavelet, &mut generic, dims, &mut scratch, (&src, dims));
                let lanes: Vec<i16> = packed.iter().flat_map(|v| [v.lo(), v.hi()]).collect();
                let expected: Vec<i16> = generic.iter().map(|v| v.lo()).collect();
                assert_eq!(lanes, expected, "{wavelet:?} forward {w}x{h}");
                // Back to bytes: the generic inverse's, and the tile itself.
                let mut out = std::vec![0u8; w * h];
                let mut rows_prepared = 0;
                assert!(inverse_to_bytes::<GUARD_BITS>(
                    wavelet,
                    &mut packed,
                    (&mut out, dims),
                    |_, _| { rows_prepared += 1 }
                ));
                assert_eq!(rows_prepared, h, "{wavelet:?} {w}x{h}");
                let bounds = level_bounds(wavelet, 1)[0];
                let mut generic_out = std::vec![0u8; w * h];
                inverse_level(
                    wavelet,
                    &mut generic,
                    dims,
                    &mut scratch,
                    Saturation {
                        bounds: &bounds,
                        coefficients: Coefficients::InBounds,
                    },
                    &mut |_, _| {},
                    Some((&mut generic_out, dims)),
                );
                assert_eq!(out, generic_out, "{wavelet:?} inverse {w}x{h}");
                assert_eq!(out, src, "{wavelet:?} round trip {w}x{h}");
            }
        }
    }

    #[test]
    fn other_lengths_are_refused_untouched() {
        for (wavelet, forward, inverse) in ROWS {
            let mut dst = [I16x2::splat(7); 8];
            for len in [0, 1, 2, 3, 5, 6, 7] {
                assert!(!forward(&row(len, 1), &mut dst), "{wavelet:?} {len}");
            }
            // Too short a destination.
            assert!(!forward(&row(20, 1), &mut dst), "{wavelet:?}");
            assert_eq!(dst, [I16x2::splat(7); 8], "{wavelet:?}");
            let mut bytes = [9u8; 6];
            assert!(!inverse(&dst, &mut bytes), "{wavelet:?}");
            assert!(!inverse(&dst[..1], &mut bytes[..4]), "{wavelet:?}");
            assert_eq!(bytes, [9; 6], "{wavelet:?}");
        }
    }

    #[test]
    fn the_constants_are_the_rounded_q16_values() {
        let sqrt3 = 3f64.sqrt();
        for (c, x) in [
            (CONSTANTS.sqrt3, sqrt3),
            (CONSTANTS.a, sqrt3 / 4.0),
            (CONSTANTS.b, (sqrt3 - 2.0) / 4.0),
        ] {
            assert_eq!(c, (x * 65_536.0).round() as i32);
        }
        let _ = <I16x2 as Lift>::constants();
    }
}
