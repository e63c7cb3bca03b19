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

/// The shift `d` (in rows: row `y` of the current frame shows what row `y + d` of the
/// previous one showed) within `commanded ± radius` whose profiles match best; ties go to
/// the shift nearest the commanded one. Shifts that leave fewer than a quarter of the
/// profile overlapping are not considered.
pub fn refine_shift(previous: &[i32], current: &[i32], commanded: i64, radius: u32) -> i64 {
    let n = previous.len().min(current.len());
    let min_overlap = (n / 4).max(1);
    let mut best: Option<(u64, u64, i64)> = None;
    let r = i64::from(radius);
    for d in commanded - r..=commanded + r {
        let Ok(shift) = usize::try_from(d) else {
            continue;
        };
        let overlap = n.saturating_sub(shift);
        if overlap < min_overlap {
            continue;
        }
        let sad: u64 = current
            .iter()
            .zip(previous.iter().skip(shift))
            .take(overlap)
            .map(|(&c, &p)| u64::from(c.abs_diff(p)))
            .sum();
        // Mean over the overlap, compared as sad/overlap without division.
        let key = (sad, overlap as u64, (d - commanded).abs());
        let better = match best {
            None => true,
            Some((bs, bo, _)) if sad * bo != bs * key.1 => sad * bo < bs * key.1,
            Some((_, _, bd)) => key.2 < (bd - commanded).abs(),
        };
        if better {
            best = Some((sad, overlap as u64, d));
        }
    }
    best.map_or(commanded, |(_, _, d)| d)
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
