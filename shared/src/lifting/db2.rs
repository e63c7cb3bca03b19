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

use super::{Lift, block_row};
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

/// `s¹ = e + R(√3·o)`.
#[inline(always)]
fn lift_s1<T: Lift>(e: T, o: T) -> T {
    e + o.sqrt3()
}

/// `d¹ = o − R(√3/4·s¹ + (√3−2)/4·s¹_prev)`.
#[inline(always)]
fn lift_d1<T: Lift>(o: T, s: T, s_prev: T) -> T {
    o - T::predict(s, s_prev)
}

/// The odd sample back from `d¹`: `o = d¹ + R(√3/4·s¹ + (√3−2)/4·s¹_prev)`.
#[inline(always)]
fn unlift_odd<T: Lift>(d: T, s: T, s_prev: T) -> T {
    d + T::predict(s, s_prev)
}

/// The even sample back from `s¹`: `e = s¹ − R(√3·o)`.
#[inline(always)]
fn unlift_even<T: Lift>(s: T, o: T) -> T {
    s - o.sqrt3()
}

// The one-sweep transforms below run all three steps per sample pair, carrying `s¹` and
// `d¹` (or `s¹` and the odd sample) of the next pair instead of sweeping the line once
// per step. Only the first pair (whose left neighbour is mirrored) and the last ones
// (whose right neighbours are) go through the index maps above. They produce exactly what
// the step-by-step [`forward`] and [`inverse`] do (tested in `lifting`).

/// `c[start..]`, empty if `c` is shorter.
#[inline(always)]
fn from<T>(c: &[T], start: usize) -> &[T] {
    c.get(start..).unwrap_or_default()
}

/// Forward lifting of one line: `src` holds the samples, `dst` (as long) gets the low band
/// then the high band. A line of one sample is copied.
pub(crate) fn forward_line<T: Lift>(src: &[T], dst: &mut [T]) {
    let n = src.len();
    let (nl, nh) = (n.div_ceil(2), n / 2);
    let Some(dst) = dst.get_mut(..n) else {
        return;
    };
    if nh == 0 {
        dst.copy_from_slice(src);
        return;
    }
    let at = |i: usize| src.get(i).copied().unwrap_or_default();
    let s1 = |l: usize| lift_s1(at(2 * l), at(2 * odd_index(l, nh) + 1));
    let (low, high) = dst.split_at_mut(nl);
    let (pairs, _) = src.as_chunks::<2>();
    let mut s = s1(0);
    let mut d = lift_d1(at(1), s, s1(prev_index(0, nl)));
    // Plain slices (not `skip`/`take` adapters) so the zip keeps one loop counter.
    for ((&[e, o], lo), hi) in from(pairs, 1)
        .iter()
        .zip(low.iter_mut())
        .zip(high.iter_mut())
    {
        let s_next = lift_s1(e, o);
        let d_next = lift_d1(o, s_next, s);
        *hi = d;
        *lo = s - d_next;
        (s, d) = (s_next, d_next);
    }
    // `s` and `d` are now the last pair's; its s² (and an odd length's last) read mirrored d¹.
    if let Some(hi) = high.get_mut(nh - 1) {
        *hi = d;
    }
    for l in nh - 1..nl {
        let s_l = if l < nh { s } else { s1(l) };
        let d_next = high.get(next_index(l, nh)).copied().unwrap_or_default();
        if let Some(lo) = low.get_mut(l) {
            *lo = s_l - d_next;
        }
    }
}

/// Inverse of [`forward_line`]: `src` holds the low then the high band, `dst` (as long)
/// gets the samples, each saturated to `±out_bound`.
pub(crate) fn inverse_line<T: Lift>(src: &[T], dst: &mut [T], out_bound: i32) {
    let n = src.len();
    let (nl, nh) = (n.div_ceil(2), n / 2);
    let Some(dst) = dst.get_mut(..n) else {
        return;
    };
    let (low, high) = src.split_at(nl);
    let lo = |l: usize| low.get(l).copied().unwrap_or_default();
    let hi = |l: usize| high.get(l).copied().unwrap_or_default();
    let s1 = |l: usize| lo(l) + hi(next_index(l, nh));
    let (pairs, odd_end) = dst.as_chunks_mut::<2>();
    if nh == 0 {
        if let [last] = odd_end {
            *last = lo(0).saturate(out_bound);
        }
        return;
    }
    let inner = nh.saturating_sub(2);
    let mut s = s1(0);
    let mut o = unlift_odd(hi(0), s, s1(prev_index(0, nl)));
    let ahead = from(low, 1).iter().zip(from(high, 1)).zip(from(high, 2));
    let inner_pairs = pairs.get_mut(..inner).unwrap_or_default();
    for ([e_out, o_out], ((&l_next, &h_next), &h_after)) in inner_pairs.iter_mut().zip(ahead) {
        let s_next = l_next + h_after;
        let o_next = unlift_odd(h_next, s_next, s);
        *e_out = unlift_even(s, o).saturate(out_bound);
        *o_out = o.saturate(out_bound);
        (s, o) = (s_next, o_next);
    }
    // The last pairs read mirrored neighbours; `s` and `o` are pair `inner`'s.
    for l in inner..nl {
        if let Some([e_out, o_out]) = pairs.get_mut(l) {
            let s_next = if l + 1 < nl { s1(l + 1) } else { s };
            let o_next = if l + 1 < nh {
                unlift_odd(hi(l + 1), s_next, s)
            } else {
                o
            };
            *e_out = unlift_even(s, o).saturate(out_bound);
            *o_out = o.saturate(out_bound);
            (s, o) = (s_next, o_next);
        } else if let [last] = odd_end {
            // An odd length's last even sample reads a mirrored odd one.
            let m = odd_index(l, nh);
            let o_m = unlift_odd(hi(m), s1(m), s1(prev_index(m, nl)));
            *last = unlift_even(s, o_m).saturate(out_bound);
        }
    }
}

/// `dst[j] = f(a[j], b[j])` over a block row.
#[inline(always)]
fn lanes<T: Copy>(dst: &mut [T], a: &[T], b: &[T], f: impl Fn(T, T) -> T) {
    for (d, (&x, &y)) in dst.iter_mut().zip(a.iter().zip(b)) {
        *d = f(x, y);
    }
}

/// Forward lifting of a block of `w` columns, `n` rows long, lifted side by side: row `k`
/// of the input starts at `k·stride` in `src`; `dst` gets `n` contiguous rows of `w`, the
/// low band's first. Low rows hold `s¹` until the next row's `d¹` turns them into `s²`.
pub(crate) fn forward_block<T: Lift>(src: &[T], stride: usize, w: usize, n: usize, dst: &mut [T]) {
    let (nl, nh) = (n.div_ceil(2), n / 2);
    let Some(dst) = dst.get_mut(..n * w) else {
        return;
    };
    let row = |k: usize| block_row(src, k, stride, w);
    if nh == 0 {
        lanes(dst, row(0), row(0), |v, _| v);
        return;
    }
    let (low, high) = dst.split_at_mut(nl * w);
    let s1_into = |low: &mut [T], l: usize| {
        let o = row(2 * odd_index(l, nh) + 1);
        lanes(
            low.get_mut(l * w..(l + 1) * w).unwrap_or_default(),
            row(2 * l),
            o,
            lift_s1,
        );
    };
    // The first pair's d¹ reads s¹ of its mirrored left neighbour (pair 1, or itself).
    s1_into(low, 0);
    if nl > 1 {
        s1_into(low, 1);
    }
    {
        let (s0, rest) = low.split_at(w);
        let s_prev = if nl > 1 {
            rest.get(..w).unwrap_or_default()
        } else {
            s0
        };
        let lanes0 = high.iter_mut().zip(s0.iter().zip(s_prev)).zip(row(1));
        for ((d, (&s, &sp)), &o) in lanes0 {
            *d = lift_d1(o, s, sp);
        }
    }
    let mut low_rows = low.chunks_exact_mut(w);
    if let Some(mut cur) = low_rows.next() {
        for (l, (next, hi)) in (1..nh).zip(low_rows.zip(high.chunks_exact_mut(w).skip(1))) {
            let (e_row, o_row) = (row(2 * l), row(2 * l + 1));
            let lanes = cur.iter_mut().zip(next.iter_mut()).zip(hi.iter_mut());
            for (((s, s_next), d_next), (&e, &o)) in lanes.zip(e_row.iter().zip(o_row)) {
                *s_next = lift_s1(e, o);
                *d_next = lift_d1(o, *s_next, *s);
                *s -= *d_next;
            }
            cur = next;
        }
    }
    // Row nh − 1 holds s¹; an odd length's last row gets its s¹ now. Both read mirrored d¹.
    if nl > nh {
        s1_into(low, nh);
    }
    for l in nh - 1..nl {
        let d = block_row(high, next_index(l, nh), w, w);
        for (s, &d) in low
            .get_mut(l * w..(l + 1) * w)
            .unwrap_or_default()
            .iter_mut()
            .zip(d)
        {
            *s -= d;
        }
    }
}

/// Turns a pair's `s¹` row and odd row into its even and odd samples, saturated.
#[inline(always)]
fn finish_pair<T: Lift>(even_row: &mut [T], odd_row: &mut [T], out_bounds: &[i32]) {
    for ((s, o), &b) in even_row.iter_mut().zip(odd_row.iter_mut()).zip(out_bounds) {
        *s = unlift_even(*s, *o).saturate(b);
        *o = o.saturate(b);
    }
}

/// Inverse of [`forward_block`]: `src` holds `n` contiguous rows of `w` (low band first);
/// the samples go to rows `stride` apart in `dst`, column `j` saturated to
/// `±out_bounds[j]`. Even output rows hold `s¹` and odd ones the unsaturated odd samples
/// until the next row pair is known.
pub(crate) fn inverse_block<T: Lift>(
    src: &[T],
    w: usize,
    n: usize,
    dst: &mut [T],
    stride: usize,
    out_bounds: &[i32],
) {
    let (nl, nh) = (n.div_ceil(2), n / 2);
    let (low, high) = src.split_at(nl * w);
    let lo = |l: usize| block_row(low, l, w, w);
    let hi = |l: usize| block_row(high, l, w, w);
    let s1_into = |out: &mut [T], l: usize| lanes(out, lo(l), hi(next_index(l, nh)), |a, b| a + b);
    let mut rows = dst
        .chunks_mut(stride)
        .map(|r| r.get_mut(..w).unwrap_or_default());
    let Some(mut even_row) = rows.next() else {
        return;
    };
    if nh == 0 {
        for ((e, &v), &b) in even_row.iter_mut().zip(lo(0)).zip(out_bounds) {
            *e = v.saturate(b);
        }
        return;
    }
    let Some(mut odd_row) = rows.next() else {
        return;
    };
    // Pair 0: s¹ and the odd sample, whose mirrored left neighbour is s¹ of pair 1 (or
    // itself), made in the next even row.
    s1_into(even_row, 0);
    let mut rows = rows.peekable();
    match rows.peek_mut() {
        Some(next_even) if nl > 1 => s1_into(next_even, 1),
        _ => {}
    }
    {
        let s_prev: &[T] = match rows.peek() {
            Some(next_even) if nl > 1 => next_even,
            _ => even_row,
        };
        let lanes0 = odd_row
            .iter_mut()
            .zip(even_row.iter().zip(s_prev))
            .zip(hi(0));
        for ((o, (&s, &sp)), &d) in lanes0 {
            *o = unlift_odd(d, s, sp);
        }
    }
    let inner = nh.saturating_sub(2);
    for l in 0..nl {
        // The next pair, with mirrored neighbours past the interior.
        let next_even = if l + 1 < nl { rows.next() } else { None };
        let next_odd = if l + 1 < nh { rows.next() } else { None };
        match (next_even, next_odd) {
            (Some(s_next_row), Some(o_next_row)) if l < inner => {
                let here = even_row.iter_mut().zip(odd_row.iter_mut()).zip(out_bounds);
                let ahead = lo(l + 1).iter().zip(hi(l + 1)).zip(hi(l + 2));
                let next = s_next_row.iter_mut().zip(o_next_row.iter_mut());
                for (((s, o), &b), ((s_next, o_next), ((&l_next, &h_next), &h_after))) in
                    here.zip(next.zip(ahead))
                {
                    *s_next = l_next + h_after;
                    *o_next = unlift_odd(h_next, *s_next, *s);
                    *s = unlift_even(*s, *o).saturate(b);
                    *o = o.saturate(b);
                }
                (even_row, odd_row) = (s_next_row, o_next_row);
            }
            (Some(s_next_row), next_odd) => {
                s1_into(s_next_row, l + 1);
                if let Some(o_next_row) = next_odd {
                    let lanes1 = o_next_row.iter_mut().zip(s_next_row.iter().zip(&*even_row));
                    for ((o, (&s, &sp)), &d) in lanes1.zip(hi(l + 1)) {
                        *o = unlift_odd(d, s, sp);
                    }
                    finish_pair(even_row, odd_row, out_bounds);
                    (even_row, odd_row) = (s_next_row, o_next_row);
                } else {
                    // Pair l is the last full one; the odd length's last row follows.
                    finish_pair(even_row, odd_row, out_bounds);
                    let m = odd_index(l + 1, nh);
                    let o_m = |j: usize| {
                        let s1 = |k: usize| {
                            let (a, b) = (lo(k).get(j), hi(next_index(k, nh)).get(j));
                            a.copied().unwrap_or_default() + b.copied().unwrap_or_default()
                        };
                        let d = hi(m).get(j).copied().unwrap_or_default();
                        unlift_odd(d, s1(m), s1(prev_index(m, nl)))
                    };
                    for (j, (s, &b)) in s_next_row.iter_mut().zip(out_bounds).enumerate() {
                        *s = unlift_even(*s, o_m(j)).saturate(b);
                    }
                    return;
                }
            }
            _ => {
                finish_pair(even_row, odd_row, out_bounds);
                return;
            }
        }
    }
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

/// Step-by-step forward lifting of the split channels, in place (the float path; the
/// reference the one-sweep forms are tested against), on rows of `width` samples lifted
/// side by side (`width` 1 for a line, a block's width on the column pass). `low` has `nl`
/// rows, `high` `nh` rows, `nl` = `nh` or `nh + 1`; a length-1 signal is left as it is.
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
