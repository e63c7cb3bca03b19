//! The 8-bit fuse step with level 1 in 16-bit lanes: both images' level 1 from their
//! bytes ([`crate::lifting::lanes`]), the bands blended two coefficients a word, the
//! result back to bytes; the deeper levels, if any, by the 32-bit step on the two LL₁
//! bands widened ([`fuse_generic`] from level 2), narrowed back before the lanes'
//! inverse. What [`super::fuse_u8`] runs with the full method on images whose width is a
//! multiple of 4 (every device tile); the saliency maps are the same as on the 32-bit
//! path.
//!
//! Level 1's arithmetic differs from the 32-bit path's in its rounding, not in its
//! method, and only where the 32-bit path rounds otherwise: db2's lifting products by Q16
//! constants rounded down ([`crate::lifting::lanes`]); at one level and an LL weight other
//! than the paper's mean, LL `⌊(1 − w)·a⌋ + ⌊w·b⌋`. Each high-band coefficient is
//! `b + R(W₁·(a − b))` with `W₁` in Q16, and the paper's mean `⌊(a + b + 1)/2⌋`, as on
//! the 32-bit path (`R` rounds to nearest, halves up). Haar's lifting is exact in lanes:
//! with the mean, or more than one level, a Haar step gives the 32-bit path's bytes.

use super::config::{FuseConfig, LlWeight};
use super::driver::{
    ImagePair, Maps, Sequential, StepStart, WindowLayout, Work, fuse_generic, maps_len,
    maps_too_small,
};
use crate::lanes::I16x2;
use crate::lifting::lanes as lifting_lanes;
use crate::saliency;
use crate::{Dims, Error, Wavelet};

/// Whether the scratch of a `dims` step with `wavelet` leaves room, beside level 1's
/// weights, for the deeper levels' maps (all but the smallest images: the LL₁ maps need
/// about half of one level-1 map).
pub(crate) fn deeper_maps_fit(wavelet: Wavelet, dims: Dims) -> bool {
    let (mw, mh) = WindowLayout::of(wavelet).map_dims(dims);
    maps_len(dims.width() / 2, dims.height().div_ceil(2)) <= mw * mh
}

/// Fuses the 8-bit images `a` and `b` (laid out as their `Dims` say, alike in size, the
/// width a multiple of 4) `cfg.levels` deep into `a`. `work` is the step's
/// scratch, its maps holding both images' level-1 saliency window sums
/// ([`super::first_level_maps`]); `work_a` and `work_b` take the images' level 1 in lanes
/// (`w·h/2` words each) and, for more levels, their LL₁ bands widened after that. On an
/// error `a` is as it was.
pub(crate) fn fuse_in_lanes(
    (a, a_dims): (&mut [u8], Dims),
    (b, b_dims): (&[u8], Dims),
    cfg: &FuseConfig,
    ll_weight: LlWeight,
    work: Work<'_, i32>,
    [work_a, work_b]: [&mut [i32]; 2],
) -> Result<(), Error> {
    let dims = Dims::new(a_dims.width(), a_dims.height())?;
    let wavelet = cfg.wavelet;
    let layout = WindowLayout::of(wavelet);
    let Work { lines, maps } = work;
    let (mw, mh) = layout.map_dims(dims);
    let maps_error = maps_too_small(layout, dims, maps.space.len());
    let (map_a, rest) = maps.space.split_at_mut_checked(mw * mh).ok_or(maps_error)?;
    let map_b = rest.get(..mw * mh).ok_or(maps_error)?;
    let words = dims.pixels() / 2;
    let (lanes_a, wide_a) = split_work(work_a, words, "work_a")?;
    let (lanes_b, wide_b) = split_work(work_b, words, "work_b")?;
    const G: u32 = crate::lifting::GUARD_BITS;
    if !(lifting_lanes::forward_from_bytes::<G>(wavelet, (a, a_dims), lanes_a)
        && lifting_lanes::forward_from_bytes::<G>(wavelet, (b, b_dims), lanes_b))
    {
        return Err(Error::InvalidParameter { name: "width" });
    }
    weights_q16(map_a, map_b);
    // With deeper levels LL₁ is fused there; image B's map is free for their maps.
    let ll_weight = if cfg.levels > 1 {
        let deeper = Work {
            lines,
            maps: Maps {
                space: rest,
                first_ready: false,
            },
        };
        let widened = ImagePair {
            a: wide_a,
            b: wide_b,
            dims: Dims::new(dims.width() / 2, dims.height().div_ceil(2))?,
        };
        fuse_deeper((&mut *lanes_a, lanes_b), widened, cfg, ll_weight, deeper)?;
        None
    } else {
        Some(ll_weight)
    };
    let bands = Bands {
        weights: map_a,
        map_width: mw,
        shifts: layout.shifts,
        ll_weight,
    };
    let row_words = dims.width() / 2;
    let mut blend = |y: usize, ra: &mut [I16x2]| {
        if let Some(rb) = lanes_b.get(y * row_words..(y + 1) * row_words) {
            bands.blend_row(y, ra, rb);
        }
    };
    // `a` is written only now, and only if the sizes checked above hold.
    if lifting_lanes::inverse_to_bytes::<G>(wavelet, lanes_a, (a, a_dims), &mut blend) {
        Ok(())
    } else {
        Err(Error::InvalidParameter { name: "width" })
    }
}

/// An image's work buffer as its level 1 in lanes (`words` words) and the rest.
fn split_work<'w>(
    work: &'w mut [i32],
    words: usize,
    which: &'static str,
) -> Result<(&'w mut [I16x2], &'w mut [i32]), Error> {
    let got = work.len();
    let (lanes, rest) = work
        .split_at_mut_checked(words)
        .ok_or(Error::BufferTooSmall {
            which,
            needed: words,
            got,
        })?;
    Ok((bytemuck::cast_slice_mut(lanes), rest))
}

/// Levels 2 … `cfg.levels` of both images, whose level 1 in lanes is `lanes`: their LL₁
/// bands widened into `widened`, fused there by the 32-bit step, and the result narrowed
/// back into image A's LL₁ words.
fn fuse_deeper(
    (lanes_a, lanes_b): (&mut [I16x2], &[I16x2]),
    widened: ImagePair<'_, i32>,
    cfg: &FuseConfig,
    ll_weight: LlWeight,
    work: Work<'_, i32>,
) -> Result<(), Error> {
    let ImagePair { a, b, dims: ll } = widened;
    let too_small = ll.too_small("work", a.len().min(b.len()));
    let (wide_a, wide_b) = (
        a.get_mut(..ll.pixels()).ok_or(too_small)?,
        b.get_mut(..ll.pixels()).ok_or(too_small)?,
    );
    widen_ll(lanes_a, wide_a, ll.width());
    widen_ll(lanes_b, wide_b, ll.width());
    let images = ImagePair {
        a: &mut *wide_a,
        b: wide_b,
        dims: ll,
    };
    fuse_generic(
        images,
        cfg,
        ll_weight,
        work,
        StepStart::deeper(2),
        &Sequential,
    )?;
    narrow_ll(wide_a, lanes_a, ll.width());
    Ok(())
}

/// The LL₁ words of a level in lanes (the first `width/2` words of every other row of
/// `width` words) as `i32` rows of `width` into `wide`.
fn widen_ll(lanes: &[I16x2], wide: &mut [i32], width: usize) {
    let rows = lanes.chunks(2 * width).zip(wide.chunks_exact_mut(width));
    for (src, dst) in rows {
        for (pair, w) in dst.as_chunks_mut::<2>().0.iter_mut().zip(src) {
            *pair = [i32::from(w.lo()), i32::from(w.hi())];
        }
    }
}

/// [`widen_ll`] undone: `i32` rows of `width` back into the LL₁ words, each value
/// saturated to a lane (the fused LL₁ lies within the inputs' bound, which a lane holds).
fn narrow_ll(wide: &[i32], lanes: &mut [I16x2], width: usize) {
    let lane = |v: i32| v.clamp(i16::MIN.into(), i16::MAX.into()) as i16;
    let rows = lanes.chunks_mut(2 * width).zip(wide.chunks_exact(width));
    for (dst, src) in rows {
        for (w, &[lo, hi]) in dst.iter_mut().zip(src.as_chunks::<2>().0) {
            *w = I16x2::new(lane(lo), lane(hi));
        }
    }
}

/// Turns image A's saliency window sums into `W₁·2¹⁶` per window, with image B's.
fn weights_q16(map_a: &mut [i32], map_b: &[i32]) {
    for (s1, &s2) in map_a.iter_mut().zip(map_b) {
        *s1 = i32::from(saliency::weight(*s1 as u32, s2 as u32).to_bits()) << 1;
    }
}

/// How a transformed row's bands are blended.
struct Bands<'m> {
    /// `W₁·2¹⁶` per window ([`WindowLayout`]).
    weights: &'m [i32],
    /// The map's width.
    map_width: usize,
    /// [`WindowLayout::shifts`] of HL, LH and HH.
    shifts: [(usize, usize); 3],
    /// Image B's LL weight; `None` where LL₁ was fused with the deeper levels.
    ll_weight: Option<LlWeight>,
}

impl Bands<'_> {
    /// Blends row `y` of image A's level (`ra`, its words) with image B's (`rb`): LL
    /// (where it is to be mixed) and HL for even `y`, LH and HH for odd `y`, each band's
    /// row `y / 2`.
    #[inline(always)]
    fn blend_row(&self, y: usize, ra: &mut [I16x2], rb: &[I16x2]) {
        let half = ra.len() / 2;
        let ((low_a, high_a), (low_b, high_b)) = (ra.split_at_mut(half), rb.split_at(half));
        let [hl, lh, hh] = self.shifts;
        let weights = |(sx, sy): (usize, usize)| {
            let start = (y / 2 + sy) * self.map_width + sx;
            self.weights
                .get(start..start + 2 * half)
                .unwrap_or_default()
        };
        if y.is_multiple_of(2) {
            if let Some(ll_weight) = self.ll_weight {
                mix_ll(low_a, low_b, ll_weight);
            }
            blend_band(high_a, high_b, weights(hl));
        } else {
            blend_band(low_a, low_b, weights(lh));
            blend_band(high_a, high_b, weights(hh));
        }
    }
}

/// `a = b + R(W₁·(a − b))` coefficient by coefficient, two a word. Rounded, not floored:
/// a floor's bias of half a step in every blend cost the study 1.1 dB. High-band
/// coefficients of two images differ by at most twice the band's bound (12 864), so the
/// difference doubled still fits a lane.
#[inline(always)]
fn blend_band(a: &mut [I16x2], b: &[I16x2], weights: &[i32]) {
    let (pairs, _) = weights.as_chunks::<2>();
    for ((x, &y), &w) in a.iter_mut().zip(b).zip(pairs) {
        *x = y + (*x - y).mul_q16_each_rounded(w);
    }
}

/// LL: `⌊(a + b + 1)/2⌋` for the paper's mean, else `⌊(1 − w)·a⌋ + ⌊w·b⌋` (LL
/// coefficients of two images can differ by more than a lane holds, so no difference is
/// taken).
#[inline(always)]
fn mix_ll(a: &mut [I16x2], b: &[I16x2], ll_weight: LlWeight) {
    if ll_weight == LlWeight::HALF {
        for (x, &y) in a.iter_mut().zip(b) {
            *x = x.halving_add(y + I16x2::splat(1));
        }
    } else {
        let w = i32::from(ll_weight.0) << 1;
        for (x, &y) in a.iter_mut().zip(b) {
            *x = x.mul_q16_add((1 << 16) - w, y, w);
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::fusion::driver::TABLE_WORDS;
    use crate::fusion::driver::tests::{fuse_from_level, fuse_u8_alone};
    use crate::fusion::integer::first_level_maps;
    use crate::fusion::{FuseConfig, GUARD_BITS, ImagePair, U8Pair};
    use crate::lifting::q16;
    use crate::lifting::{
        Coefficients, Lift, Saturation, forward_level_from_bytes, inverse_level, level_bounds,
    };
    use crate::{SaliencyNorm, Wavelet};
    use core::sync::atomic::{AtomicI64, Ordering::Relaxed};
    use std::{vec, vec::Vec};

    /// The largest `|value|` any [`Wide`] operation made.
    static PEAK: AtomicI64 = AtomicI64::new(0);

    /// The lanes' arithmetic in 64 bits, wrapping nowhere: where the lanes agree with it,
    /// no lane wrapped; [`PEAK`] says how close one came.
    #[derive(Debug, Clone, Copy, Default, PartialEq)]
    struct Wide(i64);

    impl Wide {
        fn seen(v: i64) -> Self {
            PEAK.fetch_max(v.abs(), Relaxed);
            Self(v)
        }
        fn q16(c: i32, v: i64) -> i64 {
            (i64::from(c) * v) >> 16
        }
    }

    impl core::ops::Add for Wide {
        type Output = Self;
        fn add(self, o: Self) -> Self {
            Self::seen(self.0 + o.0)
        }
    }
    impl core::ops::Sub for Wide {
        type Output = Self;
        fn sub(self, o: Self) -> Self {
            Self::seen(self.0 - o.0)
        }
    }
    impl core::ops::AddAssign for Wide {
        fn add_assign(&mut self, o: Self) {
            *self = *self + o;
        }
    }
    impl core::ops::SubAssign for Wide {
        fn sub_assign(&mut self, o: Self) {
            *self = *self - o;
        }
    }

    impl Lift for Wide {
        const ROW_PASSES: bool = false;
        fn half(self) -> Self {
            Self(self.0 >> 1)
        }
        type Constants = q16::Constants;
        fn constants() -> q16::Constants {
            q16::CONSTANTS
        }
        fn sqrt3(self, k: q16::Constants) -> Self {
            Self::seen(Self::q16(k.sqrt3, self.0))
        }
        fn predict(s: Self, s_prev: Self, k: q16::Constants) -> Self {
            Self::seen(Self::q16(k.a, s.0) + Self::q16(k.b, s_prev.0))
        }
        fn saturate(self, _bound: i32) -> Self {
            self
        }
        const SATURATES: bool = false;
        fn from_guarded_byte(v: u8) -> Self {
            Self(i64::from(v) << GUARD_BITS)
        }
        fn to_byte(self) -> u8 {
            ((self.0 + (1 << (GUARD_BITS - 1))) >> GUARD_BITS).clamp(0, 255) as u8
        }
    }

    /// The lanes' fuse step of `a` and `b` computed on [`Wide`] samples by the generic
    /// level: the same saliency maps and weights, each band blended as `fuse_one_level`
    /// says.
    fn wide_step(a: &[u8], b: &[u8], dims: Dims, cfg: &FuseConfig, ll: LlWeight) -> Vec<u8> {
        let (w, h) = (dims.width(), dims.height());
        let layout = WindowLayout::of(cfg.wavelet);
        let (mw, mh) = layout.map_dims(dims);
        let mut maps = vec![0i32; 2 * mw * mh];
        let (mut table, mut line) = (vec![0i32; TABLE_WORDS], vec![0i32; w]);
        let norm = match cfg.norm {
            SaliencyNorm::Reference(r) => SaliencyNorm::Reference(r << GUARD_BITS),
            local => local,
        };
        let guarded = FuseConfig { norm, ..*cfg };
        first_level_maps(
            [(a, dims), (b, dims)],
            &guarded,
            &mut maps,
            &mut table,
            &mut line,
        )
        .unwrap();
        let (map_a, map_b) = maps.split_at_mut(mw * mh);
        weights_q16(map_a, map_b);
        let transform = |img: &[u8]| {
            let (mut buf, mut scratch) = (vec![Wide(0); w * h], vec![Wide(0); w]);
            forward_level_from_bytes(cfg.wavelet, &mut buf, dims, &mut scratch, (img, dims));
            buf
        };
        let (mut ca, cb) = (transform(a), transform(b));
        let [hl, lh, hh] = layout.shifts;
        let weight = |(sx, sy): (usize, usize), j: usize, i: usize| map_a[(j + sy) * mw + sx + i];
        let lw = i32::from(ll.0) << 1;
        let rounded = |w: i32, v: i64| (i64::from(w) * v + (1 << 15)) >> 16;
        for y in 0..h {
            let (ra, rb) = (&mut ca[y * w..][..w], &cb[y * w..][..w]);
            for x in 0..w {
                let (low, i, j) = (x < w / 2, x % (w / 2), y / 2);
                let (p, q) = (ra[x].0, rb[x].0);
                ra[x] = Wide(match (y % 2, low) {
                    (0, true) if cfg.levels > 1 => p,
                    (0, true) if ll == LlWeight::HALF => (p + q + 1) >> 1,
                    (0, true) => Wide::q16((1 << 16) - lw, p) + Wide::q16(lw, q),
                    (0, false) => q + rounded(weight(hl, j, i), p - q),
                    (_, true) => q + rounded(weight(lh, j, i), p - q),
                    (_, false) => q + rounded(weight(hh, j, i), p - q),
                });
            }
        }
        if cfg.levels > 1 {
            deeper_levels(&mut ca, &cb, dims, &guarded, ll);
        }
        let mut out = vec![0u8; w * h];
        let bounds = level_bounds(cfg.wavelet, 1)[0];
        let saturation = Saturation {
            bounds: &bounds,
            coefficients: Coefficients::InBounds,
        };
        let mut scratch = vec![Wide(0); w];
        let out_rows = Some((&mut out[..], dims));
        inverse_level(
            cfg.wavelet,
            &mut ca,
            dims,
            &mut scratch,
            saturation,
            &mut |_, _| {},
            out_rows,
        );
        out
    }

    /// Levels 2 and on of the level-1 transforms `ca` and `cb` as `fuse_in_lanes` runs
    /// them: LL₁ to `i32`, the generic step from level 2, the result back into `ca`,
    /// saturated to a lane.
    fn deeper_levels(ca: &mut [Wide], cb: &[Wide], dims: Dims, cfg: &FuseConfig, ll: LlWeight) {
        let w = dims.width();
        let band = Dims::new(w / 2, dims.height().div_ceil(2)).unwrap();
        let at = |j: usize, i: usize| 2 * j * w + i;
        let take = |c: &[Wide]| -> Vec<i32> {
            (0..band.height())
                .flat_map(|j| (0..band.width()).map(move |i| c[at(j, i)].0 as i32))
                .collect()
        };
        let (mut la, mut lb) = (take(ca), take(cb));
        let pair = ImagePair {
            a: &mut la,
            b: &mut lb,
            dims: band,
        };
        fuse_from_level(2, pair, cfg, ll);
        for (k, &v) in la.iter().enumerate() {
            let lane = v.clamp(i16::MIN.into(), i16::MAX.into());
            ca[at(k / band.width(), k % band.width())] = Wide(i64::from(lane));
        }
    }

    /// Tiles of 0 and 255 (checkers, stripes, binary noise), of random bytes and a ramp.
    fn tiles(w: usize, h: usize) -> Vec<Vec<u8>> {
        let mut out = crate::extreme_tiles(w, h, 1, 7);
        let mut noise = crate::test_bytes(8);
        out.push((0..w * h).map(|_| noise()).collect());
        out.push((0..w * h).map(|i| ((i % w) * 255 / w) as u8).collect());
        out
    }

    /// `fuse_u8` runs level 1 in lanes, and its bytes are those of the same arithmetic
    /// in 64 bits (the deeper levels, one to two more, by the generic step): no lane
    /// wraps, on the largest coefficients 8-bit images have, with either wavelet, at
    /// every size a device tile can take and smaller.
    #[test]
    fn lanes_are_the_wide_arithmetic_and_no_lane_wraps() {
        PEAK.store(0, Relaxed);
        let mut deeper = 0;
        for (w, h) in [
            (64, 24),
            (320, 16),
            (160, 9),
            (12, 7),
            (8, 2),
            (4, 1),
            (4, 5),
        ] {
            let dims = Dims::new(w, h).unwrap();
            let images = tiles(w, h);
            for (i, a) in images.iter().enumerate() {
                let b = &images[(i + 3) % images.len()];
                let runs = [
                    (1, SaliencyNorm::Local, LlWeight::HALF),
                    (1, SaliencyNorm::Reference(200), LlWeight(9_000)),
                    (2, SaliencyNorm::Local, LlWeight::HALF),
                    (2, SaliencyNorm::Reference(200), LlWeight(9_000)),
                    (3, SaliencyNorm::Reference(60), LlWeight::HALF),
                ];
                let wavelets = [Wavelet::Db2, Wavelet::Haar].into_iter();
                for (wavelet, (levels, norm, ll)) in wavelets.flat_map(|wl| runs.map(|r| (wl, r))) {
                    let cfg = FuseConfig {
                        wavelet,
                        levels,
                        norm,
                        ..FuseConfig::default()
                    };
                    let lanes = crate::fusion::integer::takes_lanes(&cfg, dims);
                    if levels > 1 && (dims.check_levels(levels).is_err() || !lanes) {
                        continue;
                    }
                    assert!(lanes, "{w}×{h} {wavelet:?} L{levels}");
                    deeper += usize::from(levels > 1);
                    let want = wide_step(a, b, dims, &cfg, ll);
                    let mut got = a.clone();
                    fuse_u8_alone(U8Pair::same(&mut got, b, dims), &cfg, ll);
                    let what = std::format!("{w}×{h} images {i} {wavelet:?} L{levels} {norm:?}");
                    assert_eq!(got, want, "{what} {ll:?}");
                }
            }
        }
        assert!(deeper >= 100, "{deeper} runs with deeper levels");
        let peak = PEAK.load(Relaxed);
        assert!(peak < i64::from(i16::MAX), "a lane would wrap: {peak}");
    }

    /// An image fused with itself comes back, byte for byte; a strided first image keeps
    /// the bytes between its rows.
    #[test]
    fn an_image_fused_with_itself_comes_back_and_padding_stays() {
        let (w, h, stride) = (40, 10, 43);
        let dims = Dims::new(w, h).unwrap();
        let strided = Dims::with_stride(w, h, stride).unwrap();
        for img in tiles(w, h) {
            let padded = crate::padded_rows(&img, w, stride, 9);
            for (wavelet, levels) in [(Wavelet::Db2, 1), (Wavelet::Haar, 1), (Wavelet::Db2, 2)] {
                let cfg = FuseConfig {
                    wavelet,
                    levels,
                    ..FuseConfig::default()
                };
                let mut fused = padded.clone();
                let pair = U8Pair {
                    a: &mut fused,
                    a_dims: strided,
                    b: &img,
                    b_dims: dims,
                };
                fuse_u8_alone(pair, &cfg, LlWeight::HALF);
                assert_eq!(fused, padded, "{wavelet:?} L{levels}");
            }
        }
    }
}
