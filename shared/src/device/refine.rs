//! Refining the commanded belt shift between frames by a 1-D correlation of row profiles.
//!
//! The belt moves along the image rows, so a frame is the previous one shifted by some
//! rows. Each frame is reduced to its row profile (the sum of every row); the shift is the
//! one, within `± radius` of the commanded shift, whose profiles' first differences agree
//! best (least mean absolute difference over the rows both frames see). Differences
//! rather than the profiles themselves, so a change of overall brightness does not pull
//! the match. A frame with no structure along the belt (a flat profile) matches every
//! shift equally and keeps the commanded one.

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

/// A shift is taken over the commanded one only where its profiles match at least this
/// much better (mean absolute difference below `1 − 1/8` of the commanded shift's): on
/// full-resolution frames sensor noise alone moves the match by a row now and then, and
/// the motion is right to within it.
pub const CLEAR_GAIN: u64 = 8;

/// The shift `d` (in rows: row `y` of the current frame shows what row `y + d` of the
/// previous one showed) within `commanded ± radius` whose profiles match best, where it
/// matches clearly better than the commanded shift ([`CLEAR_GAIN`]); ties go to the shift
/// nearest the commanded one. Shifts that leave fewer than a quarter of the profile
/// overlapping are not considered.
pub fn refine_shift(previous: &[i32], current: &[i32], commanded: i64, radius: u32) -> i64 {
    let n = previous.len().min(current.len());
    let min_overlap = (n / 4).max(1);
    // (sum of absolute differences, overlap) of shift `d`, if it overlaps enough.
    let mismatch = |d: i64| {
        let shift = usize::try_from(d).ok()?;
        let overlap = n.saturating_sub(shift);
        if overlap < min_overlap {
            return None;
        }
        let sad: u64 = current
            .iter()
            .zip(previous.iter().skip(shift))
            .take(overlap)
            .map(|(&c, &p)| u64::from(c.abs_diff(p)))
            .sum();
        Some((sad, overlap as u64))
    };
    let mut best: Option<(u64, u64, i64)> = None;
    let r = i64::from(radius);
    for d in commanded - r..=commanded + r {
        let Some((sad, overlap)) = mismatch(d) else {
            continue;
        };
        // Means compared as sad/overlap without division.
        let better = match best {
            None => true,
            Some((bs, bo, _)) if sad * bo != bs * overlap => sad * bo < bs * overlap,
            Some((_, _, bd)) => (d - commanded).abs() < (bd - commanded).abs(),
        };
        if better {
            best = Some((sad, overlap, d));
        }
    }
    match (best, mismatch(commanded)) {
        // Mean below (1 − 1/CLEAR_GAIN) of the commanded shift's.
        (Some((sad, overlap, d)), Some((c_sad, c_overlap)))
            if sad * c_overlap * CLEAR_GAIN < c_sad * overlap * (CLEAR_GAIN - 1) =>
        {
            d
        }
        (Some((_, _, d)), None) => d,
        _ => commanded,
    }
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
        for true_shift in [5usize, 7, 9] {
            let b = textured(h, w, true_shift);
            row_profile(&b, dims, &mut pb);
            assert_eq!(refine_shift(&pa, &pb, 7, 2), true_shift as i64);
        }
        // Outside the search window, the best inside is taken, never beyond it.
        let b = textured(h, w, 12);
        row_profile(&b, dims, &mut pb);
        let got = refine_shift(&pa, &pb, 7, 2);
        assert!((5..=9).contains(&got));
    }

    /// A shift that matches only a little better than the commanded one (noise) is not
    /// taken; one that matches clearly better is.
    #[test]
    fn only_a_clearly_better_match_leaves_the_commanded_shift() {
        // The current profile is the previous one shifted by 3, with noise of ±4.
        let previous: Vec<i32> = (0..80).map(|i| (i * 37) % 23 * 10).collect();
        let noise = |i: usize| [4, -4, 3, -3, 0][i % 5];
        let current: Vec<i32> = (0..76).map(|i| previous[i + 3] + noise(i)).collect();
        assert_eq!(refine_shift(&previous, &current, 2, 2), 3);
        // The same against itself: shift 0 is best, shift 1 commanded and nearly as good.
        let smooth: Vec<i32> = (0..80).map(|i| 1000 + i % 2).collect();
        let noisy: Vec<i32> = smooth
            .iter()
            .enumerate()
            .map(|(i, &v)| v + noise(i))
            .collect();
        let (at_0, at_1) = (sad(&smooth, &noisy, 0), sad(&smooth, &noisy, 1));
        assert!(at_0 < at_1 && at_0 * 8 >= at_1 * 7, "{at_0} {at_1}");
        assert_eq!(refine_shift(&smooth, &noisy, 1, 2), 1);
    }

    /// Mean absolute difference of `current` against `previous` shifted by `d`, ×1000.
    fn sad(previous: &[i32], current: &[i32], d: usize) -> u64 {
        let overlap = previous.len().min(current.len()) - d;
        let total: u64 = current
            .iter()
            .zip(&previous[d..])
            .take(overlap)
            .map(|(&c, &p)| u64::from(c.abs_diff(p)))
            .sum();
        total * 1000 / overlap as u64
    }

    #[test]
    fn flat_frames_keep_the_commanded_shift() {
        let dims = Dims::new(8, 20).unwrap();
        let flat = [90u8; 160];
        let mut p = [0i32; 19];
        row_profile(&flat, dims, &mut p);
        assert_eq!(refine_shift(&p, &p, 4, 3), 4);
        assert_eq!(refine_shift(&p, &p, 0, 0), 0);
        assert_eq!(refine_shift(&[], &[], 3, 2), 3);
    }
}
