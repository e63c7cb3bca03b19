//! Integer saliency (paper eqs. 3–5) and the fusion weights built from it.
//!
//! For a level's input image `I` (the image at level 1, the LL band of the level above
//! otherwise):
//!
//! 1. `L = |I(x−1,y) + I(x+1,y) + I(x,y−1) + I(x,y+1) − 4·I(x,y)|`, the 4-neighbour
//!    Laplacian, with whole-sample symmetric extension at the borders.
//! 2. `Sal = L · 255 / max L`, rounded down, where `max L` is taken over the region being
//!    fused ([`SaliencyNorm::Local`]: the whole image, or the tile on the device) or given
//!    by the caller ([`SaliencyNorm::Reference`]: e.g. the maximum over the rows of a
//!    frame whose tiles are fused). A flat region (`max L = 0`) has
//!    `Sal = 0` everywhere.
//! 3. `S = exp(Sal/255) − 1`, looked up in [`EXP_TABLE`] (Q24, built at compile time).
//!    `Sal` keeps 8 fraction bits and the table is interpolated linearly between entries:
//!    weakly salient pixels, the most common kind at deeper levels, would otherwise all
//!    round to `S = 0` and turn their weights into ½ where the float path sees a real
//!    preference.
//! 4. Brought to subband resolution by summing `S` over the 2×2 window of the level's input
//!    under the two middle taps of each coefficient's filter (see the fusion module; fewer
//!    pixels at an edge, and both images sum the same pixels, so the ratio below is a ratio
//!    of 2×2 means).
//! 5. `W₁ = S₁ / (S₁ + S₂)` in Q15, and `W₁ = ½` where `S₁ + S₂ = 0`.

use crate::geometry::mirror;
use crate::packed::{
    AboveMax, LAPLACIAN_BIAS, column_laplacian_max, column_pixel_max, laplacian_at,
    laplacian_quads, quad_pixels, single_pixels, unpack,
};
use crate::{Dims, Wavelet, simd};
use fixed::types::{U1F15, U8F24};

/// Fraction bits of the saliency table.
const TABLE_Q: u32 = 24;

/// `exp(k/255) − 1` for `k = 0..=255`, in Q24 (`U8F24`): 0 … 1.71828.
pub const EXP_TABLE: [U8F24; 256] = build_exp_table();

/// Computes `e^(k/255)` by its Taylor series in Q62 integer arithmetic (exact to far below
/// the table's Q24 step), at compile time.
// `table[k]` has `k < 256` by the loop guard, and this only runs in const evaluation (for
// `EXP_TABLE`): an out-of-range index would fail the build, never panic at run time. A
// `const fn` cannot use `get_mut` or iterators.
#[allow(clippy::indexing_slicing)]
const fn build_exp_table() -> [U8F24; 256] {
    const ONE: u128 = 1 << 62;
    let mut table = [U8F24::ZERO; 256];
    let mut k = 0;
    while k < 256 {
        let mut sum: u128 = ONE;
        let mut term: u128 = ONE;
        let mut n = 1;
        while n < 40 {
            term = term * k as u128 / (255 * n as u128);
            sum += term;
            n += 1;
        }
        let frac = sum - ONE;
        let q = (frac + (1 << (62 - TABLE_Q - 1))) >> (62 - TABLE_Q);
        table[k] = U8F24::from_bits(q as u32);
        k += 1;
    }
    table
}

/// [`EXP_TABLE`] as `[S(k), S(k + 1) − S(k)]` in Q24 per entry (the last step 0), for the
/// interpolation: one entry read per pixel, no second index and no subtraction.
const EXP_STEPS: [[u32; 2]; 256] = build_exp_steps();

// `k + 1 < 256` by the loop guard; const evaluation only, as for `build_exp_table`.
#[allow(clippy::indexing_slicing)]
const fn build_exp_steps() -> [[u32; 2]; 256] {
    let mut steps = [[0; 2]; 256];
    let mut k = 0;
    while k < 256 {
        let lo = EXP_TABLE[k].to_bits();
        let hi = if k < 255 {
            EXP_TABLE[k + 1].to_bits()
        } else {
            lo
        };
        steps[k] = [lo, hi - lo];
        k += 1;
    }
    steps
}

/// How the Laplacian is normalized to 0..=255 (eq. 3).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SaliencyNorm {
    /// By the maximum over the region being fused: the whole image, or one tile.
    Local,
    /// By a caller-supplied level-1 maximum, in the input's units (8-bit gray levels for
    /// [`crate::fusion::fuse_u8`]), e.g. that of the rows of a frame the device pipeline
    /// takes its tiles from (see [`laplacian_max_u8`]), so every tile of a frame is judged
    /// on one scale. Deeper levels scale it by the transform's LL gain
    /// ([`ll_gain_q16`]: both paths run the same unscaled lifting); larger values
    /// saturate at 255. `Reference(0)` treats both images as flat: every weight ½.
    Reference(u32),
}

/// The DC gain of one 2-D level's LL band, in Q16: 1 for Haar (the S-transform keeps the
/// mean), `(1 + √3)² ≈ 7.464` for the unscaled db2 lifting.
pub fn ll_gain_q16(wavelet: Wavelet) -> u64 {
    match wavelet {
        Wavelet::Haar => 1 << 16,
        Wavelet::Db2 => 489_165, // (1 + √3)² · 2¹⁶
    }
}

/// Calls `f(x, centre, [up, down, left, right])` for every pixel of row `y`, with
/// whole-sample symmetric extension at the borders (`x = −1` reads `x = 1`). The border
/// columns are handled apart so the inner loop indexes directly. Nothing is called if
/// `buf` is shorter than the region.
// Indices stay inside the rows: `row_and_neighbours` returns three rows of exactly
// `w = dims.width() ≥ 1` elements (a `Dims` is never empty), and x − 1, x, x + 1 are kept in
// `0..w` by the `w == 1` case and the `1..w − 1` interior.
#[allow(clippy::indexing_slicing)]
#[inline(always)]
pub(crate) fn neighbourhood_row<T: Copy>(
    buf: &[T],
    dims: Dims,
    y: usize,
    mut f: impl FnMut(usize, T, [T; 4]),
) {
    let Some((up, mid, down)) = row_and_neighbours(buf, dims, y) else {
        return;
    };
    let w = mid.len();
    if w == 1 {
        f(0, mid[0], [up[0], down[0], mid[0], mid[0]]);
        return;
    }
    f(0, mid[0], [up[0], down[0], mid[1], mid[1]]);
    for x in 1..w - 1 {
        f(x, mid[x], [up[x], down[x], mid[x - 1], mid[x + 1]]);
    }
    f(
        w - 1,
        mid[w - 1],
        [up[w - 1], down[w - 1], mid[w - 2], mid[w - 2]],
    );
}

/// Sets `out[x] = f(centre, [up, down, left, right])` for every pixel of the row `mid`,
/// `up` and `down` being the rows above and below it (as [`row_and_neighbours`] gives
/// them), with the extension of [`neighbourhood_row`] at its ends. The interior runs over
/// zipped slices, with no index checks, so a simple `f` vectorizes. Nothing is written if
/// `up`, `down` or `out` is shorter than `mid`, or `mid` is empty.
// Indices stay inside the rows: all four are cut to `w = mid.len() ≥ 1`; the border
// indices are 0, 1, w − 2 and w − 1 with `w ≥ 2` past the `w == 1` case, and `m` is a
// window of 3.
#[allow(clippy::indexing_slicing)]
#[inline(always)]
pub(crate) fn map_neighbourhood<T: Copy, U>(
    [up, mid, down]: [&[T]; 3],
    out: &mut [U],
    f: impl Fn(T, [T; 4]) -> U,
) {
    let w = mid.len();
    let (Some(up), Some(down), Some(out)) = (up.get(..w), down.get(..w), out.get_mut(..w)) else {
        return;
    };
    if w == 0 {
        return;
    }
    if w == 1 {
        out[0] = f(mid[0], [up[0], down[0], mid[0], mid[0]]);
        return;
    }
    out[0] = f(mid[0], [up[0], down[0], mid[1], mid[1]]);
    let interior = out[1..w - 1]
        .iter_mut()
        .zip(&up[1..])
        .zip(&down[1..])
        .zip(mid.windows(3));
    for (((o, &u), &d), m) in interior {
        *o = f(m[1], [u, d, m[0], m[2]]);
    }
    // The right border last: read first, the end of a row not yet in cache stalled the
    // pass on that one load (`perf annotate`); read last, the sweep has brought it in.
    out[w - 1] = f(mid[w - 1], [up[w - 1], down[w - 1], mid[w - 2], mid[w - 2]]);
}

/// Rows `y − 1`, `y` and `y + 1` of the region, mirrored at its top and bottom, each
/// `dims.width()` long; `None` if `buf` does not hold them.
#[inline(always)]
pub(crate) fn row_and_neighbours<T>(buf: &[T], dims: Dims, y: usize) -> Option<(&[T], &[T], &[T])> {
    let h = dims.height();
    Some((
        dims.row(buf, mirror(y as isize - 1, h))?,
        dims.row(buf, y)?,
        dims.row(buf, mirror(y as isize + 1, h))?,
    ))
}

/// Calls `f(x, y, centre, [up, down, left, right])` for every pixel of the region, in
/// row-major order (see [`neighbourhood_row`]). Both fusion paths compute their Laplacian
/// through this walk.
#[inline]
pub(crate) fn for_each_neighbourhood<T: Copy>(
    buf: &[T],
    dims: Dims,
    mut f: impl FnMut(usize, usize, T, [T; 4]),
) {
    for y in 0..dims.height() {
        neighbourhood_row(buf, dims, y, |x, c, around| f(x, y, c, around));
    }
}

/// `|∇²I|` from a centre and its four neighbours, in `u32`.
#[inline(always)]
fn laplacian(c: i32, around: [i32; 4]) -> u32 {
    let sum: i64 = around.iter().map(|&v| i64::from(v)).sum();
    // |values| ≤ the deepest level bound < 2²⁸, so 8× that fits in u32.
    (sum - 4 * i64::from(c))
        .unsigned_abs()
        .min(u64::from(u32::MAX)) as u32
}

/// `|∇²I|` of a sample of a fusion level's input, in `i32`: such samples lie within the
/// level's input bound, below 2²⁸ (test `every_bound_fits_in_i32`), so the four
/// neighbours' sum stays below 2³⁰ and the result below 2³¹. Wrapping arithmetic only
/// spares the overflow checks; nothing wraps. On the Cortex-M7 this is a third of the
/// 64-bit [`laplacian`]'s instructions.
#[inline(always)]
fn level_laplacian(c: i32, [up, down, left, right]: [i32; 4]) -> u32 {
    up.wrapping_add(down)
        .wrapping_add(left)
        .wrapping_add(right)
        .wrapping_sub(c.wrapping_mul(4))
        .unsigned_abs()
}

/// Calls `f(x, y, |∇²I|)` for every pixel of the region, with `laplacian` the kernel.
#[inline]
fn for_each_laplacian(
    buf: &[i32],
    dims: Dims,
    laplacian: impl Fn(i32, [i32; 4]) -> u32,
    mut f: impl FnMut(usize, usize, u32),
) {
    for_each_neighbourhood(buf, dims, |x, y, c, around| f(x, y, laplacian(c, around)));
}

/// The largest `|∇²I|` over the region: the `max L` of eq. 3 (e.g. a frame's observation
/// window's, for [`SaliencyNorm::Reference`] when its tiles are fused). Fails if `buf` is
/// shorter than the region.
///
/// A lone bright pixel on a dark field stands out by four times its level (the
/// 4-neighbour Laplacian):
///
/// ```
/// use rollfuse_core::Dims;
/// use rollfuse_core::saliency::laplacian_max;
///
/// let dims = Dims::new(5, 5)?;
/// let mut image = [0i32; 25];
/// image[12] = 10;
/// assert_eq!(laplacian_max(&image, dims)?, 40);
/// assert!(laplacian_max(&image[..20], dims).is_err());
/// # Ok::<(), rollfuse_core::Error>(())
/// ```
pub fn laplacian_max(buf: &[i32], dims: Dims) -> Result<u32, crate::Error> {
    dims.check_buffer("image", buf.len())?;
    // Any i32 samples: the 64-bit Laplacian.
    Ok(laplacian_max_in(buf, dims, laplacian))
}

/// [`laplacian_max`] of an 8-bit image (a band of a downsampled camera frame, or a
/// tile), for [`SaliencyNorm::Reference`]; 0 if `buf` is shorter than the region.
pub fn laplacian_max_u8(buf: &[u8], dims: Dims) -> u32 {
    if dims.check_buffer("image", buf.len()).is_err() {
        return 0;
    }
    if cfg!(target_arch = "x86_64") {
        laplacian_max_u8_by_rows(buf, dims)
    } else {
        laplacian_max_u8_by_columns(buf, dims)
    }
}

/// [`laplacian_max_u8`] row by row ([`row_laplacian_max_u8`]): on x86-64 hosts, whose
/// wide units test a whole row in a few vector instructions, and for one-row images.
fn laplacian_max_u8_by_rows(buf: &[u8], dims: Dims) -> u32 {
    (0..dims.height())
        .filter_map(|y| row_and_neighbours(buf, dims, y))
        .fold(0, |max, (up, mid, down)| {
            row_laplacian_max_u8([up, mid, down], max)
        })
}

/// [`laplacian_max_u8`] by columns of groups of four ([`column_laplacian_max`]: two
/// word loads per group where a row walk has four), then the pixels the groups leave
/// out ([`single_pixels`]) column by column too: the same maximum on the Cortex-M7 in two thirds
/// of the instructions.
fn laplacian_max_u8_by_columns(buf: &[u8], dims: Dims) -> u32 {
    let (w, h) = (dims.width(), dims.height());
    let Some(img) = buf.get(..w * h) else {
        return 0;
    };
    if h < 2 {
        return laplacian_max_u8_by_rows(img, dims);
    }
    let max = column_laplacian_max(img, w, h, 0);
    single_pixels(w).fold(max, |max, x| column_pixel_max(img, w, x, max))
}

/// The larger of `max` and the largest `|∇²I|` of row `mid`, four pixels at a time, with
/// a test for "any above `max`" ([`crate::packed::AboveMax`]) that most groups pass: an
/// image's maximum is met early. How the test is run depends on the target: on x86-64
/// hosts, whose wide units run a whole row's tests in a few vector instructions, by
/// [`row_max_by_whole_row`]; elsewhere (the Cortex-M7) by [`row_max_by_group`].
#[inline(always)]
fn row_laplacian_max_u8(rows: [&[u8]; 3], max: u32) -> u32 {
    let max = if cfg!(target_arch = "x86_64") {
        row_max_by_whole_row(rows, max)
    } else {
        row_max_by_group(rows, max)
    };
    single_pixels(rows[1].len())
        .filter_map(|x| laplacian_at(rows, x))
        .fold(max, |max, v| max.max(v.abs_diff(LAPLACIAN_BIAS)))
}

/// [`row_laplacian_max_u8`] over [`laplacian_quads`]: each group is tested as it comes and
/// a group that fails the test updates the maximum at once.
#[inline(always)]
fn row_max_by_group(rows: [&[u8]; 3], mut max: u32) -> u32 {
    let mut above = AboveMax::new(max);
    for lanes in laplacian_quads(rows) {
        if above.flags(lanes) != 0 {
            max = lanes_max(lanes, max);
            above = AboveMax::new(max);
        }
    }
    max
}

/// [`row_laplacian_max_u8`] over [`laplacian_quads`]: the test's flags are gathered over
/// the whole row without a branch (a loop the compiler vectorizes), and only a row that
/// holds a larger value is gone over again.
#[inline(always)]
fn row_max_by_whole_row(rows: [&[u8]; 3], max: u32) -> u32 {
    if above_max_anywhere(rows, AboveMax::new(max)) {
        laplacian_quads(rows).fold(max, |max, lanes| lanes_max(lanes, max))
    } else {
        max
    }
}

/// The larger of `max` and the largest `|∇²I|` of a group's lanes.
#[inline(always)]
fn lanes_max(lanes: [u32; 2], max: u32) -> u32 {
    lanes
        .into_iter()
        .flat_map(unpack)
        .fold(max, |max, v| max.max(v.abs_diff(LAPLACIAN_BIAS)))
}

simd::kernel! {
    /// Whether a pixel of row `mid` covered by [`laplacian_quads`] has `|∇²I|` above
    /// what `above` tests against.
    #[inline(always)]
    fn above_max_anywhere(rows: [&[u8]; 3], above: AboveMax) -> bool {
        laplacian_quads(rows).fold(0, |flags, lanes| flags | above.flags(lanes)) != 0
    }
}

/// The largest `|∇²I|` over the region (its buffer already checked).
fn laplacian_max_in(buf: &[i32], dims: Dims, laplacian: impl Fn(i32, [i32; 4]) -> u32) -> u32 {
    let mut max = 0;
    for_each_laplacian(buf, dims, laplacian, |_, _, l| max = max.max(l));
    max
}

/// Maps `|∇²I|` to `Sal` in 0..=255 for a given maximum without a per-pixel division.
///
/// The Laplacian (capped at the maximum) is scaled by a power of two that brings the
/// maximum into `2¹⁵..2¹⁶`, so the reciprocal fits in 25 bits and each pixel costs one
/// 32 × 32 → 64-bit multiply (a single instruction on the Cortex-M7).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Normalizer {
    /// The unscaled maximum: larger Laplacians (Reference normalization) are capped to it.
    cap: u32,
    /// Right shift, then left shift, that bring `cap` into `2¹⁵..2¹⁶` (one is zero).
    down: u32,
    up: u32,
    recip: u32,
}

impl Normalizer {
    /// The normalizer for `max` (a `max` of 0 is taken as 1).
    pub(crate) fn new(max: u32) -> Self {
        let cap = max.max(1);
        let bits = 32 - cap.leading_zeros();
        let (down, up) = (bits.saturating_sub(16), 16u32.saturating_sub(bits));
        let m = (cap >> down) << up;
        // m ≥ 2¹⁵ keeps the reciprocal below 2²⁵; +1 makes l = max map to exactly 255 and
        // l ≤ max never beyond it.
        let recip = (((255u64 << 32) / u64::from(m)) + 1) as u32;
        Self {
            cap,
            down,
            up,
            recip,
        }
    }

    /// `Sal` in Q8 (0 ..= 255·256).
    #[inline(always)]
    fn sal_q8(self, lap: u32) -> u32 {
        // l ≤ m < 2¹⁶, so l·2⁸ < 2²⁴ and (l·recip) >> 24 is the high word of l·2⁸·recip:
        // one `UMULL` on the Cortex-M7, no 64-bit shift. With recip < 2²⁵ it is at most
        // 255·2⁸ + m/2²⁴ < 255·2⁸ + 1 (see `new`), so never past 255·2⁸.
        let l = (lap.min(self.cap) >> self.down) << (self.up + 8);
        ((u64::from(l) * u64::from(self.recip)) >> 32) as u32
    }

    /// `S = exp(Sal/255) − 1` in Q24, interpolated between table entries.
    #[inline(always)]
    fn saliency(self, lap: u32) -> u32 {
        let q = self.sal_q8(lap);
        // k = q >> 8 ≤ 255 as `sal_q8` shows (and test `saliency_matches_its_plain_statement`
        // checks against a capped form); the mask only lets the compiler see the index in
        // range, at one instruction where a `min` took four.
        let (k, frac) = (((q >> 8) & 0xff) as usize, q & 0xff);
        let [lo, step] = EXP_STEPS.get(k).copied().unwrap_or_default();
        // The step is below 2²⁴·0.007 and times 255 fits u32.
        lo + ((step * frac + 128) >> 8)
    }
}

/// The normalizing maximum at `level` (1-based) under `norm`.
pub(crate) fn level_max(
    buf: &[i32],
    dims: Dims,
    norm: SaliencyNorm,
    wavelet: Wavelet,
    level: u8,
) -> u32 {
    match norm {
        SaliencyNorm::Local => laplacian_max_in(buf, dims, level_laplacian),
        SaliencyNorm::Reference(r) => {
            let mut m = u64::from(r);
            for _ in 1..level {
                m = (m * ll_gain_q16(wavelet)) >> 16;
            }
            m.min(u64::from(u32::MAX)) as u32
        }
    }
}

/// Sets `out` to the row of `S = exp(Sal/255) − 1` (Q24) of the row `mid` between `up`
/// and `down` (see [`map_neighbourhood`]), normalized by `norm`.
#[inline(always)]
pub(crate) fn saliency_row(norm: Normalizer, rows: [&[i32]; 3], out: &mut [i32]) {
    // S ≤ 1.7183 · 2²⁴ < 2³¹.
    map_neighbourhood(rows, out, |c, around| {
        norm.saliency(level_laplacian(c, around)) as i32
    });
}

/// Entries of a [`LaplacianTable`]: one per biased Laplacian of 8-bit samples
/// ([`LAPLACIAN_BIAS`] ± 1020), rounded up to a power of two so an index is masked, not
/// checked.
pub(crate) const LAPLACIAN_TABLE_LEN: usize = 2048;

/// `S` (Q24) of every Laplacian of an image whose samples are 8-bit values shifted left by
/// `g` guard bits, under one normalizer, indexed by the Laplacian of the 8-bit values
/// themselves, biased ([`crate::packed`]): entry `LAPLACIAN_BIAS ± k` holds `S` of
/// `k·2^g`. A pixel then costs a lookup instead of the normalization and the
/// interpolation of [`Normalizer::saliency`], with the same bits, and needs no absolute
/// value.
#[derive(Clone, Copy)]
pub(crate) struct LaplacianTable<'t> {
    entries: &'t [i32; LAPLACIAN_TABLE_LEN],
}

impl<'t> LaplacianTable<'t> {
    /// Fills `entries` for `norm` and samples with `guard` bits (at most 20, so every
    /// Laplacian fits `u32`).
    pub(crate) fn fill(
        entries: &'t mut [i32; LAPLACIAN_TABLE_LEN],
        norm: Normalizer,
        guard: u32,
    ) -> Self {
        let guard = guard.min(20);
        let bias = LAPLACIAN_BIAS as usize;
        let (below, above) = entries.split_at_mut(bias);
        // Laplacians past the cap all take the cap's saliency: only the entries up to it
        // need the arithmetic.
        let below_cap = ((norm.cap >> guard) as usize).min(above.len() - 1);
        let (computed, capped) = above.split_at_mut(below_cap + 1);
        for (k, e) in computed.iter_mut().enumerate() {
            *e = norm.saliency((k as u32) << guard) as i32;
        }
        let at_cap = norm.saliency(norm.cap) as i32;
        capped.fill(at_cap);
        // Negative Laplacians mirror the positive ones; entry 0 is never read.
        for (e, &mirrored) in below.iter_mut().rev().zip(above.iter().skip(1)) {
            *e = mirrored;
        }
        if let Some(first) = below.first_mut() {
            *first = at_cap;
        }
        Self { entries }
    }

    /// `S` (Q24) of the biased Laplacian `biased` (one of `4..=2044`); any other value
    /// reads some entry (a wrong `S`, never a panic).
    #[inline(always)]
    fn saliency(&self, biased: u32) -> i32 {
        let k = (biased as usize) & (LAPLACIAN_TABLE_LEN - 1);
        self.entries.get(k).copied().unwrap_or_default()
    }
}

/// How [`saliency_row_u8`] turns a biased Laplacian into `S`: by a [`LaplacianTable`], or
/// computed under a normalizer for samples with guard bits (for small images, where
/// filling a table costs more than it saves).
pub(crate) enum ByteSaliency<'t> {
    /// Looked up.
    Table(LaplacianTable<'t>),
    /// Computed, for samples with this many guard bits.
    Computed(Normalizer, u32),
}

/// Sets `out` to the saliencies `S` (Q24) of row `mid` of an image of 8-bit samples, given
/// as `[up, mid, down]` (see [`row_and_neighbours`]), as `how` makes them. Four pixels'
/// Laplacians come from a few word operations ([`crate::packed`]); the same values as
/// [`saliency_row`] of the samples with the guard bits.
#[inline(always)]
pub(crate) fn saliency_row_u8(how: &ByteSaliency<'_>, rows: [&[u8]; 3], out: &mut [i32]) {
    match how {
        ByteSaliency::Table(table) => map_laplacian_row_u8(rows, out, |v| table.saliency(v)),
        &ByteSaliency::Computed(norm, guard) => map_laplacian_row_u8(rows, out, |v| {
            norm.saliency(v.abs_diff(LAPLACIAN_BIAS) << guard.min(20)) as i32
        }),
    }
}

/// Row `mid`'s saliencies by `table` (see [`saliency_row_u8`]) taken straight into a row
/// of window sums of phase 1 (entry 0 pixel 0 alone, entry m ≥ 1 pixels 2m − 1 and 2m:
/// the db2 layout, `crate::fusion::WindowLayout`): set (`set`, the map row's first pixel
/// row; entries no pixel reaches zeroed) or added to. Each group of four pixels of
/// [`laplacian_quads`] (pixels 1 + 4q … 4 + 4q) fills entries 1 + 2q and 2 + 2q, so the
/// saliencies are never stored: the same sums, bit for bit, as [`saliency_row_u8`] into a
/// line and that line taken into the map.
#[inline(always)]
pub(crate) fn saliency_windows_u8(
    table: &LaplacianTable<'_>,
    rows: [&[u8]; 3],
    map_row: &mut [i32],
    set: bool,
) {
    if set {
        saliency_windows_u8_as::<true>(table, rows, map_row);
    } else {
        saliency_windows_u8_as::<false>(table, rows, map_row);
    }
}

/// [`saliency_windows_u8`], setting (`SET`) or adding.
#[inline(always)]
fn saliency_windows_u8_as<const SET: bool>(
    table: &LaplacianTable<'_>,
    rows: [&[u8]; 3],
    map_row: &mut [i32],
) {
    let put = |acc: &mut i32, v: i32| {
        if SET {
            *acc = v;
        } else {
            *acc += v;
        }
    };
    let f = |v: u32| table.saliency(v);
    let w = rows[1].len();
    if let Some(entries) = map_row.get_mut(1..) {
        for (acc, [even, odd]) in entries
            .as_chunks_mut::<2>()
            .0
            .iter_mut()
            .zip(laplacian_quads(rows))
        {
            let ([e0, e1], [o0, o1]) = (unpack(even), unpack(odd));
            // As the line's pixels were taken: the pair's first set or added, its second
            // added.
            let (a, b) = (f(e0), f(e1));
            let (mut v0, mut v1) = (acc[0], acc[1]);
            put(&mut v0, a);
            put(&mut v1, b);
            *acc = [v0 + f(o0), v1 + f(o1)];
        }
    }
    for x in single_pixels(w) {
        if let (Some(acc), Some(v)) = (map_row.get_mut(x.div_ceil(2)), laplacian_at(rows, x)) {
            // Pixel 0 and every odd pixel open their entry; even ones x ≥ 2 close it.
            if x == 0 || x % 2 == 1 {
                put(acc, f(v));
            } else {
                *acc += f(v);
            }
        }
    }
    if SET {
        // Entries past pixel w − 1's (entry ⌈(w − 1)/2⌉).
        if let Some(past) = map_row.get_mut(w.saturating_sub(1).div_ceil(2) + 1..) {
            past.fill(0);
        }
    }
}

/// Sets `out[x] = f(biased Laplacian of pixel x)` for every pixel of row `mid`; nothing
/// past `out`'s end.
#[inline(always)]
fn map_laplacian_row_u8(rows: [&[u8]; 3], out: &mut [i32], f: impl Fn(u32) -> i32) {
    let w = rows[1].len();
    let quads = quad_pixels(w);
    if let Some(grouped) = out.get_mut(quads) {
        for (o, [even, odd]) in grouped
            .as_chunks_mut::<4>()
            .0
            .iter_mut()
            .zip(laplacian_quads(rows))
        {
            let ([e0, e1], [o0, o1]) = (unpack(even), unpack(odd));
            *o = [f(e0), f(o0), f(e1), f(o1)];
        }
    }
    for x in single_pixels(w) {
        if let (Some(o), Some(v)) = (out.get_mut(x), laplacian_at(rows, x)) {
            *o = f(v);
        }
    }
}

/// `W₁ = S₁ / (S₁ + S₂)` as Q15 (`1.0` = 32768), rounded to nearest, `½` when both are
/// zero.
///
/// ```
/// use rollfuse_core::saliency::weight;
///
/// assert_eq!(weight(3, 1).to_num::<f32>(), 0.75);
/// assert_eq!(weight(0, 0).to_num::<f32>(), 0.5);
/// // Sums past 32 bits keep their ratio.
/// assert_eq!(weight(u32::MAX, u32::MAX).to_num::<f32>(), 0.5);
/// ```
///
/// Both sums are first halved together until they add up to at most 2¹⁷ (keeping their
/// ratio to 17 bits). The division then runs in 32 bits: a 64-bit one is a library call of
/// some hundred instructions on the Cortex-M7, once per window.
pub fn weight(s1: u32, s2: u32) -> U1F15 {
    // The fusion's window sums stay below 2²⁸ (four saliencies of at most 1.72·2²⁴): their
    // sum fits in 32 bits and takes the short path; other callers whose sum does not
    // take the general one. Both halve the fewest times that bring the sum to 2¹⁷.
    let (a, b) = match s1.overflowing_add(s2) {
        (total, false) => halve_to_17_bits(s1, s2, total),
        (_, true) => halve_large(s1, s2),
    };
    let t = a + b;
    if t == 0 {
        return U1F15::from_bits(1 << 14);
    }
    // (a·2¹⁵ + t/2) / t: in one 32-bit division while a·2¹⁵ + t/2 < 2³² (a < 2¹⁷ − 3, as
    // t ≤ 2¹⁷); otherwise in two ([`divide_large`]).
    let w = if a < (1 << 17) - 3 {
        ((a << 15) + t / 2) / t
    } else {
        divide_large(a, t)
    };
    // a ≤ t, so w ≤ (t·2¹⁵ + t/2) / t < 2¹⁵ + 1: at most 2¹⁵, no clamp needed.
    debug_assert!(w <= 1 << 15);
    U1F15::from_bits(w as u16)
}

/// [`weight`]'s halving of sums whose total overflows 32 bits: at least the halvings that
/// bring their total below 2³¹, then as for small sums.
#[cold]
#[inline(never)]
fn halve_large(s1: u32, s2: u32) -> (u32, u32) {
    let total = u64::from(s1) + u64::from(s2);
    let skip = (64 - total.leading_zeros()).saturating_sub(31);
    let (a, b) = (s1 >> skip, s2 >> skip);
    halve_to_17_bits(a, b, a + b)
}

/// `(a·2¹⁵ + t/2) / t` for `2¹⁷ − 3 ≤ a ≤ t ≤ 2¹⁷`, as `q₁·2⁷ + (r₁·2⁷ + t/2) / t` with
/// `q₁, r₁ = divmod(a·2⁸, t)`: `a ≤ 2¹⁷` keeps `a·2⁸` and `r₁·2⁷` within 32 bits.
#[cold]
#[inline(never)]
fn divide_large(a: u32, t: u32) -> u32 {
    let (q1, r1) = ((a << 8) / t, (a << 8) % t);
    (q1 << 7) + ((r1 << 7) + t / 2) / t
}

/// Halves `a` and `b` (whose sum is `total`) together, the fewest times that bring their
/// sum to 2¹⁷ or below.
#[inline(always)]
fn halve_to_17_bits(a: u32, b: u32, total: u32) -> (u32, u32) {
    // The halvings that bring `total` below 2¹⁸ (its bit length less 18, none below
    // 2¹⁸: the bit 2¹⁷ or'ed in makes that length at least 18 with no select), then one
    // more if the halved sum is still above 2¹⁷ (once is enough: it is below 2¹⁸, and
    // halving each part halves the sum at least).
    let skip = 14 - (total | 1 << 17).leading_zeros();
    let (a, b) = (a >> skip, b >> skip);
    if a + b > 1 << 17 {
        (a >> 1, b >> 1)
    } else {
        (a, b)
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::{vec, vec::Vec};

    /// Every entry of a Laplacian table that a Laplacian of 8-bit samples reads is the
    /// saliency of that Laplacian (with the guard bits), for maxima from below one 8-bit
    /// step to past the largest 8-bit Laplacian, and 0 to 3 guard bits.
    #[test]
    fn laplacian_table_entries_are_the_saliencies_of_their_laplacians() {
        let mut entries = [0; LAPLACIAN_TABLE_LEN];
        for guard in 0..=3 {
            for max in [1, 7, 8, 9, 100, 1020 << guard, (1020 << guard) + 5, 1 << 27] {
                let norm = Normalizer::new(max);
                let table = LaplacianTable::fill(&mut entries, norm, guard);
                for lap in -1020i32..=1020 {
                    let scaled = lap.unsigned_abs() << guard;
                    assert_eq!(
                        table.saliency((LAPLACIAN_BIAS as i32 + lap) as u32),
                        norm.saliency(scaled) as i32,
                        "guard {guard}, max {max}, ∇²I {lap}"
                    );
                }
            }
        }
    }

    /// The 8-bit rows' saliencies, by table and computed, are those of the samples with
    /// the guard bits; and the 8-bit maximum is the plain one (by either way of testing
    /// groups of four), on images of every width
    /// up to 21 (groups of four and single pixels) with extreme and mixed samples.
    #[test]
    fn byte_rows_match_the_rows_with_guard_bits() {
        let mut entries = [0; LAPLACIAN_TABLE_LEN];
        let mut next = crate::test_bytes(99);
        for w in 1..=21 {
            for h in [1, 2, 5] {
                let bytes: Vec<u8> = (0..w * h)
                    .map(|i| {
                        let random = next();
                        match i % 5 {
                            0 => 255,
                            1 => 0,
                            _ => random,
                        }
                    })
                    .collect();
                let wide: Vec<i32> = bytes.iter().map(|&v| i32::from(v) << 3).collect();
                let dims = Dims::new(w, h).unwrap();
                let max = laplacian_max(&wide, dims).unwrap();
                assert_eq!(laplacian_max_u8(&bytes, dims) << 3, max, "{w}×{h}");
                let norm = Normalizer::new(max.max(1) * 3 / 4);
                let table = LaplacianTable::fill(&mut entries, norm, 3);
                for y in 0..h {
                    let (u, m, d) = row_and_neighbours(&bytes, dims, y).unwrap();
                    // Both ways of testing groups against a maximum so far agree with
                    // the plain maximum over the groups, from any maximum so far.
                    let groups_max = quad_pixels(w)
                        .filter_map(|x| laplacian_at([u, m, d], x))
                        .map(|v| v.abs_diff(LAPLACIAN_BIAS))
                        .max()
                        .unwrap_or(0);
                    for start in [0, 1, groups_max.saturating_sub(1), groups_max, 1020] {
                        let want = start.max(groups_max);
                        let what = std::format!("{w}×{h} row {y} from {start}");
                        assert_eq!(row_max_by_group([u, m, d], start), want, "{what}");
                        assert_eq!(row_max_by_whole_row([u, m, d], start), want, "{what}");
                    }
                    let (wu, wm, wd) = row_and_neighbours(&wide, dims, y).unwrap();
                    let mut want = vec![0; w];
                    saliency_row(norm, [wu, wm, wd], &mut want);
                    for how in [ByteSaliency::Table(table), ByteSaliency::Computed(norm, 3)] {
                        let mut got = vec![-1; w];
                        saliency_row_u8(&how, [u, m, d], &mut got);
                        assert_eq!(got, want, "{w}×{h} row {y}");
                    }
                }
            }
        }
    }

    /// The column walk's maximum (the Cortex-M7's) is the row walk's (the x86-64 host's)
    /// and the plain one, on random, flat, extreme and checkered images of every width up
    /// to 40 and of the camera's widths (whose walks have the width built in), 1 to 7
    /// rows and more; and from random images whose maximum grows often along the walk.
    #[test]
    fn column_walk_finds_the_row_walks_maximum() {
        let mut next = crate::test_bytes(12_345);
        let widths = (1..=40).chain([79, 80, 81, 159, 160, 161, 320]);
        for w in widths {
            for h in [1, 2, 3, 4, 5, 7, 16] {
                for pattern in 0..7 {
                    let bytes: Vec<u8> = (0..w * h)
                        .map(|i| {
                            let (x, y) = (i % w, i / w);
                            match pattern {
                                0 => 0,
                                1 => 255,
                                2 => [0, 255][(x + y) % 2],
                                3 => [0, 255][(x / 2 + y) % 2],
                                4 => [255, 0][x % 2],
                                // Growing noise: the maximum rises row after row.
                                5 => ((u32::from(next()) * (y as u32 + 1)) / h as u32) as u8,
                                _ => next(),
                            }
                        })
                        .collect();
                    let dims = Dims::new(w, h).unwrap();
                    let wide: Vec<i32> = bytes.iter().map(|&v| i32::from(v)).collect();
                    let plain = laplacian_max(&wide, dims).unwrap();
                    let what = std::format!("{w}×{h} pattern {pattern}");
                    assert_eq!(laplacian_max_u8_by_rows(&bytes, dims), plain, "{what}");
                    assert_eq!(laplacian_max_u8_by_columns(&bytes, dims), plain, "{what}");
                    assert_eq!(laplacian_max_u8(&bytes, dims), plain, "{what}");
                }
            }
        }
        // Past the region's end the buffer is not read; a short buffer gives 0.
        let dims = Dims::new(8, 3).unwrap();
        let mut bytes = std::vec![7u8; 24];
        bytes.extend([0, 255, 0, 255]);
        assert_eq!(laplacian_max_u8(&bytes, dims), 0);
        assert_eq!(laplacian_max_u8(&bytes[..23], dims), 0);
    }

    #[test]
    fn exp_table_matches_libm_to_half_a_step() {
        for (k, v) in EXP_TABLE.iter().enumerate() {
            let exact = libm::exp(k as f64 / 255.0) - 1.0;
            let got = v.to_num::<f64>();
            assert!(
                (got - exact).abs() <= 0.5 / 16384.0 + 1e-12,
                "k={k}: {got} vs {exact}"
            );
        }
        assert_eq!(EXP_TABLE[0], U8F24::ZERO);
    }

    /// The plain statement of [`weight`]: halve until the sum is at most 2¹⁷, then one
    /// 64-bit division.
    fn weight_by_u64_division(s1: u32, s2: u32) -> u16 {
        let (mut a, mut b) = (u64::from(s1), u64::from(s2));
        if a + b == 0 {
            return 1 << 14;
        }
        while a + b > (1 << 17) {
            a >>= 1;
            b >>= 1;
        }
        (((a << 15) + (a + b) / 2) / (a + b)).min(1 << 15) as u16
    }

    /// [`weight`] as it was before its halving took the bit length with no select, its
    /// rare paths went out of line, its clamp went and its short path came to take every
    /// sum that fits 32 bits: the reference for bit identity.
    fn weight_before(s1: u32, s2: u32) -> u16 {
        fn halve(a: u32, b: u32, total: u32) -> (u32, u32) {
            let skip = (32 - total.leading_zeros()).saturating_sub(18);
            let (a, b) = (a >> skip, b >> skip);
            if a + b > 1 << 17 {
                (a >> 1, b >> 1)
            } else {
                (a, b)
            }
        }
        let (a, b) = if (s1 | s2) < 1 << 30 {
            halve(s1, s2, s1 + s2)
        } else {
            let total = u64::from(s1) + u64::from(s2);
            let skip = (64 - total.leading_zeros()).saturating_sub(31);
            let (a, b) = (s1 >> skip, s2 >> skip);
            halve(a, b, a + b)
        };
        let t = a + b;
        if t == 0 {
            return 1 << 14;
        }
        let w = if a < (1 << 17) - 3 {
            ((a << 15) + t / 2) / t
        } else {
            let (q1, r1) = ((a << 8) / t, (a << 8) % t);
            (q1 << 7) + ((r1 << 7) + t / 2) / t
        };
        w.min(1 << 15) as u16
    }

    /// [`weight`] gives the bits of its former formulation: every pair of small sums, the
    /// edges of every halving step and of both fast paths both ways round, all-zero and
    /// all-maximal sums, and a million pseudo-random pairs over the whole range and over
    /// the fusion's (below 2²⁸).
    #[test]
    fn weight_matches_its_former_formulation() {
        let check = |a: u32, b: u32| {
            assert_eq!(weight(a, b).to_bits(), weight_before(a, b), "{a} {b}");
        };
        for a in 0..300 {
            for b in 0..300 {
                check(a, b);
            }
        }
        let mut edges = std::vec::Vec::new();
        for k in 0..32 {
            for d in 0..6u32 {
                edges.push((1u32 << k).wrapping_sub(d));
                edges.push((1u32 << k).wrapping_add(d));
                edges.push(((1u64 << (k + 1)) - 1) as u32);
            }
        }
        edges.extend([
            0,
            1,
            2,
            3,
            255,
            1 << 28,
            (1 << 28) - 1,
            u32::MAX,
            u32::MAX - 1,
        ]);
        for &a in &edges {
            for &b in &edges {
                check(a, b);
            }
        }
        let mut x = 0x9e37_79b9u32;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            x
        };
        for _ in 0..1_000_000 {
            let (a, b) = (next(), next());
            check(a, b);
            check(a >> (b % 32), b >> (a % 32));
            check(a >> 4, b >> 4);
            // Nearly equal and far apart, as flat and edge windows give.
            check(a >> 4, (a >> 4) + (b % 64));
            check(a >> 4, b >> 24);
        }
    }

    #[test]
    fn weight_matches_the_plain_64_bit_division() {
        // Edges of every scaling step, and a deterministic spread of the whole range.
        let mut values = [0u32; 96];
        for (k, v) in values.iter_mut().enumerate().take(64) {
            *v = (1u64 << (k / 2)).saturating_sub((k % 2) as u64) as u32;
        }
        let mut x = 0x2545_f491u32;
        for v in values.iter_mut().skip(64) {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            *v = x >> (x % 32);
        }
        values[95] = u32::MAX;
        // Around the one-division bound (a < 2¹⁷ − 3 after halving) and the short path's
        // (both below 2³⁰), unhalved and halved.
        let edges = (0..8u32).flat_map(|d| {
            [
                (1 << 17) - d,
                (1 << 18) - 2 * d,
                (1 << 30) - d,
                (1 << 31) - d,
            ]
        });
        for a in edges.clone() {
            for b in edges.clone().chain([0, 1, 2, 3, 4, 5, 1 << 29]) {
                assert_eq!(
                    weight(a, b).to_bits(),
                    weight_by_u64_division(a, b),
                    "{a} {b}"
                );
                assert_eq!(
                    weight(b, a).to_bits(),
                    weight_by_u64_division(b, a),
                    "{b} {a}"
                );
            }
        }
        for &a in &values {
            for &b in &values {
                assert_eq!(
                    weight(a, b).to_bits(),
                    weight_by_u64_division(a, b),
                    "{a} {b}"
                );
            }
        }
    }

    #[test]
    fn weights_are_half_for_flat_and_complementary_otherwise() {
        assert_eq!(weight(0, 0).to_bits(), 16384);
        assert_eq!(weight(5, 0).to_bits(), 32768);
        assert_eq!(weight(0, 9).to_bits(), 0);
        assert_eq!(weight(1000, 3000).to_bits(), 8192);
        assert_eq!(weight(u32::MAX, u32::MAX).to_bits(), 16384);
    }

    #[test]
    fn normalizer_maps_max_to_255_and_never_beyond() {
        for max in [1u32, 2, 3, 255, 1000, 65_535, 65_536, 1 << 27, u32::MAX] {
            let n = Normalizer::new(max);
            assert_eq!(n.sal_q8(max) >> 8, 255, "max {max}");
            assert_eq!(n.sal_q8(0), 0);
            if max >= 1000 {
                let half = n.sal_q8(max / 2) >> 8;
                assert!((126..=128).contains(&half), "max {max}: {half}");
            }
            assert_eq!(n.sal_q8(u32::MAX), 255 << 8);
            assert_eq!(n.saliency(u32::MAX), EXP_TABLE[255].to_bits());
        }
    }

    /// The plain statement of [`Normalizer::saliency`]: `Sal` by a 64-bit product shifted
    /// down, capped at 255, then the table read at `k` and `k + 1`.
    fn saliency_plain(n: Normalizer, lap: u32) -> u32 {
        let l = (lap.min(n.cap) >> n.down) << n.up;
        let q = (((u64::from(l) * u64::from(n.recip)) >> 24) as u32).min(255 << 8);
        let k = (q >> 8) as usize;
        let lo = EXP_TABLE[k].to_bits();
        let hi = EXP_TABLE[(k + 1).min(255)].to_bits();
        lo + (((hi - lo) * (q & 0xff) + 128) >> 8)
    }

    #[test]
    fn saliency_matches_its_plain_statement() {
        for max in [
            1u32,
            2,
            3,
            255,
            1000,
            16_320,
            65_535,
            65_536,
            121_813,
            1 << 27,
            u32::MAX,
        ] {
            let n = Normalizer::new(max);
            // Every Laplacian up to 2¹⁷ past the maximum (the reference normalization's
            // larger ones are capped), then a spread of the rest.
            let dense = 0..=max.saturating_add(1 << 17).min(1 << 20);
            let spread = (0..64).map(|k| u32::MAX >> (k % 32));
            for lap in dense.chain(spread) {
                assert_eq!(
                    n.saliency(lap),
                    saliency_plain(n, lap),
                    "max {max}, lap {lap}"
                );
            }
        }
    }

    #[test]
    fn flat_image_has_zero_laplacian() {
        let dims = Dims::new(5, 3).unwrap();
        assert_eq!(laplacian_max(&[77; 15], dims), Ok(0));
        assert!(laplacian_max(&[77; 14], dims).is_err());
        let mut impulse = [0i32; 15];
        impulse[7] = 10;
        assert_eq!(laplacian_max(&impulse, dims), Ok(40));
    }
}
