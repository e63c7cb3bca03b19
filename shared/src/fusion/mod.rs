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
//! path ([`crate::float`]); the [`Arith`] trait is the seam between them.

mod cyclic;
pub(crate) mod integer;

pub use cyclic::{CyclicBuffers, CyclicFuser};
pub use integer::{GUARD_BITS, U8Work, fuse_pair, fuse_scratch_len, fuse_u8};

use crate::{Dims, Error, Wavelet, saliency::SaliencyNorm};

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

/// Where the coefficients of each high band (HL, LH, HH) sit on the level's input grid.
///
/// A coefficient `(i, j)` of a band takes its weight from the 2×2 window of input pixels
/// `x ∈ {2i + ox, 2i + ox + 1}`, `y ∈ {2j + oy, 2j + oy + 1}`: the two middle taps of its
/// filter along each axis. The filter banks of PyWavelets and the S-transform are centred
/// on `{2i, 2i + 1}` (offset 0); the db2 lifting's low band sits one pixel later (+1) and
/// its high band one pixel earlier (−1), and its weights follow it.
pub(crate) type BandOffsets = [(isize, isize); 3];

/// The numeric operations a fusion path supplies: coefficients, saliency sums and weights
/// all live in `Self` (i32 on the integer path, f32 on the float path).
pub(crate) trait Arith: Copy + Default + core::ops::AddAssign {
    /// One forward 2-D level on `dims`.
    fn forward_level(wavelet: Wavelet, buf: &mut [Self], dims: Dims, scratch: &mut [Self]);
    /// All inverse levels, deepest first.
    fn inverse(wavelet: Wavelet, buf: &mut [Self], dims: Dims, levels: u8, scratch: &mut [Self]);
    /// Band offsets of this path's transform for `wavelet`.
    fn band_offsets(wavelet: Wavelet) -> BandOffsets;
    /// Calls `f(y, S)` with the row of saliencies `S = exp(Sal/255) − 1` of every row `y`
    /// of the level input, built in `row` (nothing at all for a flat region, whose `S` is 0
    /// everywhere).
    fn saliency_rows(
        buf: &[Self],
        dims: Dims,
        norm: SaliencyNorm,
        wavelet: Wavelet,
        level: u8,
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
}

/// The checks and the call shared by both paths' public `fuse_pair`.
pub(crate) fn fuse_pair_checked<T: Arith>(
    a: &mut [T],
    b: &mut [T],
    dims: Dims,
    cfg: &FuseConfig,
    ll_weight: LlWeight,
    scratch: &mut [T],
) -> Result<(), Error> {
    dims.check_buffer("first image", a.len())?;
    dims.check_buffer("second image", b.len())?;
    dims.check_levels(cfg.levels)?;
    if ll_weight.0 > 1 << 15 {
        return Err(Error::InvalidParameter { name: "ll_weight" });
    }
    T::check_samples(a, dims)?;
    T::check_samples(b, dims)?;
    let work = split_scratch(scratch, crate::lifting::scratch_len(dims), dims)?;
    fuse_generic(a, b, dims, cfg, ll_weight, work);
    Ok(())
}

/// Number of weights per band map for `dims`: one per coefficient of a level-1 subband.
pub(crate) fn block_count(dims: Dims) -> usize {
    dims.width().div_ceil(2) * dims.height().div_ceil(2)
}

/// Saliency maps per image: one per high band.
const MAPS: usize = 3;

/// Scratch a fuse step needs besides its transform line: three band maps per image.
pub(crate) fn maps_len(dims: Dims) -> usize {
    2 * MAPS * block_count(dims)
}

/// Work areas of one fuse step, split from the caller's scratch.
pub(crate) struct Work<'s, T> {
    pub line: &'s mut [T],
    /// `2 · MAPS` maps of `block_count` values: image A's HL, LH, HH, then image B's.
    pub maps: &'s mut [T],
}

/// Splits the caller's scratch into a transform line of `line` elements and the maps.
pub(crate) fn split_scratch<T>(
    scratch: &mut [T],
    line: usize,
    dims: Dims,
) -> Result<Work<'_, T>, Error> {
    let needed = line + maps_len(dims);
    if scratch.len() < needed {
        return Err(Error::BufferTooSmall {
            which: "scratch",
            needed,
            got: scratch.len(),
        });
    }
    let (line, rest) = scratch.split_at_mut(line);
    Ok(Work {
        line,
        maps: &mut rest[..maps_len(dims)],
    })
}

/// Sums each pixel's saliency into the 2×2 window of every band map that covers it, a row
/// at a time (`row` is a line of scratch).
fn band_saliency<T: Arith>(
    buf: &[T],
    dims: Dims,
    cfg: &FuseConfig,
    level: u8,
    maps: &mut [T],
    row: &mut [T],
) {
    let (bw, bh) = (dims.width().div_ceil(2), dims.height().div_ceil(2));
    let n = bw * bh;
    maps[..MAPS * n].fill(T::default());
    let offsets = T::band_offsets(cfg.wavelet);
    T::saliency_rows(buf, dims, cfg.norm, cfg.wavelet, level, row, |y, srow| {
        for (band, &(ox, oy)) in offsets.iter().enumerate() {
            let sy = y as isize - oy;
            let by = (sy.max(0) as usize) / 2;
            if sy < 0 || by >= bh {
                continue;
            }
            let map_row = &mut maps[band * n + by * bw..band * n + (by + 1) * bw];
            // Window of coefficient bx: x ∈ {2bx + ox, 2bx + ox + 1}; bx grows with x.
            let first = ox.max(0) as usize;
            for (x, &s) in srow.iter().enumerate().skip(first) {
                let bx = (x as isize - ox) as usize / 2;
                if bx >= bw {
                    break;
                }
                map_row[bx] += s;
            }
        }
    });
}

/// The fuse step, generic over the path. `a` and `b` hold the two images on `dims`
/// (already validated); the fused image replaces `a`, `b` is consumed.
pub(crate) fn fuse_generic<T: Arith>(
    a: &mut [T],
    b: &mut [T],
    dims: Dims,
    cfg: &FuseConfig,
    ll_weight: LlWeight,
    work: Work<'_, T>,
) {
    let Work { line, maps } = work;
    if cfg.ablation == Ablation::NoWavelet {
        for_each_in(dims, |i| a[i] = T::mix(a[i], b[i], ll_weight));
        return;
    }
    let with_weights = cfg.ablation != Ablation::MaxHigh;
    let mut d = dims;
    for level in 1..=cfg.levels {
        let n = block_count(d);
        let (maps_a, maps_b) = maps.split_at_mut(MAPS * n);
        if with_weights {
            band_saliency(a, d, cfg, level, maps_a, line);
            band_saliency(b, d, cfg, level, maps_b, line);
            // Image A's maps become W₁ per coefficient.
            for (s1, s2) in maps_a.iter_mut().zip(maps_b.iter()) {
                *s1 = T::weight(*s1, *s2);
            }
        }
        T::forward_level(cfg.wavelet, a, d, line);
        T::forward_level(cfg.wavelet, b, d, line);
        let (nlx, nly) = (d.width().div_ceil(2), d.height().div_ceil(2));
        for y in 0..d.height() {
            let (by, y_high) = if y < nly { (y, false) } else { (y - nly, true) };
            let first_high_x = if y_high { 0 } else { nlx };
            for x in first_high_x..d.width() {
                let (bx, x_high) = if x < nlx { (x, false) } else { (x - nlx, true) };
                // HL = 0, LH = 1, HH = 2.
                let band = match (x_high, y_high) {
                    (true, false) => 0,
                    (false, true) => 1,
                    _ => 2,
                };
                let i = d.at(x, y);
                a[i] = if with_weights {
                    T::blend(a[i], b[i], maps_a[band * n + by * nlx + bx])
                } else if T::abs_ge(a[i], b[i]) {
                    a[i]
                } else {
                    b[i]
                };
            }
        }
        d = d.low_band();
    }
    if cfg.ablation != Ablation::SingleLl {
        for_each_in(d, |i| a[i] = T::mix(a[i], b[i], ll_weight));
    }
    T::inverse(cfg.wavelet, a, dims, cfg.levels, line);
}

/// Calls `f(index)` for every element of the region.
fn for_each_in(dims: Dims, mut f: impl FnMut(usize)) {
    for y in 0..dims.height() {
        for x in 0..dims.width() {
            f(dims.at(x, y));
        }
    }
}
