//! Integer db2 (Daubechies-4) by the Daubechies–Sweldens lifting factorization, with
//! rounding in every step (Calderbank, Daubechies, Sweldens & Yeo, 1998):
//!
//! ```text
//! s¹[l] = e[l] + R(√3 · o[l])
//! d¹[l] = o[l] − R(√3/4 · s¹[l] + (√3 − 2)/4 · s¹[l − 1])
//! s²[l] = s¹[l] − d¹[l + 1]
//! ```
//!
//! `R(v)` rounds to the nearest integer on the integer path and is the identity on the
//! `f32` path, which runs the same steps. The integer constants are in Q32, so each
//! rounded product is the high word of one 32 × 32 → 64-bit product (or of two summed):
//! `R(√3/4 · s + (√3 − 2)/4 · s')` rounds halves up, and `R(√3 · o)`, whose constant is
//! beyond a signed Q32 word, is `2o − R((2 − √3) · o)` (halves down). Either is within ½
//! of the product by the Q32 constant, which is all the proven bounds ([`super::bounds`])
//! assume. The final scaling by `(√3 ∓ 1)/√2` is left
//! out so the transform stays integer and reversible: the low band therefore has DC gain
//! `1 + √3 ≈ 2.73` per 1-D pass. Indices outside a channel are mapped back by whole-sample
//! symmetric extension of that channel ([`mirror`]); every step reads only the other
//! channel, so the inverse applies the same extension to the same values and undoes each
//! step exactly, for every length ≥ 1.

use super::lift::Lift;
use super::rows::{ColumnBounds, RowsPrepared, RowsReady, StoreRule, row_pair, rows_at, segment};
use crate::Dims;
use crate::geometry::mirror;
use crate::simd;

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
fn lift_s1<T: Lift>(e: T, o: T, k: T::Constants) -> T {
    e + o.sqrt3(k)
}

/// `d¹ = o − R(√3/4·s¹ + (√3−2)/4·s¹_prev)`.
#[inline(always)]
fn lift_d1<T: Lift>(o: T, s: T, s_prev: T, k: T::Constants) -> T {
    o - T::predict(s, s_prev, k)
}

/// The odd sample back from `d¹`: `o = d¹ + R(√3/4·s¹ + (√3−2)/4·s¹_prev)`.
#[inline(always)]
fn unlift_odd<T: Lift>(d: T, s: T, s_prev: T, k: T::Constants) -> T {
    d + T::predict(s, s_prev, k)
}

/// The even sample back from `s¹`: `e = s¹ − R(√3·o)`.
#[inline(always)]
fn unlift_even<T: Lift>(s: T, o: T, k: T::Constants) -> T {
    s - o.sqrt3(k)
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
#[inline(always)]
pub(crate) fn forward_line<T: Lift>(src: &[T], dst: &mut [T]) {
    forward_line_from(src, dst, |v| v);
}

/// [`forward_line`] of the samples `sample(src[i])`: `src` may hold something else than
/// the samples (8-bit values, say), converted as they are read.
#[inline(always)]
pub(crate) fn forward_line_from<S: Copy, T: Lift>(
    src: &[S],
    dst: &mut [T],
    sample: impl Fn(S) -> T,
) {
    let k = T::constants();
    let n = src.len();
    let (nl, nh) = (n.div_ceil(2), n / 2);
    let Some(dst) = dst.get_mut(..n) else {
        return;
    };
    let at = |i: usize| src.get(i).map_or_else(T::default, |&v| sample(v));
    if nh == 0 {
        if let Some(d) = dst.first_mut() {
            *d = at(0);
        }
        return;
    }
    let s1 = |l: usize| lift_s1(at(2 * l), at(2 * odd_index(l, nh) + 1), k);
    let (low, high) = dst.split_at_mut(nl);
    let (pairs, _) = src.as_chunks::<2>();
    let mut s = s1(0);
    let mut d = lift_d1(at(1), s, s1(prev_index(0, nl)), k);
    // Plain slices (not `skip`/`take` adapters) so the zip keeps one loop counter.
    for ((&[e, o], lo), hi) in from(pairs, 1)
        .iter()
        .zip(low.iter_mut())
        .zip(high.iter_mut())
    {
        let (e, o) = (sample(e), sample(o));
        let s_next = lift_s1(e, o, k);
        let d_next = lift_d1(o, s_next, s, k);
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

/// [`forward_line`] of 8-bit samples with the fusion's guard bits
/// ([`Lift::from_guarded_byte`]), as [`forward_line_from`] with that conversion, but the
/// inner pairs read two at a time from one word: one load for four samples.
#[inline(always)]
pub(crate) fn forward_line_bytes<T: Lift>(src: &[u8], dst: &mut [T]) {
    let k = T::constants();
    let n = src.len();
    let (nl, nh) = (n.div_ceil(2), n / 2);
    let Some(dst) = dst.get_mut(..n) else {
        return;
    };
    let at = |i: usize| {
        src.get(i)
            .map_or_else(T::default, |&v| T::from_guarded_byte(v))
    };
    if nh == 0 {
        if let Some(d) = dst.first_mut() {
            *d = at(0);
        }
        return;
    }
    let s1 = |l: usize| lift_s1(at(2 * l), at(2 * odd_index(l, nh) + 1), k);
    let (low, high) = dst.split_at_mut(nl);
    let mut s = s1(0);
    let d0 = lift_d1(at(1), s, s1(prev_index(0, nl)), k);
    let Some((high_first, high_rest)) = high.split_first_mut() else {
        return;
    };
    *high_first = d0;
    // Pairs 1, 2, … two per word: pair l + 1 sets d¹ of l + 1 and s² of l … as in
    // `forward_line_from`, two steps per word. Each d¹ is stored as soon as it is made
    // (the high band from pair 1 on), so only s¹ is carried from word to word.
    let (quads, _) = from(src, 2).as_chunks::<4>();
    let (low2, _) = low.as_chunks_mut::<2>();
    let (high2, _) = high_rest.as_chunks_mut::<2>();
    let byte = |w: u32, i: u32| T::from_guarded_byte((w >> (8 * i)) as u8);
    // `e + R(√3·o)` with the product looked up from the odd byte.
    let s1_of = |e: T, w: u32, i: u32| e + T::sqrt3_of_guarded_byte((w >> (8 * i)) as u8, k);
    // The three cut to one length and indexed: the loop keeps one counter for all three
    // (a zip of three kept three pointers and two counters, and spilled them).
    let words = quads.len().min(low2.len()).min(high2.len());
    let (Some(quads), Some(low2), Some(high2)) = (
        quads.get(..words),
        low2.get_mut(..words),
        high2.get_mut(..words),
    ) else {
        return;
    };
    for i in 0..words {
        let (Some(q), Some(lo), Some(hi)) = (quads.get(i), low2.get_mut(i), high2.get_mut(i))
        else {
            break;
        };
        let w = u32::from_le_bytes(*q);
        let (e0, o0, e1, o1) = (byte(w, 0), byte(w, 1), byte(w, 2), byte(w, 3));
        let s_a = s1_of(e0, w, 1);
        let d_a = lift_d1(o0, s_a, s, k);
        let s_b = s1_of(e1, w, 3);
        let d_b = lift_d1(o1, s_b, s_a, k);
        *hi = [d_a, d_b];
        *lo = [s - d_a, s_a - d_b];
        s = s_b;
    }
    // d¹ of the last pair the words covered (pair 0 if none), read back.
    let mut d = high.get(2 * quads.len()).copied().unwrap_or(d0);
    // The pair a word did not cover, if any (pairs 1 + 2·quads … nh − 1).
    let done = 2 * quads.len();
    for l in done..nh - 1 {
        let (e, o) = (at(2 * l + 2), at(2 * l + 3));
        let s_next = lift_s1(e, o, k);
        let d_next = lift_d1(o, s_next, s, k);
        if let (Some(hi), Some(lo)) = (high.get_mut(l), low.get_mut(l)) {
            *hi = d;
            *lo = s - d_next;
        }
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
#[inline(always)]
pub(crate) fn inverse_line<T: Lift>(src: &[T], dst: &mut [T], out_bound: i32) {
    inverse_line_into(src, dst, |v: T| v.saturate(out_bound));
}

/// Inverse of [`forward_line`] with each sample `v` stored as `put(v)`: `src` holds the
/// low then the high band, `dst` (as long) gets the samples.
#[inline(always)]
pub(crate) fn inverse_line_into<T: Lift, O>(src: &[T], dst: &mut [O], put: impl Fn(T) -> O) {
    let k = T::constants();
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
            *last = put(lo(0));
        }
        return;
    }
    let inner = nh.saturating_sub(2);
    let mut s = s1(0);
    let mut o = unlift_odd(hi(0), s, s1(prev_index(0, nl)), k);
    // Pair l + 1's high sample is pair l's `h_after`: carried, so the sweep walks two
    // input streams, not three (one pointer fewer to keep in a register on the M7).
    let mut h_next = hi(1);
    let ahead = from(low, 1).iter().zip(from(high, 2));
    let inner_pairs = pairs.get_mut(..inner).unwrap_or_default();
    for ([e_out, o_out], (&l_next, &h_after)) in inner_pairs.iter_mut().zip(ahead) {
        let s_next = l_next + h_after;
        let o_next = unlift_odd(h_next, s_next, s, k);
        *e_out = put(unlift_even(s, o, k));
        *o_out = put(o);
        (s, o, h_next) = (s_next, o_next, h_after);
    }
    // The last pairs read mirrored neighbours; `s` and `o` are pair `inner`'s.
    for l in inner..nl {
        if let Some([e_out, o_out]) = pairs.get_mut(l) {
            let s_next = if l + 1 < nl { s1(l + 1) } else { s };
            let o_next = if l + 1 < nh {
                unlift_odd(hi(l + 1), s_next, s, k)
            } else {
                o
            };
            *e_out = put(unlift_even(s, o, k));
            *o_out = put(o);
            (s, o) = (s_next, o_next);
        } else if let [last] = odd_end {
            // An odd length's last even sample reads a mirrored odd one.
            let m = odd_index(l, nh);
            let o_m = unlift_odd(hi(m), s1(m), s1(prev_index(m, nl)), k);
            *last = put(unlift_even(s, o_m, k));
        }
    }
}

/// Forward lifting of one row in two passes that vectorize (the float path): the samples
/// split into `work` (as long) with step 1 on the way (`s¹` low, the odd samples high),
/// then steps 2 and 3 from there back into `row`, low band then high band. Each value is
/// computed by the same operations as in [`forward_line`], so the results are the same;
/// unlike that sweep, no pass carries a value from one sample pair to the next, and no
/// pass copies. A row of one sample is left as it is.
#[inline(always)]
pub(crate) fn forward_row_two_pass<T: Lift>(row: &mut [T], work: &mut [T]) {
    let k = T::constants();
    let n = row.len();
    let (nl, nh) = (n.div_ceil(2), n / 2);
    let Some(work) = work.get_mut(..n) else {
        return;
    };
    if nh == 0 {
        return;
    }
    let (s1, odd) = work.split_at_mut(nl);
    let (pairs, odd_end) = row.as_chunks::<2>();
    for ((&[e, o], s), h) in pairs.iter().zip(s1.iter_mut()).zip(odd.iter_mut()) {
        *s = lift_s1(e, o, k);
        *h = o;
    }
    // An odd length's last even sample reads a mirrored odd one.
    if let ([last], Some(&o)) = (odd_end, odd.get(odd_index(nh, nh)))
        && let Some(s) = s1.get_mut(nh)
    {
        *s = lift_s1(*last, o, k);
    }
    let (s1, odd) = (&*s1, &*odd);
    let s_at = |l: usize| s1.get(l).copied().unwrap_or_default();
    let (low, high) = row.split_at_mut(nl);
    if let (Some(d0), Some(&o0)) = (high.first_mut(), odd.first()) {
        *d0 = lift_d1(o0, s_at(0), s_at(prev_index(0, nl)), k);
    }
    // d¹[l + 1] and, from it, s²[l], for l + 1 < nh.
    let (high_first, high_rest) = high.split_at_mut(1);
    for ((((lo, hi), &o), &s_next), &s) in low
        .iter_mut()
        .zip(high_rest.iter_mut())
        .zip(from(odd, 1))
        .zip(from(s1, 1))
        .zip(s1)
    {
        let d = lift_d1(o, s_next, s, k);
        *hi = d;
        *lo = s - d;
    }
    // The last s² (two for an odd length) read mirrored d¹.
    for l in nh - 1..nl {
        let next = next_index(l, nh);
        let d = if next == 0 {
            high_first.first()
        } else {
            high_rest.get(next - 1)
        };
        if let (Some(lo), Some(&d)) = (low.get_mut(l), d) {
            *lo = s_at(l) - d;
        }
    }
}

/// Inverse of [`forward_row_two_pass`], each sample saturated to `±out_bound`: `s¹` (and a
/// copy of `d¹`) into `work`, then steps 2 and 1 back into `row`, interleaved. The same
/// values as [`inverse_line`].
#[inline(always)]
pub(crate) fn inverse_row_two_pass<T: Lift>(row: &mut [T], work: &mut [T], out_bound: i32) {
    let k = T::constants();
    let n = row.len();
    let (nl, nh) = (n.div_ceil(2), n / 2);
    let Some(work) = work.get_mut(..n) else {
        return;
    };
    if nh == 0 {
        if let Some(v) = row.first_mut() {
            *v = v.saturate(out_bound);
        }
        return;
    }
    let (s1, d1) = work.split_at_mut(nl);
    {
        let (low, high) = row.split_at(nl);
        d1.copy_from_slice(high);
        for ((s, &lo), &d_next) in s1.iter_mut().zip(low).zip(from(high, 1)) {
            *s = lo + d_next;
        }
        // The last s¹ (two for an odd length) read mirrored d¹.
        for l in nh - 1..nl {
            if let (Some(s), Some(&lo), Some(&d)) =
                (s1.get_mut(l), low.get(l), high.get(next_index(l, nh)))
            {
                *s = lo + d;
            }
        }
    }
    let (s1, d1) = (&*s1, &*d1);
    let s_at = |l: usize| s1.get(l).copied().unwrap_or_default();
    let odd_at = |l: usize| {
        let d = d1.get(l).copied().unwrap_or_default();
        unlift_odd(d, s_at(l), s_at(prev_index(l, nl)), k)
    };
    let (pairs, odd_end) = row.as_chunks_mut::<2>();
    let Some(([first_e, first_o], rest)) = pairs.split_first_mut() else {
        return;
    };
    let o0 = odd_at(0);
    *first_e = unlift_even(s_at(0), o0, k).saturate(out_bound);
    *first_o = o0.saturate(out_bound);
    for ([e_out, o_out], ((&d, &s), &s_prev)) in rest
        .iter_mut()
        .zip(from(d1, 1).iter().zip(from(s1, 1)).zip(s1))
    {
        let o = unlift_odd(d, s, s_prev, k);
        *e_out = unlift_even(s, o, k).saturate(out_bound);
        *o_out = o.saturate(out_bound);
    }
    // An odd length's last even sample reads a mirrored odd one.
    if let [last] = odd_end {
        *last = unlift_even(s_at(nh), odd_at(odd_index(nh, nh)), k).saturate(out_bound);
    }
}

/// Forward lifting of the columns of `region` (from the start of `buf`), in place, in one
/// sweep down its `n` rows. On return row `2l` holds row `l` of the
/// low band and row `2l + 1` row `l` of the high band (the layout of
/// [`crate::geometry`]). Each step works on whole rows, so the sweep reads and writes the
/// region once, front to back; `ready` runs the row pass on each row before the sweep
/// first reads it.
pub(crate) fn forward_columns<T: Lift, F: FnMut(usize, &mut [T])>(
    buf: &mut [T],
    region: Dims,
    ready: &mut RowsReady<'_, F>,
) {
    let k = T::constants();
    let n = region.height();
    let (nl, nh) = (n.div_ceil(2), n / 2);
    ready.through(buf, region, n.min(4).saturating_sub(1));
    if nh == 0 {
        return;
    }
    // s¹ first where the sweep needs it before reaching it: pair 0, pair 1 (d¹₀'s mirrored
    // left neighbour), and an odd length's last even row, whose mirrored odd partner the
    // sweep overwrites before it gets there.
    let early = |l: usize| l <= 1 || l >= nh;
    if nl > nh {
        ready.early(buf, region, 2 * nh);
        ready.early(buf, region, 2 * odd_index(nh, nh) + 1);
    }
    for l in (0..nl).filter(|&l| early(l)) {
        if let Some([e, o]) = row_pair(buf, region, 2 * l, 2 * odd_index(l, nh) + 1) {
            for (e, &o) in e.iter_mut().zip(o.iter()) {
                *e = lift_s1(*e, o, k);
            }
        }
    }
    // d¹₀ reads its mirrored left neighbour: s¹₁, or s¹₀ itself.
    first_odd_row(buf, region, |o, s, sp| lift_d1(o, s, sp, k));
    // Pair l's s¹ and d¹, and with them pair l − 1's s².
    for l in 1..nh {
        ready.through(buf, region, 2 * l + 1);
        let Some([s_prev, s, o]) = rows_at(buf, region, [2 * l - 2, 2 * l, 2 * l + 1]) else {
            return;
        };
        forward_rows(s_prev, s, o, !early(l), k);
    }
    // The last low rows' s² read mirrored d¹.
    ready.through(buf, region, n - 1);
    for l in nh - 1..nl {
        if let Some([s, d]) = row_pair(buf, region, 2 * l, 2 * next_index(l, nh) + 1) {
            for (s, &d) in s.iter_mut().zip(d.iter()) {
                *s -= d;
            }
        }
    }
}

/// Row 1 (pair 0's odd row) through `step(o, s¹₀, s¹₋₁)`, the predict step forward
/// ([`lift_d1`]) or back ([`unlift_odd`]); `s¹₋₁` is mirrored: `s¹₁` (row 2), or `s¹₀`
/// itself when the region has one low row (is one or two rows high).
#[inline(always)]
fn first_odd_row<T: Lift>(buf: &mut [T], region: Dims, step: impl Fn(T, T, T) -> T) {
    if region.height() > 2 {
        if let Some([s, o, sp]) = rows_at(buf, region, [0, 1, 2]) {
            for ((o, &s), &sp) in o.iter_mut().zip(s.iter()).zip(sp.iter()) {
                *o = step(*o, s, sp);
            }
        }
    } else if let Some([s, o]) = rows_at(buf, region, [0, 1]) {
        for (o, &s) in o.iter_mut().zip(s.iter()) {
            *o = step(*o, s, s);
        }
    }
}

simd::kernel! {
    /// One step of the forward column sweep on whole rows: pair `l`'s `s¹` (unless
    /// `with_s1` is off: done early) and `d¹`, and pair `l − 1`'s `s²`. Not inlined where
    /// there are vector units, so that the rows arrive as distinct `&mut` arguments: the
    /// compiler then knows they do not overlap and vectorizes the loop (split off one buffer
    /// inside the sweep, they kept it scalar, each row reloaded after every store to
    /// another: 13 % of `rollfuse fuse`'s time). The Cortex-M7 has no vector unit; there the
    /// call cost 5 % more instructions in the forward transform (`tests/mcu-bench`).
    #[cfg_attr(target_arch = "arm", inline(always))]
    #[cfg_attr(not(target_arch = "arm"), inline(never))]
    fn forward_rows<T: Lift>(
        s_prev: &mut [T],
        s: &mut [T],
        o: &mut [T],
        with_s1: bool,
        k: T::Constants,
    ) {
        // Each lane's three samples are read before any is written: inlined (the
        // Cortex-M7), the rows are slices of one buffer to the compiler, which reloaded
        // a sample after every store to another row.
        let lanes = s_prev.iter_mut().zip(s.iter_mut()).zip(o.iter_mut());
        if with_s1 {
            for ((sp, s), o) in lanes {
                let (sp_v, s_v, o_v) = (*sp, *s, *o);
                let s1 = lift_s1(s_v, o_v, k);
                let d1 = lift_d1(o_v, s1, sp_v, k);
                (*s, *o, *sp) = (s1, d1, sp_v - d1);
            }
        } else {
            for ((sp, s), o) in lanes {
                let (sp_v, s_v, o_v) = (*sp, *s, *o);
                let d1 = lift_d1(o_v, s_v, sp_v, k);
                (*o, *sp) = (d1, sp_v - d1);
            }
        }
    }
}

simd::kernel! {
    /// Inverse of [`forward_columns`], in place: each output sample is stored as `bounds`
    /// says (saturated to its column's bound, or not), and `done(y, row y)` runs on each
    /// row as soon as it is final. Even rows hold `s¹` and odd ones the unsaturated odd
    /// samples until the next row pair is known. The stages below are inlined: this is the
    /// Cortex-M7's hot loop, and the wider copies of [`simd::kernel!`] reach only inlined
    /// code.
    pub(crate) fn inverse_columns<
        T: Lift,
        S: StoreRule,
        P: FnMut(usize, &mut [T]),
        D: FnMut(usize, &mut [T]),
    >(
        buf: &mut [T],
        region: Dims,
        bounds: ColumnBounds<S>,
        prepared: &mut RowsPrepared<'_, P>,
        done: &mut D,
    ) {
        let k = T::constants();
        let n = region.height();
        let (nl, nh) = (n.div_ceil(2), n / 2);
        // The first pairs and the early steps below read rows up to 5; the mirrored last
        // pairs' rows are the tail `prepared` has done.
        prepared.through(buf, region, 5);
        if nh == 0 {
            if let Some([row]) = rows_at(buf, region, [0]) {
                bounds.store_row(row);
                done(0, row);
            }
            return;
        }
        // s¹ = s² + d¹[l + 1] first where the sweep needs it before reaching it (pairs 0 and
        // 1) or would by then have turned the mirrored d¹ into odd samples (the last pairs).
        let early = |l: usize| l <= 1 || l + 1 >= nh;
        unlift_s2_rows(buf, region, early);
        first_odd_row(buf, region, |d, s, sp| unlift_odd(d, s, sp, k));
        // An odd length's last even row reads the odd sample of a mirrored pair: made while
        // that sample is not yet saturated, i.e. before its pair is finished.
        let last_even = (nl > nh).then(|| (nh, odd_index(nh, nh)));
        let finish_last_even = |buf: &mut [T], l: usize, done: &mut D| {
            if let Some((last, m)) = last_even
                && m == l
                && let Some([o, s]) = rows_at(buf, region, [2 * m + 1, 2 * last])
            {
                unlift_even_row(s, o, bounds, k);
                done(2 * last, s);
            }
        };
        // Pair l + 1's s¹ and odd sample, and pair l's output.
        for l in 0..nh - 1 {
            prepared.through(buf, region, 2 * l + 5);
            finish_last_even(buf, l, done);
            if early(l + 1) {
                let Some([s, o, s_next, o_next]) =
                    rows_at(buf, region, [2 * l, 2 * l + 1, 2 * l + 2, 2 * l + 3])
                else {
                    return;
                };
                finish_pair_before_early(s, o, s_next, o_next, bounds, k);
                done(2 * l, s);
                done(2 * l + 1, o);
            } else {
                let at = [2 * l, 2 * l + 1, 2 * l + 2, 2 * l + 3, 2 * l + 5];
                let Some([s, o, s_next, o_next, d_after]) = rows_at(buf, region, at) else {
                    return;
                };
                finish_pair(s, o, s_next, o_next, d_after, bounds, k);
                done(2 * l, s);
                done(2 * l + 1, o);
            }
        }
        prepared.through(buf, region, n - 1);
        finish_last_even(buf, nh - 1, done);
        if let Some([s, o]) = rows_at(buf, region, [2 * nh - 2, 2 * nh - 1]) {
            finish_last_pair(s, o, bounds, k);
            done(2 * nh - 2, s);
            done(2 * nh - 1, o);
        }
    }
}

/// The inverse sweep's first step on the low rows `early` picks: `s¹ = s² + d¹[l + 1]`.
#[inline(always)]
fn unlift_s2_rows<T: Lift>(buf: &mut [T], region: Dims, early: impl Fn(usize) -> bool) {
    let n = region.height();
    let (nl, nh) = (n.div_ceil(2), n / 2);
    for l in (0..nl).filter(|&l| early(l)) {
        if let Some([s, d]) = row_pair(buf, region, 2 * l, 2 * next_index(l, nh) + 1) {
            for (s, &d) in s.iter_mut().zip(d.iter()) {
                *s += d;
            }
        }
    }
}

/// An odd length's last even row back from `s¹` (row `s`) and its mirrored odd partner
/// (row `o`, not yet stored), stored as `bounds` says.
#[inline(always)]
fn unlift_even_row<T: Lift, S: StoreRule>(
    s: &mut [T],
    o: &mut [T],
    bounds: ColumnBounds<S>,
    k: T::Constants,
) {
    for (cols, b) in bounds.segments() {
        let lanes = segment(s, &cols).iter_mut().zip(segment(o, &cols).iter());
        for (s, &o) in lanes {
            *s = bounds.store(unlift_even(*s, o, k), b);
        }
    }
}

/// Pair `l`'s output (rows `s`, `o`, stored as `bounds` says) and pair `l + 1`'s odd sample
/// (row `o_next`), where pair `l + 1`'s `s¹` (row `s_next`) was made early.
#[inline(always)]
fn finish_pair_before_early<T: Lift, S: StoreRule>(
    s: &mut [T],
    o: &mut [T],
    s_next: &mut [T],
    o_next: &mut [T],
    bounds: ColumnBounds<S>,
    k: T::Constants,
) {
    for (cols, b) in bounds.segments() {
        let lanes = segment(s, &cols)
            .iter_mut()
            .zip(segment(o, &cols).iter_mut());
        let next = segment(s_next, &cols)
            .iter()
            .zip(segment(o_next, &cols).iter_mut());
        for ((s, o), (&s_next, o_next)) in lanes.zip(next) {
            *o_next = unlift_odd(*o_next, s_next, *s, k);
            *s = bounds.store(unlift_even(*s, *o, k), b);
            *o = bounds.store(*o, b);
        }
    }
}

/// Pair `l`'s output (rows `s`, `o`, stored as `bounds` says) and pair `l + 1`'s `s¹` and odd
/// sample (rows `s_next`, `o_next`), `s¹` from `d¹[l + 2]` (row `d_after`).
#[inline(always)]
fn finish_pair<T: Lift, S: StoreRule>(
    s: &mut [T],
    o: &mut [T],
    s_next: &mut [T],
    o_next: &mut [T],
    d_after: &mut [T],
    bounds: ColumnBounds<S>,
    k: T::Constants,
) {
    for (cols, b) in bounds.segments() {
        let lanes = segment(s, &cols)
            .iter_mut()
            .zip(segment(o, &cols).iter_mut());
        let next = segment(s_next, &cols)
            .iter_mut()
            .zip(segment(o_next, &cols).iter_mut());
        let ahead = segment(d_after, &cols).iter();
        for (((s, o), (s_next, o_next)), &d_after) in lanes.zip(next).zip(ahead) {
            *s_next += d_after;
            *o_next = unlift_odd(*o_next, *s_next, *s, k);
            *s = bounds.store(unlift_even(*s, *o, k), b);
            *o = bounds.store(*o, b);
        }
    }
}

/// The last pair's output (rows `s`, `o`), stored as `bounds` says: its neighbours are all
/// done.
#[inline(always)]
fn finish_last_pair<T: Lift, S: StoreRule>(
    s: &mut [T],
    o: &mut [T],
    bounds: ColumnBounds<S>,
    k: T::Constants,
) {
    for (cols, b) in bounds.segments() {
        let lanes = segment(s, &cols)
            .iter_mut()
            .zip(segment(o, &cols).iter_mut());
        for (s, o) in lanes {
            *s = bounds.store(unlift_even(*s, *o, k), b);
            *o = bounds.store(*o, b);
        }
    }
}

/// `dst[i] += f(a[i], b[i])` (or `-=`) over equal-length runs: each step's rows as one
/// flat loop the compiler can vectorize.
#[inline(always)]
#[cfg(test)]
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
#[cfg(test)]
fn rows<T>(c: &[T], r0: usize, r1: usize, w: usize) -> &[T] {
    c.get(r0 * w..r1 * w).unwrap_or_default()
}

/// Rows `r0..r1`, mutable (empty past the channel's end, as [`rows`]).
#[inline(always)]
#[cfg(test)]
fn rows_mut<T>(c: &mut [T], r0: usize, r1: usize, w: usize) -> &mut [T] {
    c.get_mut(r0 * w..r1 * w).unwrap_or_default()
}

/// How many rows of `w` samples the split channels hold: `low` = `high` or `high + 1`.
#[derive(Debug, Clone, Copy)]
#[cfg(test)]
struct ChannelRows {
    /// Rows of the low channel (`nl`).
    low: usize,
    /// Rows of the high channel (`nh`).
    high: usize,
}

/// Step 1, `s¹[l] = e[l] ± R(√3·o[l])`: rows below `nh` read their own odd row, the last
/// even row of an odd length reads a mirrored one.
#[inline(always)]
#[cfg(test)]
fn update1<T: Lift>(low: &mut [T], high: &[T], w: usize, channels: ChannelRows, add: bool) {
    let (nl, nh) = (channels.low, channels.high);
    let o = rows(high, 0, nh, w);
    apply(rows_mut(low, 0, nh, w), o, o, add, |v, _| {
        v.sqrt3(T::constants())
    });
    for l in nh..nl {
        let m = odd_index(l, nh);
        let o = rows(high, m, m + 1, w);
        apply(rows_mut(low, l, l + 1, w), o, o, add, |v, _| {
            v.sqrt3(T::constants())
        });
    }
}

/// Step 2, `d¹[l] = o[l] ∓ R(√3/4·s¹[l] + (√3−2)/4·s¹[l−1])`: row 0 reads a mirrored
/// `s¹[−1]`.
#[inline(always)]
#[cfg(test)]
fn predict<T: Lift>(high: &mut [T], low: &[T], w: usize, channels: ChannelRows, add: bool) {
    let (nl, nh) = (channels.low, channels.high);
    let p = prev_index(0, nl);
    apply(
        rows_mut(high, 0, 1, w),
        rows(low, 0, 1, w),
        rows(low, p, p + 1, w),
        add,
        |s, sp| T::predict(s, sp, T::constants()),
    );
    if nh > 1 {
        apply(
            rows_mut(high, 1, nh, w),
            rows(low, 1, nh, w),
            rows(low, 0, nh - 1, w),
            add,
            |s, sp| T::predict(s, sp, T::constants()),
        );
    }
}

/// Step 3, `s²[l] = s¹[l] ∓ d¹[l + 1]`: the last rows read mirrored `d¹` rows.
#[inline(always)]
#[cfg(test)]
fn update2<T: Lift>(low: &mut [T], high: &[T], w: usize, channels: ChannelRows, add: bool) {
    let (nl, nh) = (channels.low, channels.high);
    let inner = nh - 1;
    let d = rows(high, 1, nh, w);
    apply(rows_mut(low, 0, inner, w), d, d, add, |v, _| v);
    for l in inner..nl {
        let n = next_index(l, nh);
        let d = rows(high, n, n + 1, w);
        apply(rows_mut(low, l, l + 1, w), d, d, add, |v, _| v);
    }
}

/// Step-by-step forward lifting of the split channels, in place (the reference the
/// one-sweep and two-pass forms are tested against), on rows of `width` samples lifted
/// side by side (`width` 1 for a line, a block's width on the column pass). `low` has `nl`
/// rows, `high` `nh` rows, `nl` = `nh` or `nh + 1`; a length-1 signal is left as it is.
#[inline(always)]
#[cfg(test)]
pub(crate) fn forward<T: Lift>(low: &mut [T], high: &mut [T], width: usize) {
    let w = width.max(1);
    let n = ChannelRows {
        low: low.len() / w,
        high: high.len() / w,
    };
    if n.high == 0 {
        return;
    }
    update1(low, high, w, n, true);
    predict(high, low, w, n, false);
    update2(low, high, w, n, false);
}

/// Inverse lifting, exactly undoing [`forward`].
#[inline(always)]
#[cfg(test)]
pub(crate) fn inverse<T: Lift>(low: &mut [T], high: &mut [T], width: usize) {
    let w = width.max(1);
    let n = ChannelRows {
        low: low.len() / w,
        high: high.len() / w,
    };
    if n.high == 0 {
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
    fn constant_signal_has_zero_high_band_and_dc_gain_one_plus_sqrt3() {
        let mut low = [100i32; 5];
        let mut high = [100i32; 5];
        forward(&mut low, &mut high, 1);
        assert_eq!(high, [0; 5]);
        // 100 · (1 + √3) = 273.2
        assert!(low.iter().all(|&s| s == 273), "{low:?}");
    }
}
