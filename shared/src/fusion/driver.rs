//! The fuse step's driver, shared by the integer and float paths: saliency maps, the
//! level-by-level transform and weighting of both images, and the inverse.

use core::ops::RangeInclusive;

use super::config::{Ablation, FuseConfig, LlWeight};
use crate::lifting::{self, Coefficients, LevelBounds, Lift, Saturation};
use crate::saliency::{LAPLACIAN_TABLE_LEN, SaliencyNorm, row_and_neighbours};
use crate::{Dims, Error, MAX_LEVELS, Wavelet, simd};

/// Where each high band's coefficients take their saliency, on one map per image.
///
/// A coefficient of a band takes its weight from the 2×2 window of the level's input under
/// the two middle taps of its filter along each axis. The S-transform centres them on
/// `{2i, 2i + 1}`; the db2 lifting's low band sits one pixel later and its high band one
/// pixel earlier, so its HL coefficient `(i, j)` reads `x ∈ {2i − 1, 2i}`,
/// `y ∈ {2j + 1, 2j + 2}`, and likewise for LH and HH. Every one of those windows starts at
/// an even (Haar) or an odd (db2) pixel, so one map of 2×2 window sums per image serves all
/// three bands: map entry `(m, n)` sums `x ∈ {2m − phase, 2m − phase + 1}` by
/// `y ∈ {2n − phase, 2n − phase + 1}` (pixels outside the image count for nothing, and
/// both images sum the same pixels), and coefficient `(i, j)` of band `k` reads entry
/// `(i + shifts[k].0, j + shifts[k].1)`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct WindowLayout {
    /// 0: windows start at even pixels; 1: at odd ones.
    pub phase: usize,
    /// Map entry of coefficient `(0, 0)` of HL, LH and HH.
    pub shifts: [(usize, usize); 3],
}

impl WindowLayout {
    /// The layout of the lifting of `wavelet` (both fusion paths run the same lifting).
    pub fn of(wavelet: Wavelet) -> Self {
        match wavelet {
            Wavelet::Haar => Self {
                phase: 0,
                shifts: [(0, 0); 3],
            },
            // HL: x ∈ {2i − 1, 2i}, y ∈ {2j + 1, 2j + 2}; LH the other way round; HH both
            // one pixel earlier.
            Wavelet::Db2 => Self {
                phase: 1,
                shifts: [(0, 1), (1, 0), (0, 0)],
            },
        }
    }

    /// Map width and height for a level input of `dims`.
    pub fn map_dims(self, dims: Dims) -> (usize, usize) {
        (
            dims.width().div_ceil(2) + self.phase,
            dims.height().div_ceil(2) + self.phase,
        )
    }
}

/// The numeric operations a fusion path supplies: coefficients, saliency sums and weights
/// all live in `Self` (i32 on the integer path, f32 on the float path). Both transforms
/// are the lifting's own, generic over [`Lift`]; the inverse's saturation differs by path.
pub(crate) trait Arith: Lift + Send + Sync + core::ops::AddAssign {
    /// The bounds the inverse of a `levels`-deep transform saturates each level to.
    fn inverse_bounds(wavelet: Wavelet, levels: u8) -> [LevelBounds; MAX_LEVELS as usize];
    /// The inverse levels `levels` (deepest first) of a fused transform whose level
    /// `levels.start()` has the input region `dims` in `buf`; `prepare(level, y, row y)`
    /// runs on each row of each level's region before that level reads it. With `out` the
    /// result goes there as bytes ([`Lift::to_byte`]) instead of into `buf`.
    fn inverse(
        wavelet: Wavelet,
        (buf, dims): (&mut [Self], Dims),
        levels: RangeInclusive<u8>,
        scratch: &mut [Self],
        prepare: &mut impl FnMut(u8, usize, &mut [Self]),
        out: Option<lifting::ByteRows<'_>>,
    ) {
        let bounds = Self::inverse_bounds(wavelet, *levels.end());
        // Fused coefficients are convex combinations of forward-transform outputs of the
        // same band (weights and the LL mix lie in 0..=1), so within its bound.
        let saturation = Saturation {
            bounds: &bounds,
            coefficients: Coefficients::InBounds,
        };
        let hooks = lifting::RowHooks { prepare, out };
        lifting::inverse_levels_into(wavelet, buf, dims, levels, scratch, saturation, hooks);
    }
    /// What [`Arith::saliency_row`] normalizes the Laplacian by.
    type SaliencyScale: Copy + PartialEq + Send + Sync;
    /// The normalization of the saliency of the level input `buf` on `dims`, or `None` for
    /// a flat region (whose `S` is 0 everywhere). `known_max`, where given, is the level
    /// input's largest `|∇²I|` under [`SaliencyNorm::Local`], found by
    /// [`Arith::check_and_max`]: no scan for it then.
    fn saliency_scale(
        buf: &[Self],
        dims: Dims,
        norm: SaliencyNorm,
        wavelet: Wavelet,
        level: u8,
        known_max: Option<Self>,
    ) -> Option<Self::SaliencyScale>;
    /// Sets `out` to the saliencies `S = exp(Sal/255) − 1` of the row `mid` of a level
    /// input, given as `[up, mid, down]` with its (mirrored) neighbours.
    fn saliency_row(scale: Self::SaliencyScale, rows: [&[Self]; 3], out: &mut [Self]);
    /// `W₁` from the two saliency sums.
    fn weight(s1: Self, s2: Self) -> Self;
    /// `W₁·h1 + (1 − W₁)·h2`.
    fn blend(h1: Self, h2: Self, w1: Self) -> Self;
    /// `(1 − w)·a + w·b`.
    fn mix(a: Self, b: Self, w: LlWeight) -> Self;
    /// `|a| ≥ |b|`.
    fn abs_ge(a: Self, b: Self) -> bool;
    /// Refuses samples this path cannot take (out of the proven range, or not finite).
    fn check_samples(buf: &[Self], dims: Dims) -> Result<(), Error>;
    /// [`Arith::check_samples`], and with `local_max` the image's largest `|∇²I|` (what
    /// [`SaliencyNorm::Local`] normalizes level 1 by) where this path finds it in the same
    /// pass over the image; `None` leaves that scan to [`Arith::saliency_rows`].
    fn check_and_max(buf: &[Self], dims: Dims, local_max: bool) -> Result<Option<Self>, Error> {
        let _ = local_max;
        Self::check_samples(buf, dims).map(|()| None)
    }
}

/// Runs the two independent halves of a fuse step level (each image's saliency and
/// forward transform): one after the other, or at once where there are threads (the host
/// passes `rayon::join`). Either way the result is the same, to the bit.
pub trait Join {
    /// Runs `a` and `b`, in any order or at once, and returns when both are done.
    fn join(&self, a: impl FnOnce() + Send, b: impl FnOnce() + Send);
}

/// [`Join`] on one thread: `a`, then `b`.
#[derive(Debug, Clone, Copy, Default)]
pub struct Sequential;

impl Join for Sequential {
    fn join(&self, a: impl FnOnce() + Send, b: impl FnOnce() + Send) {
        a();
        b();
    }
}

/// The two images of a fuse step on one region: the fused image replaces `a`, `b` is
/// consumed.
pub(crate) struct ImagePair<'i, T> {
    /// The first image (in cyclic use, the running result).
    pub a: &'i mut [T],
    /// The second image.
    pub b: &'i mut [T],
    /// The region both hold.
    pub dims: Dims,
}

/// The 8-bit images behind a fuse step's buffers (with their regions), where the step
/// reads level 1's rows from them and writes its result back to `a` as bytes
/// ([`Lift::from_guarded_byte`], [`Lift::to_byte`]): no widened copy of either image and
/// no rounding pass after.
pub(crate) struct ByteImages<'i> {
    /// Image A's bytes: read by the forward transform, overwritten by the result.
    pub a: &'i mut [u8],
    /// Where image A lies in `a`.
    pub a_dims: Dims,
    /// Image B's bytes.
    pub b: &'i [u8],
    /// Where image B lies in `b`.
    pub b_dims: Dims,
}

/// Where a fuse step starts ([`fuse_generic`]): at level 1 on the images themselves
/// (with their level-1 `|∇²I|` maxima where the checks found them, and the 8-bit images
/// to read, where given), or at a deeper level on the LL bands of a level fused
/// elsewhere (`lanes`).
pub(crate) struct StepStart<'i, T> {
    /// The level whose input the step's images are.
    pub level: u8,
    /// The images' level-1 `|∇²I|` maxima (level 1 only).
    pub maxima: [Option<T>; 2],
    /// The 8-bit images behind the buffers (level 1 only).
    pub bytes: Option<ByteImages<'i>>,
}

impl<'i, T> StepStart<'i, T> {
    /// Level 1, with what the checks found and the bytes to read, if any.
    pub fn level_one(maxima: [Option<T>; 2], bytes: Option<ByteImages<'i>>) -> Self {
        Self {
            level: 1,
            maxima,
            bytes,
        }
    }

    /// Level `level`'s input: LL bands, no bytes.
    pub fn deeper(level: u8) -> Self {
        Self {
            level,
            maxima: [None, None],
            bytes: None,
        }
    }
}

/// What a fuse step's caller knows of its samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Samples {
    /// Anything: every sample is checked before either image is touched.
    Unchecked,
    /// Converted from bytes (0–255): in range by construction, so not checked again (the
    /// level-1 maxima, where needed, found without the check by the saliency scale).
    FromBytes,
}

/// The checks and the call shared by both paths' public `fuse_pair`, with the scratch laid
/// out as `layout` says.
pub(crate) fn fuse_pair_checked<T: Arith>(
    images: ImagePair<'_, T>,
    cfg: &FuseConfig,
    ll_weight: LlWeight,
    scratch: &mut [T],
    (layout, samples): (ScratchLayout, Samples),
    join: &impl Join,
) -> Result<(), Error> {
    let ImagePair { a, b, dims } = images;
    dims.check_buffer("first image", a.len())?;
    dims.check_buffer("second image", b.len())?;
    dims.check_levels(cfg.levels)?;
    if ll_weight.0 > 1 << 15 {
        return Err(Error::InvalidParameter { name: "ll_weight" });
    }
    let (work, _) = split_scratch(scratch, crate::lifting::scratch_len(dims), layout, dims)?;
    // Both images are checked before either is touched; the level-1 maxima come along.
    let local_max = cfg.norm == SaliencyNorm::Local && cfg.ablation.uses_saliency();
    // Images of bytes: no check, and the level-1 maxima are left to the saliency scale.
    let (max_a, max_b) = if samples == Samples::Unchecked {
        (
            T::check_and_max(a, dims, local_max)?,
            T::check_and_max(b, dims, local_max)?,
        )
    } else {
        (None, None)
    };
    let images = ImagePair { a, b, dims };
    let start = StepStart::level_one([max_a, max_b], None);
    fuse_generic(images, cfg, ll_weight, work, start, join)
}

/// Scratch a fuse step needs besides its transform line: one window map per image, each
/// at most `(⌈w/2⌉ + 1) × (⌈h/2⌉ + 1)` (see [`WindowLayout`]).
pub(crate) const fn maps_len(width: usize, height: usize) -> usize {
    2 * (width.div_ceil(2) + 1) * (height.div_ceil(2) + 1)
}

/// How a fuse step's scratch is laid out ([`split_scratch`]): after the transform line,
/// which it always holds, and the window maps, which it holds after the lines.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ScratchLayout {
    /// A second transform line, so `join` can work on both images at once.
    pub second_line: bool,
    /// The saliency rings ([`Lines::rings`]).
    pub rings: bool,
    /// Space for [`fuse_u8`]'s saliency table ([`TABLE_WORDS`]), after the rest.
    pub table: bool,
}

/// Work areas of one fuse step, split from the caller's scratch.
pub(crate) struct Work<'s, T> {
    /// The transforms' rows.
    pub lines: Lines<'s, T>,
    /// The window maps.
    pub maps: Maps<'s, T>,
}

/// The rows of scratch a fuse step's transforms work in.
pub(crate) struct Lines<'s, T> {
    /// The transform line (image A's, and B's too when there is no second).
    pub line: &'s mut [T],
    /// A second line, so both images can be worked on at once.
    pub line_b: Option<&'s mut [T]>,
    /// Two rows per image (A's, then B's), where the step has them: each image's
    /// saliency is then taken in its forward transform's sweep ([`saliency_and_forward`]).
    pub rings: Option<&'s mut [T]>,
}

/// The scratch of a fuse step's window maps.
pub(crate) struct Maps<'s, T> {
    /// Two window maps: image A's, then image B's.
    pub space: &'s mut [T],
    /// Whether level 1's two window maps are already in `space` (taken from the images'
    /// 8-bit samples by [`fuse_u8`]): level 1 then runs its transforms alone.
    pub first_ready: bool,
}

/// Scratch for [`fuse_u8`]'s saliency table ([`crate::saliency::LaplacianTable`]).
pub(crate) const TABLE_WORDS: usize = LAPLACIAN_TABLE_LEN;

/// Scratch for the saliency rings of [`Lines::rings`]: two rows per image.
pub(crate) fn rings_len(dims: Dims) -> usize {
    4 * dims.width()
}

/// Splits the caller's scratch as `layout` says: transform lines of `line` elements, the
/// maps and the saliency rings; and the space for a saliency table, returned beside (empty
/// without).
pub(crate) fn split_scratch<T>(
    scratch: &mut [T],
    line: usize,
    layout: ScratchLayout,
    dims: Dims,
) -> Result<(Work<'_, T>, &mut [T]), Error> {
    let lines = 1 + usize::from(layout.second_line);
    let maps = maps_len(dims.width(), dims.height());
    let ring = if layout.rings { rings_len(dims) } else { 0 };
    let table = if layout.table { TABLE_WORDS } else { 0 };
    let needed = lines * line + maps + ring + table;
    let too_small = Error::BufferTooSmall {
        which: "scratch",
        needed,
        got: scratch.len(),
    };
    if scratch.len() < needed {
        return Err(too_small);
    }
    let (first, rest) = scratch.split_at_mut_checked(line).ok_or(too_small)?;
    let (line_b, rest) = if layout.second_line {
        let (b, rest) = rest.split_at_mut_checked(line).ok_or(too_small)?;
        (Some(b), rest)
    } else {
        (None, rest)
    };
    let (maps, rest) = rest.split_at_mut_checked(maps).ok_or(too_small)?;
    let (ring_part, rest) = rest.split_at_mut_checked(ring).ok_or(too_small)?;
    let table_part = rest.get_mut(..table).ok_or(too_small)?;
    let work = Work {
        lines: Lines {
            line: first,
            line_b,
            rings: layout.rings.then_some(ring_part),
        },
        maps: Maps {
            space: maps,
            first_ready: false,
        },
    };
    Ok((work, table_part))
}

/// What too short a `maps` scratch (of `got` elements) reports for a level input of `dims`.
pub(super) fn maps_too_small(layout: WindowLayout, dims: Dims, got: usize) -> Error {
    let (mw, mh) = layout.map_dims(dims);
    Error::BufferTooSmall {
        which: "scratch",
        needed: 2 * mw * mh,
        got,
    }
}

/// The two window maps (image A's, image B's) of a level input of `dims`, from the front
/// of `maps`.
pub(super) fn split_maps<T>(
    maps: &mut [T],
    layout: WindowLayout,
    dims: Dims,
) -> Result<[&mut [T]; 2], Error> {
    let (mw, mh) = layout.map_dims(dims);
    let too_small = maps_too_small(layout, dims, maps.len());
    let (map_a, rest) = maps.split_at_mut_checked(mw * mh).ok_or(too_small)?;
    let map_b = rest.get_mut(..mw * mh).ok_or(too_small)?;
    Ok([map_a, map_b])
}

/// A level's map of 2×2 window sums of saliency ([`WindowLayout`]), filled from the level
/// input's rows of saliency, taken in order.
pub(super) struct WindowMap<'m, T> {
    /// `layout.map_dims(dims)`, row-major.
    map: &'m mut [T],
    layout: WindowLayout,
    /// Map width.
    width: usize,
    /// Whether any row was taken.
    taken: bool,
}

impl<'m, T: Arith> WindowMap<'m, T> {
    pub(super) fn new(map: &'m mut [T], layout: WindowLayout, dims: Dims) -> Self {
        Self {
            map,
            layout,
            width: layout.map_dims(dims).0,
            taken: false,
        }
    }

    /// Hands `fill` the map row that pixel row `y` goes into, and whether `y` is its first
    /// pixel row (then `fill` sets the row's sums, else adds to them), as [`Self::take`]
    /// does with a row of saliency; nothing if the map is too short.
    #[inline(always)]
    pub(super) fn take_with(&mut self, y: usize, fill: impl FnOnce(&mut [T], bool)) {
        self.taken = true;
        let phase = self.layout.phase;
        let m = (y + phase) / 2;
        let first = y == 0 || (y + phase).is_multiple_of(2);
        if let Some(map_row) = self.map.get_mut(m * self.width..(m + 1) * self.width) {
            fill(map_row, first);
        }
    }

    /// Takes in row `y` of saliency. Each map row is set by its first pixel row and added
    /// to by its second, so the map is not cleared first (a pass over it).
    #[inline(always)]
    pub(super) fn take(&mut self, y: usize, srow: &[T]) {
        self.taken = true;
        let phase = self.layout.phase;
        let m = (y + phase) / 2;
        // A map row's first pixel row: 2m − phase, or row 0 alone for phase 1.
        let first = y == 0 || (y + phase).is_multiple_of(2);
        // A short `map` just loses the row.
        let Some(map_row) = self.map.get_mut(m * self.width..(m + 1) * self.width) else {
            return;
        };
        if first {
            window_row::<T, true>(map_row, srow, phase);
        } else {
            window_row::<T, false>(map_row, srow, phase);
        }
    }

    /// Zeroes what no pixel row reached: the whole map of a flat level input (it has no
    /// saliency rows), the last row for phase 1 with an odd height.
    pub(super) fn finish(self, dims: Dims) {
        let (mw, mh) = self.layout.map_dims(dims);
        let reached = if self.taken {
            (dims.height() + self.layout.phase).div_ceil(2).min(mh) * mw
        } else {
            0
        };
        if let Some(rest) = self.map.get_mut(reached..mh * mw) {
            rest.fill(T::default());
        }
    }
}

simd::kernel! {
    /// Takes row `y` of a level input's saliency into `map`, computed into `row` from the
    /// input's rows `[up, mid, down]`.
    #[inline(always)]
    fn saliency_map_row<T: Arith>(
        scale: T::SaliencyScale,
        rows: [&[T]; 3],
        y: usize,
        map: &mut WindowMap<'_, T>,
        row: &mut [T],
    ) {
        // `row` may be longer than the level input's rows (a line of the level above).
        if let Some(row) = row.get_mut(..rows[1].len()) {
            T::saliency_row(scale, rows, row);
            map.take(y, row);
        }
    }
}

/// Hands each row of a region, met in order, to a callback with its neighbours (`[up, row,
/// down]`, mirrored at the ends as [`row_and_neighbours`] does), one row late: row `k − 1`
/// once row `k` is met, the last when [`LaggedRows::finish`] is called. It keeps copies
/// of the last two rows met, so the region may change under it (a transform sweep lifts
/// each row it has shown).
pub(super) struct LaggedRows<'r, T> {
    /// The last row met with an even index, and with an odd one.
    even: &'r mut [T],
    odd: &'r mut [T],
    /// Rows met so far.
    met: usize,
}

impl<'r, T: Copy> LaggedRows<'r, T> {
    /// On `ring`, two rows of `width`; `None` if it is shorter.
    fn new(ring: &'r mut [T], width: usize) -> Option<Self> {
        let (even, odd) = ring.get_mut(..2 * width)?.split_at_mut(width);
        Some(Self { even, odd, met: 0 })
    }

    /// Meets the next row (`width` long) and hands on the one before it.
    #[inline(always)]
    fn meet(&mut self, row: &[T], mut f: impl FnMut(usize, [&[T]; 3])) {
        let k = self.met;
        if k >= 1 {
            let (mid, up): (&[T], &[T]) = match k {
                // Row 0's upper neighbour, mirrored, is row 1.
                1 => (self.even, row),
                _ if k.is_multiple_of(2) => (self.odd, self.even),
                _ => (self.even, self.odd),
            };
            f(k - 1, [up, mid, row]);
        }
        let keep = if k.is_multiple_of(2) {
            &mut *self.even
        } else {
            &mut *self.odd
        };
        if let Some(keep) = keep.get_mut(..row.len()) {
            keep.copy_from_slice(row);
        }
        self.met += 1;
    }

    /// Hands on the last row met: its lower neighbour, mirrored, is the row above it (or
    /// for a single row, itself).
    fn finish(self, mut f: impl FnMut(usize, [&[T]; 3])) {
        let (last, above): (&[T], &[T]) = match self.met {
            0 => return,
            1 => (self.even, self.even),
            n if !n.is_multiple_of(2) => (self.even, self.odd),
            _ => (self.odd, self.even),
        };
        f(self.met - 1, [above, last, above]);
    }
}

/// An image's window map to fill, its layout and the image's saliency normalization
/// ([`Arith::saliency_scale`]; `None`: flat).
pub(super) type MapOf<'m, T> = (
    &'m mut [T],
    WindowLayout,
    Option<<T as Arith>::SaliencyScale>,
);

/// Sets the `dims` region of `img` to the samples of the 8-bit image `src` (on its own
/// region) with the guard bits ([`Lift::from_guarded_byte`]).
pub(super) fn widen<T: Lift>((bytes, src_dims): (&[u8], Dims), img: &mut [T], dims: Dims) {
    for (row, dst) in src_dims.rows(bytes).zip(dims.rows_mut(img)) {
        for (d, &v) in dst.iter_mut().zip(row) {
            *d = T::from_guarded_byte(v);
        }
    }
}

/// One image's part of a fuse step level: its saliency map (when `map` is given: the
/// map, its layout and the image's normalization, `None` for a flat image), then its forward
/// transform. With `src` (an 8-bit image and its region) the image is read from those
/// bytes ([`ByteImages`]), not from `img`. With `ring` (two rows of scratch) both run in one sweep over the image:
/// each row's saliency is taken as the transform's sweep brings in the row below it, from
/// copies of the original rows above, which the transform has lifted by then. That saves
/// a pass over the image; the result is the same to the bit.
pub(super) fn saliency_and_forward<T: Arith>(
    img: &mut [T],
    dims: Dims,
    wavelet: Wavelet,
    map: Option<MapOf<'_, T>>,
    line: &mut [T],
    ring: Option<&mut [T]>,
    src: Option<(&[u8], Dims)>,
) {
    let Some((map, layout, scale)) = map else {
        match src {
            Some(src) => lifting::forward_level_from_bytes(wavelet, img, dims, line, src),
            None => lifting::forward_level(wavelet, img, dims, line),
        }
        return;
    };
    // (`transform_level` widens bytes itself before a map is taken: no `src` comes here.)
    if let Some(src) = src {
        widen(src, img, dims);
    }
    let (w, h) = (dims.width(), dims.height());
    let mut map = WindowMap::new(map, layout, dims);
    let lagged = ring.and_then(|r| LaggedRows::new(r, w));
    match (scale, lagged) {
        (Some(scale), Some(mut lagged)) => {
            lifting::forward_level_observed(wavelet, img, dims, line, |_, row, line| {
                lagged.meet(row, |y, rows| {
                    saliency_map_row(scale, rows, y, &mut map, line)
                });
            });
            lagged.finish(|y, rows| saliency_map_row(scale, rows, y, &mut map, line));
        }
        (Some(scale), None) => {
            for y in 0..h {
                if let Some((up, mid, down)) = row_and_neighbours(img, dims, y) {
                    saliency_map_row(scale, [up, mid, down], y, &mut map, line);
                }
            }
            lifting::forward_level(wavelet, img, dims, line);
        }
        (None, _) => lifting::forward_level(wavelet, img, dims, line),
    }
    map.finish(dims);
}

/// Takes one row of saliency into a row of window sums: sets the sums (`SET`, a map row's
/// first pixel row) or adds to them. With phase 1, entry 0 holds pixel 0 alone and entry
/// m ≥ 1 pixels 2m − 1, 2m; with phase 0, entry m pixels 2m, 2m + 1. A set row also zeroes
/// the entries no pixel reaches (phase 1, odd width: the last), so nothing stale is left.
/// Set sums are `p0 + p1`, bit for bit what adding both to a cleared entry gave.
#[inline(always)]
pub(super) fn window_row<T: Arith, const SET: bool>(map_row: &mut [T], srow: &[T], phase: usize) {
    let put = |acc: &mut T, v: T| {
        if SET {
            *acc = v;
        } else {
            *acc += v;
        }
    };
    let (map_row, srow) = if phase == 1 {
        let (Some((first, map_rest)), Some((&s0, s_rest))) =
            (map_row.split_first_mut(), srow.split_first())
        else {
            return;
        };
        put(first, s0);
        (map_rest, s_rest)
    } else {
        (map_row, srow)
    };
    let (pairs, odd_end) = srow.as_chunks::<2>();
    let (paired, tail) = map_row.split_at_mut(pairs.len().min(map_row.len()));
    for (acc, &[p0, p1]) in paired.iter_mut().zip(pairs) {
        put(acc, p0);
        *acc += p1;
    }
    let past = match (odd_end, tail.split_first_mut()) {
        (&[v], Some((acc, past))) => {
            put(acc, v);
            past
        }
        _ => tail,
    };
    if SET {
        past.fill(T::default());
    }
}

simd::kernel! {
    /// Turns image A's map of saliency sums into `W₁` per window, with image B's. Out of
    /// line: inlined into the level's step, its loop reloaded spilled pointers.
    #[inline(never)]
    fn weight_map<T: Arith>(map_a: &mut [T], map_b: &[T]) {
        for (s1, &s2) in map_a.iter_mut().zip(map_b) {
            *s1 = T::weight(*s1, s2);
        }
    }
}

simd::kernel! {
    /// Fuses one row of a high band: `a = W₁·a + (1 − W₁)·b` with `w` the row of `W₁`, or with
    /// `weights` off (the max-high ablation) the larger magnitude.
    #[inline(always)]
    fn fuse_band_row<T: Arith>(a: &mut [T], b: &[T], w: &[T], weights: bool) {
        if weights {
            for ((x, &y), &w1) in a.iter_mut().zip(b).zip(w) {
                *x = T::blend(*x, y, w1);
            }
        } else {
            for (x, &y) in a.iter_mut().zip(b) {
                if !T::abs_ge(*x, y) {
                    *x = y;
                }
            }
        }
    }
}

/// The fuse step, generic over the path, on two images already validated, from the
/// level `start` says to `cfg.levels`. The shallower levels' bands are
/// fused as soon as both images are transformed (the deeper levels' maps reuse their maps'
/// memory); the deepest level's bands are fused in the inverse's sweep, as it first reads
/// each row, which saves a pass over the image (for one level, a read and a write of all
/// of it). The errors cannot happen after the callers' checks: they stand in for the
/// panics of slicing past a buffer's end.
pub(crate) fn fuse_generic<T: Arith>(
    images: ImagePair<'_, T>,
    cfg: &FuseConfig,
    ll_weight: LlWeight,
    work: Work<'_, T>,
    start: StepStart<'_, T>,
    join: &impl Join,
) -> Result<(), Error> {
    let StepStart {
        level: first,
        maxima,
        mut bytes,
    } = start;
    let ImagePair { a, b, dims } = images;
    let Work {
        mut lines,
        mut maps,
    } = work;
    let image_error = dims.too_small("image", a.len().min(b.len()));
    if cfg.ablation == Ablation::NoWavelet {
        return mix_region(a, b, dims, ll_weight).ok_or(image_error);
    }
    let mut d = dims;
    // Level 1 reads the images' bytes, where given.
    let mut sources = bytes.as_ref().map(|i| [(&*i.a, i.a_dims), (i.b, i.b_dims)]);
    for level in first..cfg.levels {
        let level_images = ImagePair {
            a: &mut *a,
            b: &mut *b,
            dims: d,
        };
        let fusion = transform_level(
            level_images,
            level,
            cfg,
            &mut maps,
            &mut lines,
            LevelInputs {
                maxima,
                sources: sources.take(),
            },
            join,
        )?;
        for y in 0..d.height() {
            let (Some(ra), Some(rb)) = (d.row_mut(a, y), d.row(b, y)) else {
                return Err(image_error);
            };
            fusion.fuse_row(y, ra, rb, ll_weight)?;
        }
        d = d.low_band();
    }
    let level_images = ImagePair {
        a: &mut *a,
        b: &mut *b,
        dims: d,
    };
    let deepest = transform_level(
        level_images,
        cfg.levels,
        cfg,
        &mut maps,
        &mut lines,
        LevelInputs {
            maxima,
            sources: sources.take(),
        },
        join,
    )?;
    let b = &*b;
    let mut outcome = Ok(());
    let mut fuse_deepest = |level: u8, y: usize, ra: &mut [T]| {
        if level == cfg.levels {
            let fused = match d.row(b, y) {
                Some(rb) => deepest.fuse_row(y, ra, rb, ll_weight),
                None => Err(image_error),
            };
            outcome = outcome.and(fused);
        }
    };
    let out = bytes.take().map(|i| (i.a, i.a_dims));
    T::inverse(
        cfg.wavelet,
        (a, dims),
        first..=cfg.levels,
        lines.line,
        &mut fuse_deepest,
        out,
    );
    outcome
}

/// What a fuse step level's images come with besides their buffers.
pub(super) struct LevelInputs<'s, T> {
    /// The images' level-1 `|∇²I|` where the checks found them (used at level 1 only).
    maxima: [Option<T>; 2],
    /// The 8-bit images level 1 reads its rows from ([`ByteImages`]), if any.
    sources: Option<[(&'s [u8], Dims); 2]>,
}

/// One level of a fuse step up to its fusion: each image's saliency map (read before its
/// transform overwrites it) and its transform, then `W₁` per window. Returns how to fuse
/// the level's rows. `images` are the level's inputs (the images, then their LL bands);
/// the maps take this level's saliency sums unless they hold them already.
pub(super) fn transform_level<'m, T: Arith>(
    images: ImagePair<'_, T>,
    level: u8,
    cfg: &FuseConfig,
    maps: &'m mut Maps<'_, T>,
    lines: &mut Lines<'_, T>,
    inputs: LevelInputs<'_, T>,
    join: &impl Join,
) -> Result<LevelFusion<'m, T>, Error> {
    let LevelInputs {
        maxima: [max_a, max_b],
        sources,
    } = inputs;
    let ImagePair { a, b, dims: d } = images;
    let maps_ready = level == 1 && maps.first_ready;
    let with_weights = cfg.ablation.uses_saliency();
    let (wl, layout) = (cfg.wavelet, WindowLayout::of(cfg.wavelet));
    let mw = layout.map_dims(d).0;
    let maps_error = maps_too_small(layout, d, maps.space.len());
    let [map_a, map_b] = split_maps(&mut *maps.space, layout, d)?;
    let scale_of = |img: &[T], max| {
        let known_max = if level == 1 { max } else { None };
        T::saliency_scale(img, d, cfg.norm, cfg.wavelet, level, known_max)
    };
    let take_maps = with_weights && !maps_ready;
    // A map is taken from the samples: widened first where they are bytes.
    let sources = match sources {
        Some([src_a, src_b]) if take_maps => {
            widen(src_a, a, d);
            widen(src_b, b, d);
            None
        }
        other => other,
    };
    let [scale_a, scale_b] = if take_maps {
        [scale_of(a, max_a), scale_of(b, max_b)]
    } else {
        [None, None]
    };
    // The two images are independent until the weights.
    let with_map = |map, scale| take_maps.then_some((map, layout, scale));
    let (ring_a, ring_b) = match lines.rings.as_deref_mut() {
        Some(r) => {
            let (ra, rb) = r.split_at_mut(r.len() / 2);
            (Some(ra), Some(rb))
        }
        None => (None, None),
    };
    let line = &mut *lines.line;
    let [src_a, src_b] = sources.map_or([None; 2], |s| s.map(Some));
    match lines.line_b.as_deref_mut() {
        Some(lb) => join.join(
            || {
                let map = with_map(&mut *map_a, scale_a);
                saliency_and_forward(a, d, wl, map, line, ring_a, src_a);
            },
            || {
                let map = with_map(&mut *map_b, scale_b);
                saliency_and_forward(b, d, wl, map, lb, ring_b, src_b);
            },
        ),
        None => {
            let map = with_map(&mut *map_a, scale_a);
            saliency_and_forward(a, d, wl, map, line, ring_a, src_a);
            let map = with_map(&mut *map_b, scale_b);
            saliency_and_forward(b, d, wl, map, line, ring_b, src_b);
        }
    }
    if with_weights {
        weight_map(map_a, map_b);
    }
    Ok(LevelFusion {
        dims: d,
        weights: with_weights.then_some(&*map_a),
        map_width: mw,
        shifts: layout.shifts,
        // The deepest LL band is mixed with the high bands, while its rows are in cache.
        mix_ll: level == cfg.levels && cfg.ablation != Ablation::SingleLl,
        maps_error,
    })
}

/// How the rows of one transformed level are fused.
pub(super) struct LevelFusion<'m, T> {
    /// The level's region.
    dims: Dims,
    /// `W₁` per window ([`WindowLayout`]); `None` for the max-high ablation.
    weights: Option<&'m [T]>,
    /// The map's width.
    map_width: usize,
    /// [`WindowLayout::shifts`].
    shifts: [(usize, usize); 3],
    /// Whether the LL band is mixed too (the deepest level's).
    mix_ll: bool,
    /// What a map too short for a row's weights reports.
    maps_error: Error,
}

impl<T: Arith> LevelFusion<'_, T> {
    /// Fuses row `y` of the transformed level `ra` with `rb`, image B's: HL right of the
    /// low columns for even `y`; LH and HH for odd `y`, each band's row `y / 2`
    /// (`crate::geometry`).
    #[inline(always)]
    fn fuse_row(&self, y: usize, ra: &mut [T], rb: &[T], ll_weight: LlWeight) -> Result<(), Error> {
        let nlx = self.dims.width().div_ceil(2);
        let got = ra.len().min(rb.len());
        let ((low_a, high_a), (low_b, high_b)) = ra
            .split_at_mut_checked(nlx)
            .zip(rb.split_at_checked(nlx))
            .ok_or_else(|| self.dims.too_small("image", got))?;
        let [hl, lh, hh] = self.shifts;
        let j = y / 2;
        // Row j of W₁ for the band whose map entries are shifted by `(sx, sy)`.
        let weights = |(sx, sy): (usize, usize), len: usize| match self.weights {
            Some(map) => {
                let start = (j + sy) * self.map_width + sx;
                map.get(start..start + len).ok_or(self.maps_error)
            }
            None => Ok(&[][..]),
        };
        let with_weights = self.weights.is_some();
        if y.is_multiple_of(2) {
            if self.mix_ll {
                mix_row(low_a, low_b, ll_weight);
            }
            fuse_band_row(high_a, high_b, weights(hl, high_a.len())?, with_weights);
        } else {
            fuse_band_row(low_a, low_b, weights(lh, low_a.len())?, with_weights);
            fuse_band_row(high_a, high_b, weights(hh, high_a.len())?, with_weights);
        }
        Ok(())
    }
}

/// Sets `a = (1 − w)·a + w·b` over the `dims` region; `None` if a buffer does not hold it.
pub(super) fn mix_region<T: Arith>(
    a: &mut [T],
    b: &[T],
    dims: Dims,
    ll_weight: LlWeight,
) -> Option<()> {
    for y in 0..dims.height() {
        mix_row(dims.row_mut(a, y)?, dims.row(b, y)?, ll_weight);
    }
    Some(())
}

simd::kernel! {
    /// Sets `a = (1 − w)·a + w·b` along a row.
    #[inline(always)]
    fn mix_row<T: Arith>(a: &mut [T], b: &[T], ll_weight: LlWeight) {
        for (x, &v) in a.iter_mut().zip(b) {
            *x = T::mix(*x, v, ll_weight);
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    extern crate std;
    use super::*;
    use crate::fusion::*;
    use std::{vec, vec::Vec};

    /// A smooth ramp with a bright square and a few dots: texture at every level.
    fn scene(w: usize, h: usize, seed: usize) -> Vec<f32> {
        (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let square = if (w / 4..w / 2).contains(&x) && (h / 3..h / 2).contains(&y) {
                    90.0
                } else {
                    0.0
                };
                let dot = if (x * 7 + y * 13 + seed).is_multiple_of(29) {
                    60.0
                } else {
                    0.0
                };
                (x + 2 * y + seed) as f32 * 0.7 + square + dot
            })
            .collect()
    }

    #[test]
    fn saliency_in_the_transform_sweep_changes_no_bit() {
        for (w, h) in [(61, 47), (31, 24), (40, 30), (7, 2), (5, 1), (1, 6), (2, 3)] {
            let dims = Dims::new(w, h).unwrap();
            for wavelet in [Wavelet::Haar, Wavelet::Db2] {
                for levels in 1..=3 {
                    if dims.check_levels(levels).is_err() {
                        continue;
                    }
                    let cfg = FuseConfig {
                        wavelet,
                        levels,
                        ..FuseConfig::default()
                    };
                    let fused = |rings: bool| {
                        let (mut a, mut b) = (scene(w, h, 0), scene(w, h, 5));
                        let mut scratch = vec![0f32; crate::float::fuse_scratch_len(dims)];
                        let half = LlWeight::HALF;
                        let layout = ScratchLayout {
                            second_line: true,
                            rings,
                            table: false,
                        };
                        let seq = &Sequential;
                        let images = ImagePair {
                            a: &mut a,
                            b: &mut b,
                            dims,
                        };
                        let how = (layout, Samples::Unchecked);
                        fuse_pair_checked(images, &cfg, half, &mut scratch, how, seq).unwrap();
                        a
                    };
                    let (swept, apart) = (fused(true), fused(false));
                    let same = swept
                        .iter()
                        .zip(&apart)
                        .all(|(x, y)| x.to_bits() == y.to_bits());
                    assert!(same, "{w}×{h} {wavelet:?} L{levels}");
                }
            }
        }
    }

    /// `fuse_u8` (level 1's saliency from the bytes, by table or computed) gives the bits
    /// of the generic step on the samples with the guard bits, rounded back: under each
    /// image's own maximum (two tables), a shared reference maximum (one), one that caps
    /// most Laplacians and one above every Laplacian; on regions with and without tables
    /// (below `TABLE_MIN_PIXELS`), narrow ones (no groups of four) and strided inputs.
    /// What `fuse_u8` must give: both 8-bit images widened by the guard bits, the generic
    /// step (a reference norm scaled alike) and its result rounded back to bytes.
    fn widened_step(
        a: &[u8],
        b: &[u8],
        dims: Dims,
        cfg: &FuseConfig,
        ll: LlWeight,
        scratch: &mut [i32],
    ) -> Vec<u8> {
        let wide =
            |img: &[u8]| -> Vec<i32> { img.iter().map(|&v| i32::from(v) << GUARD_BITS).collect() };
        let (mut wa, mut wb) = (wide(a), wide(b));
        let generic = FuseConfig {
            norm: match cfg.norm {
                SaliencyNorm::Reference(r) => SaliencyNorm::Reference(r << GUARD_BITS),
                local => local,
            },
            ..*cfg
        };
        fuse_pair(&mut wa, &mut wb, dims, &generic, ll, scratch).unwrap();
        let half = 1 << (GUARD_BITS - 1);
        wa.iter()
            .map(|&v| ((v + half) >> GUARD_BITS).clamp(0, 255) as u8)
            .collect()
    }

    /// [`fuse_u8`] of `pair` under `cfg`, LL weighted ½, on work buffers of its own.
    fn fuse_u8_half(pair: U8Pair<'_>, cfg: &FuseConfig) {
        fuse_u8_alone(pair, cfg, LlWeight::HALF);
    }

    /// [`fuse_u8`] of `pair` under `cfg` and `ll`, on work buffers of its own.
    pub(crate) fn fuse_u8_alone(pair: U8Pair<'_>, cfg: &FuseConfig, ll: LlWeight) {
        let dims = Dims::new(pair.a_dims.width(), pair.a_dims.height()).unwrap();
        let (mut ua, mut ub) = (vec![0; dims.pixels()], vec![0; dims.pixels()]);
        let mut scratch = vec![0i32; fuse_scratch_len(dims)];
        let work = U8Work {
            a: &mut ua,
            b: &mut ub,
            scratch: &mut scratch,
        };
        fuse_u8(pair, cfg, ll, work).unwrap();
    }

    /// The generic step from `level` on the level inputs (LL bands) `images`, on scratch
    /// laid out as [`fuse_u8`]'s.
    pub(crate) fn fuse_from_level(
        level: u8,
        images: ImagePair<'_, i32>,
        cfg: &FuseConfig,
        ll: LlWeight,
    ) {
        let dims = images.dims;
        let mut scratch = vec![0i32; fuse_scratch_len(dims)];
        let layout = ScratchLayout {
            second_line: false,
            rings: false,
            table: false,
        };
        let line = lifting::scratch_len(dims);
        let (work, _) = split_scratch(&mut scratch, line, layout, dims).unwrap();
        let start = StepStart::deeper(level);
        fuse_generic(images, cfg, ll, work, start, &Sequential).unwrap();
    }

    /// The step started at level 2 on two LL₁ bands is the step of one level fewer on
    /// them as images, with its reference maximum carried down a level
    /// (`saliency::level_max`): the level count, the saliency's normalization and which
    /// level mixes LL follow the level the step starts at.
    #[test]
    fn a_step_from_level_two_is_the_shallower_step_on_the_ll_bands() {
        for (w, h) in [(64, 24), (40, 30), (61, 47), (12, 9)] {
            let dims = Dims::new(w, h).unwrap();
            let mut images = crate::extreme_tiles(w, h, 1, 5);
            let mut noise = crate::test_bytes(3);
            images.push((0..w * h).map(|_| noise()).collect());
            let band = dims.low_band();
            let ll = Dims::new(band.width(), band.height()).unwrap();
            for wavelet in [Wavelet::Haar, Wavelet::Db2] {
                // An 8-bit image's LL₁ band (no guard bits: within `MAX_SAMPLE`).
                let ll_of = |img: &[u8]| -> Vec<i32> {
                    let mut buf: Vec<i32> = img.iter().map(|&v| i32::from(v)).collect();
                    let mut line = vec![0; lifting::scratch_len(dims)];
                    lifting::forward_level(wavelet, &mut buf, dims, &mut line);
                    (0..ll.height())
                        .flat_map(|y| band.row(&buf, y).unwrap().to_vec())
                        .collect()
                };
                for levels in 2..=3 {
                    if dims.check_levels(levels).is_err() {
                        continue;
                    }
                    for norm in [SaliencyNorm::Local, SaliencyNorm::Reference(40)] {
                        let cfg = FuseConfig {
                            wavelet,
                            levels,
                            norm,
                            ..FuseConfig::default()
                        };
                        let carried = match norm {
                            SaliencyNorm::Reference(_) => SaliencyNorm::Reference(
                                crate::saliency::level_max(&[], ll, norm, wavelet, 2),
                            ),
                            local => local,
                        };
                        let shallower = FuseConfig {
                            levels: levels - 1,
                            norm: carried,
                            ..cfg
                        };
                        for (i, a) in images.iter().enumerate() {
                            let b = &images[(i + 2) % images.len()];
                            let (mut got, mut got_b) = (ll_of(a), ll_of(b));
                            let pair = ImagePair {
                                a: &mut got,
                                b: &mut got_b,
                                dims: ll,
                            };
                            fuse_from_level(2, pair, &cfg, LlWeight(9_000));
                            let (mut want, mut want_b) = (ll_of(a), ll_of(b));
                            let mut scratch = vec![0; fuse_scratch_len(ll)];
                            let weight = LlWeight(9_000);
                            fuse_pair(&mut want, &mut want_b, ll, &shallower, weight, &mut scratch)
                                .unwrap();
                            let what = std::format!("{w}×{h} {wavelet:?} L{levels} {norm:?} {i}");
                            assert_eq!(got, want, "{what}");
                        }
                    }
                }
            }
        }
    }

    /// Whether `fuse_u8` runs `cfg` on `dims` in lanes and rounds otherwise than the
    /// 32-bit step there (`lanes::tests`): db2's lifting, and Haar's LL at one level
    /// weighted other than ½. Haar in lanes otherwise gives the step's bytes.
    fn lanes_round_otherwise(cfg: &FuseConfig, dims: Dims, ll: LlWeight) -> bool {
        integer::takes_lanes(cfg, dims)
            && (cfg.wavelet == Wavelet::Db2 || (cfg.levels == 1 && ll != LlWeight::HALF))
    }

    #[test]
    fn fuse_u8_matches_the_step_on_samples_with_guard_bits() {
        // 8-bit samples with 0/255 dots: Laplacians up to the largest.
        let bytes = |w: usize, h: usize, seed: usize| -> Vec<u8> {
            scene(w, h, seed)
                .iter()
                .enumerate()
                .map(|(i, &v)| match (i * 11 + seed) % 37 {
                    0 => 255,
                    1 => 0,
                    _ => v.round().clamp(0.0, 255.0) as u8,
                })
                .collect()
        };
        let norms = [
            SaliencyNorm::Local,
            SaliencyNorm::Reference(40),
            SaliencyNorm::Reference(3),
            SaliencyNorm::Reference(5000),
        ];
        let mut tabled = 0;
        for (w, h) in [
            (160, 16),
            (61, 47),
            (40, 30),
            (31, 24),
            (7, 2),
            (5, 9),
            (2, 3),
        ] {
            let dims = Dims::new(w, h).unwrap();
            tabled += usize::from(dims.pixels() >= 1024);
            let (a, b) = (bytes(w, h, 0), bytes(w, h, 5));
            // `a` again with two bytes of padding after each row.
            let stride = w + 2;
            let padded = crate::padded_rows(&a, w, stride, 7);
            let strided = Dims::with_stride(w, h, stride).unwrap();
            for wavelet in [Wavelet::Haar, Wavelet::Db2] {
                for levels in 1..=2 {
                    if dims.check_levels(levels).is_err() {
                        continue;
                    }
                    for norm in norms {
                        let cfg = FuseConfig {
                            wavelet,
                            levels,
                            norm,
                            ..FuseConfig::default()
                        };
                        if lanes_round_otherwise(&cfg, dims, LlWeight::HALF) {
                            continue;
                        }
                        let mut scratch = vec![0i32; fuse_scratch_len(dims)];
                        let want = widened_step(&a, &b, dims, &cfg, LlWeight::HALF, &mut scratch);
                        let mut got = padded.clone();
                        let pair = U8Pair {
                            a: &mut got,
                            a_dims: strided,
                            b: &b,
                            b_dims: dims,
                        };
                        fuse_u8_half(pair, &cfg);
                        let what = std::format!("{w}×{h} {wavelet:?} L{levels} {norm:?}");
                        for (row, want_row) in got.chunks(stride).zip(want.chunks(w)) {
                            assert_eq!(&row[..w], want_row, "{what}");
                            assert_eq!(&row[w..], &[7, 7][..row.len() - w], "{what}: padding");
                        }
                    }
                }
            }
        }
        assert_eq!(tabled, 3, "regions with tables");
    }

    /// Binary noise, checkers and stripes of 0 and 255, at a tile's size, give the
    /// largest coefficients 8-bit samples can: the level-1 inverse to bytes, whose column
    /// pass stores without saturating (`lifting::Unsaturated`), gives the bytes of the
    /// saturating step on them. (Tiny images of 0/255 noise can differ: the hard-cases
    /// search, docs/hard-cases.md.)
    #[test]
    fn fuse_u8_of_extreme_tiles_matches_the_saturating_step() {
        let (w, h) = (64, 24);
        let dims = Dims::new(w, h).unwrap();
        let images = crate::extreme_tiles(w, h, 4, 99);
        for (i, a) in images.iter().enumerate() {
            let b = &images[(i + 3) % images.len()];
            for wavelet in [Wavelet::Haar, Wavelet::Db2] {
                for levels in 1..=2 {
                    let cfg = FuseConfig {
                        wavelet,
                        levels,
                        ..FuseConfig::default()
                    };
                    if lanes_round_otherwise(&cfg, dims, LlWeight::HALF) {
                        continue;
                    }
                    let mut scratch = vec![0i32; fuse_scratch_len(dims)];
                    let want = widened_step(a, b, dims, &cfg, LlWeight::HALF, &mut scratch);
                    let mut got = a.clone();
                    fuse_u8_half(U8Pair::same(&mut got, b, dims), &cfg);
                    assert_eq!(got, want, "images {i}, {wavelet:?} L{levels}");
                }
            }
        }
    }

    /// `fuse_u8` lifts level 1's rows straight from the bytes and writes its result
    /// straight back as bytes (no widened copies, no saturation of the last row pass, no
    /// rounding pass): the same bytes as widening both images, the generic step and
    /// rounding its result, for every ablation, flat and extreme images (all 0, all 255,
    /// 0/255 checkerboards and stripes), random ones, and regions one sample wide or high.
    #[test]
    fn fuse_u8_from_bytes_matches_the_widened_step() {
        let mut state = 0x2545_f491_u32;
        let mut random = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state
        };
        let kinds = 7;
        let image = |kind: usize, w: usize, h: usize, rng: &mut dyn FnMut() -> u32| -> Vec<u8> {
            (0..w * h)
                .map(|i| {
                    let (x, y) = (i % w, i / w);
                    match kind {
                        0 => 0,
                        1 => 255,
                        2 => [0, 255][(x + y) % 2],
                        3 => [255, 0][(x + y) % 2],
                        4 => [0, 255][x % 2],
                        5 => [0, 255][y % 2],
                        _ => (rng() >> 24) as u8,
                    }
                })
                .collect()
        };
        let ablations = [
            Ablation::None,
            Ablation::MaxHigh,
            Ablation::SingleLl,
            Ablation::NoWavelet,
        ];
        let mut runs = 0;
        for (w, h) in [(64, 16), (33, 9), (8, 8), (1, 7), (9, 1), (2, 2), (3, 5)] {
            let dims = Dims::new(w, h).unwrap();
            for ka in 0..kinds {
                for kb in 0..kinds {
                    let a = image(ka, w, h, &mut random);
                    let b = image(kb, w, h, &mut random);
                    for wavelet in [Wavelet::Haar, Wavelet::Db2] {
                        for levels in 1..=3 {
                            if dims.check_levels(levels).is_err() {
                                continue;
                            }
                            let ablation = ablations[(ka + kb + usize::from(levels)) % 4];
                            let norm = if (ka + kb) % 2 == 0 {
                                SaliencyNorm::Local
                            } else {
                                SaliencyNorm::Reference(17 * (ka as u32 + 1))
                            };
                            let cfg = FuseConfig {
                                wavelet,
                                levels,
                                ablation,
                                norm,
                                ..FuseConfig::default()
                            };
                            let ll = LlWeight((random() >> 17) as u16);
                            if lanes_round_otherwise(&cfg, dims, ll) {
                                continue;
                            }
                            let mut scratch = vec![0i32; fuse_scratch_len(dims)];
                            let want = widened_step(&a, &b, dims, &cfg, ll, &mut scratch);
                            let mut got = a.clone();
                            let (mut ua, mut ub) = (vec![0; w * h], vec![0; w * h]);
                            let work = U8Work {
                                a: &mut ua,
                                b: &mut ub,
                                scratch: &mut scratch,
                            };
                            fuse_u8(U8Pair::same(&mut got, &b, dims), &cfg, ll, work).unwrap();
                            assert_eq!(
                                got, want,
                                "{w}×{h} images {ka}, {kb} {wavelet:?} L{levels} {ablation:?} {norm:?}"
                            );
                            runs += 1;
                        }
                    }
                }
            }
        }
        assert!(runs > 500, "{runs} runs");
    }
}
