//! The pull of every match toward no motion, measured from the roll itself.
//!
//! What the frame holds fixed — a feature cut off where the gel lifts from it, the
//! roller's shading — agrees with itself at no shift, so every match comes out a little
//! short of the belt's true move. Where the contact band is narrow that is about 0.15–0.2
//! rows a match whatever its length (in the simulator's narrow regime, lag-1 matches 3 %
//! short and lag-4 ones 1.4 %), and a roll placed by lag-1 matches drifts by a few per
//! cent of its travel. A pull that does not grow with the shift shows in the matches
//! themselves: a match over `L` frames is pulled once, the `L` lag-1 matches along the
//! same frames `L` times, so their difference over `L − 1` is the pull. Its median over
//! the roll is added back to every match. What grows with the shift cannot be told from
//! the belt's own scale and stays.

use std::collections::VecDeque;

/// Chains of matches the pull is taken from (the newest).
const SAMPLES: usize = 64;
/// Chains needed before the pull is used.
const MIN_SAMPLES: usize = 16;
/// The largest pull believed, rows: more is not a pull but a wrong match.
const MAX_PULL: f64 = 1.0;
/// Below this shift, rows, the pull is taken in proportion (no shift, no pull).
const FULL_PULL_FROM: f64 = 2.0;

/// The running estimate of the pull.
#[derive(Debug, Clone, Default)]
pub struct Pull {
    samples: VecDeque<f64>,
}

impl Pull {
    /// Takes one chain: a match of `long_rows` over `lag` frames (at least 2) and the sum
    /// `chain_rows` of the lag-1 matches over the same frames.
    pub fn observe(&mut self, long_rows: f64, chain_rows: f64, lag: usize) {
        if lag < 2 || long_rows.abs() < FULL_PULL_FROM {
            return;
        }
        let sample = (long_rows - chain_rows) * long_rows.signum() / (lag - 1) as f64;
        if sample.abs() > MAX_PULL {
            return;
        }
        if self.samples.len() == SAMPLES {
            self.samples.pop_front();
        }
        self.samples.push_back(sample);
    }

    /// The pull, rows a match toward no motion: the median of the chains seen, 0 before
    /// [`MIN_SAMPLES`].
    pub fn rows(&self) -> f64 {
        if self.samples.len() < MIN_SAMPLES {
            return 0.0;
        }
        let mut s: Vec<f64> = self.samples.iter().copied().collect();
        s.sort_by(f64::total_cmp);
        s[s.len() / 2]
    }

    /// How much of the pull a match of `rows` carries: its direction, in proportion
    /// below [`FULL_PULL_FROM`].
    pub fn share(rows: f64) -> f64 {
        rows.signum() * (rows.abs() / FULL_PULL_FROM).min(1.0)
    }

    /// `rows` with the pull added back.
    pub fn corrected(&self, rows: f64) -> f64 {
        rows + self.rows() * Self::share(rows)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Steps of 6–8 rows, each match `pull` short.
    fn chains(pull: f64, lag: usize) -> Pull {
        let mut p = Pull::default();
        for k in 0..40 {
            let steps: Vec<f64> = (0..lag).map(|i| 6.0 + ((k + i) % 3) as f64).collect();
            let chain: f64 = steps.iter().map(|s| s - pull).sum();
            p.observe(steps.iter().sum::<f64>() - pull, chain, lag);
        }
        p
    }

    #[test]
    fn a_pull_the_same_at_every_lag_is_measured_and_added_back() {
        for lag in [2, 3, 4] {
            let p = chains(0.18, lag);
            assert!((p.rows() - 0.18).abs() < 1e-9, "{}", p.rows());
            assert!((p.corrected(6.82) - 7.0).abs() < 1e-9);
            assert!((p.corrected(-6.82) + 7.0).abs() < 1e-9);
            // Half the pull at a shift of one row.
            assert!((p.corrected(1.0) - 1.09).abs() < 1e-9);
        }
    }

    #[test]
    fn no_pull_and_too_few_chains_change_nothing() {
        assert_eq!(chains(0.0, 3).rows(), 0.0);
        let mut p = Pull::default();
        for _ in 0..MIN_SAMPLES - 1 {
            p.observe(13.6, 13.8, 2);
        }
        assert_eq!(p.corrected(7.0), 7.0);
    }

    #[test]
    fn a_wrong_long_match_is_not_a_pull() {
        let mut p = chains(0.1, 2);
        for _ in 0..10 {
            p.observe(20.0, 14.0, 2);
        }
        assert!((p.rows() - 0.1).abs() < 1e-9, "{}", p.rows());
    }
}
