//! What the lifting kernels share: rows of a region borrowed together, the bounds an
//! inverse column pass stores to, and the row passes run as a column sweep reaches them.

use super::lift::Lift;
use crate::Dims;

/// Rows `at` (increasing) of `region`, from the start of `buf`, all mutable at once; `None`
/// if they are not increasing or `buf` ends first (callers stay inside).
#[inline(always)]
pub(super) fn rows_at<T, const N: usize>(
    buf: &mut [T],
    region: Dims,
    at: [usize; N],
) -> Option<[&mut [T]; N]> {
    let (stride, w) = (region.stride(), region.width());
    let mut rows: [Option<&mut [T]>; N] = [const { None }; N];
    let mut rest = buf;
    let mut consumed = 0;
    for (slot, &k) in rows.iter_mut().zip(&at) {
        let start = (k * stride).checked_sub(consumed)?;
        let (row, after) = core::mem::take(&mut rest)
            .get_mut(start..)?
            .split_at_mut_checked(w)?;
        *slot = Some(row);
        rest = after;
        consumed = k * stride + w;
    }
    if rows.iter().any(Option::is_none) {
        return None;
    }
    Some(rows.map(Option::unwrap_or_default))
}

/// Rows `a` and `b` (different, in either order) of a region, as [`rows_at`], returned in
/// the order asked for.
#[inline(always)]
pub(super) fn row_pair<T>(
    buf: &mut [T],
    region: Dims,
    a: usize,
    b: usize,
) -> Option<[&mut [T]; 2]> {
    if a < b {
        rows_at(buf, region, [a, b])
    } else {
        rows_at(buf, region, [b, a]).map(|[x, y]| [y, x])
    }
}

/// Columns `cols` of a row (empty past its end: callers stay inside).
#[inline(always)]
pub(super) fn segment<'r, T>(row: &'r mut [T], cols: &core::ops::Range<usize>) -> &'r mut [T] {
    row.get_mut(cols.clone()).unwrap_or_default()
}

/// The saturation bounds of an inverse column pass's output: columns left of `split`
/// came from the row pass's low band, the rest from its high band. `rule` says whether
/// stores saturate to them ([`StoreRule`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct ColumnBounds<S = Saturate> {
    /// The first column of the right part.
    pub(super) split: usize,
    /// The row's length.
    pub(super) width: usize,
    /// The bound of the left part.
    pub(super) left: i32,
    /// The bound of the right part.
    pub(super) right: i32,
    /// What a store does with the bound.
    pub(super) rule: S,
}

impl<S> ColumnBounds<S> {
    /// `width` columns bounded by `left` up to `⌈width/2⌉` and by `right` after.
    pub(super) fn split_at_half(width: usize, [left, right]: [i32; 2], rule: S) -> Self {
        Self {
            split: width.div_ceil(2),
            width,
            left,
            right,
            rule,
        }
    }
}

impl<S: StoreRule> ColumnBounds<S> {
    /// The two parts of a row, each with its bound.
    #[inline(always)]
    pub(super) fn segments(self) -> [(core::ops::Range<usize>, i32); 2] {
        let split = self.split.min(self.width);
        [(0..split, self.left), (split..self.width, self.right)]
    }

    /// `v` as a store to a column bounded by `bound` leaves it.
    #[inline(always)]
    pub(super) fn store<T: Lift>(self, v: T, bound: i32) -> T {
        self.rule.store(v, bound)
    }

    /// Stores a row in place, as the rule says.
    #[inline(always)]
    pub(super) fn store_row<T: Lift>(self, row: &mut [T]) {
        for (cols, b) in self.segments() {
            for v in segment(row, &cols) {
                *v = self.store(*v, b);
            }
        }
    }
}

/// What an inverse column pass does with its output bounds, chosen at compile time so
/// the hot loops carry no test for it.
pub(crate) trait StoreRule: Copy {
    /// `v` as stored to a value bounded by `bound`.
    fn store<T: Lift>(self, v: T, bound: i32) -> T;
}

/// Every stored value is saturated to its bound: what keeps any coefficients from
/// overflowing the passes after.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Saturate;

impl StoreRule for Saturate {
    #[inline(always)]
    fn store<T: Lift>(self, v: T, bound: i32) -> T {
        v.saturate(bound)
    }
}

/// Stores as they are: for a level-1 inverse to bytes of 8-bit samples' coefficients,
/// whose whole inverse is proven far inside `i32` without saturating (test
/// `level_one_to_bytes_needs_no_column_saturation`) and whose bytes are clamped anyway.
/// Fused coefficients can take a column output past the saturation bound (of samples up
/// to `MAX_SAMPLE`) only on tiny images of 0/255 noise; there the value as lifted is the
/// linear inverse's, where the saturated one was an arbitrary cap
/// (docs/hard-cases.md, "Bounds stated").
#[derive(Debug, Clone, Copy)]
pub(crate) struct Unsaturated;

impl StoreRule for Unsaturated {
    #[inline(always)]
    fn store<T: Lift>(self, v: T, _bound: i32) -> T {
        v
    }
}

/// `dst.copy_from_slice(src)` over their common length, for the row copies of the
/// transforms. On the Cortex-M7 `copy_from_slice` calls the compiler's `memcpy`, which
/// costs more per word than this loop, unrolled by the compiler, and a fixed price per call
/// besides (`bash tests/mcu-bench/run.sh`). Elsewhere `memcpy` is the fast one.
#[inline(always)]
pub(crate) fn copy_row<T: Copy>(dst: &mut [T], src: &[T]) {
    let n = dst.len().min(src.len());
    let (Some(dst), Some(src)) = (dst.get_mut(..n), src.get(..n)) else {
        return;
    };
    if cfg!(target_arch = "arm") {
        // Eight words a step, taken apart and put together: a plain element loop is
        // turned back into a `memcpy` call.
        let (dst8, dst_rest) = dst.as_chunks_mut::<8>();
        let (src8, src_rest) = src.as_chunks::<8>();
        for (d, s) in dst8.iter_mut().zip(src8) {
            let [a, b, c, e, f, g, h, i] = *s;
            *d = [a, b, c, e, f, g, h, i];
        }
        for (d, &s) in dst_rest.iter_mut().zip(src_rest) {
            *d = s;
        }
    } else {
        dst.copy_from_slice(src);
    }
}

/// Runs a row pass once on every row of a region, each before the forward column sweep
/// first reads it: in order, but for the rows an odd length's mirrored boundary reads
/// first ([`Self::early`]).
pub(crate) struct RowsReady<'f, F> {
    row_pass: &'f mut F,
    /// Rows below this one are done.
    next: usize,
    /// Rows at or past `next` done early.
    early: [Option<usize>; 2],
}

impl<'f, F> RowsReady<'f, F> {
    /// Nothing done yet.
    pub fn new(row_pass: &'f mut F) -> Self {
        Self {
            row_pass,
            next: 0,
            early: [None; 2],
        }
    }

    /// Runs the pass on every row of `region` (from the start of `buf`) up to `last` not
    /// done yet.
    #[inline(always)]
    pub fn through<T>(&mut self, buf: &mut [T], region: Dims, last: usize)
    where
        F: FnMut(usize, &mut [T]),
    {
        while self.next <= last {
            let k = self.next;
            self.next += 1;
            if !self.early.contains(&Some(k))
                && let Some([row]) = rows_at(buf, region, [k])
            {
                (self.row_pass)(k, row);
            }
        }
    }

    /// Runs the pass on row `k` now, out of order, unless it is done. A sweep has at most
    /// two such rows (an odd length's last row and its mirrored odd partner).
    pub fn early<T>(&mut self, buf: &mut [T], region: Dims, k: usize)
    where
        F: FnMut(usize, &mut [T]),
    {
        if k < self.next || self.early.contains(&Some(k)) {
            return;
        }
        let free = self.early.iter_mut().find(|slot| slot.is_none());
        if let (Some(slot), Some([row])) = (free, rows_at(buf, region, [k])) {
            *slot = Some(k);
            (self.row_pass)(k, row);
        }
    }
}

/// Runs a preparation once on every row of a region before the inverse column sweep
/// first reads or writes it (fusion blends each row of the bands there, while the sweep
/// brings it into cache): the last [`Self::TAIL`] rows, which the sweep's mirrored
/// boundary reaches early, at once; the others in order as the sweep asks for them.
pub(crate) struct RowsPrepared<'f, F> {
    prepare: &'f mut F,
    /// Rows below this one are prepared.
    next: usize,
    /// Rows from this one on are prepared.
    tail: usize,
}

impl<'f, F> RowsPrepared<'f, F> {
    /// Rows at the end that a sweep may read before it reaches them in order (db2's
    /// mirrored last pairs reach back at most four rows).
    const TAIL: usize = 6;

    /// Prepares the tail of `region`, from the start of `buf`.
    pub fn new<T>(prepare: &'f mut F, buf: &mut [T], region: Dims) -> Self
    where
        F: FnMut(usize, &mut [T]),
    {
        let n = region.height();
        let tail = n.saturating_sub(Self::TAIL);
        for k in tail..n {
            if let Some([row]) = rows_at(buf, region, [k]) {
                prepare(k, row);
            }
        }
        Self {
            prepare,
            next: 0,
            tail,
        }
    }

    /// Prepares every row up to `last` not prepared yet.
    #[inline(always)]
    pub fn through<T>(&mut self, buf: &mut [T], region: Dims, last: usize)
    where
        F: FnMut(usize, &mut [T]),
    {
        let end = last.saturating_add(1).min(self.tail);
        while self.next < end {
            let k = self.next;
            self.next += 1;
            if let Some([row]) = rows_at(buf, region, [k]) {
                (self.prepare)(k, row);
            }
        }
    }
}
