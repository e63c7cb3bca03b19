//! The 8-bit fuse step at one db2 level in 16-bit lanes: both images' level 1 from their
//! bytes ([`db2_lanes`]), the bands blended two coefficients a word, the result back to
//! bytes. What [`super::fuse_u8`] runs for db2 at one level, the full method, on images
//! whose width is a multiple of 4 (every device tile); the saliency maps are the same as
//! on the 32-bit path.
//!
//! The arithmetic differs from the 32-bit path's in its rounding, not in its method:
//! lifting products by Q16 constants rounded down ([`db2_lanes`]); each high-band
//! coefficient `b + R(W₁·(a − b))` with `W₁` in Q16; LL `⌊(a + b + 1)/2⌋` for the paper's
//! mean, else `⌊(1 − w)·a⌋ + ⌊w·b⌋` (`R` rounds to nearest, halves up).

use super::{LlWeight, WindowLayout, split_maps};
use crate::lanes::I16x2;
use crate::lifting::db2_lanes;
use crate::saliency;
use crate::{Dims, Error};

/// Fuses the 8-bit images `a` and `b` (laid out as their `Dims` say, alike in size, the
/// width a multiple of 4) at one db2 level into `a`. `maps` holds both images' level-1
/// saliency window sums ([`super::first_level_maps`]); `work_a` and `work_b` take the two
/// transforms (`w·h/2` words each). On an error `a` is as it was.
#[inline(never)]
pub(crate) fn fuse_one_level(
    (a, a_dims): (&mut [u8], Dims),
    (b, b_dims): (&[u8], Dims),
    maps: &mut [i32],
    ll_weight: LlWeight,
    [work_a, work_b]: [&mut [i32]; 2],
) -> Result<(), Error> {
    let dims = Dims::new(a_dims.width(), a_dims.height())?;
    let layout = WindowLayout::of(crate::Wavelet::Db2);
    let [map_a, map_b] = split_maps(maps, layout, dims)?;
    let words = dims.pixels() / 2;
    let too_small = |which, got| Error::BufferTooSmall {
        which,
        needed: words,
        got,
    };
    let (len_a, len_b) = (work_a.len(), work_b.len());
    let buf_a: &mut [I16x2] =
        bytemuck::cast_slice_mut(work_a.get_mut(..words).ok_or(too_small("work_a", len_a))?);
    let buf_b: &mut [I16x2] =
        bytemuck::cast_slice_mut(work_b.get_mut(..words).ok_or(too_small("work_b", len_b))?);
    const G: u32 = super::GUARD_BITS;
    if !(db2_lanes::forward_from_bytes::<G>((a, a_dims), buf_a)
        && db2_lanes::forward_from_bytes::<G>((b, b_dims), buf_b))
    {
        return Err(Error::InvalidParameter { name: "width" });
    }
    weights_q16(map_a, map_b);
    let bands = Bands {
        weights: map_a,
        map_width: layout.map_dims(dims).0,
        shifts: layout.shifts,
        ll_weight,
    };
    let row_words = dims.width() / 2;
    let mut blend = |y: usize, ra: &mut [I16x2]| {
        if let Some(rb) = buf_b.get(y * row_words..(y + 1) * row_words) {
            bands.blend_row(y, ra, rb);
        }
    };
    // `a` is written only now, and only if the sizes checked above hold.
    if db2_lanes::inverse_to_bytes::<G>(buf_a, (a, a_dims), &mut blend) {
        Ok(())
    } else {
        Err(Error::InvalidParameter { name: "width" })
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
    /// Image B's LL weight.
    ll_weight: LlWeight,
}

impl Bands<'_> {
    /// Blends row `y` of image A's level (`ra`, its words) with image B's (`rb`): LL and
    /// HL for even `y`, LH and HH for odd `y`, each band's row `y / 2`.
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
            mix_ll(low_a, low_b, self.ll_weight);
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
    use crate::fusion::integer::first_level_maps;
    use crate::fusion::tests::fuse_u8_alone;
    use crate::fusion::{FuseConfig, GUARD_BITS, TABLE_WORDS, U8Pair};
    use crate::lifting::{
        Coefficients, Lift, Saturation, db2_lanes, forward_level_from_bytes, inverse_level,
        level_bounds,
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
        type Constants = db2_lanes::Constants;
        fn constants() -> db2_lanes::Constants {
            db2_lanes::CONSTANTS
        }
        fn sqrt3(self, k: db2_lanes::Constants) -> Self {
            Self::seen(Self::q16(k.sqrt3, self.0))
        }
        fn predict(s: Self, s_prev: Self, k: db2_lanes::Constants) -> Self {
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
        let layout = WindowLayout::of(Wavelet::Db2);
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
            forward_level_from_bytes(Wavelet::Db2, &mut buf, dims, &mut scratch, (img, dims));
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
                    (0, true) if ll == LlWeight::HALF => (p + q + 1) >> 1,
                    (0, true) => Wide::q16((1 << 16) - lw, p) + Wide::q16(lw, q),
                    (0, false) => q + rounded(weight(hl, j, i), p - q),
                    (_, true) => q + rounded(weight(lh, j, i), p - q),
                    (_, false) => q + rounded(weight(hh, j, i), p - q),
                });
            }
        }
        let mut out = vec![0u8; w * h];
        let bounds = level_bounds(Wavelet::Db2, 1)[0];
        let saturation = Saturation {
            bounds: &bounds,
            coefficients: Coefficients::InBounds,
        };
        let mut scratch = vec![Wide(0); w];
        let out_rows = Some((&mut out[..], dims));
        inverse_level(
            Wavelet::Db2,
            &mut ca,
            dims,
            &mut scratch,
            saturation,
            &mut |_, _| {},
            out_rows,
        );
        out
    }

    /// Tiles of 0 and 255 (checkers, stripes, binary noise), of random bytes and a ramp.
    fn tiles(w: usize, h: usize) -> Vec<Vec<u8>> {
        let mut out = crate::extreme_tiles(w, h, 1, 7);
        let mut noise = crate::test_bytes(8);
        out.push((0..w * h).map(|_| noise()).collect());
        out.push((0..w * h).map(|i| ((i % w) * 255 / w) as u8).collect());
        out
    }

    /// `fuse_u8` at one db2 level runs in lanes, and its bytes are those of the same
    /// arithmetic in 64 bits: no lane wraps, on the largest coefficients 8-bit images
    /// have, at every size a device tile can take and smaller.
    #[test]
    fn lanes_are_the_wide_arithmetic_and_no_lane_wraps() {
        PEAK.store(0, Relaxed);
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
                for (norm, ll) in [
                    (SaliencyNorm::Local, LlWeight::HALF),
                    (SaliencyNorm::Reference(200), LlWeight(9_000)),
                ] {
                    let cfg = FuseConfig {
                        wavelet: Wavelet::Db2,
                        levels: 1,
                        norm,
                        ..FuseConfig::default()
                    };
                    assert!(crate::fusion::integer::takes_lanes(&cfg, dims));
                    let want = wide_step(a, b, dims, &cfg, ll);
                    let mut got = a.clone();
                    fuse_u8_alone(U8Pair::same(&mut got, b, dims), &cfg, ll);
                    assert_eq!(got, want, "{w}×{h} images {i} {norm:?} {ll:?}");
                }
            }
        }
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
            let mut padded = vec![9u8; stride * h];
            for (dst, src) in padded.chunks_mut(stride).zip(img.chunks(w)) {
                dst[..w].copy_from_slice(src);
            }
            let pair = U8Pair {
                a: &mut padded,
                a_dims: strided,
                b: &img,
                b_dims: dims,
            };
            fuse_u8_alone(pair, &FuseConfig::default(), LlWeight::HALF);
            for (row, want) in padded.chunks(stride).zip(img.chunks(w)) {
                assert_eq!(&row[..w], want);
                assert_eq!(&row[w..], &[9, 9, 9][..row.len() - w]);
            }
        }
    }
}
