//! Integer db2 (Daubechies-4) by the Daubechies–Sweldens lifting factorization, with
//! rounding in every step (Calderbank, Daubechies, Sweldens & Yeo, 1998):
//!
//! ```text
//! s¹[l] = e[l] + R(√3 · o[l])
//! d¹[l] = o[l] − R(√3/4 · s¹[l] + (√3 − 2)/4 · s¹[l − 1])
//! s²[l] = s¹[l] − d¹[l + 1]
//! ```
//!
//! `R(v)` rounds half up on the integer path (constants in Q16, products in i64) and is the
//! identity on the `f32` path, which runs the same steps. The final scaling by `(√3 ∓ 1)/√2` is left
//! out so the transform stays integer and reversible: the low band therefore has DC gain
//! `1 + √3 ≈ 2.73` per 1-D pass. Indices outside a channel are mapped back by whole-sample
//! symmetric extension of that channel ([`mirror`]); every step reads only the other
//! channel, so the inverse applies the same extension to the same values and undoes each
//! step exactly, for every length ≥ 1.

use super::Lift;
use crate::geometry::mirror;

/// Fraction bits of the lifting constants.
pub(crate) const Q: u32 = 16;
/// √3 in Q16.
pub(crate) const SQRT3: i64 = 113_512;
/// √3/4 in Q16.
pub(crate) const A: i64 = 28_378;
/// (√3 − 2)/4 in Q16 (negative).
pub(crate) const B: i64 = -4_390;

/// Rounds a Q16 product to the nearest integer, halves upward.
#[inline(always)]
pub(crate) fn round_q(v: i64) -> i32 {
    ((v + (1 << (Q - 1))) >> Q) as i32
}

/// Index of `d¹[l + 1]`: the neighbour inside, or its mirror image past the end.
#[inline(always)]
fn next_index(l: usize, nh: usize) -> usize {
    if l + 1 < nh {
        l + 1
    } else {
        mirror(l as isize + 1, nh)
    }
}

/// Index of `s¹[l − 1]`.
#[inline(always)]
fn prev_index(l: usize, nl: usize) -> usize {
    if l > 0 { l - 1 } else { mirror(-1, nl) }
}

/// Index of `o[l]` seen from the even channel (past the end for the last even sample of
/// an odd length).
#[inline(always)]
fn odd_index(l: usize, nh: usize) -> usize {
    if l < nh { l } else { mirror(l as isize, nh) }
}

/// `dst[i] += f(a[i], b[i])` (or `-=`) over equal-length runs: each step's rows as one
/// flat loop the compiler can vectorize.
#[inline(always)]
fn apply<T: Lift>(dst: &mut [T], a: &[T], b: &[T], add: bool, f: impl Fn(T, T) -> T) {
    for ((d, &x), &y) in dst.iter_mut().zip(a).zip(b) {
        if add {
            *d += f(x, y);
        } else {
            *d -= f(x, y);
        }
    }
}

/// Rows `r0..r1` of a channel made of rows of `w` samples. The callers stay inside the
/// channel (`r1 ≤ nl` or `nh`); rows past its end would read as empty, so the step
/// touches nothing there.
#[inline(always)]
fn rows<T>(c: &[T], r0: usize, r1: usize, w: usize) -> &[T] {
    c.get(r0 * w..r1 * w).unwrap_or_default()
}

/// Rows `r0..r1`, mutable (empty past the channel's end, as [`rows`]).
#[inline(always)]
fn rows_mut<T>(c: &mut [T], r0: usize, r1: usize, w: usize) -> &mut [T] {
    c.get_mut(r0 * w..r1 * w).unwrap_or_default()
}

/// Step 1, `s¹[l] = e[l] ± R(√3·o[l])`: rows below `nh` read their own odd row, the last
/// even row of an odd length reads a mirrored one.
fn update1<T: Lift>(low: &mut [T], high: &[T], w: usize, (nl, nh): (usize, usize), add: bool) {
    let o = rows(high, 0, nh, w);
    apply(rows_mut(low, 0, nh, w), o, o, add, |v, _| v.sqrt3());
    for l in nh..nl {
        let m = odd_index(l, nh);
        let o = rows(high, m, m + 1, w);
        apply(rows_mut(low, l, l + 1, w), o, o, add, |v, _| v.sqrt3());
    }
}

/// Step 2, `d¹[l] = o[l] ∓ R(√3/4·s¹[l] + (√3−2)/4·s¹[l−1])`: row 0 reads a mirrored
/// `s¹[−1]`.
fn predict<T: Lift>(high: &mut [T], low: &[T], w: usize, (nl, nh): (usize, usize), add: bool) {
    let p = prev_index(0, nl);
    apply(
        rows_mut(high, 0, 1, w),
        rows(low, 0, 1, w),
        rows(low, p, p + 1, w),
        add,
        T::predict,
    );
    if nh > 1 {
        apply(
            rows_mut(high, 1, nh, w),
            rows(low, 1, nh, w),
            rows(low, 0, nh - 1, w),
            add,
            T::predict,
        );
    }
}

/// Step 3, `s²[l] = s¹[l] ∓ d¹[l + 1]`: the last rows read mirrored `d¹` rows.
fn update2<T: Lift>(low: &mut [T], high: &[T], w: usize, (nl, nh): (usize, usize), add: bool) {
    let inner = nh - 1;
    let d = rows(high, 1, nh, w);
    apply(rows_mut(low, 0, inner, w), d, d, add, |v, _| v);
    for l in inner..nl {
        let n = next_index(l, nh);
        let d = rows(high, n, n + 1, w);
        apply(rows_mut(low, l, l + 1, w), d, d, add, |v, _| v);
    }
}

/// Forward lifting of the split channels, in place, on rows of `width` samples lifted side
/// by side (`width` 1 for a single line; a block of columns on the column pass). `low` has
/// `nl` rows, `high` `nh` rows, `nl` = `nh` or `nh + 1`. A length-1 signal (no odd
/// sample) is left as it is.
pub(crate) fn forward<T: Lift>(low: &mut [T], high: &mut [T], width: usize) {
    let w = width.max(1);
    let n = (low.len() / w, high.len() / w);
    if n.1 == 0 {
        return;
    }
    update1(low, high, w, n, true);
    predict(high, low, w, n, false);
    update2(low, high, w, n, false);
}

/// Inverse lifting, exactly undoing [`forward`].
pub(crate) fn inverse<T: Lift>(low: &mut [T], high: &mut [T], width: usize) {
    let w = width.max(1);
    let n = (low.len() / w, high.len() / w);
    if n.1 == 0 {
        return;
    }
    update2(low, high, w, n, true);
    predict(high, low, w, n, true);
    update1(low, high, w, n, false);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constants_are_the_rounded_q16_values() {
        let s3 = 3f64.sqrt();
        let q = (1u64 << Q) as f64;
        assert_eq!(SQRT3, (s3 * q).round() as i64);
        assert_eq!(A, (s3 / 4.0 * q).round() as i64);
        assert_eq!(B, ((s3 - 2.0) / 4.0 * q).round() as i64);
    }

    #[test]
    fn constant_signal_has_zero_high_band_and_dc_gain_one_plus_sqrt3() {
        let mut low = [100i32; 5];
        let mut high = [100i32; 5];
        forward(&mut low, &mut high, 1);
        assert_eq!(high, [0; 5]);
        // 100 · (1 + √3) = 273.2
        assert!(low.iter().all(|&s| s == 273), "{low:?}");
    }
}
