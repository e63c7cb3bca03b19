//! Refining the commanded belt shift between frames by a 1-D correlation of row profiles.
//!
//! The belt moves along the image rows, so a frame is the previous one shifted by some
//! rows. Each frame is reduced to its row profile (the sum of every row); the shift is the
//! one, within `± radius` of the commanded shift, whose profiles' first differences agree
//! best (least mean absolute difference over the rows both frames see), refined to a
//! sixteenth of a row by the V through it and its neighbours. Differences rather than the profiles
//! themselves, so a change of overall brightness does not pull the match. A frame with no
//! structure along the belt (a flat profile) matches every shift about equally and is
//! refined to nothing: the caller keeps the commanded shift.

use crate::Dims;

/// Writes the first differences of the row sums of `frame` (packed `dims`) to `out`
/// (`dims.height() − 1` values; nothing for a one-row frame).
pub fn row_profile(frame: &[u8], dims: Dims, out: &mut [i32]) {
    let w = dims.width();
    let mut rows = frame
        .chunks_exact(w)
        .take(dims.height())
        // A row of bytes sums to far below 2³¹ (its width is at most `MAX_DIMENSION`).
        .map(|r| crate::packed::row_sum(r) as i32);
    let Some(mut prev) = rows.next() else {
        return;
    };
    for (o, sum) in out.iter_mut().zip(rows) {
        *o = sum - prev;
        prev = sum;
    }
}

/// Fractions of a row a refined shift is given in: 1/16.
pub const SUBROWS: i64 = 16;

/// A match counts only where its profiles agree at least this much better than the mean
/// over the search (mean absolute difference below `1 − 1/8` of it): a frame with no
/// structure along the belt matches every shift about equally, and says nothing.
pub const CLEAR_GAIN: u64 = 8;

/// Mean absolute difference of the profiles at shift `d`, ×1024, if the overlap is at
/// least `min_overlap` rows.
fn mismatch(previous: &[i32], current: &[i32], d: i64, min_overlap: usize) -> Option<i64> {
    let n = previous.len().min(current.len());
    let shift = usize::try_from(d).ok()?;
    let overlap = n.saturating_sub(shift);
    if overlap < min_overlap.max(1) {
        return None;
    }
    let sad: u64 = current
        .iter()
        .zip(previous.iter().skip(shift))
        .take(overlap)
        .map(|(&c, &p)| u64::from(c.abs_diff(p)))
        .sum();
    // A row's difference is below 2^18 and rows below 2^13: the sum below 2^31, ×1024 well
    // inside i64.
    i64::try_from((sad << 10) / overlap as u64).ok()
}

/// The shift (in 1/[`SUBROWS`] rows: row `y` of the current frame shows what row `y + d`
/// of the previous one showed) within `commanded ± radius` whose profiles match best,
/// refined between rows by the V through its neighbours; `None` where no shift
/// matches clearly better than the search's mean ([`CLEAR_GAIN`]: no structure along the
/// belt) or none leaves a quarter of the profile overlapping. Ties go to the shift nearest
/// the commanded one.
pub fn refine_shift(previous: &[i32], current: &[i32], commanded: i64, radius: u32) -> Option<i64> {
    let min_overlap = previous.len().min(current.len()) / 4;
    let r = i64::from(radius);
    let at = |d: i64| mismatch(previous, current, d, min_overlap);
    let (mut best, mut sum, mut count): (Option<(i64, i64)>, i64, i64) = (None, 0, 0);
    for d in commanded - r..=commanded + r {
        let Some(m) = at(d) else { continue };
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
    let fraction = match (at(d - 1), at(d + 1)) {
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
        let (mut pa, mut pb) = (std::vec![0; h - 1], std::vec![0; h - 1]);
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
        // A smooth profile and the same moved 6.5 rows.
        let f = |y: f64| ((y * 0.7).sin() * 400.0 + (y * 0.23).cos() * 300.0) as i32;
        let previous: Vec<i32> = (0..80).map(|i| f(i as f64)).collect();
        let current: Vec<i32> = (0..80).map(|i| f(i as f64 + 6.5)).collect();
        let got = refine_shift(&previous, &current, 6, 3).unwrap();
        assert!((got - 104).abs() <= 3, "{got} sixteenths, want 104");
    }

    /// A profile with no structure along the belt matches every shift about equally:
    /// nothing is refined, and the caller keeps the commanded shift.
    #[test]
    fn no_structure_refines_nothing() {
        let noise = |i: usize| [4, -4, 3, -3, 0][i % 5];
        let smooth: Vec<i32> = (0..80).map(|i| 1000 + i % 2).collect();
        let noisy: Vec<i32> = smooth
            .iter()
            .enumerate()
            .map(|(i, &v)| v + noise(i))
            .collect();
        assert_eq!(refine_shift(&smooth, &noisy, 1, 2), None);
        let dims = Dims::new(8, 20).unwrap();
        let flat = [90u8; 160];
        let mut p = [0i32; 19];
        row_profile(&flat, dims, &mut p);
        assert_eq!(refine_shift(&p, &p, 4, 3), None);
        assert_eq!(refine_shift(&p, &p, 0, 0), None);
        assert_eq!(refine_shift(&[], &[], 3, 2), None);
    }
}
