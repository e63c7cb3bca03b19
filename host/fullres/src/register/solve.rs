//! Positions from all the evidence at once: weighted least squares over a window of
//! frames, the older frames held where they were placed.
//!
//! Each piece of evidence says how far apart two frames are (a match, or the prior on a
//! step) or where one frame is (a commanded row), with a standard deviation. The
//! positions of the free frames minimize the sum of squared misfits, each over its
//! standard deviation; the worst misfit, if it is both over [`OUTLIER_SIGMAS`] deviations
//! and over [`OUTLIER_ROWS`] rows, is dropped and the rest solved again.

use nalgebra::{DMatrix, DVector};

/// Misfits beyond this many standard deviations are outliers…
pub const OUTLIER_SIGMAS: f64 = 3.0;
/// …if they are also beyond this many rows.
pub const OUTLIER_ROWS: f64 = 1.0;

/// "Frame `to` lies `rows` after frame `from`", ± `sigma`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Relation {
    /// The earlier frame (an index into the positions).
    pub from: usize,
    /// The later frame.
    pub to: usize,
    /// Rows from `from` to `to`.
    pub rows: f64,
    /// Standard deviation, rows.
    pub sigma: f64,
}

/// "Frame `frame` lies at `row`", ± `sigma`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Anchor {
    /// The frame.
    pub frame: usize,
    /// Its row.
    pub row: f64,
    /// Standard deviation, rows.
    pub sigma: f64,
}

/// The problem: `positions[..free_from]` are held, the rest are solved for.
#[derive(Debug, Clone, Default)]
pub struct Problem {
    /// Every frame's position (the free ones are the starting guess).
    pub positions: Vec<f64>,
    /// Frames from this index on are free.
    pub free_from: usize,
    /// Matches: may be dropped as outliers.
    pub matches: Vec<Relation>,
    /// Priors on steps: never dropped.
    pub priors: Vec<Relation>,
    /// Rows frames are known to lie at, loosely (commanded rows).
    pub anchors: Vec<Anchor>,
}

/// The solution.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    /// Every frame's position.
    pub positions: Vec<f64>,
    /// Per free frame, the standard deviation of its step from the frame before.
    pub step_sigma: Vec<f64>,
    /// The matches dropped as outliers (indices into `matches`).
    pub dropped: Vec<usize>,
}

impl Problem {
    /// Solves, dropping outliers one at a time (at most as many as there are matches).
    pub fn solve(&self) -> Solution {
        let mut dropped: Vec<usize> = Vec::new();
        loop {
            let (positions, step_sigma) = self.solve_once(&dropped);
            let worst = self
                .matches
                .iter()
                .enumerate()
                .filter(|(i, _)| !dropped.contains(i))
                .map(|(i, m)| {
                    let misfit = positions[m.to] - positions[m.from] - m.rows;
                    (i, misfit.abs(), misfit.abs() / m.sigma)
                })
                .filter(|&(_, rows, sigmas)| rows > OUTLIER_ROWS && sigmas > OUTLIER_SIGMAS)
                .max_by(|a, b| a.2.total_cmp(&b.2));
            match worst {
                Some((i, _, _)) if dropped.len() < self.matches.len() => dropped.push(i),
                _ => {
                    return Solution {
                        positions,
                        step_sigma,
                        dropped,
                    };
                }
            }
        }
    }

    /// The least-squares positions without the `dropped` matches, and each free frame's
    /// step deviation.
    fn solve_once(&self, dropped: &[usize]) -> (Vec<f64>, Vec<f64>) {
        let n = self.positions.len();
        let free = n.saturating_sub(self.free_from);
        let mut positions = self.positions.clone();
        if free == 0 {
            return (positions, Vec::new());
        }
        let mut h = DMatrix::<f64>::zeros(free, free);
        let mut g = DVector::<f64>::zeros(free);
        let index = |i: usize| i.checked_sub(self.free_from);
        let relations = self
            .matches
            .iter()
            .enumerate()
            .filter(|(i, _)| !dropped.contains(i))
            .map(|(_, r)| r)
            .chain(&self.priors);
        for r in relations {
            let w = 1.0 / (r.sigma * r.sigma);
            // Residual x_to − x_from − rows, linear in the free positions.
            let mut rhs = r.rows;
            let terms = [(r.to, 1.0), (r.from, -1.0)];
            for &(i, c) in &terms {
                if index(i).is_none() {
                    rhs -= c * self.positions[i];
                }
            }
            for &(i, ci) in &terms {
                let Some(a) = index(i) else { continue };
                g[a] += w * ci * rhs;
                for &(j, cj) in &terms {
                    if let Some(b) = index(j) {
                        h[(a, b)] += w * ci * cj;
                    }
                }
            }
        }
        for a in &self.anchors {
            if let Some(i) = index(a.frame) {
                let w = 1.0 / (a.sigma * a.sigma);
                h[(i, i)] += w;
                g[i] += w * a.row;
            }
        }
        // A free frame no evidence reaches keeps its guess (a weak pull to it).
        for i in 0..free {
            h[(i, i)] += 1e-9;
            g[i] += 1e-9 * self.positions[self.free_from + i];
        }
        let Some(chol) = h.clone().cholesky() else {
            return (positions, vec![f64::INFINITY; free]);
        };
        let x = chol.solve(&g);
        let cov = chol.inverse();
        for i in 0..free {
            positions[self.free_from + i] = x[i];
        }
        let step_sigma = (0..free)
            .map(|i| {
                let var = if i == 0 {
                    cov[(0, 0)]
                } else {
                    cov[(i, i)] + cov[(i - 1, i - 1)] - 2.0 * cov[(i, i - 1)]
                };
                var.max(0.0).sqrt()
            })
            .collect();
        (positions, step_sigma)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn relation(from: usize, to: usize, rows: f64, sigma: f64) -> Relation {
        Relation {
            from,
            to,
            rows,
            sigma,
        }
    }

    #[test]
    fn matches_over_several_frames_outvote_a_wrong_one() {
        // Frames 7 rows apart; the match 2→3 says 3 (wrong), the others agree on 7.
        let mut matches = vec![
            relation(0, 1, 7.0, 0.2),
            relation(1, 2, 7.0, 0.2),
            relation(2, 3, 3.0, 0.2),
            relation(3, 4, 7.0, 0.2),
        ];
        matches.extend([relation(1, 3, 14.0, 0.3), relation(2, 4, 14.0, 0.3)]);
        let p = Problem {
            positions: vec![0.0; 5],
            free_from: 1,
            matches,
            priors: Vec::new(),
            anchors: Vec::new(),
        };
        let s = p.solve();
        assert_eq!(s.dropped, vec![2]);
        for (k, x) in s.positions.iter().enumerate() {
            assert!((x - 7.0 * k as f64).abs() < 1e-6, "{:?}", s.positions);
        }
    }

    #[test]
    fn a_prior_carries_the_frames_no_match_reaches() {
        let p = Problem {
            positions: vec![0.0, 7.0, 0.0, 0.0],
            free_from: 2,
            matches: Vec::new(),
            priors: vec![relation(1, 2, 6.5, 1.2), relation(2, 3, 6.5, 1.2)],
            anchors: Vec::new(),
        };
        let s = p.solve();
        assert!((s.positions[3] - 20.0).abs() < 1e-6, "{:?}", s.positions);
        // Two steps of 1.2 each: the second step is as uncertain as its prior.
        assert!((s.step_sigma[1] - 1.2).abs() < 1e-6, "{:?}", s.step_sigma);
    }
}
