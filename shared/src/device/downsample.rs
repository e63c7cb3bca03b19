//! Camera frames to downsampled 8-bit luma.

use super::refine::{PROFILE_BANDS, band_columns, write_differences};
use crate::packed;
use crate::protocol::PixelFormat;
use crate::{Dims, Error};

/// Luma of one RGB565 little-endian pixel: channels expanded to 8 bits by repeating
/// their top bits, then BT.601 luma in Q8.
#[inline(always)]
fn rgb565_luma([lo, hi]: [u8; 2]) -> u32 {
    let v = u32::from(lo) | u32::from(hi) << 8;
    let (r5, g6, b5) = (v >> 11, (v >> 5) & 0x3f, v & 0x1f);
    let (r, g, b) = (r5 << 3 | r5 >> 2, g6 << 2 | g6 >> 4, b5 << 3 | b5 >> 2);
    (77 * r + 150 * g + 29 * b + 128) >> 8
}

/// Adds to each of `sums` the luma of one row of its box: `F` pixels of `BPP` bytes from
/// `seg`. Monomorphized per format and factor so the inner loop has no branches: a
/// per-pixel format match would cost several times the arithmetic on the Cortex-M7.
#[inline(always)]
fn add_boxes<const F: usize, const BPP: usize>(
    sums: &mut [u32],
    seg: &[u8],
    luma: impl Fn([u8; BPP]) -> u32,
) {
    for (s, px) in sums.iter_mut().zip(seg.chunks_exact(F * BPP)) {
        let mut t = 0;
        for p in px.chunks_exact(BPP) {
            if let Ok(p) = <[u8; BPP]>::try_from(p) {
                t += luma(p);
            }
        }
        *s += t;
    }
}

/// [`add_boxes`] for `format` and `factor` (1, 2 or 4).
fn add_row(sums: &mut [u32], seg: &[u8], format: PixelFormat, factor: usize) {
    let gray = |[v]: [u8; 1]| u32::from(v);
    // Y0 U Y1 V: a pixel's luma is its first byte.
    let yuyv = |[y, _]: [u8; 2]| u32::from(y);
    match (format, factor) {
        (PixelFormat::Gray8, 1) => add_boxes::<1, 1>(sums, seg, gray),
        (PixelFormat::Gray8, 2) => add_boxes::<2, 1>(sums, seg, gray),
        (PixelFormat::Gray8, _) => add_boxes::<4, 1>(sums, seg, gray),
        (PixelFormat::Yuyv, 1) => add_boxes::<1, 2>(sums, seg, yuyv),
        (PixelFormat::Yuyv, 2) => add_boxes::<2, 2>(sums, seg, yuyv),
        (PixelFormat::Yuyv, _) => add_boxes::<4, 2>(sums, seg, yuyv),
        (PixelFormat::Rgb565, 1) => add_boxes::<1, 2>(sums, seg, rgb565_luma),
        (PixelFormat::Rgb565, 2) => add_boxes::<2, 2>(sums, seg, rgb565_luma),
        (PixelFormat::Rgb565, _) => add_boxes::<4, 2>(sums, seg, rgb565_luma),
    }
}

/// One output row of a 2× downsampling (the product's default) straight from its two
/// camera rows. The general path keeps per-box sums between rows, and storing and
/// reloading them is about half its cost on the Cortex-M7; here there are none, and gray
/// and YUYV rows are read four bytes per word ([`crate::packed`]).
#[inline(always)]
fn halve_row(out: &mut [u8], r0: &[u8], r1: &[u8], format: PixelFormat) {
    let mean = |s: u32| ((s + 2) >> 2) as u8;
    match format {
        PixelFormat::Gray8 => packed::halve_gray_row(out, r0, r1),
        PixelFormat::Yuyv => packed::halve_yuyv_row(out, r0, r1),
        PixelFormat::Rgb565 => {
            let pixels = out
                .iter_mut()
                .zip(r0.as_chunks::<4>().0.iter().zip(r1.as_chunks::<4>().0));
            for (o, (&[a0, a1, a2, a3], &[b0, b1, b2, b3])) in pixels {
                *o = mean(
                    rgb565_luma([a0, a1])
                        + rgb565_luma([a2, a3])
                        + rgb565_luma([b0, b1])
                        + rgb565_luma([b2, b3]),
                );
            }
        }
    }
}

/// The size of a `width × height` frame downsampled by `factor` (the last
/// `width % factor` columns and `height % factor` rows are dropped).
pub fn downsampled_dims(width: usize, height: usize, factor: usize) -> Result<Dims, Error> {
    if !matches!(factor, 1 | 2 | 4) {
        return Err(Error::InvalidParameter { name: "downsample" });
    }
    Dims::new(width / factor, height / factor)
}

/// Downsamples a `width × height` camera frame in `format` by `factor` (1, 2 or 4): each
/// output pixel is the rounded mean luma of a `factor × factor` box. Writes the packed
/// result to `out` and returns its size.
pub fn downsample(
    src: &[u8],
    format: PixelFormat,
    (width, height): (usize, usize),
    factor: usize,
    out: &mut [u8],
) -> Result<Dims, Error> {
    let all = downsampled_dims(width, height, factor)?.height();
    downsample_rows(src, format, (width, height), factor, 0..all, out)
}

/// The lumas of a row of YUYV pixels (bytes 0 and 2 of each four-byte group), four pixels
/// from two words read and one written: a full-resolution frame's only pass over its
/// camera row.
#[inline(always)]
fn yuyv_luma_row(out: &mut [u8], row: &[u8]) {
    let (out4, out_rest) = out.as_chunks_mut::<4>();
    let (groups, _) = row.as_chunks::<4>();
    let (pairs, single) = groups.as_chunks::<2>();
    for (o, [a, b]) in out4.iter_mut().zip(pairs) {
        // Y0 | Y1 << 16, folded to Y0 | Y1 << 8 in the low half; likewise Y2, Y3 above.
        let a = u32::from_le_bytes(*a) & 0x00FF_00FF;
        let b = u32::from_le_bytes(*b) & 0x00FF_00FF;
        let (lo, hi) = ((a | a >> 8) & 0xFFFF, (b | b >> 8) << 16);
        *o = (lo | hi).to_le_bytes();
    }
    // Up to three pixels left: one pair from a whole group, then half of the next.
    let done = 4 * out4.len();
    let tail = single
        .iter()
        .flatten()
        .chain(row.get(2 * done + 4 * single.len()..).unwrap_or(&[]));
    for (o, &y) in out_rest.iter_mut().zip(tail.step_by(2)) {
        *o = y;
    }
}

/// The lumas of whole groups of four YUYV pixels (two camera words each) into `out`,
/// returning their sum: the lanes of luma the conversion has in hand are added up as they
/// pass (two additions per four pixels, where a separate [`crate::packed::row_sum`] pass
/// read the row again).
#[inline(always)]
fn yuyv_luma_groups_sum(out: &mut [[u8; 4]], pairs: &[[[u8; 4]; 2]]) -> u32 {
    let mut total = 0;
    // A lane gains at most 2·255 per group of four pixels: 128 groups keep it below 2¹⁶.
    for (out4, pairs) in out.chunks_mut(128).zip(pairs.chunks(128)) {
        let mut acc = 0u32;
        for (o, [a, b]) in out4.iter_mut().zip(pairs) {
            let a = u32::from_le_bytes(*a) & 0x00FF_00FF;
            let b = u32::from_le_bytes(*b) & 0x00FF_00FF;
            acc += a + b;
            let (lo, hi) = ((a | a >> 8) & 0xFFFF, (b | b >> 8) << 16);
            *o = (lo | hi).to_le_bytes();
        }
        total += (acc & 0xFFFF) + (acc >> 16);
    }
    total
}

/// [`yuyv_luma_row`] that also returns the sums of luma of the row's bands of columns
/// ([`band_columns`]; they end at multiples of four pixels, so each is whole groups of
/// the conversion, and the last takes the up to three pixels left over).
#[inline(always)]
fn yuyv_luma_row_band_sums(out: &mut [u8], row: &[u8]) -> [u32; PROFILE_BANDS] {
    let w = out.len();
    let (mut out4, out_rest) = out.as_chunks_mut::<4>();
    let (groups, _) = row.as_chunks::<4>();
    let (mut pairs, single) = groups.as_chunks::<2>();
    let done = 4 * out4.len();
    let mut sums = [0u32; PROFILE_BANDS];
    let mut at = 0;
    for (b, sum) in sums.iter_mut().enumerate() {
        let n = (band_columns(w, b).end / 4)
            .saturating_sub(at)
            .min(out4.len());
        let (band_out, rest_out) = core::mem::take(&mut out4).split_at_mut(n);
        let (band_pairs, rest_pairs) = pairs.split_at(n.min(pairs.len()));
        *sum = yuyv_luma_groups_sum(band_out, band_pairs);
        (out4, pairs, at) = (rest_out, rest_pairs, at + n);
    }
    let tail = single
        .iter()
        .flatten()
        .chain(row.get(2 * done + 4 * single.len()..).unwrap_or(&[]));
    for (o, &y) in out_rest.iter_mut().zip(tail.step_by(2)) {
        *o = y;
        sums[PROFILE_BANDS - 1] += u32::from(y);
    }
    sums
}

/// [`downsample_rows`] that also writes the band's row profile, as
/// [`super::refine::row_profile`] of the band would (`dims.height() − 1` rows of first
/// differences of the [`PROFILE_BANDS`] band sums into `profile`): at 1× from YUYV the sums are taken during
/// the conversion, otherwise by that function after it.
pub fn downsample_rows_profiled(
    src: &[u8],
    format: PixelFormat,
    (width, height): (usize, usize),
    factor: usize,
    rows: core::ops::Range<usize>,
    out: &mut [u8],
    profile: &mut [i32],
) -> Result<Dims, Error> {
    if factor != 1 || format != PixelFormat::Yuyv {
        return band_then_profile(src, format, (width, height), factor, rows, out, profile);
    }
    // The checks of `downsample_rows`, whose 1× pass this is.
    let full = downsampled_dims(width, height, factor)?;
    if rows.end > full.height() {
        return Err(Error::InvalidParameter { name: "rows" });
    }
    let dims = Dims::new(full.width(), rows.end.saturating_sub(rows.start))?;
    let row_bytes = width * format.bytes_per_pixel();
    let needed = row_bytes * height;
    if src.len() < needed {
        return Err(Error::BufferTooSmall {
            which: "camera frame",
            needed,
            got: src.len(),
        });
    }
    dims.check_buffer("downsampled frame", out.len())?;
    let camera_rows = src
        .chunks_exact(row_bytes)
        .skip(rows.start)
        .take(rows.len());
    let out_rows = out.chunks_exact_mut(dims.width());
    let sums = camera_rows
        .zip(out_rows)
        .map(|(row, out_row)| yuyv_luma_row_band_sums(out_row, row));
    write_differences(sums, profile);
    Ok(dims)
}

/// [`downsample_rows`], then [`super::refine::row_profile`] of the band. Not inlined:
/// the two calls as they were before the profile was fused into the 1× pass.
#[inline(never)]
fn band_then_profile(
    src: &[u8],
    format: PixelFormat,
    size: (usize, usize),
    factor: usize,
    rows: core::ops::Range<usize>,
    out: &mut [u8],
    profile: &mut [i32],
) -> Result<Dims, Error> {
    let dims = downsample_rows(src, format, size, factor, rows, out)?;
    super::refine::row_profile(out, dims, profile);
    Ok(dims)
}

/// One output row at full resolution: each pixel's luma, with no sums kept (the general
/// path's per-box sums cost about 15 instructions a pixel on the Cortex-M7 at 1×).
#[inline(always)]
fn luma_row(out: &mut [u8], row: &[u8], format: PixelFormat) {
    match format {
        PixelFormat::Gray8 => {
            for (o, &v) in out.iter_mut().zip(row) {
                *o = v;
            }
        }
        PixelFormat::Yuyv => yuyv_luma_row(out, row),
        PixelFormat::Rgb565 => {
            for (o, &[lo, hi]) in out.iter_mut().zip(row.as_chunks::<2>().0) {
                *o = rgb565_luma([lo, hi]) as u8;
            }
        }
    }
}

/// Full-resolution output rows from their camera rows. Not inlined: in
/// [`downsample_rows`]'s body its loop made the 2× path's registers spill.
#[inline(never)]
fn full_rows<'a>(
    camera_rows: impl Iterator<Item = &'a [u8]>,
    out_rows: core::slice::ChunksExactMut<'_, u8>,
    format: PixelFormat,
) {
    for (row, out_row) in camera_rows.zip(out_rows) {
        luma_row(out_row, row, format);
    }
}

/// [`downsample`] of output rows `rows` only (downsampled rows, e.g. the pipeline's
/// observation window), packed into `out` from its start; returns the size of that band.
/// Camera rows outside the band are not read.
pub fn downsample_rows(
    src: &[u8],
    format: PixelFormat,
    (width, height): (usize, usize),
    factor: usize,
    rows: core::ops::Range<usize>,
    out: &mut [u8],
) -> Result<Dims, Error> {
    let full = downsampled_dims(width, height, factor)?;
    if rows.end > full.height() {
        return Err(Error::InvalidParameter { name: "rows" });
    }
    let dims = Dims::new(full.width(), rows.end.saturating_sub(rows.start))?;
    let row_bytes = width * format.bytes_per_pixel();
    let needed = row_bytes * height;
    if src.len() < needed {
        return Err(Error::BufferTooSmall {
            which: "camera frame",
            needed,
            got: src.len(),
        });
    }
    dims.check_buffer("downsampled frame", out.len())?;
    let bpp = format.bytes_per_pixel();
    // The box area is 1, 4 or 16: the rounded mean is a shift.
    let shift = 2 * factor.trailing_zeros();
    let w = dims.width();
    if factor == 1 {
        let camera_rows = src
            .chunks_exact(row_bytes)
            .skip(rows.start)
            .take(rows.len());
        full_rows(camera_rows, out.chunks_exact_mut(w), format);
        return Ok(dims);
    }
    for (y, out_row) in rows.zip(out.chunks_exact_mut(w)) {
        let rows = src.chunks_exact(row_bytes).skip(y * factor).take(factor);
        if factor == 2 {
            let mut pair = rows.clone();
            if let (Some(r0), Some(r1)) = (pair.next(), pair.next()) {
                halve_row(out_row, r0, r1, format);
                continue;
            }
        }
        // Sum each box's rows into the output row, a chunk at a time, then round once.
        let mut sums = [0u32; 64];
        for (x0, out_chunk) in (0..w)
            .step_by(sums.len())
            .zip(out_row.chunks_mut(sums.len()))
        {
            // `out_chunk` is one of `chunks_mut(sums.len())`: never longer than `sums`.
            let Some(sums) = sums.get_mut(..out_chunk.len()) else {
                continue;
            };
            sums.fill(0);
            let bytes = x0 * factor * bpp..(x0 + sums.len()) * factor * bpp;
            for row in rows.clone() {
                add_row(sums, row.get(bytes.clone()).unwrap_or(&[]), format, factor);
            }
            for (o, &s) in out_chunk.iter_mut().zip(sums.iter()) {
                *o = ((s + (1 << shift >> 1)) >> shift) as u8;
            }
        }
    }
    Ok(dims)
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::{vec, vec::Vec};

    #[test]
    fn boxes_average_and_round() {
        let src: [u8; 16] = core::array::from_fn(|i| i as u8 * 10);
        let mut out = [0u8; 4];
        let d = downsample(&src, PixelFormat::Gray8, (4, 4), 2, &mut out).unwrap();
        assert_eq!((d.width(), d.height()), (2, 2));
        // (0 + 10 + 40 + 50) / 4 = 25.
        assert_eq!(out, [25, 45, 105, 125]);
        let mut one = [0u8; 1];
        downsample(&src, PixelFormat::Gray8, (4, 4), 4, &mut one).unwrap();
        assert_eq!(one, [75]);
    }

    #[test]
    fn luma_from_rgb565_and_yuyv() {
        // White, black, pure green in RGB565 little-endian.
        let rgb = [0xff, 0xff, 0x00, 0x00, 0xe0, 0x07];
        let mut out = [0u8; 3];
        downsample(&rgb, PixelFormat::Rgb565, (3, 1), 1, &mut out).unwrap();
        assert_eq!(out, [255, 0, 149]);
        let yuyv = [10, 128, 30, 128];
        let mut out = [0u8; 1];
        downsample(&yuyv, PixelFormat::Yuyv, (2, 2), 2, &mut out).unwrap_err();
        downsample(
            &[10, 128, 30, 128, 50, 1, 70, 2],
            PixelFormat::Yuyv,
            (2, 2),
            2,
            &mut out,
        )
        .unwrap();
        assert_eq!(out, [40]);
    }

    /// Every row width from 0 to 11 pixels (whole words, and one to three pixels over).
    #[test]
    fn yuyv_lumas_are_the_even_bytes() {
        for width in 0..12 {
            let row: Vec<u8> = (0..2 * width).map(|i| (i * 53 % 251) as u8).collect();
            let mut out = vec![0xAA; width];
            yuyv_luma_row(&mut out, &row);
            let want: Vec<u8> = row.iter().step_by(2).copied().collect();
            assert_eq!(out, want, "width {width}");
        }
    }

    /// The band and profile of `downsample_rows_profiled` are those of `downsample_rows`
    /// and `row_profile`, for every format and factor, on random, flat (0 and 255) and
    /// checkered frames 1, 2, 3, 5, 150 and 1030 pixels wide (past one block of 512
    /// pixels of the summed conversion) and 1 to 9 rows high, over every band.
    #[test]
    fn profiled_bands_match_the_band_then_its_profile() {
        use crate::device::refine::row_profile;
        let mut x = 0x2545_f491u32;
        for (w, h) in [(1, 1), (1, 4), (2, 3), (3, 9), (5, 2), (150, 5), (1030, 3)] {
            for pattern in 0..4 {
                let src: std::vec::Vec<u8> = (0..w * h * 2)
                    .map(|i| match pattern {
                        0 => 0,
                        1 => 255,
                        2 => [0, 255][(i / 2 + i / (2 * w)) % 2],
                        _ => {
                            x ^= x << 13;
                            x ^= x >> 17;
                            x ^= x << 5;
                            (x >> 24) as u8
                        }
                    })
                    .collect();
                for format in [PixelFormat::Gray8, PixelFormat::Yuyv, PixelFormat::Rgb565] {
                    for factor in [1, 2, 4] {
                        let Ok(d) = downsampled_dims(w, h, factor) else {
                            continue;
                        };
                        for start in 0..d.height() {
                            for end in start + 1..=d.height() {
                                let n = d.width() * (end - start);
                                let mut want = std::vec![0xa5u8; n + 3];
                                let mut got = want.clone();
                                let mut want_p = std::vec![-7; (end - start + 2) * PROFILE_BANDS];
                                let mut got_p = want_p.clone();
                                let fr = (w, h);
                                let wd = downsample_rows(
                                    &src,
                                    format,
                                    fr,
                                    factor,
                                    start..end,
                                    &mut want,
                                )
                                .unwrap();
                                row_profile(&want, wd, &mut want_p);
                                let gd = downsample_rows_profiled(
                                    &src,
                                    format,
                                    fr,
                                    factor,
                                    start..end,
                                    &mut got,
                                    &mut got_p,
                                )
                                .unwrap();
                                let what = std::format!(
                                    "{w}×{h} {format:?} ×{factor} {start}..{end} pattern {pattern}"
                                );
                                assert_eq!(gd, wd, "{what}");
                                assert_eq!(got, want, "{what}");
                                assert_eq!(got_p, want_p, "{what}");
                            }
                        }
                        // The same refusals.
                        let mut band = std::vec![0u8; w * h];
                        let mut p = std::vec![0; h * PROFILE_BANDS];
                        let rows = 0..d.height() + 1;
                        assert_eq!(
                            downsample_rows_profiled(
                                &src,
                                format,
                                (w, h),
                                factor,
                                rows.clone(),
                                &mut band,
                                &mut p
                            ),
                            downsample_rows(&src, format, (w, h), factor, rows, &mut band)
                        );
                        let short = &src[..src.len() / 2 / format.bytes_per_pixel().max(1)];
                        let all = 0..d.height();
                        assert_eq!(
                            downsample_rows_profiled(
                                short,
                                format,
                                (w, h),
                                factor,
                                all.clone(),
                                &mut band,
                                &mut p
                            ),
                            downsample_rows(short, format, (w, h), factor, all, &mut band)
                        );
                    }
                }
            }
        }
    }

    /// Every format and factor against the definition, pixel by pixel, on a frame whose
    /// size leaves columns and rows over (dropped) and is wider than one 64-pixel chunk.
    #[test]
    fn every_format_and_factor_matches_the_box_mean() {
        const W: usize = 150;
        const H: usize = 11;
        let mut x = 0x9e37_79b9u32;
        let src: [u8; W * H * 2] = core::array::from_fn(|_| {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            (x >> 24) as u8
        });
        for format in [PixelFormat::Gray8, PixelFormat::Yuyv, PixelFormat::Rgb565] {
            let bpp = format.bytes_per_pixel();
            let luma = |px: usize, py: usize| {
                let at = (py * W + px) * bpp;
                match format {
                    PixelFormat::Gray8 | PixelFormat::Yuyv => u32::from(src[at]),
                    PixelFormat::Rgb565 => rgb565_luma([src[at], src[at + 1]]),
                }
            };
            for factor in [1, 2, 4] {
                let mut out = [0u8; W * H];
                let d = downsample(&src, format, (W, H), factor, &mut out).unwrap();
                assert_eq!((d.width(), d.height()), (W / factor, H / factor));
                // Every band of rows is those rows of the whole, packed from the start.
                for start in 0..d.height() {
                    for end in start + 1..=d.height() {
                        let mut band = [0xa5u8; W * H];
                        let got =
                            downsample_rows(&src, format, (W, H), factor, start..end, &mut band)
                                .unwrap();
                        let n = got.pixels();
                        assert_eq!((got.width(), got.height()), (d.width(), end - start));
                        assert_eq!(band[..n], out[start * d.width()..end * d.width()]);
                        assert!(band[n..].iter().all(|&v| v == 0xa5), "wrote past the band");
                    }
                }
                let area = (factor * factor) as u32;
                for oy in 0..d.height() {
                    for ox in 0..d.width() {
                        let sum: u32 = (0..factor * factor)
                            .map(|k| luma(ox * factor + k % factor, oy * factor + k / factor))
                            .sum();
                        let want = ((sum + area / 2) / area) as u8;
                        assert_eq!(
                            out[oy * d.width() + ox],
                            want,
                            "{format:?} ×{factor} ({ox}, {oy})"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn bad_sizes_are_errors() {
        let mut out = [0u8; 4];
        assert!(downsample(&[0; 15], PixelFormat::Gray8, (4, 4), 2, &mut out).is_err());
        assert!(downsample(&[0; 16], PixelFormat::Gray8, (4, 4), 3, &mut out).is_err());
        assert!(downsample(&[0; 16], PixelFormat::Gray8, (4, 4), 1, &mut out).is_err());
        assert!(downsample(&[0; 16], PixelFormat::Gray8, (1, 16), 2, &mut out).is_err());
        // Bands beyond the frame, empty bands, a band larger than `out`.
        let rows = |r: core::ops::Range<usize>, out: &mut [u8]| {
            downsample_rows(&[0; 16], PixelFormat::Gray8, (4, 4), 2, r, out)
        };
        assert!(rows(1..3, &mut out).is_err());
        assert!(rows(1..1, &mut out).is_err());
        assert!(rows(0..2, &mut out[..3]).is_err());
        assert!(rows(1..2, &mut out[..2]).is_ok());
    }
}
