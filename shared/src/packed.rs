//! Four 8-bit samples in one 32-bit word: the 8-bit kernels of the device pipeline (the
//! frame's Laplacian maximum, level 1's saliency, the widening of samples for the
//! transform) work on the bytes of a word in two 16-bit lanes at a time, in plain
//! integer arithmetic (SIMD within a register). The Cortex-M7's own SIMD instructions
//! are out of reach of stable Rust but through inline assembly; these lanes need none.
//!
//! A word's even bytes (0 and 2) go to its low and high lane by a mask, its odd bytes
//! (1 and 3) by a shift and the same mask. A lane holds 16 bits, and nothing here lets
//! a lane's value leave `0..2¹⁶`, so no carry or borrow crosses into the other lane.

use crate::geometry::mirror;

/// The even bytes of a word, one per 16-bit lane.
const EVEN_BYTES: u32 = 0x00FF_00FF;

/// Added to every Laplacian `4c − (up + down + left + right)` of 8-bit samples, which lies
/// in `−1020..=1020`, so a lane never holds a negative value: a biased Laplacian lies in
/// `4..=2044`, and `|∇²I|` is its distance from the bias.
pub(crate) const LAPLACIAN_BIAS: u32 = 1024;

/// [`LAPLACIAN_BIAS`] in both lanes.
const BIAS_LANES: u32 = LAPLACIAN_BIAS * 0x0001_0001;

/// The lanes' sign bits, once a comparison has moved a lane's result there.
const LANE_SIGNS: u32 = 0x8000_8000;

/// `(even bytes, odd bytes)` of `word`, each pair in the low and high lane.
#[inline(always)]
fn lanes(word: u32) -> (u32, u32) {
    (word & EVEN_BYTES, (word >> 8) & EVEN_BYTES)
}

/// The two lanes of a word, low first.
#[inline(always)]
pub(crate) fn unpack(lanes: u32) -> [u32; 2] {
    [lanes & 0xFFFF, lanes >> 16]
}

/// Biased Laplacians of pixels `x .. x + 4` of a row: `left` and `right` hold the row's
/// samples from `x − 1` and from `x + 1`, `up` and `down` samples `x .. x + 4` of the rows
/// above and below. Returns `[even, odd]`: pixels `x` and `x + 2` in the low and high
/// lanes of `even`, `x + 1` and `x + 3` in those of `odd`.
///
/// The two reads of the row serve all three of its roles: `left`'s lanes are pixels
/// `[x − 1, x + 1]` (even bytes) and `[x, x + 2]` (odd), `right`'s `[x + 1, x + 3]` and
/// `[x + 2, x + 4]`. So the even pixels' centres are `left`'s odd lanes and their
/// neighbours its even lanes and `right`'s even lanes; the odd pixels' centres are
/// `right`'s even lanes, their neighbours `left`'s odd lanes and `right`'s odd lanes.
#[inline(always)]
fn laplacian_quad([up, left, right, down]: [&[u8; 4]; 4]) -> [u32; 2] {
    let word = |b: &[u8; 4]| u32::from_le_bytes(*b);
    let (up_e, up_o) = lanes(word(up));
    let (down_e, down_o) = lanes(word(down));
    let (left_e, left_o) = lanes(word(left));
    let (right_e, right_o) = lanes(word(right));
    // Per lane: 4c + bias ≤ 2044 and the neighbours' sum ≤ 1020, so both stay in 16 bits
    // and the difference is at least 4.
    let even = (BIAS_LANES + (left_o << 2)) - (up_e + down_e + left_e + right_e);
    let odd = (BIAS_LANES + (right_e << 2)) - (up_o + down_o + left_o + right_o);
    [even, odd]
}

/// Pixels of a row of `width` that [`laplacian_quads`] covers: `1 .. 1 + 4·n`, every group
/// of four whose right neighbours are inside the row.
#[inline(always)]
pub(crate) fn quad_pixels(width: usize) -> core::ops::Range<usize> {
    1..1 + 4 * (width.saturating_sub(2) / 4)
}

/// The biased Laplacians of row `mid` over [`quad_pixels`], four pixels at a time (see
/// [`laplacian_quad`] for the lanes), with `up` and `down` the rows above and below (as
/// [`crate::saliency::row_and_neighbours`] gives them, mirrored at the image's ends).
/// Shorter `up` or `down` rows end the groups early.
#[inline(always)]
pub(crate) fn laplacian_quads<'r>(
    [up, mid, down]: [&'r [u8]; 3],
) -> impl Iterator<Item = [u32; 2]> + 'r {
    // Words from sample `k` on: the groups from `x = 1` read `x − 1` and `x + 1` of `mid`.
    // Each group needs its right neighbours, so `mid` from 2 has the fewest words.
    let from = |r: &'r [u8], k: usize| r.get(k..).unwrap_or_default().as_chunks::<4>().0;
    from(mid, 0)
        .iter()
        .zip(from(mid, 2))
        .zip(from(up, 1).iter().zip(from(down, 1)))
        .map(|((l, r), (u, d))| laplacian_quad([u, l, r, d]))
}

/// The biased Laplacian of pixel `x` of row `mid`, the row mirrored at its ends (`x − 1`
/// reads `x + 1` at the left end, and the other way round at the right); `None` past
/// the rows' ends.
#[inline(always)]
pub(crate) fn laplacian_at([up, mid, down]: [&[u8]; 3], x: usize) -> Option<u32> {
    let w = mid.len();
    let at = |row: &[u8], i: usize| row.get(i).map(|&v| u32::from(v));
    let left = at(mid, mirror(x as isize - 1, w))?;
    let right = at(mid, mirror(x as isize + 1, w))?;
    let sum = at(up, x)? + at(down, x)? + left + right;
    Some(LAPLACIAN_BIAS + 4 * at(mid, x)? - sum)
}

/// The pixels of a row of `width` that [`laplacian_quads`] leaves out: the first, and
/// those past the last group of four.
#[inline(always)]
pub(crate) fn single_pixels(width: usize) -> impl Iterator<Item = usize> {
    let quads = quad_pixels(width);
    (0..width.min(1)).chain(quads.end.max(1).min(width)..width)
}

/// Tells whether any lane of a group of biased Laplacians is further than `max` from the
/// bias, in a few instructions: most groups of an image are below its maximum found so far.
#[derive(Debug, Clone, Copy)]
pub(crate) struct AboveMax {
    /// Per lane `2¹⁵ − bias − 1 − max`: a lane's sum with it reaches bit 15 when the
    /// Laplacian exceeds `max`.
    over: u32,
    /// Per lane `2¹⁵ + bias − 1 − max`: a lane subtracted from it keeps bit 15 when the
    /// Laplacian is below `−max`.
    under: u32,
}

impl AboveMax {
    /// The test against `max` (at most 1020, the largest `|∇²I|` of 8-bit samples; larger
    /// values are taken as 1020, which no lane exceeds).
    #[inline(always)]
    pub(crate) fn new(max: u32) -> Self {
        let max = max.min(1020);
        let lane = |v: u32| v * 0x0001_0001;
        Self {
            over: lane(0x8000 - LAPLACIAN_BIAS - 1 - max),
            under: lane(0x8000 + LAPLACIAN_BIAS - 1 - max),
        }
    }

    /// Nonzero exactly when a lane of `even` or `odd` holds a biased Laplacian `v` with
    /// `|v − bias| > max` (flags of groups may be ORed and tested once). Lanes lie in
    /// `4..=2044`: `v + over` and `under − v` stay in `0..2¹⁶`; they reach bit 15 exactly
    /// when `v > bias + max` or `v < bias − max`.
    #[inline(always)]
    pub(crate) fn flags(self, [even, odd]: [u32; 2]) -> u32 {
        let flags = even.wrapping_add(self.over)
            | self.under.wrapping_sub(even)
            | odd.wrapping_add(self.over)
            | self.under.wrapping_sub(odd);
        flags & LANE_SIGNS
    }
}

/// The larger of `max` and the largest `|∇²I|` over the pixels [`quad_pixels`] covers in
/// every row of an 8-bit image of `width` by `height ≥ 2` (`img` exactly that long;
/// rows mirrored at the top and bottom, as [`crate::saliency::row_and_neighbours`] gives
/// them), walking each column of groups of four down the image.
///
/// Walking down a column, a row's two words (from `x − 1` and from `x + 1`, as in
/// [`laplacian_quad`]) are read once and serve all three roles: the row's own horizontal
/// terms and centres, and the vertical neighbours of the rows above and below (its lanes
/// of pixels `x, x + 2` and `x + 1, x + 3`). So a group costs two loads, where a row walk
/// reads four words; and the test against the maximum so far needs no bias: per lane
/// `t = K + L` and `u = K − L` with `K = 2¹⁵ − 1 − max` reach bit 15 exactly when
/// `L > max` or `−L > max` (every value stays in `0..2¹⁶`).
// Rows are `width` long and every group's six bytes `x − 1 .. x + 5` lie inside one
// (`quad_pixels`); the chunks below are cut accordingly.
#[inline(never)]
pub(crate) fn column_laplacian_max(img: &[u8], width: usize, height: usize, max: u32) -> u32 {
    let mut max = max;
    if height < 2 || img.len() != width * height {
        return max;
    }
    let quads = quad_pixels(width).len() / 4;
    for off in (0..quads).map(|q| 4 * q) {
        let mut from = 0;
        while let Some(y) = first_flagged_row_of(img, width, off, lane_threshold(max), from) {
            max = group_max(img, width, off, y, max);
            from = y + 1;
        }
    }
    max
}

/// The larger of `max` and the largest `|∇²I|` of the pixels in column `x` of an 8-bit
/// image of `width` by `height ≥ 2` (`img` exactly that long; mirrored at every edge),
/// walking down the column: for the pixels [`laplacian_quads`] leaves out
/// ([`single_pixels`]).
pub(crate) fn column_pixel_max(img: &[u8], width: usize, x: usize, max: u32) -> u32 {
    let (left, right) = (mirror(x as isize - 1, width), mirror(x as isize + 1, width));
    let at = |row: &[u8], i: usize| row.get(i).map_or(0, |&v| u32::from(v));
    // A row's centre and the sum of its left and right neighbours.
    let pixel = |row: &[u8]| (at(row, x), at(row, left) + at(row, right));
    let mut rows = img.chunks_exact(width.max(1));
    let (Some(first), Some(second)) = (rows.next(), rows.next()) else {
        return max;
    };
    // Row 0's upper neighbour is row 1.
    let (mut up, (mut centre, mut sides)) = (at(second, x), pixel(first));
    let mut max = max;
    for row in img.chunks_exact(width.max(1)).skip(1) {
        let (c, s) = pixel(row);
        max = max.max((4 * centre).abs_diff(sides + up + c));
        (up, centre, sides) = (centre, c, s);
    }
    // The last row's lower neighbour is row h − 2, its upper one.
    max.max((4 * centre).abs_diff(sides + 2 * up))
}

/// The lanes of a row's group from its six bytes `x − 1 .. x + 5` (from `off`):
/// `[(x − 1, x + 1), (x, x + 2), (x + 1, x + 3), (x + 2, x + 4)]`; `None` past the row.
#[inline(always)]
fn group_lanes(row: &[u8], off: usize) -> Option<[u32; 4]> {
    let b = row.get(off..)?.first_chunk::<6>()?;
    let word = |w: Option<&[u8; 4]>| w.map_or(0, |w| u32::from_le_bytes(*w));
    let (left_e, centre_e) = lanes(word(b.first_chunk::<4>()));
    let (centre_o, right_o) = lanes(word(b.last_chunk::<4>()));
    Some([left_e, centre_e, centre_o, right_o])
}

/// The larger of `max` and the largest `|∇²I|` of the group at `off` of row `y` (rows
/// mirrored at the top and bottom).
#[inline(never)]
fn group_max(img: &[u8], width: usize, off: usize, y: usize, max: u32) -> u32 {
    let height = img.len() / width.max(1);
    let row = |y: isize| img.get(mirror(y, height) * width..).unwrap_or_default();
    let y = y as isize;
    let rows = [row(y - 1), row(y), row(y + 1)].map(|r| r.get(..width).unwrap_or_default());
    (off + 1..off + 5)
        .filter_map(|x| laplacian_at(rows, x))
        .fold(max, |max, v| max.max(v.abs_diff(LAPLACIAN_BIAS)))
}

/// [`first_flagged_row`] with the width a compile-time constant for the rows of the
/// camera's frame at each downsampling (320, 160 and 80 pixels).
fn first_flagged_row_of(
    img: &[u8],
    width: usize,
    off: usize,
    k: u32,
    from: usize,
) -> Option<usize> {
    match width {
        320 => first_flagged_row::<320>(img, width, off, k, from),
        160 => first_flagged_row::<160>(img, width, off, k, from),
        80 => first_flagged_row::<80>(img, width, off, k, from),
        _ => first_flagged_row::<0>(img, width, off, k, from),
    }
}

/// Walks the groups at `off` of centre rows `from ..` of an image of `width` (at least two
/// rows, mirrored at the top and bottom) down to the last row, and stops at the first
/// whose test against `k` ([`lane_threshold`]) flags a lane: that row, or `None`.
///
/// The hot loop holds only the walk: the caller updates the maximum ([`group_max`]) and
/// goes on from the next row.
#[inline(never)]
fn first_flagged_row<const WIDTH: usize>(
    img: &[u8],
    width: usize,
    off: usize,
    k: u32,
    from: usize,
) -> Option<usize> {
    // A width known at compile time steps down the column by an immediate: one register
    // fewer in the walk.
    let width = if WIDTH == 0 { width } else { WIDTH };
    let height = img.len() / width.max(1);
    let row = |y: usize| img.get(y * width..(y + 1) * width);
    let up = row(if from == 0 { 1 } else { from - 1 })?;
    let [_, ue, uo, _] = group_lanes(up, off)?;
    let [le, ce, co, ro] = group_lanes(row(from)?, off)?;
    // The centre row's pixels (even lanes `ce`, odd `co`), and `K + 4·centre` less the
    // sums of their neighbours but the one below: `t` of [`lane_flags`] but for it.
    let (mut ce, mut co) = (ce, co);
    let (mut part_e, mut part_o) = (
        k + (ce << 2) - (le + co + ue),
        k + (co << 2) - (ce + ro + uo),
    );
    let mut rows = img.get((from + 1) * width..)?.chunks_exact(width);
    for next in &mut rows {
        let Some([nle, nce, nco, nro]) = group_lanes(next, off) else {
            break;
        };
        if lane_flags_from_t(k, [part_e - nce, part_o - nco]) != 0 {
            // `next` is the row below the flagged one.
            return Some(height - rows.len() - 2);
        }
        (part_e, part_o) = (
            k + (nce << 2) - nle - nco - ce,
            k + (nco << 2) - nce - nro - co,
        );
        (ce, co) = (nce, nco);
    }
    // The last row's lower neighbour is row h − 2.
    let [_, de, d_o, _] = group_lanes(row(height.checked_sub(2)?)?, off)?;
    (lane_flags_from_t(k, [part_e - de, part_o - d_o]) != 0).then_some(height - 1)
}

/// `2¹⁵ − 1 − max` in both lanes (`max` taken as at most 1020, the largest `|∇²I|` of
/// 8-bit samples).
#[inline(always)]
fn lane_threshold(max: u32) -> u32 {
    (0x7FFF - max.min(1020)) * 0x0001_0001
}

/// Nonzero when a lane of `t = K + L` (`L = 4·centre − sum of neighbours` of the even
/// and the odd pixels, two per word; `K` = `k` from [`lane_threshold`]) has `|L|` above
/// the maximum `k` was made for: `t` or `u = 2K − t = K − L` reaches bit 15.
// Per lane 4·centre ≤ 1020 and the sum ≤ 1020, K ≥ 2¹⁵ − 1021: nothing leaves 0..2¹⁶.
#[inline(always)]
fn lane_flags_from_t(k: u32, [t_e, t_o]: [u32; 2]) -> u32 {
    let (u_e, u_o) = (2 * k - t_e, 2 * k - t_o);
    (t_e | u_e | t_o | u_o) & LANE_SIGNS
}

/// Sets `dst[i] = src[i] << SHIFT` (`SHIFT` at most 8) over their common length, four
/// samples per word read.
#[inline(always)]
pub(crate) fn widen_shifted<const SHIFT: u32>(src: &[u8], dst: &mut [i32]) {
    const { assert!(SHIFT <= 8) };
    let shift = SHIFT;
    let (src4, src_rest) = src.as_chunks::<4>();
    let (dst4, dst_rest) = dst.as_chunks_mut::<4>();
    let mask = 0xFF << shift;
    for (d, s) in dst4.iter_mut().zip(src4) {
        let w = u32::from_le_bytes(*s);
        // Each byte moved to bits `shift..shift + 8` and cut out there: one instruction
        // each on Arm, where a shifted operand is free.
        *d = [
            (w << shift) & mask,
            (w >> (8 - shift)) & mask,
            (w >> (16 - shift)) & mask,
            (w >> (24 - shift)) & mask,
        ]
        .map(|v| v as i32);
    }
    for (d, &s) in dst_rest.iter_mut().zip(src_rest) {
        *d = i32::from(s) << shift;
    }
}

/// The sum of a row of 8-bit samples, four per word read.
#[inline(always)]
pub(crate) fn row_sum(row: &[u8]) -> u32 {
    let (words, rest) = row.as_chunks::<4>();
    let mut total: u32 = rest.iter().map(|&v| u32::from(v)).sum();
    // A lane gains at most 2·255 per word: 128 words keep it below 2¹⁶.
    for block in words.chunks(128) {
        let mut acc = 0u32;
        for w in block {
            let (even, odd) = lanes(u32::from_le_bytes(*w));
            acc += even + odd;
        }
        total += (acc & 0xFFFF) + (acc >> 16);
    }
    total
}

/// The rounded mean of the four lane sums `a` and `b` (lane sums of two samples each):
/// `(a₀ + a₁ + b₀ + b₁ + 2) / 4`, as a byte.
#[inline(always)]
fn mean_of_lanes(a: u32, b: u32) -> u8 {
    let both = a + b;
    // The low lane plus the high one: the garbage above bit 16 is cut off with the shift.
    (((both + (both >> 16) + 2) >> 2) & 0xFF) as u8
}

/// One output row of a 2× downsampling of YUYV camera rows `r0` and `r1`: each output
/// pixel the rounded mean of the lumas (bytes 0 and 2) of one four-byte group of each row.
#[inline(always)]
pub(crate) fn halve_yuyv_row(out: &mut [u8], r0: &[u8], r1: &[u8]) {
    let pairs = r0.as_chunks::<4>().0.iter().zip(r1.as_chunks::<4>().0);
    for (o, (a, b)) in out.iter_mut().zip(pairs) {
        let word = |g: &[u8; 4]| u32::from_le_bytes(*g) & EVEN_BYTES;
        *o = mean_of_lanes(word(a), word(b));
    }
}

/// One output row of a 2× downsampling of 8-bit camera rows `r0` and `r1`: each output
/// pixel the rounded mean of a 2×2 box.
#[inline(always)]
pub(crate) fn halve_gray_row(out: &mut [u8], r0: &[u8], r1: &[u8]) {
    let (out2, out_rest) = out.as_chunks_mut::<2>();
    let words = r0.as_chunks::<4>().0.iter().zip(r1.as_chunks::<4>().0);
    for (o, (a, b)) in out2.iter_mut().zip(words) {
        // Each lane: the two samples of a box's row, for output pixels 0 and 1.
        let (a_e, a_o) = lanes(u32::from_le_bytes(*a));
        let (b_e, b_o) = lanes(u32::from_le_bytes(*b));
        let sums = a_e + a_o + b_e + b_o + 0x0002_0002;
        *o = [((sums >> 2) & 0xFF) as u8, ((sums >> 18) & 0xFF) as u8];
    }
    // An odd last output pixel.
    let done = 2 * out2.len();
    if let (Some(o), Some(a), Some(b)) = (
        out_rest.first_mut(),
        r0.get(2 * done..2 * done + 2),
        r1.get(2 * done..2 * done + 2),
    ) {
        let sum: u32 = a.iter().chain(b).map(|&v| u32::from(v)).sum();
        *o = ((sum + 2) >> 2) as u8;
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::{vec, vec::Vec};

    /// The plain statement: `4c − Σ neighbours + bias` with mirrored ends.
    fn plain(rows: [&[u8]; 3], x: usize) -> u32 {
        let w = rows[1].len();
        let at = |r: &[u8], i: usize| i32::from(r[i]);
        let l = at(rows[1], mirror(x as isize - 1, w));
        let r = at(rows[1], mirror(x as isize + 1, w));
        (1024 + 4 * at(rows[1], x) - at(rows[0], x) - at(rows[2], x) - l - r) as u32
    }

    /// Every pixel of rows of every width up to 40, extreme and mixed samples: the groups
    /// and the single pixels together cover each pixel once, with the plain value.
    #[test]
    fn quads_and_singles_give_every_pixels_laplacian() {
        let mut next = crate::test_bytes(7);
        for w in 1..=40 {
            for pattern in 0..6 {
                let mut row = || -> Vec<u8> {
                    (0..w)
                        .map(|i| match pattern {
                            0 => 0,
                            1 => 255,
                            2 => {
                                if i % 2 == 0 {
                                    255
                                } else {
                                    0
                                }
                            }
                            _ => next(),
                        })
                        .collect()
                };
                let (up, mid, down) = (row(), row(), row());
                let rows = [&up[..], &mid[..], &down[..]];
                let mut got = vec![None; w];
                let quads = quad_pixels(w);
                for (q, lanes) in laplacian_quads(rows).enumerate() {
                    let x = quads.start + 4 * q;
                    let [e0, e1] = unpack(lanes[0]);
                    let [o0, o1] = unpack(lanes[1]);
                    for (dx, v) in [(0, e0), (1, o0), (2, e1), (3, o1)] {
                        assert!(got[x + dx].replace(v).is_none(), "w {w}: {x} twice");
                    }
                }
                for x in single_pixels(w) {
                    let v = laplacian_at(rows, x).unwrap();
                    assert!(got[x].replace(v).is_none(), "w {w}: {x} twice");
                }
                for (x, v) in got.iter().enumerate() {
                    assert_eq!(*v, Some(plain(rows, x)), "w {w} pattern {pattern} x {x}");
                }
            }
        }
    }

    #[test]
    fn above_max_flags_exactly_the_lanes_past_the_maximum() {
        for max in [0, 1, 5, 100, 1019, 1020] {
            let test = AboveMax::new(max);
            for lap in -1020i32..=1020 {
                let v = (1024 + lap) as u32;
                let expected = lap.unsigned_abs() > max;
                // `v` in each of the four lanes, the others holding a zero Laplacian.
                let zero = BIAS_LANES;
                let (low, high) = (zero & 0xFFFF_0000 | v, v << 16 | (zero & 0xFFFF));
                for lanes in [[low, zero], [high, zero], [zero, low], [zero, high]] {
                    assert_eq!(test.flags(lanes) != 0, expected, "max {max} lap {lap}");
                }
            }
        }
    }

    #[test]
    fn widening_shifts_every_sample() {
        let src: Vec<u8> = (0..23)
            .map(|i| (i * 37 % 256) as u8)
            .chain([255, 0])
            .collect();
        fn check<const SHIFT: u32>(src: &[u8]) {
            let mut dst = vec![-1; src.len()];
            widen_shifted::<SHIFT>(src, &mut dst);
            let want: Vec<i32> = src.iter().map(|&v| i32::from(v) << SHIFT).collect();
            assert_eq!(dst, want, "shift {SHIFT}");
        }
        check::<0>(&src);
        check::<3>(&src);
        check::<8>(&src);
    }

    #[test]
    fn row_sums_and_halved_rows_match_the_plain_ones() {
        let mut next = crate::test_bytes(5);
        let mut bytes = |n: usize| -> Vec<u8> {
            (0..n)
                .map(|i| {
                    let random = next();
                    if i % 7 == 0 { 255 } else { random }
                })
                .collect()
        };
        for n in [0, 1, 3, 4, 5, 511, 512, 513, 2050] {
            let row = bytes(n);
            let plain: u32 = row.iter().map(|&v| u32::from(v)).sum();
            assert_eq!(row_sum(&row), plain, "{n}");
            assert_eq!(row_sum(&[255; 4096]), 255 * 4096);
        }
        for w in [1, 2, 3, 8, 33] {
            let (r0, r1) = (bytes(4 * w), bytes(4 * w));
            let mut out = vec![0; w];
            halve_yuyv_row(&mut out, &r0, &r1);
            // The rounded mean of a box's four samples.
            let mean = |box4: [u8; 4]| {
                let s: u32 = box4.iter().map(|&v| u32::from(v)).sum();
                ((s + 2) >> 2) as u8
            };
            let want: Vec<u8> = (0..w)
                .map(|x| mean([r0[4 * x], r0[4 * x + 2], r1[4 * x], r1[4 * x + 2]]))
                .collect();
            assert_eq!(out, want, "yuyv {w}");
            let (g0, g1) = (bytes(2 * w), bytes(2 * w));
            let mut out = vec![0; w];
            halve_gray_row(&mut out, &g0, &g1);
            let want: Vec<u8> = (0..w)
                .map(|x| mean([g0[2 * x], g0[2 * x + 1], g1[2 * x], g1[2 * x + 1]]))
                .collect();
            assert_eq!(out, want, "gray {w}");
        }
    }
}
