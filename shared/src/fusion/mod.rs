//! Saliency-weighted wavelet fusion (paper eqs. 1–7) and its cyclic use over a sequence.
//!
//! One fuse step of images `A` and `B`, `levels` deep:
//!
//! - for each level `k`: saliency of both level inputs (the images, then their LL bands),
//!   weights `W₁, W₂` per coefficient ([`crate::saliency`]), one transform level of both,
//!   and each high band (HL, LH, HH) of the result set to `W₁·H_A + W₂·H_B`;
//! - the deepest LL band set to `(1 − w)·LL_A + w·LL_B` with `w = ½` (the paper's mean,
//!   eq. 2) or `w = 1/n` for an order-independent mean over `n` frames ([`LlWeighting`]);
//! - the inverse transform of the result (eq. 7).
//!
//! The same driver runs the integer path ([`fuse_pair`], what the MCU runs) and the `f32`
//! path ([`crate::float`]); the crate-private `Arith` trait is the seam between them.

mod cyclic;
pub(crate) mod integer;

pub use cyclic::{CyclicBuffers, CyclicFuser};
pub use integer::{GUARD_BITS, U8Work, fuse_pair, fuse_scratch_len, fuse_scratch_words, fuse_u8};

use crate::{Dims, Error, Wavelet, saliency::SaliencyNorm, simd};

/// The ablations of the paper's Table II: each removes one part of the method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Ablation {
    /// The full method.
    #[default]
    None,
    /// No wavelet transform: the pixels themselves are averaged (with the LL weighting).
    NoWavelet,
    /// The LL band is not fused: the fused image keeps the first input's (in cyclic use,
    /// the running result's, so the first frame's low frequencies).
    SingleLl,
    /// High bands by max-|coefficient| selection instead of saliency weights.
    MaxHigh,
}

/// How the LL band of a new frame is weighted against the running result.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LlWeighting {
    /// The paper's pairwise mean: the newest frame weighs ½, the first `1/2ⁿ⁻¹`.
    #[default]
    Paper,
    /// Frame `n` weighs `1/n` against the running result, so every frame weighs `1/n` in
    /// the end and the LL band does not depend on the order (up to rounding: the weight
    /// is Q15 and the integer path rounds its running result to 8 bits every cycle).
    Equal,
}

/// Everything that defines a fuse step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FuseConfig {
    /// The wavelet.
    pub wavelet: Wavelet,
    /// Decomposition levels, 1..=4.
    pub levels: u8,
    /// Which part of the method to remove, if any.
    pub ablation: Ablation,
    /// How the Laplacian is normalized.
    pub norm: SaliencyNorm,
    /// How the LL band weighs each frame in cyclic use.
    pub ll_weighting: LlWeighting,
}

impl Ablation {
    /// Whether the high bands take saliency weights (not so without the wavelet, or
    /// with max-|coefficient| selection).
    pub(crate) fn uses_saliency(self) -> bool {
        !matches!(self, Ablation::NoWavelet | Ablation::MaxHigh)
    }
}

impl Default for FuseConfig {
    /// db2, one level (the paper's setting), full method, per-image normalization.
    fn default() -> Self {
        Self {
            wavelet: Wavelet::Db2,
            levels: 1,
            ablation: Ablation::None,
            norm: SaliencyNorm::Local,
            ll_weighting: LlWeighting::Paper,
        }
    }
}

/// Weight of the second input's LL band, Q15 (`32768` = 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LlWeight(pub(crate) u16);

impl LlWeight {
    /// The paper's mean: ½.
    pub const HALF: Self = Self(1 << 14);

    /// The weight of frame number `n` (1-based) under `weighting`.
    pub fn for_frame(weighting: LlWeighting, n: u32) -> Self {
        match weighting {
            LlWeighting::Paper => Self::HALF,
            LlWeighting::Equal => Self(((1u32 << 15) / n.max(1)) as u16),
        }
    }

    /// As a fraction in 0..=1.
    pub fn as_f32(self) -> f32 {
        f32::from(self.0) / 32768.0
    }
}

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
/// all live in `Self` (i32 on the integer path, f32 on the float path).
pub(crate) trait Arith: Copy + Default + Send + Sync + core::ops::AddAssign {
    /// One forward 2-D level on `dims`.
    fn forward_level(wavelet: Wavelet, buf: &mut [Self], dims: Dims, scratch: &mut [Self]);
    /// All inverse levels, deepest first.
    fn inverse(wavelet: Wavelet, buf: &mut [Self], dims: Dims, levels: u8, scratch: &mut [Self]);
    /// Calls `f(y, S)` with the row of saliencies `S = exp(Sal/255) − 1` of every row `y`
    /// of the level input, built in `row` (nothing at all for a flat region, whose `S` is 0
    /// everywhere). `known_max`, where given, is the level input's largest `|∇²I|` under
    /// [`SaliencyNorm::Local`], found by [`Arith::check_and_max`]: no scan for it then.
    #[allow(clippy::too_many_arguments)]
    fn saliency_rows(
        buf: &[Self],
        dims: Dims,
        norm: SaliencyNorm,
        wavelet: Wavelet,
        level: u8,
        known_max: Option<Self>,
        row: &mut [Self],
        f: impl FnMut(usize, &[Self]),
    );
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

/// The checks and the call shared by both paths' public `fuse_pair`. `lines` is how many
/// transform lines the scratch holds: 1, or 2 to let `join` run both images at once.
#[allow(clippy::too_many_arguments)]
pub(crate) fn fuse_pair_checked<T: Arith>(
    a: &mut [T],
    b: &mut [T],
    dims: Dims,
    cfg: &FuseConfig,
    ll_weight: LlWeight,
    scratch: &mut [T],
    lines: usize,
    join: &impl Join,
) -> Result<(), Error> {
    dims.check_buffer("first image", a.len())?;
    dims.check_buffer("second image", b.len())?;
    dims.check_levels(cfg.levels)?;
    if ll_weight.0 > 1 << 15 {
        return Err(Error::InvalidParameter { name: "ll_weight" });
    }
    let work = split_scratch(scratch, crate::lifting::scratch_len(dims), lines, dims)?;
    // Both images are checked before either is touched; the level-1 maxima come along.
    let local_max = cfg.norm == SaliencyNorm::Local && cfg.ablation.uses_saliency();
    let max_a = T::check_and_max(a, dims, local_max)?;
    let max_b = T::check_and_max(b, dims, local_max)?;
    fuse_generic(a, b, dims, cfg, ll_weight, work, [max_a, max_b], join)
}

/// Scratch a fuse step needs besides its transform line: one window map per image, each
/// at most `(⌈w/2⌉ + 1) × (⌈h/2⌉ + 1)` (see [`WindowLayout`]).
pub(crate) const fn maps_len(width: usize, height: usize) -> usize {
    2 * (width.div_ceil(2) + 1) * (height.div_ceil(2) + 1)
}

/// Work areas of one fuse step, split from the caller's scratch.
pub(crate) struct Work<'s, T> {
    /// The transform line (image A's, and B's too when there is no second).
    pub line: &'s mut [T],
    /// A second line, so both images can be worked on at once.
    pub line_b: Option<&'s mut [T]>,
    /// Two window maps: image A's, then image B's.
    pub maps: &'s mut [T],
}

/// Splits the caller's scratch into `lines` (1 or 2) transform lines of `line` elements
/// and the maps.
pub(crate) fn split_scratch<T>(
    scratch: &mut [T],
    line: usize,
    lines: usize,
    dims: Dims,
) -> Result<Work<'_, T>, Error> {
    let maps = maps_len(dims.width(), dims.height());
    let needed = lines * line + maps;
    let too_small = Error::BufferTooSmall {
        which: "scratch",
        needed,
        got: scratch.len(),
    };
    if scratch.len() < needed {
        return Err(too_small);
    }
    let (first, rest) = scratch.split_at_mut_checked(line).ok_or(too_small)?;
    let (line_b, rest) = if lines > 1 {
        let (b, rest) = rest.split_at_mut_checked(line).ok_or(too_small)?;
        (Some(b), rest)
    } else {
        (None, rest)
    };
    Ok(Work {
        line: first,
        line_b,
        maps: rest.get_mut(..maps).ok_or(too_small)?,
    })
}

simd::kernel! {
    /// Fills `map` (`layout.map_dims(dims)`, row-major) with the 2×2 window sums of the
    /// level input's saliency, a row at a time (`row` is a line of scratch; `known_max` as
    /// for [`Arith::saliency_rows`]).
    #[allow(clippy::too_many_arguments)]
    fn window_saliency<T: Arith>(
        buf: &[T],
        dims: Dims,
        cfg: &FuseConfig,
        level: u8,
        known_max: Option<T>,
        layout: WindowLayout,
        map: &mut [T],
        row: &mut [T],
    ) {
        let (mw, mh) = layout.map_dims(dims);
        // Each map row is set by its first pixel row and added to by its second, so the
        // map is not cleared first (a pass over it); what no pixel reaches is zeroed here.
        let mut rows_seen = false;
        T::saliency_rows(
            buf,
            dims,
            cfg.norm,
            cfg.wavelet,
            level,
            known_max,
            row,
            |y, srow| {
                rows_seen = true;
                let m = (y + layout.phase) / 2;
                // A map row's first pixel row: 2m − phase, or row 0 alone for phase 1.
                let first = y == 0 || (y + layout.phase).is_multiple_of(2);
                // The map has `map_dims(dims)` rows; a short `map` just loses the row.
                let Some(map_row) = map.get_mut(m * mw..(m + 1) * mw) else {
                    return;
                };
                if first {
                    window_row::<T, true>(map_row, srow, layout.phase);
                } else {
                    window_row::<T, false>(map_row, srow, layout.phase);
                }
            },
        );
        let reached = if rows_seen {
            // Phase 1 with an odd height leaves the last map row to no pixel row.
            (dims.height() + layout.phase).div_ceil(2).min(mh) * mw
        } else {
            // A flat image has no saliency rows: its map is all zero.
            0
        };
        if let Some(rest) = map.get_mut(reached..mh * mw) {
            rest.fill(T::default());
        }
    }
}

/// Takes one row of saliency into a row of window sums: sets the sums (`SET`, a map row's
/// first pixel row) or adds to them. With phase 1, entry 0 holds pixel 0 alone and entry
/// m ≥ 1 pixels 2m − 1, 2m; with phase 0, entry m pixels 2m, 2m + 1. A set row also zeroes
/// the entries no pixel reaches (phase 1, odd width: the last), so nothing stale is left.
/// Set sums are `p0 + p1`, bit for bit what adding both to a cleared entry gave.
#[inline(always)]
fn window_row<T: Arith, const SET: bool>(map_row: &mut [T], srow: &[T], phase: usize) {
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
    /// Turns image A's map of saliency sums into `W₁` per window, with image B's.
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

/// The fuse step, generic over the path. `a` and `b` hold the two images on `dims`
/// (already validated, with their level-1 `|∇²I|` maxima where the check found them);
/// the fused image replaces `a`, `b` is consumed. The errors cannot happen after the
/// callers' checks: they stand in for the panics of slicing past a buffer's end.
#[allow(clippy::too_many_arguments)]
pub(crate) fn fuse_generic<T: Arith>(
    a: &mut [T],
    b: &mut [T],
    dims: Dims,
    cfg: &FuseConfig,
    ll_weight: LlWeight,
    work: Work<'_, T>,
    [max_a, max_b]: [Option<T>; 2],
    join: &impl Join,
) -> Result<(), Error> {
    let Work {
        line,
        mut line_b,
        maps,
    } = work;
    let image_error = dims.too_small("image", a.len().min(b.len()));
    if cfg.ablation == Ablation::NoWavelet {
        return mix_region(a, b, dims, ll_weight).ok_or(image_error);
    }
    let with_weights = cfg.ablation.uses_saliency();
    let layout = WindowLayout::of(cfg.wavelet);
    let [hl_shift, lh_shift, hh_shift] = layout.shifts;
    let mut d = dims;
    for level in 1..=cfg.levels {
        let (mw, mh) = layout.map_dims(d);
        let maps_error = Error::BufferTooSmall {
            which: "scratch",
            needed: 2 * mw * mh,
            got: maps.len(),
        };
        let (map_a, rest) = maps.split_at_mut_checked(mw * mh).ok_or(maps_error)?;
        let map_b = rest.get_mut(..mw * mh).ok_or(maps_error)?;
        // Each image's saliency (read before its transform overwrites it), then its
        // transform: the two images are independent until the weights.
        let side = |img: &mut [T], max: Option<T>, map: &mut [T], line: &mut [T]| {
            if with_weights {
                let known_max = if level == 1 { max } else { None };
                window_saliency(img, d, cfg, level, known_max, layout, map, line);
            }
            T::forward_level(cfg.wavelet, img, d, line);
        };
        match line_b.as_deref_mut() {
            Some(lb) => join.join(|| side(a, max_a, map_a, line), || side(b, max_b, map_b, lb)),
            None => {
                side(a, max_a, map_a, line);
                side(b, max_b, map_b, line);
            }
        }
        if with_weights {
            weight_map(map_a, map_b);
        }
        // The deepest LL band is mixed in the same sweep as the high bands, while its rows
        // are in cache (the even rows' low halves, on the last level).
        let mix_ll = level == cfg.levels && cfg.ablation != Ablation::SingleLl;
        let nlx = d.width().div_ceil(2);
        // Row y of the transformed level: HL right of the low columns for even y; LH and
        // HH for odd y, each band's row y / 2 (`crate::geometry`). `weights((sx, sy), j,
        // len)` is row j of W₁ for the band whose map entries are shifted by `(sx, sy)`.
        let weights = |(sx, sy): (usize, usize), j: usize, len: usize| {
            let start = (j + sy) * mw + sx;
            map_a.get(start..start + len).ok_or(maps_error)
        };
        for y in 0..d.height() {
            let (Some(ra), Some(rb)) = (d.row_mut(a, y), d.row(b, y)) else {
                return Err(image_error);
            };
            // nlx = ⌈w/2⌉ ≤ w, the rows' length.
            let (low_a, high_a) = ra.split_at_mut(nlx);
            let (low_b, high_b) = rb.split_at(nlx);
            let j = y / 2;
            if y % 2 == 0 {
                if mix_ll {
                    mix_row(low_a, low_b, ll_weight);
                }
                let w_hl = weights(hl_shift, j, high_a.len())?;
                fuse_band_row(high_a, high_b, w_hl, with_weights);
            } else {
                let w_lh = weights(lh_shift, j, low_a.len())?;
                fuse_band_row(low_a, low_b, w_lh, with_weights);
                let w_hh = weights(hh_shift, j, high_a.len())?;
                fuse_band_row(high_a, high_b, w_hh, with_weights);
            }
        }
        d = d.low_band();
    }
    T::inverse(cfg.wavelet, a, dims, cfg.levels, line);
    Ok(())
}

/// Sets `a = (1 − w)·a + w·b` over the `dims` region; `None` if a buffer does not hold it.
fn mix_region<T: Arith>(a: &mut [T], b: &[T], dims: Dims, ll_weight: LlWeight) -> Option<()> {
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
