//! The integer fusion path: i32 coefficients, Q15 weights, the lifting of
//! [`crate::lifting`]. This is what the MCU runs.

use super::{
    Arith, FuseConfig, LlWeight, Sequential, TABLE_WORDS, fuse_generic, fuse_pair_checked,
    maps_len, split_scratch,
};
use crate::lifting::{self, Coefficients, bounds::level_bounds};
use crate::saliency::{self, ByteTable, SaliencyNorm};
use crate::{Dims, Error, Wavelet};

impl Arith for i32 {
    fn inverse(
        wavelet: Wavelet,
        (buf, dims, levels): (&mut [i32], Dims, u8),
        scratch: &mut [i32],
        prepare: &mut impl FnMut(u8, usize, &mut [i32]),
    ) {
        let bounds = level_bounds(wavelet, levels);
        // Fused coefficients are convex combinations of forward-transform outputs of the
        // same band (weights and the LL mix lie in 0..=1), so within its bound.
        let inside = Coefficients::InBounds;
        let how = (&bounds, inside);
        lifting::inverse_levels(wavelet, buf, dims, levels, scratch, how, prepare);
    }

    type SaliencyScale = saliency::Normalizer;

    fn saliency_scale(
        buf: &[i32],
        dims: Dims,
        norm: SaliencyNorm,
        wavelet: Wavelet,
        level: u8,
        // Never given: `check_and_max` leaves the scan to this function.
        _known_max: Option<i32>,
    ) -> Option<saliency::Normalizer> {
        let max = saliency::level_max(buf, dims, norm, wavelet, level);
        (max != 0).then(|| saliency::Normalizer::new(max))
    }

    fn fill_byte_table(norm: saliency::Normalizer, space: &mut [i32]) -> bool {
        let Some(entries) = space.first_chunk_mut() else {
            return false;
        };
        ByteTable::fill(entries, norm, GUARD_BITS);
        true
    }

    #[inline(always)]
    fn saliency_row(
        norm: saliency::Normalizer,
        table: Option<&[i32]>,
        rows: [&[i32]; 3],
        out: &mut [i32],
    ) {
        match table.and_then(|t| t.first_chunk()) {
            Some(entries) => {
                saliency::saliency_row_bytes(&ByteTable::new(entries, GUARD_BITS), rows, out)
            }
            None => saliency::saliency_row(norm, rows, out),
        }
    }

    fn weight(s1: i32, s2: i32) -> i32 {
        i32::from(saliency::weight(s1.unsigned_abs(), s2.unsigned_abs()).to_bits())
    }

    #[inline(always)]
    fn blend(h1: i32, h2: i32, w1: i32) -> i32 {
        let w1 = i64::from(w1);
        ((i64::from(h1) * w1 + i64::from(h2) * ((1 << 15) - w1) + (1 << 14)) >> 15) as i32
    }

    #[inline(always)]
    fn mix(a: i32, b: i32, w: LlWeight) -> i32 {
        let w = i64::from(w.0);
        ((i64::from(a) * ((1 << 15) - w) + i64::from(b) * w + (1 << 14)) >> 15) as i32
    }

    #[inline(always)]
    fn abs_ge(a: i32, b: i32) -> bool {
        a.unsigned_abs() >= b.unsigned_abs()
    }

    fn check_samples(buf: &[i32], dims: Dims) -> Result<(), Error> {
        lifting::check_samples(buf, dims)
    }
}

/// Scratch length (in `i32`) that [`fuse_pair`] and [`fuse_u8`] need for `dims`: a
/// transform line, the saliency maps and the saliency tables ([`fuse_scratch_words`]).
pub fn fuse_scratch_len(dims: Dims) -> usize {
    fuse_scratch_words(dims.width(), dims.height())
}

/// [`fuse_scratch_len`] for a `width × height` image, usable in constants (array sizes):
/// `max(w, min(w, COLUMN_BLOCK)·h)` for the transform ([`lifting::scratch_len`]) plus
/// `2·(⌈w/2⌉ + 1)·(⌈h/2⌉ + 1)` for the two saliency maps, plus 2048 for the two tables
/// [`fuse_u8`] looks level 1's saliencies up in (used by it alone).
pub const fn fuse_scratch_words(width: usize, height: usize) -> usize {
    lifting::scratch_words(width, height) + maps_len(width, height) + TABLE_WORDS
}

/// One integer fuse step: the fused image of `a` and `b` replaces `a`; `b` is used as work
/// space. Both hold samples with `|x| ≤ MAX_SAMPLE` on the `dims` region; `ll_weight` is
/// the second image's LL weight ([`LlWeight::HALF`] for the paper's mean). The result is
/// not clamped: callers that keep 8-bit images clamp it (as [`super::CyclicFuser`] does).
pub fn fuse_pair(
    a: &mut [i32],
    b: &mut [i32],
    dims: Dims,
    cfg: &FuseConfig,
    ll_weight: LlWeight,
    scratch: &mut [i32],
) -> Result<(), Error> {
    // One scratch size for both entry points; this one leaves the tables unused (its
    // samples need not be 8-bit).
    let needed = fuse_scratch_len(dims);
    if scratch.len() < needed {
        return Err(Error::BufferTooSmall {
            which: "scratch",
            needed,
            got: scratch.len(),
        });
    }
    let layout = (1, false, false);
    fuse_pair_checked(a, b, dims, cfg, ll_weight, scratch, layout, &Sequential)
}

/// Fraction bits the 8-bit fusion keeps below the pixel's integer part while it works.
///
/// The unscaled lifting stores high bands at about half the orthonormal scale and the
/// inverse amplifies their rounding; three guard bits (samples × 8, at most 2040, well
/// inside `MAX_SAMPLE`) keep the fused 8-bit result within a gray level of exact
/// arithmetic, at no cost in bounds.
pub const GUARD_BITS: u32 = 3;

/// Work buffers of [`fuse_u8`]: `a` and `b` hold at least `w·h` words, `scratch` at least
/// [`fuse_scratch_len`].
pub struct U8Work<'w> {
    /// Transform work for the first image; holds the fused 8-bit values on return.
    pub a: &'w mut [i32],
    /// Transform work for the second image.
    pub b: &'w mut [i32],
    /// Lines and saliency maps.
    pub scratch: &'w mut [i32],
}

/// Fuses two 8-bit images (each with its own stride) on the integer path with
/// [`GUARD_BITS`] of extra precision. The result, rounded and clamped to 0..=255, is left
/// packed `w × h` in `work.a`, so a caller may fuse into one of its inputs.
pub fn fuse_u8(
    (a, a_dims): (&[u8], Dims),
    (b, b_dims): (&[u8], Dims),
    cfg: &FuseConfig,
    ll_weight: LlWeight,
    work: U8Work<'_>,
) -> Result<(), Error> {
    let (w, h) = (a_dims.width(), a_dims.height());
    if (w, h) != (b_dims.width(), b_dims.height()) {
        return Err(Error::SizeMismatch);
    }
    a_dims.check_buffer("first image", a.len())?;
    b_dims.check_buffer("second image", b.len())?;
    let packed = Dims::new(w, h)?;
    packed.check_levels(cfg.levels)?;
    packed.check_buffer("work_a", work.a.len())?;
    packed.check_buffer("work_b", work.b.len())?;
    if ll_weight.0 > 1 << 15 {
        return Err(Error::InvalidParameter { name: "ll_weight" });
    }
    let parts = split_scratch(
        work.scratch,
        lifting::scratch_len(packed),
        (1, false, true),
        packed,
    )?;
    // Every buffer was checked to hold its region above: the zips pair all `h` rows.
    for (src, src_dims, dst) in [(a, a_dims, &mut *work.a), (b, b_dims, &mut *work.b)] {
        for (row, dst_row) in src_dims.rows(src).zip(dst.chunks_exact_mut(w)) {
            for (d, &v) in dst_row.iter_mut().zip(row) {
                *d = i32::from(v) << GUARD_BITS;
            }
        }
    }
    // A reference maximum is in 8-bit units; the samples now carry the guard bits.
    let cfg = &FuseConfig {
        norm: match cfg.norm {
            SaliencyNorm::Reference(r) => {
                SaliencyNorm::Reference(r.saturating_mul(1 << GUARD_BITS))
            }
            local => local,
        },
        ..*cfg
    };
    fuse_generic(
        work.a,
        work.b,
        packed,
        cfg,
        ll_weight,
        parts,
        [None; 2],
        &Sequential,
    )?;
    let half = 1 << (GUARD_BITS - 1);
    for v in work.a.iter_mut().take(packed.pixels()) {
        *v = ((*v + half) >> GUARD_BITS).clamp(0, 255);
    }
    Ok(())
}
