//! The integer fusion path: i32 coefficients, Q15 weights, the lifting of
//! [`crate::lifting`]. This is what the MCU runs.

use super::config::{Ablation, FuseConfig, LlWeight};
use super::driver::{
    Arith, ByteImages, ImagePair, Samples, ScratchLayout, Sequential, StepStart, TABLE_WORDS,
    WindowLayout, WindowMap, fuse_generic, fuse_pair_checked, maps_len, split_maps, split_scratch,
};
use crate::lifting::{self, GUARD_BITS, LevelBounds, bounds::level_bounds};
use crate::packed::widen_shifted;
use crate::saliency::{
    self, ByteSaliency, LaplacianTable, Normalizer, SaliencyNorm, laplacian_max_u8,
    row_and_neighbours, saliency_row_u8, saliency_windows_u8,
};
use crate::{Dims, Error, MAX_LEVELS, Wavelet};

impl Arith for i32 {
    /// The bounds the forward transform proves.
    fn inverse_bounds(wavelet: Wavelet, levels: u8) -> [LevelBounds; MAX_LEVELS as usize] {
        level_bounds(wavelet, levels)
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

    #[inline(always)]
    fn saliency_row(norm: saliency::Normalizer, rows: [&[i32]; 3], out: &mut [i32]) {
        saliency::saliency_row(norm, rows, out);
    }

    /// `W₁` in Q15, kept shifted left by 15 more bits (at most 2³⁰) as `blend` takes it.
    /// Saliency sums are never negative: they pass as they are, no absolute value.
    fn weight(s1: i32, s2: i32) -> i32 {
        i32::from(saliency::weight(s1 as u32, s2 as u32).to_bits()) << 15
    }

    /// `(h1·w + h2·(2¹⁵ − w) + 2¹⁴) >> 15` for the Q15 weight `w` (`w1 = w·2¹⁵`), to the
    /// bit: that is `h2 + ((h1 − h2)·w + 2¹⁴) >> 15` (`h2·2¹⁵` leaves the floor whole),
    /// and with `(h1 − h2)·4` against `w·2¹⁵` the shift becomes the high word of a
    /// rounded 32×32-bit product, one instruction on the Cortex-M7 (SMMLAR). The bounds
    /// keep `|h1 − h2|` below 2²⁹ (test `band_differences_fit_the_rounded_product`).
    #[inline(always)]
    fn blend(h1: i32, h2: i32, w1: i32) -> i32 {
        h2 + rounded_high_word((h1 - h2) << 2, w1)
    }

    #[inline(always)]
    fn mix(a: i32, b: i32, w: LlWeight) -> i32 {
        // `blend` with the weight on `b`.
        a + rounded_high_word((b - a) << 2, i32::from(w.0) << 15)
    }

    #[inline(always)]
    fn abs_ge(a: i32, b: i32) -> bool {
        a.unsigned_abs() >= b.unsigned_abs()
    }

    fn check_samples(buf: &[i32], dims: Dims) -> Result<(), Error> {
        lifting::check_samples(buf, dims)
    }
}

/// `(x·y + 2³¹) >> 32`: what LLVM turns into SMMULR / SMMLAR on Arm.
#[inline(always)]
fn rounded_high_word(x: i32, y: i32) -> i32 {
    ((i64::from(x) * i64::from(y) + (1 << 31)) >> 32) as i32
}

/// Scratch length (in `i32`) that [`fuse_pair`] and [`fuse_u8`] need for `dims`: a
/// transform line, the saliency maps and the saliency tables ([`fuse_scratch_words`]).
pub fn fuse_scratch_len(dims: Dims) -> usize {
    fuse_scratch_words(dims.width(), dims.height())
}

/// [`fuse_scratch_len`] for a `width × height` image, usable in constants (array sizes):
/// `w` for the transform's line ([`lifting::scratch_len`]) plus `2·(⌈w/2⌉ + 1)·(⌈h/2⌉ + 1)`
/// for the two saliency maps, plus 2048 for the table [`fuse_u8`] looks level 1's
/// saliencies up in (used by it alone).
pub const fn fuse_scratch_words(width: usize, height: usize) -> usize {
    lifting::scratch_words(width, height) + maps_len(width, height) + TABLE_WORDS
}

/// One integer fuse step: the fused image of `a` and `b` replaces `a`; `b` is used as work
/// space. Both hold samples with `|x| ≤ MAX_SAMPLE` on the `dims` region; `ll_weight` is
/// the second image's LL weight ([`LlWeight::HALF`] for the paper's mean). The result is
/// not clamped: callers that keep 8-bit images clamp it (as [`super::CyclicFuser`] does).
///
/// ```
/// use rollfuse_core::Dims;
/// use rollfuse_core::fusion::{FuseConfig, LlWeight, fuse_pair, fuse_scratch_len};
///
/// let dims = Dims::new(8, 6)?;
/// let image: Vec<i32> = (0..48).map(|i| (i % 8) * 30 + (i / 8) * 7).collect();
/// let (mut a, mut b) = (image.clone(), image.clone());
/// let mut scratch = vec![0; fuse_scratch_len(dims)];
/// let cfg = FuseConfig::default(); // db2, one level, the full method
/// fuse_pair(&mut a, &mut b, dims, &cfg, LlWeight::HALF, &mut scratch)?;
/// // The fused image replaces `a`; an image fused with itself comes back bit for bit.
/// assert_eq!(a, image);
/// # Ok::<(), rollfuse_core::Error>(())
/// ```
pub fn fuse_pair(
    a: &mut [i32],
    b: &mut [i32],
    dims: Dims,
    cfg: &FuseConfig,
    ll_weight: LlWeight,
    scratch: &mut [i32],
) -> Result<(), Error> {
    // One scratch size for both entry points; this one leaves the table unused (its
    // samples need not be 8-bit).
    let needed = fuse_scratch_len(dims);
    if scratch.len() < needed {
        return Err(Error::BufferTooSmall {
            which: "scratch",
            needed,
            got: scratch.len(),
        });
    }
    let layout = ScratchLayout {
        second_line: false,
        rings: false,
        table: false,
    };
    let images = ImagePair { a, b, dims };
    let how = (layout, Samples::Unchecked);
    fuse_pair_checked(images, cfg, ll_weight, scratch, how, &Sequential)
}

/// Work buffers of [`fuse_u8`]: `a` and `b` hold at least `w·h` words, `scratch` at least
/// [`fuse_scratch_len`].
pub struct U8Work<'w> {
    /// Transform work for the first image.
    pub a: &'w mut [i32],
    /// Transform work for the second image.
    pub b: &'w mut [i32],
    /// Lines, saliency maps and the saliency table.
    pub scratch: &'w mut [i32],
}

/// The two 8-bit images [`fuse_u8`] fuses, each laid out in its buffer as its [`Dims`] say
/// (rows may be strided).
pub struct U8Pair<'i> {
    /// The first image (in cyclic use, the running result); the result replaces it.
    pub a: &'i mut [u8],
    /// Where `a`'s pixels lie in its buffer.
    pub a_dims: Dims,
    /// The second image.
    pub b: &'i [u8],
    /// Where `b`'s pixels lie in its buffer.
    pub b_dims: Dims,
}

impl<'i> U8Pair<'i> {
    /// Two images laid out alike.
    pub fn same(a: &'i mut [u8], b: &'i [u8], dims: Dims) -> Self {
        Self {
            a,
            a_dims: dims,
            b,
            b_dims: dims,
        }
    }
}

/// A level-1 region smaller than this takes its saliency without a table: filling one
/// costs about as much as looking this many pixels up saves.
const TABLE_MIN_PIXELS: usize = 1024;

/// Fuses two 8-bit images (each with its own stride) on the integer path with
/// [`GUARD_BITS`] of extra precision. The result, rounded and clamped to 0..=255, replaces
/// `a`'s region (the bytes between its rows are left alone); should the step fail, `a`
/// is as it was.
///
/// Level 1's saliency is taken from the bytes themselves, four pixels per few word
/// operations, and looked up in a table of every Laplacian 8-bit samples can have: the
/// same bits as the generic step on the samples with the guard bits
/// (test `fuse_u8_matches_the_step_on_samples_with_guard_bits`), but where that step's
/// level-1 inverse saturates a column output which this one, going to bytes, keeps
/// (`lifting::Unsaturated`; only tiny images of 0/255 noise were found to do that).
pub fn fuse_u8(
    images: U8Pair<'_>,
    cfg: &FuseConfig,
    ll_weight: LlWeight,
    work: U8Work<'_>,
) -> Result<(), Error> {
    let U8Pair {
        a,
        a_dims,
        b,
        b_dims,
    } = images;
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
    let layout = ScratchLayout {
        second_line: false,
        rings: false,
        table: true,
    };
    let line = lifting::scratch_len(packed);
    let (mut parts, table) = split_scratch(work.scratch, line, layout, packed)?;
    // A reference maximum is in 8-bit units; the samples get the guard bits.
    let cfg = &FuseConfig {
        norm: match cfg.norm {
            SaliencyNorm::Reference(r) => {
                SaliencyNorm::Reference(r.saturating_mul(1 << GUARD_BITS))
            }
            local => local,
        },
        ..*cfg
    };
    if cfg.ablation.uses_saliency() {
        let images = [(&*a, a_dims), (b, b_dims)];
        first_level_maps(images, cfg, parts.maps.space, table, parts.lines.line)?;
        parts.maps.first_ready = true;
    }
    if takes_lanes(cfg, packed) {
        let images = ((a, a_dims), (b, b_dims));
        let work = [work.a, work.b];
        return super::lanes::fuse_in_lanes(images.0, images.1, cfg, ll_weight, parts, work);
    }
    let images = ImagePair {
        a: &mut *work.a,
        b: &mut *work.b,
        dims: packed,
    };
    if cfg.ablation != Ablation::NoWavelet {
        // Level 1 reads its rows from the bytes and the result goes straight back to
        // them: no widened copies, no rounding pass. Past the checks above nothing fails
        // once the inverse has begun writing `a` (the step's errors stand in for panics).
        let bytes = ByteImages {
            a,
            a_dims,
            b,
            b_dims,
        };
        let start = StepStart::level_one([None; 2], Some(bytes));
        return fuse_generic(images, cfg, ll_weight, parts, start, &Sequential);
    }
    // Without the wavelet the samples are mixed as they are.
    // Every buffer was checked to hold its region above: the zips pair all `h` rows.
    for (src, src_dims, dst) in [(&*a, a_dims, &mut *images.a), (b, b_dims, &mut *images.b)] {
        for (row, dst_row) in src_dims.rows(src).zip(dst.chunks_exact_mut(w)) {
            widen_shifted::<GUARD_BITS>(row, dst_row);
        }
    }
    let start = StepStart::level_one([None; 2], None);
    fuse_generic(images, cfg, ll_weight, parts, start, &Sequential)?;
    let half = 1 << (GUARD_BITS - 1);
    for (row, fused) in a_dims.rows_mut(a).zip(work.a.chunks_exact(w)) {
        for (d, &v) in row.iter_mut().zip(fused) {
            *d = ((v + half) >> GUARD_BITS).clamp(0, 255) as u8;
        }
    }
    Ok(())
}

/// Whether [`fuse_u8`] runs level 1 in 16-bit lanes ([`super::lanes`]): the full method,
/// a width that is a multiple of 4, and for more levels than one room for their maps
/// beside level 1's weights.
pub(crate) fn takes_lanes(cfg: &FuseConfig, dims: Dims) -> bool {
    cfg.ablation == Ablation::None
        && dims.width().is_multiple_of(4)
        && (cfg.levels == 1 || super::lanes::deeper_maps_fit(cfg.wavelet, dims))
}

/// Level 1's two window maps of saliency sums ([`WindowLayout`]) of the 8-bit images, into
/// `maps` as the generic step lays them out; `table` ([`TABLE_WORDS`]) holds the saliency
/// table, filled once for both images where they share a normalizer (a reference
/// maximum), and `line` (the image's width) one row of saliencies at a time. `cfg.norm`
/// is in units of the samples with the guard bits.
pub(crate) fn first_level_maps(
    images: [(&[u8], Dims); 2],
    cfg: &FuseConfig,
    maps: &mut [i32],
    table: &mut [i32],
    line: &mut [i32],
) -> Result<(), Error> {
    let dims = Dims::new(images[0].1.width(), images[0].1.height())?;
    let layout = WindowLayout::of(cfg.wavelet);
    let [map_a, map_b] = split_maps(maps, layout, dims)?;
    let too_small = |needed, got| Error::BufferTooSmall {
        which: "scratch",
        needed,
        got,
    };
    let table_len = table.len();
    let table = table
        .first_chunk_mut()
        .ok_or(too_small(TABLE_WORDS, table_len))?;
    let line_len = line.len();
    let line = line
        .get_mut(..dims.width())
        .ok_or(too_small(dims.width(), line_len))?;
    // `None`: a flat image, whose saliency is 0 everywhere.
    let [norm_a, norm_b] = images.map(|(img, img_dims)| {
        let max = match cfg.norm {
            SaliencyNorm::Local => laplacian_max_u8(img, img_dims) << GUARD_BITS,
            SaliencyNorm::Reference(r) => r,
        };
        (max != 0).then(|| Normalizer::new(max))
    });
    let use_table = dims.pixels() >= TABLE_MIN_PIXELS;
    let [(a, a_dims), (b, b_dims)] = images;
    let mut map_of = |(img, img_dims), how: Option<&ByteSaliency<'_>>, map| {
        let mut map = WindowMap::new(map, layout, dims);
        match how {
            // db2's windows (phase 1) line up with the groups of four: the saliencies go
            // straight into the map, with no line between.
            Some(ByteSaliency::Table(table)) if layout.phase == 1 => {
                for y in 0..dims.height() {
                    if let Some((up, mid, down)) = row_and_neighbours(img, img_dims, y) {
                        map.take_with(y, |row, first| {
                            saliency_windows_u8(table, [up, mid, down], row, first);
                        });
                    }
                }
            }
            Some(how) => {
                for y in 0..dims.height() {
                    if let Some((up, mid, down)) = row_and_neighbours(img, img_dims, y) {
                        saliency_row_u8(how, [up, mid, down], line);
                        map.take(y, line);
                    }
                }
            }
            None => {}
        }
        map.finish(dims);
    };
    if norm_a == norm_b {
        let shared = byte_saliency(norm_a, table, use_table);
        map_of((a, a_dims), shared.as_ref(), map_a);
        map_of((b, b_dims), shared.as_ref(), map_b);
    } else {
        let how_a = byte_saliency(norm_a, &mut *table, use_table);
        map_of((a, a_dims), how_a.as_ref(), map_a);
        let how_b = byte_saliency(norm_b, table, use_table);
        map_of((b, b_dims), how_b.as_ref(), map_b);
    }
    Ok(())
}

/// How an image of 8-bit samples with [`GUARD_BITS`] takes its saliency under `norm`
/// (`None`: flat): by a table filled in `table`, or computed per pixel.
fn byte_saliency(
    norm: Option<Normalizer>,
    table: &mut [i32; TABLE_WORDS],
    use_table: bool,
) -> Option<ByteSaliency<'_>> {
    norm.map(|norm| match use_table {
        true => ByteSaliency::Table(LaplacianTable::fill(table, norm, GUARD_BITS)),
        false => ByteSaliency::Computed(norm, GUARD_BITS),
    })
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::lifting::MAX_SAMPLE;

    /// Level 1's saliencies taken straight into db2's window map give the map of the
    /// line-then-take path, bit for bit (every entry, the zeroed ones included), on
    /// random, flat, extreme, checkered and striped images of every width up to 40 and
    /// the camera's, 1 to 7 rows and 16, over a map holding stale values.
    #[test]
    fn saliency_windows_match_the_line_then_take_path() {
        let mut next = crate::test_bytes(4_242);
        let mut entries = [0; TABLE_WORDS];
        let layout = WindowLayout::of(Wavelet::Db2);
        for w in (1..=40).chain([79, 80, 81, 159, 160, 161, 320]) {
            for h in [1, 2, 3, 4, 5, 7, 16] {
                for pattern in 0..6 {
                    let img: std::vec::Vec<u8> = (0..w * h)
                        .map(|i| {
                            let (x, y) = (i % w, i / w);
                            match pattern {
                                0 => 0,
                                1 => 255,
                                2 => [0, 255][(x + y) % 2],
                                3 => [255, 0][x % 2],
                                4 => [0, 255][y % 2],
                                _ => next(),
                            }
                        })
                        .collect();
                    let dims = Dims::new(w, h).unwrap();
                    let max = laplacian_max_u8(&img, dims).max(1) << GUARD_BITS;
                    let table =
                        LaplacianTable::fill(&mut entries, Normalizer::new(max), GUARD_BITS);
                    let how = ByteSaliency::Table(table);
                    let (mw, mh) = layout.map_dims(dims);
                    let mut want = std::vec![0x5A5A_5A5A; mw * mh];
                    let mut got = want.clone();
                    let mut line = std::vec![0; w];
                    let mut map = WindowMap::new(&mut want, layout, dims);
                    for y in 0..h {
                        let (up, mid, down) = row_and_neighbours(&img, dims, y).unwrap();
                        saliency_row_u8(&how, [up, mid, down], &mut line);
                        map.take(y, &line);
                    }
                    map.finish(dims);
                    let ByteSaliency::Table(table) = &how else {
                        unreachable!()
                    };
                    let mut map = WindowMap::new(&mut got, layout, dims);
                    for y in 0..h {
                        let (up, mid, down) = row_and_neighbours(&img, dims, y).unwrap();
                        map.take_with(y, |row, first| {
                            saliency_windows_u8(table, [up, mid, down], row, first);
                        });
                    }
                    map.finish(dims);
                    assert_eq!(got, want, "{w}×{h} pattern {pattern}");
                }
            }
        }
    }

    /// `blend` and `mix` take `(a − b)·4` into a 32-bit product: every band's
    /// difference of two coefficients, at most twice its bound, must stay below 2²⁹.
    #[test]
    fn band_differences_fit_the_rounded_product() {
        for wavelet in [Wavelet::Haar, Wavelet::Db2] {
            for b in level_bounds(wavelet, 4) {
                let largest = [b.ll, b.hl, b.lh, b.hh].into_iter().max().unwrap_or(0);
                assert!(2 * largest < 1 << 29, "{wavelet:?}: {b:?}");
            }
        }
        assert_eq!(MAX_SAMPLE, 4095, "the bounds above are for this input");
    }

    /// The one-product forms give the bits of the two-product definitions, over the
    /// whole range of weights and the largest differences the bounds allow.
    #[test]
    fn blend_and_mix_match_the_two_products() {
        let limit = (1 << 28) - 1;
        let mut values = [0, 1, -1, 2, -3, 16384, -16385, 255 << 3, limit, -limit].to_vec();
        // A few thousand more, spread over the range by a multiplicative hash.
        values.extend((0..3000u32).map(|k| {
            let v = k.wrapping_mul(2_654_435_761) >> 3;
            (v as i32 % limit) * if k % 2 == 0 { 1 } else { -1 }
        }));
        let mut weights = [0, 1, 2, 16383, 16384, 16385, 32767, 32768].to_vec();
        weights.extend((0..40u32).map(|k| (k.wrapping_mul(2_654_435_761) >> 17) as i32));
        for &w in &weights {
            let w64 = i64::from(w);
            for (&h1, &h2) in values.iter().zip(values.iter().rev().cycle().skip(7)) {
                let (a, b) = (i64::from(h1), i64::from(h2));
                let want = (a * w64 + b * ((1 << 15) - w64) + (1 << 14)) >> 15;
                let got = <i32 as Arith>::blend(h1, h2, w << 15);
                assert_eq!(i64::from(got), want, "blend({h1}, {h2}, {w})");
                let want = (a * ((1 << 15) - w64) + b * w64 + (1 << 14)) >> 15;
                let got = <i32 as Arith>::mix(h1, h2, LlWeight(w as u16));
                assert_eq!(i64::from(got), want, "mix({h1}, {h2}, {w})");
            }
        }
    }
}
