//! Refining the commanded belt shift between frames by a 1-D correlation of row profiles.
//!
//! The belt moves along the image rows, so a frame is the previous one shifted by some
//! rows. Each frame is reduced to its row profile: the sums of every row over
//! [`PROFILE_BANDS`] bands of columns side by side, so features at different columns
//! of a row do not cancel in one sum. The shift is the one, within `± radius` of the
//! commanded shift, whose profiles' first differences agree best (least mean absolute
//! difference over the rows both frames see, every band counted), refined to a sixteenth
//! of a row by the V through it and its neighbours. Differences rather than the profiles
//! themselves, so a change of overall brightness does not pull the match. A frame with no
//! structure along the belt (a flat profile) matches every shift about equally and is
//! refined to nothing: the caller keeps the commanded shift.

use crate::Dims;

/// Bands of columns a row profile sums separately: each row's profile is this many
/// values, the bands' sums left to right.
pub const PROFILE_BANDS: usize = 4;

/// The columns of band `band` of a `width`-wide row: the row cut in [`PROFILE_BANDS`]
/// near-equal parts at multiples of four columns (so the 1× YUYV conversion, four pixels
/// at a time, sums whole groups into each band).
pub fn band_columns(width: usize, band: usize) -> core::ops::Range<usize> {
    let edge = |b: usize| {
        if b >= PROFILE_BANDS {
            width
        } else {
            (b * width / PROFILE_BANDS) & !3
        }
    };
    edge(band)..edge(band + 1)
}

/// Values in the row profile of a band of `rows` rows: [`PROFILE_BANDS`] for each row
/// after the first.
pub const fn profile_len(rows: usize) -> usize {
    rows.saturating_sub(1) * PROFILE_BANDS
}

/// Writes the first differences of the band sums ([`band_columns`]) of the rows of
/// `frame` (packed `dims`) to `out`: [`profile_len`] values, each row's bands together;
/// nothing for a one-row frame.
pub fn row_profile(frame: &[u8], dims: Dims, out: &mut [i32]) {
    let w = dims.width();
    let sums = frame.chunks_exact(w).take(dims.height()).map(|row| {
        core::array::from_fn(|b| {
            let band = row.get(band_columns(w, b)).unwrap_or(&[]);
            crate::packed::row_sum(band)
        })
    });
    write_differences(sums, out);
}

/// Writes the first differences of consecutive rows' band sums to `out` (as many rows as
/// it holds), drawing every row from `sums` however many that is.
#[inline(always)]
pub(crate) fn write_differences(sums: impl Iterator<Item = [u32; PROFILE_BANDS]>, out: &mut [i32]) {
    let mut diffs = out.chunks_exact_mut(PROFILE_BANDS);
    let mut previous = None;
    for sums in sums {
        // A row of bytes sums to far below 2³¹ (its width is at most `MAX_DIMENSION`).
        let sums = sums.map(|s| s as i32);
        if let Some(p) = previous
            && let Some(d) = diffs.next()
        {
            for ((d, &s), &p) in d.iter_mut().zip(&sums).zip(&p) {
                *d = s - p;
            }
        }
        previous = Some(sums);
    }
}

/// Fractions of a row a refined shift is given in: 1/16.
pub const SUBROWS: i64 = 16;

/// A match counts only where its profiles agree at least this much better than the mean
/// over the search (mean absolute difference below `1 − 1/8` of it): a frame with no
/// structure along the belt matches every shift about equally, and says nothing.
pub const CLEAR_GAIN: u64 = 8;

/// Mismatches a search keeps for the V through its best shift's neighbours: all of a
/// search of up to ±16 rows (a wider one measures the two again).
const REMEMBERED: usize = 33;

/// Mean absolute difference of the profiles at shift `d` rows, ×1024, if the overlap is
/// at least `min_overlap` rows.
fn mismatch(previous: &[i32], current: &[i32], d: i64, min_overlap: usize) -> Option<i64> {
    let n = previous.len().min(current.len()) / PROFILE_BANDS;
    let shift = usize::try_from(d).ok()?;
    let overlap = n.saturating_sub(shift);
    if overlap < min_overlap.max(1) {
        return None;
    }
    let values = overlap * PROFILE_BANDS;
    let from = shift * PROFILE_BANDS;
    let (current, previous) = (current.get(..values)?, previous.get(from..from + values)?);
    let sad: u64 = current
        .iter()
        .zip(previous)
        .map(|(&c, &p)| u64::from(c.abs_diff(p)))
        .sum();
    // A band's difference is below 2^18 and values below 2^15: the sum below 2^33, ×1024
    // well inside i64.
    i64::try_from((sad << 10) / values as u64).ok()
}

/// The shift (in 1/[`SUBROWS`] rows: row `y` of the current frame shows what row `y + d`
/// of the previous one showed) within `commanded ± radius` whose profiles match best,
/// refined between rows by the V through its neighbours; `None` where no shift
/// matches clearly better than the search's mean ([`CLEAR_GAIN`]: no structure along the
/// belt) or none leaves a quarter of the profile's rows overlapping. Ties go to the shift
/// nearest the commanded one. The profiles are [`row_profile`]s: [`PROFILE_BANDS`]
/// values a row.
pub fn refine_shift(previous: &[i32], current: &[i32], commanded: i64, radius: u32) -> Option<i64> {
    let min_overlap = previous.len().min(current.len()) / PROFILE_BANDS / 4;
    let r = i64::from(radius);
    let at = |d: i64| mismatch(previous, current, d, min_overlap);
    // The search's mismatches, kept for the V through the best one's neighbours.
    let mut seen = [None; REMEMBERED];
    let slot = |d: i64| {
        let i = usize::try_from(d.saturating_sub(commanded.saturating_sub(r))).ok()?;
        (i < REMEMBERED && d <= commanded + r).then_some(i)
    };
    let (mut best, mut sum, mut count): (Option<(i64, i64)>, i64, i64) = (None, 0, 0);
    for d in commanded - r..=commanded + r {
        let m = at(d);
        if let Some(kept) = slot(d).and_then(|i| seen.get_mut(i)) {
            *kept = m;
        }
        let Some(m) = m else { continue };
        sum = sum.saturating_add(m);
        count += 1;
        let better = match best {
            None => true,
            Some((bm, _)) if m != bm => m < bm,
            Some((_, bd)) => (d - commanded).abs() < (bd - commanded).abs(),
        };
        if better {
            best = Some((m, d));
        }
    }
    let (m, d) = best?;
    let mean = sum / count.max(1);
    // Best below (1 − 1/CLEAR_GAIN) of the mean, compared without division.
    if m.saturating_mul(CLEAR_GAIN as i64) >= mean.saturating_mul(CLEAR_GAIN as i64 - 1) {
        return None;
    }
    let near = |d: i64| match slot(d).and_then(|i| seen.get(i)) {
        Some(&kept) => kept,
        None => at(d),
    };
    let fraction = match (near(d - 1), near(d + 1)) {
        (Some(before), Some(after)) => {
            // Absolute differences fall to their minimum in a V, not a parabola: the
            // vertex of the V through the three, (before − after) / (2·(steeper − m)) rows,
            // within half a row.
            let rise = before.max(after) - m;
            if rise > 0 {
                ((before - after) * SUBROWS / (2 * rise)).clamp(-SUBROWS / 2, SUBROWS / 2)
            } else {
                0
            }
        }
        _ => 0,
    };
    Some(d * SUBROWS + fraction)
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    fn textured(rows: usize, w: usize, start: usize) -> Vec<u8> {
        (0..rows * w)
            .map(|i| {
                let y = (i / w + start) as u32;
                let x = (i % w) as u32;
                (y.wrapping_mul(2_654_435_761).rotate_left(7) ^ x) as u8
            })
            .collect()
    }

    #[test]
    fn recovers_the_true_shift_near_the_commanded_one() {
        let (w, h) = (16, 60);
        let dims = Dims::new(w, h).unwrap();
        let a = textured(h, w, 0);
        let n = (h - 1) * PROFILE_BANDS;
        let (mut pa, mut pb) = (std::vec![0; n], std::vec![0; n]);
        row_profile(&a, dims, &mut pa);
        for true_shift in [5i64, 7, 9] {
            let b = textured(h, w, true_shift as usize);
            row_profile(&b, dims, &mut pb);
            let got = refine_shift(&pa, &pb, 7, 2).unwrap();
            assert!((got - true_shift * SUBROWS).abs() <= 2, "{got}");
        }
        // Outside the search window, the best inside is taken, never beyond it.
        let b = textured(h, w, 12);
        row_profile(&b, dims, &mut pb);
        let got = refine_shift(&pa, &pb, 7, 2);
        assert!(got.is_none_or(|d| (5 * SUBROWS - 8..=9 * SUBROWS + 8).contains(&d)));
    }

    #[test]
    fn a_shift_between_rows_is_found_to_a_fraction() {
        // A smooth profile, each band its own, and the same moved 6.5 rows.
        let f = |y: f64, b: usize| {
            let b = b as f64;
            ((y * (0.5 + 0.1 * b)).sin() * 400.0 + (y * 0.23 + b).cos() * 300.0) as i32
        };
        let profile = |moved: f64| -> Vec<i32> {
            (0..80)
                .flat_map(|i| (0..PROFILE_BANDS).map(move |b| f(i as f64 + moved, b)))
                .collect()
        };
        let (previous, current) = (profile(0.0), profile(6.5));
        let got = refine_shift(&previous, &current, 6, 3).unwrap();
        assert!((got - 104).abs() <= 3, "{got} sixteenths, want 104");
    }

    /// A profile with no structure along the belt matches every shift about equally:
    /// nothing is refined, and the caller keeps the commanded shift.
    #[test]
    fn no_structure_refines_nothing() {
        let noise = |i: usize| [4, -4, 3, -3, 0][i % 5];
        let smooth: Vec<i32> = (0..80 * PROFILE_BANDS as i32)
            .map(|i| 1000 + i % 2)
            .collect();
        let noisy: Vec<i32> = smooth
            .iter()
            .enumerate()
            .map(|(i, &v)| v + noise(i))
            .collect();
        assert_eq!(refine_shift(&smooth, &noisy, 1, 2), None);
        let dims = Dims::new(8, 20).unwrap();
        let flat = [90u8; 160];
        let mut p = [0i32; 19 * PROFILE_BANDS];
        row_profile(&flat, dims, &mut p);
        assert_eq!(refine_shift(&p, &p, 4, 3), None);
        assert_eq!(refine_shift(&p, &p, 0, 0), None);
        assert_eq!(refine_shift(&[], &[], 3, 2), None);
    }

    /// The bands cover the row, in order, without overlap, cut at multiples of four.
    #[test]
    fn bands_cut_a_row_at_multiples_of_four_columns() {
        for width in [1, 2, 7, 16, 320, 321, 4095] {
            let mut next = 0;
            for b in 0..PROFILE_BANDS {
                let cols = band_columns(width, b);
                assert_eq!(cols.start, next, "width {width}");
                assert!(
                    cols.start.is_multiple_of(4) || cols.start == width,
                    "width {width}"
                );
                next = cols.end;
            }
            assert_eq!(next, width);
        }
    }

    /// Features at different columns of the same rows, one brighter where the other is
    /// darker, cancel in a whole row's sum; the bands keep them apart.
    #[test]
    fn features_that_cancel_across_a_row_are_still_matched() {
        let (w, h) = (16, 60);
        let dims = Dims::new(w, h).unwrap();
        let frame = |start: usize| -> Vec<u8> {
            (0..h * w)
                .map(|i| {
                    let (y, x) = ((i / w + start) as u32, i % w);
                    let v = (y.wrapping_mul(2_654_435_761) >> 24) as u8 / 2;
                    if x < w / 2 { 64 + v } else { 191 - v }
                })
                .collect()
        };
        let n = (h - 1) * PROFILE_BANDS;
        let (mut pa, mut pb) = (std::vec![0; n], std::vec![0; n]);
        row_profile(&frame(0), dims, &mut pa);
        row_profile(&frame(6), dims, &mut pb);
        assert_eq!(refine_shift(&pa, &pb, 5, 2), Some(6 * SUBROWS));
    }
}
