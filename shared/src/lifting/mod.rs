//! Reversible integer wavelet lifting, 1-D and separable 2-D, 1 to 4 levels.
//!
//! Every size from 1 to [`crate::MAX_DIMENSION`] works, odd sizes included; forward then inverse is bit-exact for every
//! input in range. A row is lifted with one caller-provided scratch row, low band first:
//! integers in one sweep over sample pairs into the scratch and copied back, floats' db2
//! in two passes, into the scratch and back (`Lift::ROW_PASSES` says why). Columns are
//! lifted in place, whole rows at a time, in one sweep down the region: row pair
//! `(2l, 2l + 1)` becomes low-band row `l` and high-band row `l` where it stands, so the
//! column pass reads and writes the region once, front to back, with no copy. The 2-D
//! layout is described in [`crate::geometry`].
//!
//! Overflow is ruled out by construction, not hoped against: the forward transform accepts
//! samples with `|x| ≤` [`MAX_SAMPLE`], and [`bounds`] proves how far every band can grow
//! from there. The inverse saturates to those same bounds every value it stores and every
//! coefficient it loads (fused ones, convex combinations of in-bound ones, skip that:
//! `Coefficients`). Forward-transform output is always inside them, so reconstruction
//! stays exact; edited coefficients can never push a value past them. The one exception
//! is the fusion's level-1 inverse to bytes, whose inputs come from 8-bit samples: its
//! column pass stores unsaturated (`Unsaturated`), proven far inside `i32`, and its
//! bytes are clamped.

pub mod bounds;
mod db2;
#[cfg(any(test, feature = "pywt"))]
pub mod filter_bank;
mod haar;
pub(crate) mod lanes;
pub(crate) mod lift;
pub(crate) mod q16;
mod q32;
pub(crate) mod rows;
mod wavelet;

use core::ops::RangeInclusive;

#[cfg(test)]
use crate::geometry::Line;
use crate::{Dims, Error, MAX_LEVELS, simd};
pub use bounds::{LevelBounds, MAX_SAMPLE, level_bounds};
pub use lift::GUARD_BITS;
pub(crate) use lift::Lift;
pub(crate) use rows::{
    ColumnBounds, RowsPrepared, RowsReady, Saturate, StoreRule, Unsaturated, copy_row,
};
pub use wavelet::Wavelet;

impl Wavelet {
    /// Forward lifting of one line: `src` holds the samples, `dst` (as long) gets the low
    /// band then the high band.
    fn forward_line<T: Lift>(self, src: &[T], dst: &mut [T]) {
        match self {
            Wavelet::Haar => haar::forward_line(src, dst),
            Wavelet::Db2 => db2::forward_line(src, dst),
        }
    }

    /// Inverse of [`Self::forward_line`], each output sample saturated to `±out_bound`.
    fn inverse_line<T: Lift>(self, src: &[T], dst: &mut [T], out_bound: i32) {
        match self {
            Wavelet::Haar => haar::inverse_line(src, dst, out_bound),
            Wavelet::Db2 => db2::inverse_line(src, dst, out_bound),
        }
    }

    /// Forward lifting of the columns of `region` in place, from the start of `buf` (layout
    /// in [`crate::geometry`]). `ready` runs the row pass on each row before the sweep first
    /// reads it.
    fn forward_columns<T: Lift, F: FnMut(usize, &mut [T])>(
        self,
        buf: &mut [T],
        region: Dims,
        ready: &mut RowsReady<'_, F>,
    ) {
        match self {
            Wavelet::Haar => haar::forward_columns(buf, region, ready),
            Wavelet::Db2 => db2::forward_columns(buf, region, ready),
        }
    }

    /// Inverse of [`Self::forward_columns`], each output sample stored as `bounds` says;
    /// `prepared` runs its preparation on each row before the sweep first reads
    /// it, `done` runs on each row as soon as it is final.
    fn inverse_columns<T: Lift, S: StoreRule, P: FnMut(usize, &mut [T])>(
        self,
        buf: &mut [T],
        region: Dims,
        bounds: ColumnBounds<S>,
        prepared: &mut RowsPrepared<'_, P>,
        done: &mut impl FnMut(usize, &mut [T]),
    ) {
        match self {
            Wavelet::Haar => haar::inverse_columns(buf, region, bounds, prepared, done),
            Wavelet::Db2 => db2::inverse_columns(buf, region, bounds, prepared, done),
        }
    }

    /// Forward lifting of split channels made of rows of `width` samples side by side,
    /// step by step (the reference the one-sweep and two-pass forms are tested against).
    #[cfg(test)]
    #[inline(always)]
    fn forward_split<T: Lift>(self, low: &mut [T], high: &mut [T], width: usize) {
        match self {
            Wavelet::Haar => haar::forward(low, high),
            Wavelet::Db2 => db2::forward(low, high, width),
        }
    }

    /// Inverse of [`Self::forward_split`].
    #[cfg(test)]
    #[inline(always)]
    fn inverse_split<T: Lift>(self, low: &mut [T], high: &mut [T], width: usize) {
        match self {
            Wavelet::Haar => haar::inverse(low, high),
            Wavelet::Db2 => db2::inverse(low, high, width),
        }
    }
}

/// Scratch length the 2-D transforms need for `dims`: one row.
pub fn scratch_len(dims: Dims) -> usize {
    scratch_words(dims.width(), dims.height())
}

/// [`scratch_len`] for a `width × height` image, usable in constants: `width` (the column
/// pass works in place).
pub const fn scratch_words(width: usize, _height: usize) -> usize {
    width
}

simd::kernel! {
    /// One forward 1-D pass over a row, low band first, with `scratch` as work space (one
    /// sweep into it and a copy back, or two passes: [`Lift::ROW_PASSES`]). A `scratch` shorter than the row leaves it as it is (the public entry points
    /// check its length first).
    fn forward_row<T: Lift>(wavelet: Wavelet, row: &mut [T], scratch: &mut [T]) {
        let n = row.len();
        let Some(work) = scratch.get_mut(..n) else {
            return;
        };
        match wavelet {
            Wavelet::Db2 if T::ROW_PASSES => db2::forward_row_two_pass(row, work),
            _ => {
                wavelet.forward_line(row, work);
                copy_row(row, work);
            }
        }
    }
}

/// One forward 1-D pass over a strided `line`, element by element: the reference the row
/// and column passes are tested against. The result goes back low band first, or with
/// `interleave` (as the column pass lays it out) low and high samples alternating.
#[cfg(test)]
fn forward_line_reference<T: Lift>(
    wavelet: Wavelet,
    buf: &mut [T],
    line: Line,
    scratch: &mut [T],
    interleave: bool,
) {
    let nl = line.len.div_ceil(2);
    let work = &mut scratch[..line.len];
    for (k, p) in line.positions().enumerate() {
        let slot = if k % 2 == 0 { k / 2 } else { nl + k / 2 };
        work[slot] = buf[p];
    }
    let (low, high) = work.split_at_mut(nl);
    wavelet.forward_split(low, high, 1);
    for (k, p) in line.positions().enumerate() {
        let slot = if !interleave {
            k
        } else if k % 2 == 0 {
            k / 2
        } else {
            nl + k / 2
        };
        buf[p] = work[slot];
    }
}

simd::kernel! {
    /// One inverse 1-D pass over a row: copies low and high bands to `scratch` (saturated to
    /// `load_bounds` when given) and lifts them back into the row, saturated to `out_bound`
    /// (for floats' db2, two passes through `scratch`: [`Lift::ROW_PASSES`]).
    fn inverse_row<T: Lift>(
        wavelet: Wavelet,
        row: &mut [T],
        scratch: &mut [T],
        load_bounds: Option<(i32, i32)>,
        out_bound: i32,
    ) {
        let n = row.len();
        let nl = n.div_ceil(2);
        let Some(work) = scratch.get_mut(..n) else {
            return;
        };
        match (wavelet, load_bounds) {
            (Wavelet::Db2, None) if T::ROW_PASSES => {
                db2::inverse_row_two_pass(row, work, out_bound);
                return;
            }
            (_, Some((low_bound, high_bound))) => {
                let (low, high) = work.split_at_mut(nl);
                let (row_low, row_high) = row.split_at(nl);
                for (d, &v) in low.iter_mut().zip(row_low) {
                    *d = v.saturate(low_bound);
                }
                for (d, &v) in high.iter_mut().zip(row_high) {
                    *d = v.saturate(high_bound);
                }
            }
            (_, None) => copy_row(work, row),
        }
        wavelet.inverse_line(work, row, out_bound);
    }
}

/// Checks that every sample of the region is within `±MAX_SAMPLE` (and that `buf` holds
/// the region).
pub(crate) fn check_samples(buf: &[i32], dims: Dims) -> Result<(), Error> {
    dims.check_buffer("image", buf.len())?;
    for row in dims.rows(buf) {
        if row.iter().any(|v| v.unsigned_abs() > MAX_SAMPLE) {
            return Err(Error::SampleOutOfRange);
        }
    }
    Ok(())
}

/// Checks buffer lengths, and `levels` where given (a 1-D line of length 1 is a valid,
/// identity transform; a 2-D level needs two samples along some side).
fn check_args(buf: &[i32], dims: Dims, levels: Option<u8>, scratch: &[i32]) -> Result<(), Error> {
    dims.check_buffer("image", buf.len())?;
    if let Some(levels) = levels {
        dims.check_levels(levels)?;
    }
    let needed = scratch_len(dims);
    if scratch.len() < needed {
        return Err(Error::BufferTooSmall {
            which: "scratch",
            needed,
            got: scratch.len(),
        });
    }
    Ok(())
}

/// One forward 2-D level on the `dims` region (rows, then columns), in place. Rows and
/// column blocks that `buf` or `scratch` cannot hold are skipped: the public entry points
/// check both lengths first.
pub(crate) fn forward_level<T: Lift>(
    wavelet: Wavelet,
    buf: &mut [T],
    dims: Dims,
    scratch: &mut [T],
) {
    let w = dims.width();
    sweep_level(wavelet, buf, dims, |_, row| {
        if w > 1 {
            forward_row(wavelet, row, scratch);
        }
    });
}

/// [`forward_level`] of an image of 8-bit samples with the fusion's guard bits: the row
/// pass that fills row `k` of the `dims` region of `buf` reads row `k` of the `src_dims`
/// region of `src` as `v·2^GUARD_BITS` ([`Lift::from_guarded_byte`]). Rows are lifted
/// straight from the bytes, with no copy of the row in between (but floats' db2 rows,
/// lifted in two passes: widened into `buf` first). Either way the values are those of [`forward_level`] on the
/// widened image.
pub(crate) fn forward_level_from_bytes<T: Lift>(
    wavelet: Wavelet,
    buf: &mut [T],
    dims: Dims,
    scratch: &mut [T],
    (src, src_dims): (&[u8], Dims),
) {
    sweep_level(wavelet, buf, dims, |k, row| {
        if let Some(bytes) = src_dims.row(src, k) {
            forward_row_from_bytes(wavelet, bytes, row, scratch);
        }
    });
}

/// The row pass of [`forward_level_from_bytes`] on one row. A function of its own: inlined
/// into the sweep, the lifting loop spilled more registers on the Cortex-M7
/// (`tests/mcu-bench`).
#[inline(never)]
fn forward_row_from_bytes<T: Lift>(
    wavelet: Wavelet,
    bytes: &[u8],
    row: &mut [T],
    scratch: &mut [T],
) {
    match wavelet {
        Wavelet::Haar => haar::forward_line_from(bytes, row, T::from_guarded_byte),
        Wavelet::Db2 if !T::ROW_PASSES => db2::forward_line_bytes(bytes, row),
        Wavelet::Db2 => {
            for (d, &v) in row.iter_mut().zip(bytes) {
                *d = T::from_guarded_byte(v);
            }
            if row.len() > 1 {
                forward_row(wavelet, row, scratch);
            }
        }
    }
}

/// [`forward_level`] that first shows each row of the region to `observe`:
/// `observe(k, row k, scratch)` runs for `k = 0, 1, …` in order, each call before row `k`
/// is transformed, with the level's scratch line to use as it likes (the row pass needs
/// it only afterwards). Where the column sweep takes the rows in order (an even height)
/// each is observed as the sweep brings it into cache, so observer and transform read
/// the region once between them; otherwise every row is observed first.
pub(crate) fn forward_level_observed<T: Lift>(
    wavelet: Wavelet,
    buf: &mut [T],
    dims: Dims,
    scratch: &mut [T],
    mut observe: impl FnMut(usize, &[T], &mut [T]),
) {
    let (w, h) = (dims.width(), dims.height());
    if h.is_multiple_of(2) {
        sweep_level(wavelet, buf, dims, |k, row| {
            observe(k, row, scratch);
            if w > 1 {
                forward_row(wavelet, row, scratch);
            }
        });
    } else {
        // An odd height's sweep lifts its last rows early (`RowsReady::early`).
        for (k, row) in dims.rows(buf).enumerate() {
            observe(k, row, scratch);
        }
        forward_level(wavelet, buf, dims, scratch);
    }
}

/// One forward 2-D level with `row_pass(k, row k)` as its row transform: each row is
/// lifted just before the column sweep first reads it, while the sweep's rows are in
/// cache, so the level reads and writes the region once.
fn sweep_level<T: Lift>(
    wavelet: Wavelet,
    buf: &mut [T],
    dims: Dims,
    mut row_pass: impl FnMut(usize, &mut [T]),
) {
    if dims.height() > 1 {
        let mut ready = RowsReady::new(&mut row_pass);
        wavelet.forward_columns(buf, dims, &mut ready);
    } else if let Some(row) = dims.row_mut(buf, 0) {
        row_pass(0, row);
    }
}

/// What an inverse column pass saturates to, each in two parts of the row
/// ([`ColumnBounds`]): left of the row pass's split the columns hold its low band.
#[derive(Debug, Clone, Copy)]
struct ColumnPassBounds<S> {
    /// The coefficients of the even rows (the column-low band), as they are loaded.
    low: ColumnBounds,
    /// The coefficients of the odd rows (the column-high band), as they are loaded.
    high: ColumnBounds,
    /// The output (the row pass's bands), stored as its rule says.
    out: ColumnBounds<S>,
}

impl<S> ColumnPassBounds<S> {
    /// A `w`-column level's bounds, its stores following `rule`. Columns left of
    /// `⌈w/2⌉` came from the rows' low band, the rest from the high band; a one-column
    /// region had no row pass, so its columns are the level's input.
    fn of(bounds: &LevelBounds, w: usize, rule: S) -> Self {
        let left_out = if w == 1 { bounds.input } else { bounds.row_low };
        Self {
            low: ColumnBounds::split_at_half(w, [bounds.ll, bounds.hl], Saturate),
            high: ColumnBounds::split_at_half(w, [bounds.lh, bounds.hh], Saturate),
            out: ColumnBounds::split_at_half(w, [left_out, bounds.row_high], rule),
        }
    }
}

/// The inverse column pass: loads saturated to `bounds.low` and `bounds.high` (unless the
/// `coefficients` are [`Coefficients::InBounds`]) and the columns lifted back in place,
/// stored as `bounds.out` says; `prepare(y, row y)` runs on each row before anything else
/// reads it, `done` on each row as soon as it is final.
fn inverse_columns<T: Lift, S: StoreRule>(
    wavelet: Wavelet,
    buf: &mut [T],
    dims: Dims,
    bounds: ColumnPassBounds<S>,
    coefficients: Coefficients,
    prepare: &mut impl FnMut(usize, &mut [T]),
    done: &mut impl FnMut(usize, &mut [T]),
) {
    let h = dims.height();
    let mut prepared = RowsPrepared::new(prepare, buf, dims);
    if coefficients == Coefficients::Any {
        // The saturation reads every row first.
        prepared.through(buf, dims, h);
        // Even rows hold the low band, odd rows the high band.
        for y in 0..h {
            if let Some(row) = dims.row_mut(buf, y) {
                if y % 2 == 0 {
                    bounds.low.store_row(row);
                } else {
                    bounds.high.store_row(row);
                }
            }
        }
    }
    wavelet.inverse_columns(buf, dims, bounds.out, &mut prepared, done);
}

/// What an inverse transform may assume about the coefficients it is given.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Coefficients {
    /// Anything: every coefficient is saturated to its band's bound as it is loaded.
    Any,
    /// Each coefficient already lies within its band's bound: it came from the forward
    /// transform of samples within `±MAX_SAMPLE`, or is a convex combination of such
    /// coefficients of the same band (what fusion makes of them). Loads skip the
    /// saturation, except on levels one row high (their low band is the deeper level's
    /// output, not a coefficient); stores still saturate, since such coefficients need
    /// not be the transform of any image in range (but for the level-1 inverse to bytes:
    /// [`Unsaturated`]).
    InBounds,
}

/// How an inverse transform saturates: to the bounds the forward transform proves for each
/// band, loads included unless the coefficients are known to lie within them.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Saturation<B> {
    /// The bounds: one level's ([`LevelBounds`]), or each level's.
    pub bounds: B,
    /// What the inverse may assume about the coefficients it loads.
    pub coefficients: Coefficients,
}

/// 8-bit rows an inverse transform's output goes to instead of its buffer: the `Dims`
/// region of the bytes, as large as the transform's.
pub(crate) type ByteRows<'o> = (&'o mut [u8], Dims);

/// Row `row` of a level-1 inverse lifted back into `out`, each sample as
/// [`Lift::to_byte`] makes it; `load_bounds` and `out_bound` as for [`inverse_row`].
/// Rows whose loads need no saturation (but floats' db2, lifted in two passes) are lifted
/// straight from `row` into `out` without the saturation to `±out_bound`: that is at least `MAX_SAMPLE`, and any
/// value past it rounds to a byte past 255 or below 0 just as the saturated one does
/// (the clamp of [`Lift::to_byte`]). Other rows are lifted in place first.
#[inline(always)]
fn inverse_row_to_bytes<T: Lift>(
    wavelet: Wavelet,
    row: &mut [T],
    scratch: &mut [T],
    load_bounds: Option<(i32, i32)>,
    out_bound: i32,
    out: &mut [u8],
) {
    const {
        assert!(
            (MAX_SAMPLE as i32 + (1 << (GUARD_BITS - 1))) >> GUARD_BITS >= 255,
            "a sample past the bound must round to a byte past 255 too"
        );
    };
    let direct = load_bounds.is_none() && out_bound >= MAX_SAMPLE as i32 && row.len() > 1;
    match wavelet {
        Wavelet::Haar if direct => haar::inverse_line_into(row, out, T::to_byte),
        Wavelet::Db2 if direct && !T::ROW_PASSES => {
            db2::inverse_line_into(row, out, T::to_byte);
        }
        _ => {
            if row.len() > 1 {
                inverse_row(wavelet, row, scratch, load_bounds, out_bound);
            }
            for (o, &v) in out.iter_mut().zip(row.iter()) {
                *o = v.to_byte();
            }
        }
    }
}

/// One inverse 2-D level (columns, then rows), saturating as `saturation` says for that
/// level; `prepare(y, row y)` runs on each row of the region before the level reads it.
/// With `out` the level's output rows go there as bytes ([`inverse_row_to_bytes`]), not
/// back into `buf`.
pub(crate) fn inverse_level<T: Lift>(
    wavelet: Wavelet,
    buf: &mut [T],
    dims: Dims,
    scratch: &mut [T],
    saturation: Saturation<&LevelBounds>,
    prepare: &mut impl FnMut(usize, &mut [T]),
    mut out: Option<ByteRows<'_>>,
) {
    let bounds = saturation.bounds;
    let (w, h) = (dims.width(), dims.height());
    if h > 1 {
        // Floats saturate nothing either way: one copy of the pass serves them.
        let unsaturated = out.is_some() && T::SATURATES;
        // Each row is lifted back as soon as the column sweep has finished it, while it
        // is in cache. The column pass's output is already saturated to the row bands'
        // bounds, or to bytes needs no saturation ([`Unsaturated`]): loading it
        // saturates nothing more.
        let mut row_pass = |k: usize, row: &mut [T]| match &mut out {
            None => {
                if w > 1 {
                    inverse_row(wavelet, row, scratch, None, bounds.input);
                }
            }
            Some((bytes, out_dims)) => {
                if let Some(out_row) = out_dims.row_mut(bytes, k) {
                    inverse_row_to_bytes(wavelet, row, scratch, None, bounds.input, out_row);
                }
            }
        };
        let (loads, done) = (saturation.coefficients, &mut row_pass);
        if unsaturated {
            let column_bounds = ColumnPassBounds::of(bounds, w, Unsaturated);
            inverse_columns(wavelet, buf, dims, column_bounds, loads, prepare, done);
        } else {
            let column_bounds = ColumnPassBounds::of(bounds, w, Saturate);
            inverse_columns(wavelet, buf, dims, column_bounds, loads, prepare, done);
        }
    } else if let Some(row) = dims.row_mut(buf, 0) {
        prepare(0, row);
        // Without a column pass loads always saturate: a one-row level's low band holds
        // the deeper level's reconstruction, which fused coefficients can push past the
        // row-low bound (up to LL's).
        let load_bounds = Some((bounds.row_low, bounds.row_high));
        match out {
            None => {
                if w > 1 {
                    inverse_row(wavelet, row, scratch, load_bounds, bounds.input);
                }
            }
            Some((bytes, out_dims)) => {
                if let Some(out_row) = out_dims.row_mut(bytes, 0) {
                    inverse_row_to_bytes(wavelet, row, scratch, load_bounds, bounds.input, out_row);
                }
            }
        }
    }
}

/// Forward 1-D transform of `line` in place: `⌈n/2⌉` low then `⌊n/2⌋` high coefficients.
/// Samples must satisfy `|x| ≤ MAX_SAMPLE`; `scratch` needs `line.len()` elements.
///
/// The integer Haar step of a pair `(a, b)` is `d = b − a` and `s = a + ⌊d/2⌋`, and
/// [`inverse_1d`] undoes it exactly:
///
/// ```
/// use rollfuse_core::Wavelet;
/// use rollfuse_core::lifting::{forward_1d, inverse_1d};
///
/// let mut line = [10, 12, 20, 30];
/// let mut scratch = [0; 4];
/// forward_1d(Wavelet::Haar, &mut line, &mut scratch)?;
/// assert_eq!(line, [11, 25, 2, 10]);
/// inverse_1d(Wavelet::Haar, &mut line, &mut scratch)?;
/// assert_eq!(line, [10, 12, 20, 30]);
/// # Ok::<(), rollfuse_core::Error>(())
/// ```
pub fn forward_1d(wavelet: Wavelet, line: &mut [i32], scratch: &mut [i32]) -> Result<(), Error> {
    let dims = Dims::new(line.len(), 1)?;
    check_args(line, dims, None, scratch)?;
    check_samples(line, dims)?;
    forward_level(wavelet, line, dims, scratch);
    Ok(())
}

/// Inverse of [`forward_1d`].
pub fn inverse_1d(wavelet: Wavelet, line: &mut [i32], scratch: &mut [i32]) -> Result<(), Error> {
    let dims = Dims::new(line.len(), 1)?;
    check_args(line, dims, None, scratch)?;
    // A single row has no column pass: its row bands are its final bands.
    let bounds = &level_bounds(wavelet, 1)[0];
    let saturation = Saturation {
        bounds,
        coefficients: Coefficients::Any,
    };
    inverse_level(
        wavelet,
        line,
        dims,
        scratch,
        saturation,
        &mut |_, _| {},
        None,
    );
    Ok(())
}

/// Forward 2-D transform of the `dims` region of `buf`, `levels` deep, in place (layout in
/// [`crate::geometry`]). Samples must satisfy `|x| ≤ MAX_SAMPLE`; `scratch` needs
/// [`scratch_len`] elements.
///
/// Lossless: [`inverse_2d`] gives back every sample. Out-of-range input is refused, not
/// wrapped:
///
/// ```
/// use rollfuse_core::{Dims, Wavelet};
/// use rollfuse_core::lifting::{MAX_SAMPLE, forward_2d, inverse_2d, scratch_len};
///
/// let dims = Dims::new(13, 9)?;
/// let image: Vec<i32> = (0..13 * 9).map(|i| (i * 37 % 256) as i32).collect();
/// let mut buf = image.clone();
/// let mut scratch = vec![0; scratch_len(dims)];
/// forward_2d(Wavelet::Db2, &mut buf, dims, 2, &mut scratch)?;
/// assert_ne!(buf, image);
/// inverse_2d(Wavelet::Db2, &mut buf, dims, 2, &mut scratch)?;
/// assert_eq!(buf, image);
///
/// buf[0] = MAX_SAMPLE as i32 + 1;
/// assert!(forward_2d(Wavelet::Db2, &mut buf, dims, 2, &mut scratch).is_err());
/// # Ok::<(), rollfuse_core::Error>(())
/// ```
pub fn forward_2d(
    wavelet: Wavelet,
    buf: &mut [i32],
    dims: Dims,
    levels: u8,
    scratch: &mut [i32],
) -> Result<(), Error> {
    check_args(buf, dims, Some(levels), scratch)?;
    check_samples(buf, dims)?;
    let mut d = dims;
    for _ in 0..levels {
        forward_level(wavelet, buf, d, scratch);
        d = d.low_band();
    }
    Ok(())
}

/// Inverse of [`forward_2d`]. Any coefficients are accepted: each value is saturated to the
/// bound the forward transform proves for its band, so the output stays within
/// `±MAX_SAMPLE` and nothing can overflow.
pub fn inverse_2d(
    wavelet: Wavelet,
    buf: &mut [i32],
    dims: Dims,
    levels: u8,
    scratch: &mut [i32],
) -> Result<(), Error> {
    check_args(buf, dims, Some(levels), scratch)?;
    let bounds = level_bounds(wavelet, levels);
    let saturation = Saturation {
        bounds: &bounds,
        coefficients: Coefficients::Any,
    };
    inverse_levels(
        wavelet,
        buf,
        dims,
        levels,
        scratch,
        saturation,
        &mut |_, _, _| {},
    );
    Ok(())
}

/// All inverse levels of a `levels`-deep transform of `dims`, deepest first, each
/// saturating to its entry of the bounds (floats ignore them); `prepare(level, y, row y)`
/// runs on each row of each level's region (level 1 the full region) before that level
/// reads it.
pub(crate) fn inverse_levels<T: Lift>(
    wavelet: Wavelet,
    buf: &mut [T],
    dims: Dims,
    levels: u8,
    scratch: &mut [T],
    saturation: Saturation<&[LevelBounds; MAX_LEVELS as usize]>,
    prepare: &mut impl FnMut(u8, usize, &mut [T]),
) {
    let hooks = RowHooks { prepare, out: None };
    inverse_levels_into(wavelet, buf, dims, 1..=levels, scratch, saturation, hooks);
}

/// What an inverse transform does besides lifting: `prepare(level, y, row y)` runs on each
/// row of each level's region before that level reads it, and with `out` the result goes
/// there as bytes ([`inverse_row_to_bytes`]), `buf` left holding what level 1's column
/// pass made.
pub(crate) struct RowHooks<'o, P> {
    /// The preparation of each row.
    pub prepare: P,
    /// Where the result goes instead of `buf`.
    pub out: Option<ByteRows<'o>>,
}

/// [`inverse_levels`] of the levels `levels` (deepest first) of a transform whose level
/// `levels.start()` has the input region `dims`, with its rows' [`RowHooks`]; entry `k` of
/// the bounds is level `k + 1`'s, and `prepare` is given each level's number.
pub(crate) fn inverse_levels_into<T: Lift, P: FnMut(u8, usize, &mut [T])>(
    wavelet: Wavelet,
    buf: &mut [T],
    dims: Dims,
    levels: RangeInclusive<u8>,
    scratch: &mut [T],
    saturation: Saturation<&[LevelBounds; MAX_LEVELS as usize]>,
    hooks: RowHooks<'_, P>,
) {
    let RowHooks {
        mut prepare,
        mut out,
    } = hooks;
    let first = *levels.start();
    let sizes = level_sizes(dims);
    let bounds = saturation
        .bounds
        .iter()
        .skip(usize::from(first.saturating_sub(1)));
    for ((&d, bounds), level) in sizes.iter().zip(bounds).zip(levels).rev() {
        let mut prepare_level = |y: usize, row: &mut [T]| prepare(level, y, row);
        let level_saturation = Saturation {
            bounds,
            coefficients: saturation.coefficients,
        };
        let level_out = if level == first { out.take() } else { None };
        inverse_level(
            wavelet,
            buf,
            d,
            scratch,
            level_saturation,
            &mut prepare_level,
            level_out,
        );
    }
}

/// The region of each level, `dims` first, then the low band of the one before.
pub(crate) fn level_sizes(dims: Dims) -> [Dims; MAX_LEVELS as usize] {
    let mut sizes = [dims; MAX_LEVELS as usize];
    let mut d = dims;
    for s in &mut sizes {
        *s = d;
        d = d.low_band();
    }
    sizes
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::lift::{saturate_by_range_test, within};
    use super::*;
    use proptest::prelude::*;
    use std::{vec, vec::Vec};

    /// The one-compare range test the Cortex-M7's saturation takes is `|v| ≤ bound`, for
    /// bounds from 0 to `i32::MAX` and values at and around both limits, the extremes of
    /// `i32` and a spread between; both forms of the saturation give the clamp's value.
    #[test]
    fn one_compare_range_test_is_the_two_sided_one() {
        let mut bounds = vec![0, 1, 2, 255, 4095, 1 << 29, (1 << 30) - 1, 1 << 30];
        bounds.extend([i32::MAX - 1, i32::MAX]);
        bounds.extend((0..200u32).map(|k| (k.wrapping_mul(2_654_435_761) >> 1) as i32));
        for &b in &bounds {
            let mut values = vec![0, 1, -1, i32::MIN, i32::MIN + 1, i32::MAX, i32::MAX - 1];
            for edge in [b, -b] {
                values.extend([edge.saturating_sub(1), edge, edge.saturating_add(1)]);
            }
            values.extend((0..200u32).map(|k| k.wrapping_mul(2_246_822_519) as i32));
            for &v in &values {
                assert_eq!(within(v, b), -b <= v && v <= b, "within({v}, {b})");
                let want = v.clamp(-b, b);
                assert_eq!(
                    saturate_by_range_test(v, b),
                    want,
                    "the M7's saturate({v}, {b})"
                );
                assert_eq!(v.saturate(b), want, "saturate({v}, {b})");
            }
        }
    }

    /// Test images: random 8-bit content and the extremes the bounds must survive.
    #[derive(Debug, Clone, Copy)]
    enum Content {
        Random(u64),
        AllZero,
        AllMax,
        Checkerboard,
        Impulse,
    }

    fn render(content: Content, w: usize, h: usize, max: i32) -> Vec<i32> {
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                match content {
                    Content::Random(seed) => {
                        state = state
                            .wrapping_mul(6_364_136_223_846_793_005)
                            .wrapping_add(seed | 1);
                        ((state >> 33) % (max as u64 + 1)) as i32
                    }
                    Content::AllZero => 0,
                    Content::AllMax => max,
                    Content::Checkerboard => {
                        if (x + y) % 2 == 0 {
                            0
                        } else {
                            max
                        }
                    }
                    Content::Impulse => i32::from(x == w / 2 && y == h / 2) * max,
                }
            })
            .collect()
    }

    fn content() -> impl Strategy<Value = Content> {
        prop_oneof![
            4 => any::<u64>().prop_map(Content::Random),
            1 => Just(Content::AllZero),
            1 => Just(Content::AllMax),
            1 => Just(Content::Checkerboard),
            1 => Just(Content::Impulse),
        ]
    }

    /// Whether the samples of region `d` in columns `cols` and rows `rows` are within
    /// `±bound`.
    fn region_within(
        buf: &[i32],
        d: Dims,
        cols: core::ops::Range<usize>,
        mut rows: impl Iterator<Item = usize>,
        bound: i32,
    ) -> bool {
        rows.all(|y| cols.clone().all(|x| buf[d.at(x, y)].abs() <= bound))
    }

    /// Runs the forward transform pass by pass and checks each pass's output against its
    /// proven bound, then inverts and compares bit for bit.
    fn check_round_trip(
        wavelet: Wavelet,
        w: usize,
        h: usize,
        levels: u8,
        img: &[i32],
        max_input: u32,
    ) {
        let dims = Dims::new(w, h).unwrap();
        let bounds = bounds::level_bounds_for(wavelet, levels, max_input);
        let mut buf = img.to_vec();
        let mut scratch = vec![0; w.max(h)];
        let mut d = dims;
        for b in bounds.iter().take(levels as usize) {
            let (lw, lh) = (d.width(), d.height());
            let nlx = lw.div_ceil(2);
            assert!(region_within(&buf, d, 0..lw, 0..lh, b.input));
            if lw > 1 {
                for y in 0..lh {
                    let row = Line::row(d, y);
                    forward_line_reference(wavelet, &mut buf, row, &mut scratch, false);
                }
                assert!(region_within(&buf, d, 0..nlx, 0..lh, b.row_low), "row low");
                assert!(
                    region_within(&buf, d, nlx..lw, 0..lh, b.row_high),
                    "row high"
                );
            }
            if lh > 1 {
                for x in 0..lw {
                    let column = Line::column(d, x);
                    forward_line_reference(wavelet, &mut buf, column, &mut scratch, true);
                }
            }
            // Column-low bands in the even rows, column-high in the odd ones.
            let (even, odd) = ((0..lh).step_by(2), (1..lh).step_by(2));
            assert!(region_within(&buf, d, 0..nlx, even.clone(), b.ll), "LL");
            assert!(region_within(&buf, d, nlx..lw, even, b.hl), "HL");
            assert!(region_within(&buf, d, 0..nlx, odd.clone(), b.lh), "LH");
            assert!(region_within(&buf, d, nlx..lw, odd, b.hh), "HH");
            assert!(b.peak >= b.ll.max(b.hl).max(b.lh).max(b.hh));
            d = d.low_band();
        }
        // The pass-by-pass result is what the public API computes.
        let mut public = img.to_vec();
        forward_2d(wavelet, &mut public, dims, levels, &mut scratch).unwrap();
        assert_eq!(public, buf);
        inverse_2d(wavelet, &mut buf, dims, levels, &mut scratch).unwrap();
        assert_eq!(buf, img, "forward∘inverse must be exact");
    }

    /// The line and column transforms against the step-by-step reference on one set of
    /// lines: `values` holds `n` rows of `w` lanes, each column one line. The inverse gets
    /// them as coefficients of any size, so its saturation on store is exercised too, with
    /// `bounds` on the columns of `region`.
    fn check_against_steps<T: Lift + PartialEq + core::fmt::Debug>(
        wavelet: Wavelet,
        values: &[T],
        region: Dims,
        bounds: ColumnBounds,
    ) {
        let (w, n, stride) = (region.width(), region.height(), region.stride());
        let nl = n.div_ceil(2);
        let column = |j: usize| -> Vec<T> { (0..n).map(|k| values[k * w + j]).collect() };
        // Row k of the column layout holds sample k / 2 of the low band (k even) or of the
        // high band (k odd).
        let interleaved = |k: usize| {
            if k.is_multiple_of(2) {
                k / 2
            } else {
                nl + k / 2
            }
        };
        let strided = |row: &dyn Fn(usize) -> usize| {
            let mut buf = vec![T::default(); n * stride];
            for k in 0..n {
                let src = &values[row(k) * w..(row(k) + 1) * w];
                buf[k * stride..k * stride + w].copy_from_slice(src);
            }
            buf
        };
        // The row hooks must run exactly once on every row (the round-trip tests check
        // that the row pass runs before the sweep reads a row: the 2-D result is exact),
        // and in order for an even length (what `forward_level_observed` relies on).
        let mut fwd = strided(&|k| k);
        let mut order = Vec::new();
        let mut record = |k: usize, _: &mut [T]| order.push(k);
        let mut ready = RowsReady::new(&mut record);
        wavelet.forward_columns(&mut fwd, region, &mut ready);
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(
            sorted,
            (0..n).collect::<Vec<_>>(),
            "forward row hooks, {wavelet:?}, n {n}"
        );
        if n % 2 == 0 {
            assert_eq!(order, sorted, "forward row hook order, {wavelet:?}, n {n}");
        }
        // The inverse reads each column's values as low band then high band.
        let mut inv = strided(&interleaved);
        // The inverse starts from zeros: each row's coefficients arrive by its
        // preparation, so a row the sweep touched before preparing it spoils the result.
        let coefficients = inv.clone();
        inv.fill(T::default());
        let mut prepared_rows = Vec::new();
        let mut fill = |k: usize, row: &mut [T]| {
            prepared_rows.push(k);
            row.copy_from_slice(&coefficients[k * stride..k * stride + w]);
        };
        let mut prepared = RowsPrepared::new(&mut fill, &mut inv, region);
        // Each finished row is handed on once, with its own index.
        let mut rows_seen = Vec::new();
        let mut count = |k: usize, row: &mut [T]| rows_seen.push((k, row.as_ptr() as usize));
        wavelet.inverse_columns(&mut inv, region, bounds, &mut prepared, &mut count);
        let base = inv.as_ptr() as usize;
        let row_size = stride * core::mem::size_of::<T>();
        for &(k, at) in &rows_seen {
            assert_eq!(
                at,
                base + k * row_size,
                "row {k} handed on, {wavelet:?}, n {n}"
            );
        }
        let mut finished: Vec<usize> = rows_seen.iter().map(|&(k, _)| k).collect();
        finished.sort_unstable();
        assert_eq!(
            finished,
            (0..n).collect::<Vec<_>>(),
            "inverse row hook calls, {wavelet:?}, n {n}"
        );
        prepared_rows.sort_unstable();
        assert_eq!(
            prepared_rows,
            (0..n).collect::<Vec<_>>(),
            "inverse preparations, {wavelet:?}, n {n}"
        );
        for j in 0..w {
            let x = column(j);
            let bound = if j < bounds.split {
                bounds.left
            } else {
                bounds.right
            };
            // Forward: deinterleave, lift step by step.
            let mut split: Vec<T> = x
                .iter()
                .step_by(2)
                .chain(x.iter().skip(1).step_by(2))
                .copied()
                .collect();
            let (low, high) = split.split_at_mut(nl);
            wavelet.forward_split(low, high, 1);
            let mut line = vec![T::default(); n];
            wavelet.forward_line(&x, &mut line);
            assert_eq!(line, split, "forward line, {wavelet:?}, n {n}");
            // The row pass as the 2-D transform runs it (floats' db2 in two passes).
            let mut row = x.clone();
            let mut scratch = vec![T::default(); n];
            forward_row(wavelet, &mut row, &mut scratch);
            assert_eq!(row, split, "forward row, {wavelet:?}, n {n}");
            let in_place: Vec<T> = (0..n).map(|k| fwd[k * stride + j]).collect();
            let expect: Vec<T> = (0..n).map(|k| split[interleaved(k)]).collect();
            assert_eq!(
                in_place, expect,
                "forward columns, {wavelet:?}, n {n}, column {j}"
            );
            // Inverse: lift step by step, interleave, saturate.
            let mut work = x.clone();
            let (low, high) = work.split_at_mut(nl);
            wavelet.inverse_split(low, high, 1);
            let expect: Vec<T> = (0..n)
                .map(|k| if k % 2 == 0 { low[k / 2] } else { high[k / 2] }.saturate(bound))
                .collect();
            wavelet.inverse_line(&x, &mut line, bound);
            assert_eq!(line, expect, "inverse line, {wavelet:?}, n {n}");
            let mut row = x.clone();
            inverse_row(wavelet, &mut row, &mut scratch, None, bound);
            assert_eq!(row, expect, "inverse row, {wavelet:?}, n {n}");
            let in_place: Vec<T> = (0..n).map(|k| inv[k * stride + j]).collect();
            assert_eq!(
                in_place, expect,
                "inverse columns, {wavelet:?}, n {n}, column {j}"
            );
        }
    }

    /// The byte-reading row passes and the byte-writing inverse rows give the values of
    /// the plain ones on the widened samples (and their rounding), for every length to
    /// 70 and the camera's row lengths, both wavelets, random bytes and the extremes (all
    /// 0, all 255, 0/255 alternating either way, a lone 255).
    #[test]
    fn byte_rows_match_the_widened_rows() {
        let mut state = 0x9E37_79B9u32;
        for n in (1..=70usize).chain([79, 80, 81, 159, 160, 161, 319, 320]) {
            for kind in 0..6 {
                let bytes: Vec<u8> = (0..n)
                    .map(|i| match kind {
                        0 => 0,
                        1 => 255,
                        2 => [0, 255][i % 2],
                        3 => [255, 0][i % 2],
                        4 => u8::from(i == n / 2) * 255,
                        _ => {
                            state ^= state << 13;
                            state ^= state >> 17;
                            state ^= state << 5;
                            (state >> 24) as u8
                        }
                    })
                    .collect();
                let wide: Vec<i32> = bytes.iter().map(|&v| i32::from(v) << GUARD_BITS).collect();
                for wavelet in [Wavelet::Haar, Wavelet::Db2] {
                    let what = std::format!("{wavelet:?} n {n} kind {kind}");
                    let mut want = vec![0; n];
                    wavelet.forward_line(&wide, &mut want);
                    let mut got = vec![0; n];
                    match wavelet {
                        Wavelet::Haar => {
                            haar::forward_line_from(&bytes, &mut got, i32::from_guarded_byte)
                        }
                        Wavelet::Db2 => db2::forward_line_bytes(&bytes, &mut got),
                    }
                    assert_eq!(got, want, "forward {what}");
                    let mut from = vec![0; n];
                    db2::forward_line_from(&bytes, &mut from, i32::from_guarded_byte);
                    if wavelet == Wavelet::Db2 {
                        assert_eq!(from, want, "forward_line_from {what}");
                    }
                    // The inverse of those coefficients, and of coefficients pushed past
                    // the samples' range (so the dropped saturation would matter).
                    for scale in [1, 3, -3] {
                        let coeffs: Vec<i32> = want.iter().map(|&v| v * scale).collect();
                        let mut back = vec![0; n];
                        wavelet.inverse_line(&coeffs, &mut back, MAX_SAMPLE as i32);
                        let rounded: Vec<u8> = back.iter().map(|&v| v.to_byte()).collect();
                        let mut out = vec![0u8; n];
                        let mut row = coeffs.clone();
                        let mut scratch = vec![0; n];
                        inverse_row_to_bytes(
                            wavelet,
                            &mut row,
                            &mut scratch,
                            None,
                            MAX_SAMPLE as i32,
                            &mut out,
                        );
                        assert_eq!(out, rounded, "inverse ×{scale} {what}");
                        if scale == 1 {
                            assert_eq!(out, bytes, "round trip {what}");
                        }
                    }
                }
            }
        }
    }

    /// The sweep (the column steps read each lane's samples before writing any) matches
    /// the step-by-step lifting on extreme images: flat at 0 and at the largest samples of
    /// either sign, checkerboards of the extremes, alternating rows and columns, in
    /// regions 1 wide, 1 high and larger, with and without a row stride.
    #[test]
    fn one_sweep_lifting_matches_the_steps_on_extremes() {
        let m = 1 << 20;
        for (w, n) in [
            (1, 1),
            (1, 7),
            (7, 1),
            (2, 2),
            (5, 6),
            (6, 5),
            (33, 16),
            (16, 33),
        ] {
            for pattern in 0..6 {
                let ints: Vec<i32> = (0..w * n)
                    .map(|i| {
                        let (x, y) = (i % w, i / w);
                        match pattern {
                            0 => 0,
                            1 => m,
                            2 => -m,
                            3 => [m, -m][(x + y) % 2],
                            4 => [m, -m][y % 2],
                            _ => [m, 0][x % 2],
                        }
                    })
                    .collect();
                for pad in [0, 2] {
                    let region = Dims::with_stride(w, n, w + pad).unwrap();
                    let bounds = ColumnBounds {
                        split: w / 2,
                        width: w,
                        left: (1 << 18) + 1000,
                        right: (1 << 18) - 5000,
                        rule: Saturate,
                    };
                    for wavelet in [Wavelet::Haar, Wavelet::Db2] {
                        check_against_steps(wavelet, &ints, region, bounds);
                    }
                }
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        #[test]
        fn one_sweep_lifting_matches_the_steps(
            n in 1usize..=70,
            w in 1usize..=33,
            pad in 0usize..3,
            seed in any::<u64>(),
            db2 in any::<bool>(),
        ) {
            // Values up to ±2²⁰: far past what the forward transform makes of 8-bit
            // samples, so the inverse's output saturation (bounds near 2¹⁸) comes into play.
            let wavelet = if db2 { Wavelet::Db2 } else { Wavelet::Haar };
            let m = 1 << 20;
            let ints: Vec<i32> = render(Content::Random(seed), n * w, 1, 2 * m).iter().map(|v| v - m).collect();
            let region = Dims::with_stride(w, n, w + pad).unwrap();
            let bounds = ColumnBounds {
                split: w / 2,
                width: w,
                left: (1 << 18) + 1000,
                right: (1 << 18) - 5000,
                rule: Saturate,
            };
            check_against_steps(wavelet, &ints, region, bounds);
            let floats: Vec<f32> = ints.iter().map(|&v| v as f32 / 64.0).collect();
            check_against_steps(wavelet, &floats, region, bounds);
            let doubles: Vec<f64> = ints.iter().map(|&v| f64::from(v) / 64.0).collect();
            check_against_steps(wavelet, &doubles, region, bounds);
        }

        #[test]
        fn forward_inverse_is_exact_and_within_bounds(
            w in 1usize..=257,
            h in 1usize..=257,
            level_pick in 0u8..4,
            content in content(),
            db2 in any::<bool>(),
        ) {
            let dims = Dims::new(w, h).unwrap();
            let max = dims.max_levels();
            prop_assume!(max >= 1);
            let levels = 1 + level_pick % max;
            let wavelet = if db2 { Wavelet::Db2 } else { Wavelet::Haar };
            let img = render(content, w, h, 255);
            check_round_trip(wavelet, w, h, levels, &img, 255);
        }

        #[test]
        fn extreme_samples_stay_within_bounds(
            w in 1usize..=40,
            h in 1usize..=40,
            seed in any::<u64>(),
            db2 in any::<bool>(),
        ) {
            let dims = Dims::new(w, h).unwrap();
            prop_assume!(dims.max_levels() >= 1);
            let wavelet = if db2 { Wavelet::Db2 } else { Wavelet::Haar };
            // Signed full-range content: the largest inputs the transform accepts.
            let m = MAX_SAMPLE as i32;
            let img: Vec<i32> = render(Content::Random(seed), w, h, 2 * m).iter().map(|v| v - m).collect();
            check_round_trip(wavelet, w, h, dims.max_levels(), &img, MAX_SAMPLE);
        }

        #[test]
        fn one_dimensional_round_trip(n in 1usize..=300, seed in any::<u64>(), db2 in any::<bool>()) {
            let wavelet = if db2 { Wavelet::Db2 } else { Wavelet::Haar };
            let x = render(Content::Random(seed), n, 1, 255);
            let mut y = x.clone();
            let mut scratch = vec![0; n];
            forward_1d(wavelet, &mut y, &mut scratch).unwrap();
            inverse_1d(wavelet, &mut y, &mut scratch).unwrap();
            prop_assert_eq!(y, x);
        }

        #[test]
        fn blended_coefficients_need_no_saturation_on_load(
            w in 1usize..=40,
            h in 1usize..=40,
            seeds in any::<(u64, u64, u64)>(),
            db2 in any::<bool>(),
        ) {
            // What fusion hands the inverse: per coefficient, a Q15 blend of two images'
            // coefficients. Skipping the load saturation must change nothing, even for
            // the largest inputs.
            use crate::fusion::driver::Arith;
            let dims = Dims::new(w, h).unwrap();
            prop_assume!(dims.max_levels() >= 1);
            let levels = dims.max_levels();
            let wavelet = if db2 { Wavelet::Db2 } else { Wavelet::Haar };
            let m = MAX_SAMPLE as i32;
            let signed = |seed| -> Vec<i32> {
                render(Content::Random(seed), w, h, 2 * m).iter().map(|v| v - m).collect()
            };
            let (mut a, mut b) = (signed(seeds.0), signed(seeds.1));
            let mut scratch = vec![0; scratch_len(dims)];
            forward_2d(wavelet, &mut a, dims, levels, &mut scratch).unwrap();
            forward_2d(wavelet, &mut b, dims, levels, &mut scratch).unwrap();
            let weights = render(Content::Random(seeds.2), w, h, 1 << 15);
            for ((x, &y), &w1) in a.iter_mut().zip(&b).zip(&weights) {
                *x = i32::blend(*x, y, w1);
            }
            let bounds = level_bounds(wavelet, levels);
            let mut trusted = a.clone();
            let any = Saturation { bounds: &bounds, coefficients: Coefficients::Any };
            inverse_levels(wavelet, &mut a, dims, levels, &mut scratch, any, &mut |_, _, _| {});
            let inside = Saturation { bounds: &bounds, coefficients: Coefficients::InBounds };
            let none = &mut |_, _, _: &mut [i32]| {};
            inverse_levels(wavelet, &mut trusted, dims, levels, &mut scratch, inside, none);
            prop_assert_eq!(trusted, a);
        }

        #[test]
        fn inverse_of_any_coefficients_stays_in_range(
            w in 1usize..=33,
            h in 1usize..=33,
            seed in any::<u64>(),
            db2 in any::<bool>(),
        ) {
            // Garbage coefficients (as large as i32 allows) must not overflow: every value
            // is saturated to its band's bound and the output to ±MAX_SAMPLE.
            let dims = Dims::new(w, h).unwrap();
            prop_assume!(dims.max_levels() >= 1);
            let wavelet = if db2 { Wavelet::Db2 } else { Wavelet::Haar };
            let mut buf: Vec<i32> = render(Content::Random(seed), w, h, i32::MAX)
                .iter()
                .enumerate()
                .map(|(i, v)| if i % 3 == 0 { -v } else { *v })
                .collect();
            let mut scratch = vec![0; scratch_len(dims)];
            inverse_2d(wavelet, &mut buf, dims, dims.max_levels(), &mut scratch).unwrap();
            prop_assert!(buf.iter().all(|v| v.unsigned_abs() <= MAX_SAMPLE));
        }
    }

    #[test]
    fn bad_arguments_are_errors() {
        let dims = Dims::new(8, 8).unwrap();
        let mut buf = vec![0; 64];
        // One row.
        let mut scratch = vec![0; 8];
        assert_eq!(scratch_len(dims), 8);
        assert_eq!(
            forward_2d(Wavelet::Db2, &mut buf[..63], dims, 1, &mut scratch),
            Err(Error::BufferTooSmall {
                which: "image",
                needed: 64,
                got: 63
            })
        );
        assert_eq!(
            forward_2d(Wavelet::Db2, &mut buf, dims, 1, &mut scratch[..7]),
            Err(Error::BufferTooSmall {
                which: "scratch",
                needed: 8,
                got: 7
            })
        );
        assert_eq!(
            forward_2d(Wavelet::Haar, &mut buf, dims, 5, &mut scratch),
            Err(Error::LevelsOutOfRange { levels: 5 })
        );
        assert_eq!(
            forward_2d(Wavelet::Haar, &mut buf, dims, 4, &mut scratch),
            Err(Error::LevelsTooDeep { levels: 4, max: 3 })
        );
        buf[5] = MAX_SAMPLE as i32 + 1;
        assert_eq!(
            forward_2d(Wavelet::Haar, &mut buf, dims, 1, &mut scratch),
            Err(Error::SampleOutOfRange)
        );
        let mut one = [7];
        assert_eq!(
            forward_1d(Wavelet::Db2, &mut one, &mut []),
            Err(Error::BufferTooSmall {
                which: "scratch",
                needed: 1,
                got: 0
            })
        );
        assert_eq!(
            forward_1d(Wavelet::Db2, &mut [], &mut []),
            Err(Error::ZeroSize)
        );
    }
}
