//! Haar as the S-transform: `d = o − e`, `s = e + ⌊d/2⌋ = ⌊(e + o)/2⌋` (in `f32`, without
//! the floor: `s = (e + o)/2`).
//!
//! `low` holds the even samples and `high` the odd ones on entry to the forward step (and
//! the low and high bands on exit). For an odd length, `low` has one more element than
//! `high`; the unpaired last sample passes to the low band unchanged.

use super::{Lift, block_row};

/// Forward S-transform of one line: `src` holds the samples, `dst` (as long) gets the low
/// band then the high band.
pub(crate) fn forward_line<T: Lift>(src: &[T], dst: &mut [T]) {
    let Some(dst) = dst.get_mut(..src.len()) else {
        return;
    };
    let (low, high) = dst.split_at_mut(src.len().div_ceil(2));
    let (pairs, odd_end) = src.as_chunks::<2>();
    for ((&[e, o], s), d) in pairs.iter().zip(low.iter_mut()).zip(high.iter_mut()) {
        let diff = o - e;
        *d = diff;
        *s = e + diff.half();
    }
    if let ([last], Some(s)) = (odd_end, low.last_mut()) {
        *s = *last;
    }
}

/// Inverse of [`forward_line`]: `src` holds the low then the high band, `dst` (as long)
/// gets the samples, each saturated to `±out_bound`.
pub(crate) fn inverse_line<T: Lift>(src: &[T], dst: &mut [T], out_bound: i32) {
    let Some(dst) = dst.get_mut(..src.len()) else {
        return;
    };
    let (low, high) = src.split_at(src.len().div_ceil(2));
    let (pairs, odd_end) = dst.as_chunks_mut::<2>();
    for ([e, o], (&s, &d)) in pairs.iter_mut().zip(low.iter().zip(high)) {
        let even = s - d.half();
        *e = even.saturate(out_bound);
        *o = (d + even).saturate(out_bound);
    }
    if let ([last], Some(&s)) = (odd_end, low.last()) {
        *last = s.saturate(out_bound);
    }
}

/// Forward S-transform of a block of `w` columns, `n` rows long: row `k` of the input starts
/// at `k·stride` in `src`; `dst` gets `n` contiguous rows of `w`, the low band's first.
pub(crate) fn forward_block<T: Lift>(src: &[T], stride: usize, w: usize, n: usize, dst: &mut [T]) {
    let Some(dst) = dst.get_mut(..n * w) else {
        return;
    };
    let (low, high) = dst.split_at_mut(n.div_ceil(2) * w);
    for (l, (s_row, d_row)) in low
        .chunks_exact_mut(w)
        .zip(high.chunks_exact_mut(w))
        .enumerate()
    {
        let (e_row, o_row) = (
            block_row(src, 2 * l, stride, w),
            block_row(src, 2 * l + 1, stride, w),
        );
        for ((s, d), (&e, &o)) in s_row
            .iter_mut()
            .zip(d_row.iter_mut())
            .zip(e_row.iter().zip(o_row))
        {
            let diff = o - e;
            *d = diff;
            *s = e + diff.half();
        }
    }
    if n % 2 == 1 {
        let last = block_row(src, n - 1, stride, w);
        if let Some(s_row) = low.get_mut((n / 2) * w..) {
            for (s, &v) in s_row.iter_mut().zip(last) {
                *s = v;
            }
        }
    }
}

/// Inverse of [`forward_block`]: `src` holds `n` contiguous rows of `w` (low band first);
/// the samples go to rows `stride` apart in `dst`, column `j` saturated to `±out_bounds[j]`.
pub(crate) fn inverse_block<T: Lift>(
    src: &[T],
    w: usize,
    n: usize,
    dst: &mut [T],
    stride: usize,
    out_bounds: &[i32],
) {
    let nl = n.div_ceil(2);
    let (low, high) = src.split_at(nl * w);
    let mut rows = dst
        .chunks_mut(stride)
        .map(|r| r.get_mut(..w).unwrap_or_default());
    for (s_row, d_row) in low.chunks_exact(w).zip(high.chunks_exact(w)) {
        let (Some(e_row), Some(o_row)) = (rows.next(), rows.next()) else {
            return;
        };
        let lanes = e_row.iter_mut().zip(o_row.iter_mut()).zip(out_bounds);
        for (((e, o), &b), (&s, &d)) in lanes.zip(s_row.iter().zip(d_row)) {
            let even = s - d.half();
            *e = even.saturate(b);
            *o = (d + even).saturate(b);
        }
    }
    if n % 2 == 1 {
        let last = block_row(low, nl - 1, w, w);
        if let Some(e_row) = rows.next() {
            for ((e, &s), &b) in e_row.iter_mut().zip(last).zip(out_bounds) {
                *e = s.saturate(b);
            }
        }
    }
}

/// Forward S-transform of the split channels, in place (the float path; the reference the
/// line and block forms are tested against). Rows of any width lifted side by
/// side pair up element by element, so the flattened channels are all it needs.
pub(crate) fn forward<T: Lift>(low: &mut [T], high: &mut [T]) {
    for (s, d) in low.iter_mut().zip(high.iter_mut()) {
        *d -= *s;
        *s += d.half();
    }
}

/// Inverse S-transform, exactly undoing [`forward`].
pub(crate) fn inverse<T: Lift>(low: &mut [T], high: &mut [T]) {
    for (s, d) in low.iter_mut().zip(high.iter_mut()) {
        *s -= d.half();
        *d += *s;
    }
}
