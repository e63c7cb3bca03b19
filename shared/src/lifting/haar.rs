//! Haar as the S-transform: `d = o − e`, `s = e + ⌊d/2⌋ = ⌊(e + o)/2⌋` (in `f32`, without
//! the floor: `s = (e + o)/2`).
//!
//! `low` holds the even samples and `high` the odd ones on entry to the forward step (and
//! the low and high bands on exit). For an odd length, `low` has one more element than
//! `high`; the unpaired last sample passes to the low band unchanged.

use super::lift::Lift;
use super::rows::{ColumnBounds, RowsPrepared, RowsReady, StoreRule, rows_at, segment};
use crate::{Dims, simd};

/// Forward S-transform of one line: `src` holds the samples, `dst` (as long) gets the low
/// band then the high band.
#[inline(always)]
pub(crate) fn forward_line<T: Lift>(src: &[T], dst: &mut [T]) {
    forward_line_from(src, dst, |v| v);
}

/// [`forward_line`] of the samples `sample(src[i])` (`src` may hold 8-bit values, say).
#[inline(always)]
pub(crate) fn forward_line_from<S: Copy, T: Lift>(
    src: &[S],
    dst: &mut [T],
    sample: impl Fn(S) -> T,
) {
    let Some(dst) = dst.get_mut(..src.len()) else {
        return;
    };
    let (low, high) = dst.split_at_mut(src.len().div_ceil(2));
    let (pairs, odd_end) = src.as_chunks::<2>();
    for ((&[e, o], s), d) in pairs.iter().zip(low.iter_mut()).zip(high.iter_mut()) {
        let (e, o) = (sample(e), sample(o));
        let diff = o - e;
        *d = diff;
        *s = e + diff.half();
    }
    if let ([last], Some(s)) = (odd_end, low.last_mut()) {
        *s = sample(*last);
    }
}

/// Inverse of [`forward_line`]: `src` holds the low then the high band, `dst` (as long)
/// gets the samples, each saturated to `±out_bound`.
#[inline(always)]
pub(crate) fn inverse_line<T: Lift>(src: &[T], dst: &mut [T], out_bound: i32) {
    inverse_line_into(src, dst, |v: T| v.saturate(out_bound));
}

/// Inverse of [`forward_line`] with each sample `v` stored as `put(v)`.
#[inline(always)]
pub(crate) fn inverse_line_into<T: Lift, O>(src: &[T], dst: &mut [O], put: impl Fn(T) -> O) {
    let Some(dst) = dst.get_mut(..src.len()) else {
        return;
    };
    let (low, high) = src.split_at(src.len().div_ceil(2));
    let (pairs, odd_end) = dst.as_chunks_mut::<2>();
    for ([e, o], (&s, &d)) in pairs.iter_mut().zip(low.iter().zip(high)) {
        let even = s - d.half();
        *e = put(even);
        *o = put(d + even);
    }
    if let ([last], Some(&s)) = (odd_end, low.last()) {
        *last = put(s);
    }
}

/// Forward S-transform of the columns of `region` (from the start of `buf`), in place: row
/// pair `(2l, 2l + 1)` becomes low-band row `l` and
/// high-band row `l` in its place (an odd length's last row is low already).
/// `ready` runs the row pass on each row before it is read.
pub(crate) fn forward_columns<T: Lift, F: FnMut(usize, &mut [T])>(
    buf: &mut [T],
    region: Dims,
    ready: &mut RowsReady<'_, F>,
) {
    let n = region.height();
    for l in 0..n / 2 {
        ready.through(buf, region, 2 * l + 1);
        if let Some([e_row, o_row]) = rows_at(buf, region, [2 * l, 2 * l + 1]) {
            forward_rows(e_row, o_row);
        }
    }
    // An odd length's last row.
    ready.through(buf, region, n.saturating_sub(1));
}

simd::kernel! {
    /// Inverse of [`forward_columns`], in place, each output sample stored as `bounds` says
    /// (saturated to its column's bound, or not); `done(y, row y)` runs on each row once
    /// it is final.
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
        let n = region.height();
        for l in 0..n / 2 {
            prepared.through(buf, region, 2 * l + 1);
            let Some([s_row, d_row]) = rows_at(buf, region, [2 * l, 2 * l + 1]) else {
                return;
            };
            for (cols, b) in bounds.segments() {
                inverse_rows(segment(s_row, &cols), segment(d_row, &cols), b, bounds);
            }
            done(2 * l, s_row);
            done(2 * l + 1, d_row);
        }
        prepared.through(buf, region, n.saturating_sub(1));
        if n % 2 == 1
            && let Some([last]) = rows_at(buf, region, [n - 1])
        {
            bounds.store_row(last);
            done(n - 1, last);
        }
    }
}

simd::kernel! {
    /// One row pair of the forward column pass: the even row becomes the low band, the odd
    /// row the high band. Not inlined where there are vector units, for the reason given at
    /// `db2::forward_rows`: distinct `&mut` arguments let the loop vectorize.
    #[cfg_attr(target_arch = "arm", inline(always))]
    #[cfg_attr(not(target_arch = "arm"), inline(never))]
    fn forward_rows<T: Lift>(e_row: &mut [T], o_row: &mut [T]) {
        for (e, o) in e_row.iter_mut().zip(o_row.iter_mut()) {
            let diff = *o - *e;
            *o = diff;
            *e += diff.half();
        }
    }
}

simd::kernel! {
    /// One row pair of the inverse column pass, each output stored to `±bound` as `rule` says (not
    /// inlined where there are vector units, as [`forward_rows`]).
    #[cfg_attr(target_arch = "arm", inline(always))]
    #[cfg_attr(not(target_arch = "arm"), inline(never))]
    fn inverse_rows<T: Lift, S: StoreRule>(
        s_row: &mut [T],
        d_row: &mut [T],
        bound: i32,
        rule: ColumnBounds<S>,
    ) {
        for (s, d) in s_row.iter_mut().zip(d_row.iter_mut()) {
            let even = *s - d.half();
            *s = rule.store(even, bound);
            *d = rule.store(*d + even, bound);
        }
    }
}

/// Forward S-transform of the split channels, in place (the reference the line and
/// column forms are tested against). Rows of any width lifted side by
/// side pair up element by element, so the flattened channels are all it needs.
#[inline(always)]
#[cfg(test)]
pub(crate) fn forward<T: Lift>(low: &mut [T], high: &mut [T]) {
    for (s, d) in low.iter_mut().zip(high.iter_mut()) {
        *d -= *s;
        *s += d.half();
    }
}

/// Inverse S-transform, exactly undoing [`forward`].
#[inline(always)]
#[cfg(test)]
pub(crate) fn inverse<T: Lift>(low: &mut [T], high: &mut [T]) {
    for (s, d) in low.iter_mut().zip(high.iter_mut()) {
        *s -= d.half();
        *d += *s;
    }
}
