//! Positions from all the evidence at once: weighted least squares over a window of
//! frames, the older frames held where they were placed.
//!
//! Each piece of evidence says how far apart two frames are (a match, or the prior on a
//! step) or where one frame is (a commanded row), with a standard deviation. The
//! positions of the free frames minimize the sum of squared misfits, each over its
//! standard deviation. A match is an outlier when its misfit against the rest of the
//! evidence (its own pull on the fit taken out) is both over [`OUTLIER_SIGMAS`]
//! deviations and over [`OUTLIER_ROWS`] rows; the worst is dropped and the rest solved
//! again.

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
            let fit = self.solve_once(&dropped);
            let worst = self
                .matches
                .iter()
                .enumerate()
                .filter(|(i, _)| !dropped.contains(i))
                .filter_map(|(i, m)| {
                    let (rows, sigmas) = fit.deleted_misfit(m, self.free_from)?;
                    let outlier = rows > OUTLIER_ROWS && sigmas > OUTLIER_SIGMAS;
                    // The worst fitting goes first: a wrong match between neighbours
                    // also makes the longer, right ones across it look wrong.
                    outlier.then(|| (i, fit.misfit(m).abs() / m.sigma))
                })
                .max_by(|a, b| a.1.total_cmp(&b.1));
            match worst {
                Some((i, _)) if dropped.len() < self.matches.len() => dropped.push(i),
                _ => {
                    return Solution {
                        positions: fit.positions,
                        step_sigma: fit.step_sigma,
                        dropped,
                    };
                }
            }
        }
    }

    /// The least-squares fit without the `dropped` matches.
    fn solve_once(&self, dropped: &[usize]) -> Fit {
        let n = self.positions.len();
        let free = n.saturating_sub(self.free_from);
        let mut positions = self.positions.clone();
        if free == 0 {
            return Fit {
                positions,
                step_sigma: Vec::new(),
                covariance: None,
            };
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
            return Fit {
                positions,
                step_sigma: vec![f64::INFINITY; free],
                covariance: None,
            };
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
        Fit {
            positions,
            step_sigma,
            covariance: Some(cov),
        }
    }
}

/// One least-squares fit.
struct Fit {
    positions: Vec<f64>,
    step_sigma: Vec<f64>,
    /// Of the free positions (absent when the evidence could not be solved).
    covariance: Option<DMatrix<f64>>,
}

impl Fit {
    /// Fitted minus measured rows of `m`.
    fn misfit(&self, m: &Relation) -> f64 {
        self.positions[m.to] - self.positions[m.from] - m.rows
    }

    /// How far `m` is from what the rest of the evidence says, in rows and in standard
    /// deviations. A match over several frames that alone spans a weakly joined step (a
    /// frame whose other matches failed, held only by the speed's prior) pulls the fit
    /// to itself and shows almost no misfit: its leverage is taken out, so it is
    /// measured against the fit without it. A match between neighbours keeps its plain
    /// misfit: alone against the prior it is a belt that jerked, which the prior, knowing
    /// only the mean speed, cannot judge. `None`: nothing else measures what it does.
    fn deleted_misfit(&self, m: &Relation, free_from: usize) -> Option<(f64, f64)> {
        let misfit = self.misfit(m);
        let variance = match &self.covariance {
            Some(cov) if m.to.abs_diff(m.from) > 1 => {
                let (to, from) = (m.to.checked_sub(free_from), m.from.checked_sub(free_from));
                let c = |a: Option<usize>, b: Option<usize>| match (a, b) {
                    (Some(a), Some(b)) => cov[(a, b)],
                    _ => 0.0,
                };
                c(to, to) + c(from, from) - 2.0 * c(to, from)
            }
            _ => 0.0,
        };
        // The share of the match's own weight in its fitted value.
        let leverage = variance / (m.sigma * m.sigma);
        let rest = 1.0 - leverage;
        if rest <= 1e-6 {
            return None;
        }
        Some((misfit.abs() / rest, misfit.abs() / (m.sigma * rest.sqrt())))
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

    /// Every position `rows` after the one before, from 0.
    fn assert_evenly_apart(s: &Solution, rows: f64) {
        for (k, x) in s.positions.iter().enumerate() {
            assert!((x - rows * k as f64).abs() < 1e-6, "{:?}", s.positions);
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
        assert_evenly_apart(&s, 7.0);
    }

    /// Frame 2 matched nothing before it; the one match across its step (1→3) is 5 rows
    /// short. With its own pull on the fit it shows 0.13 rows of misfit and moves the
    /// step 1→2 to 2.3 rows; against the rest (the prior, 7 ± 1.2) it is 4 deviations off.
    #[test]
    fn a_long_match_alone_across_a_step_is_judged_by_the_rest() {
        let p = Problem {
            positions: vec![0.0; 5],
            free_from: 1,
            matches: vec![
                relation(0, 1, 7.0, 0.2),
                relation(2, 3, 7.0, 0.2),
                relation(3, 4, 7.0, 0.2),
                relation(1, 3, 9.0, 0.2),
            ],
            priors: (0..4).map(|k| relation(k, k + 1, 7.0, 1.2)).collect(),
            anchors: Vec::new(),
        };
        let s = p.solve();
        assert_eq!(s.dropped, vec![3]);
        assert_evenly_apart(&s, 7.0);
    }

    /// A neighbour's match far from the prior is a jerk of the belt, kept.
    #[test]
    fn a_match_between_neighbours_outweighs_the_prior() {
        let p = Problem {
            positions: vec![0.0; 3],
            free_from: 1,
            matches: vec![relation(0, 1, 7.0, 0.2), relation(1, 2, 13.0, 0.2)],
            priors: (0..2).map(|k| relation(k, k + 1, 7.0, 1.2)).collect(),
            anchors: Vec::new(),
        };
        let s = p.solve();
        assert!(s.dropped.is_empty());
        assert!((s.positions[2] - s.positions[1] - 13.0).abs() < 0.2);
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
