//! One frame against another: the shift along the belt at which their bands agree.
//!
//! Row `y` of frame `k`'s band shows what row `y + d` of frame `j`'s showed, `d` being
//! how far the belt moved between them. The bands are compared over the rows both hold,
//! each frame's rows multiplied by the *other* frame's visibility at the rows they are
//! compared with: a frame shows the belt's features at a contrast that rises toward the
//! apex, so two views of one feature at different rows differ by that contrast, and
//! cross-multiplying cancels it. Without that, the contrast profile (fixed in the frame)
//! pulls every match toward no motion. What cross-multiplying leaves — a feature cut off
//! where the gel lifts from it, a plateau's shading of the roller's curve, both fixed in
//! the frame — pulls least where the two views lie evenly either side of the apex, so a
//! belt row weighs by a Gaussian of how far the midpoint of its two views is from the
//! apex (σ half the band).

use super::features::{Band, Features};

/// The fewest rows two bands must share to be compared.
pub const MIN_SHARED_ROWS: usize = 12;

/// The best shift between two bands.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Match {
    /// Rows the belt moved from the earlier frame to the later (sub-pixel when refined).
    pub shift: f64,
    /// Normalized correlation at the best whole shift.
    pub score: f32,
    /// The best other local maximum of the correlation, 3 or more rows away (−1 if none):
    /// close to `score` means the match is ambiguous.
    pub runner_up: f32,
    /// How sharply the correlation falls either side of the best shift (its negative
    /// second difference); near 0 the shift is poorly defined.
    pub sharpness: f32,
}

/// The normalized correlation of `later` against `earlier` moved by `d` rows.
fn score_at(
    later: &Features,
    earlier: &Features,
    band: &Band,
    groups: usize,
    d: i64,
) -> Option<f32> {
    let n = band.rows() as i64;
    let (lo, hi) = (0.max(-d), n.min(n - d));
    if hi - lo < MIN_SHARED_ROWS.min(band.rows()) as i64 {
        return None;
    }
    let evenness = band.evenness();
    let (mut sx, mut sy, mut sxx, mut syy, mut sxy) = (0f64, 0f64, 0f64, 0f64, 0f64);
    for i in lo..hi {
        let (a, b) = (i as usize, (i + d) as usize);
        // Where the two views of this belt row straddle the apex evenly, the contrast
        // profile pulls neither way.
        let even = evenness(i as f32 + 0.5 * d as f32);
        let (wa, wb) = (band.weights[b] * even, band.weights[a] * even);
        let ra = &later.data[a * groups..(a + 1) * groups];
        let rb = &earlier.data[b * groups..(b + 1) * groups];
        let (mut x1, mut y1, mut xx, mut yy, mut xy) = (0f32, 0f32, 0f32, 0f32, 0f32);
        for (&p, &q) in ra.iter().zip(rb) {
            let (x, y) = (p * wa, q * wb);
            x1 += x;
            y1 += y;
            xx += x * x;
            yy += y * y;
            xy += x * y;
        }
        sx += f64::from(x1);
        sy += f64::from(y1);
        sxx += f64::from(xx);
        syy += f64::from(yy);
        sxy += f64::from(xy);
    }
    let count = ((hi - lo) as usize * groups) as f64;
    let vx = sxx - sx * sx / count;
    let vy = syy - sy * sy / count;
    if !(vx > 0.0 && vy > 0.0) {
        return None;
    }
    Some(((sxy - sx * sy / count) / (vx * vy).sqrt()) as f32)
}

/// The best shift of `later` against `earlier` among `shifts`, refined to a fraction of a
/// row by a parabola through its neighbours when `subpixel`; `None` when no shift leaves
/// enough shared rows with any texture.
pub fn best_match(
    later: &Features,
    earlier: &Features,
    band: &Band,
    groups: usize,
    shifts: std::ops::RangeInclusive<i64>,
    subpixel: bool,
) -> Option<Match> {
    let start = *shifts.start();
    let scores: Vec<Option<f32>> = shifts
        .map(|d| score_at(later, earlier, band, groups, d))
        .collect();
    let at = |i: isize| -> Option<f32> {
        usize::try_from(i)
            .ok()
            .and_then(|i| scores.get(i).copied().flatten())
    };
    let (best, score) = scores
        .iter()
        .enumerate()
        .filter_map(|(i, s)| s.map(|s| (i as isize, s)))
        .max_by(|a, b| a.1.total_cmp(&b.1))?;
    let runner_up = (0..scores.len() as isize)
        .filter(|&i| (i - best).abs() >= 3)
        .filter_map(|i| {
            let s = at(i)?;
            let left = at(i - 1).is_none_or(|l| l <= s);
            let right = at(i + 1).is_none_or(|r| r <= s);
            (left && right).then_some(s)
        })
        .fold(-1f32, f32::max);
    let (mut shift, mut sharpness) = (start as f64 + best as f64, 0.0);
    if let (Some(a), Some(c)) = (at(best - 1), at(best + 1)) {
        let curvature = a - 2.0 * score + c;
        sharpness = -0.5 * curvature;
        if subpixel && curvature < 0.0 {
            shift += f64::from((0.5 * (a - c) / curvature).clamp(-0.5, 0.5));
        }
    }
    Some(Match {
        shift,
        score,
        runner_up,
        sharpness,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A belt texture seen through rows of contrast `weights` with the frame at `top`.
    fn seen(top: f64, weights: &[f32], groups: usize) -> Features {
        let texture = |r: f64, g: usize| {
            let r = r + g as f64 * 3.7;
            ((r * 0.9).sin() + (r * 0.37).cos() * 0.6 + (r * 2.1).sin() * 0.3) as f32
        };
        let mut data = Vec::new();
        for (y, &w) in weights.iter().enumerate() {
            for g in 0..groups {
                data.push(w * texture(top + y as f64, g) * 10.0);
            }
        }
        Features { data, content: 1.0 }
    }

    #[test]
    fn a_shift_is_found_to_a_fraction_of_a_row() {
        let band = Band {
            top: 0,
            weights: vec![1.0; 40],
        };
        let (a, b) = (seen(0.0, &band.weights, 8), seen(6.3, &band.weights, 8));
        let m = best_match(&b, &a, &band, 8, 0..=15, true).unwrap();
        assert!((m.shift - 6.3).abs() < 0.15, "{m:?}");
        assert!(m.score > 0.95 && m.sharpness > 0.0, "{m:?}");
    }

    #[test]
    fn contrast_that_rises_toward_the_apex_does_not_pull_the_match_toward_no_motion() {
        // Visibility peaking mid-band and falling to a tenth at its ends.
        let weights: Vec<f32> = (0..50)
            .map(|y| (1.0 - ((y as f32 - 25.0) / 26.0).powi(2)).max(0.1))
            .collect();
        let band = Band { top: 0, weights };
        let (a, b) = (seen(0.0, &band.weights, 6), seen(9.0, &band.weights, 6));
        let m = best_match(&b, &a, &band, 6, 0..=20, true).unwrap();
        assert!((m.shift - 9.0).abs() < 0.1, "{m:?}");
        // Matched plainly (no cross-weighting), the same views come out short.
        let flat = Band {
            top: 0,
            weights: vec![1.0; 50],
        };
        let plain = best_match(&b, &a, &flat, 6, 0..=20, true).unwrap();
        assert!(plain.shift < m.shift, "{plain:?} against {m:?}");
    }

    #[test]
    fn flat_bands_match_nothing() {
        let band = Band {
            top: 0,
            weights: vec![1.0; 30],
        };
        let flat = Features {
            data: vec![0.0; 30 * 4],
            content: 0.0,
        };
        assert_eq!(best_match(&flat, &flat, &band, 4, -5..=5, true), None);
    }
}
