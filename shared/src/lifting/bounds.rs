//! Proven coefficient bounds, per level, for the integer transforms.
//!
//! Each 1-D lifting pass is a linear map plus rounding. If every input satisfies
//! `|x| ≤ M`, every low-band output satisfies `|s| ≤ G_low · M + ε_low` and every high-band
//! output `|d| ≤ G_high · M + ε_high`, where `G` is the largest ℓ¹ norm of the map's rows
//! (over every position and every line length, boundaries included) and `ε` bounds the
//! rounding. A 2-D level is a row pass then a column pass, so the bounds compose; the next
//! level starts from the LL bound. [`level_bounds`] evaluates this chain in integer
//! arithmetic, rounding every gain upward.
//!
//! The gains:
//! - Haar (S-transform): `s = ⌊(e+o)/2⌋`, so `|s| ≤ M`; `d = o − e`, so `|d| ≤ 2M`.
//! - db2 (unscaled lifting): interior rows `(0.933, 1.616, 0.433, −0.250)` for the low band
//!   (ℓ¹ 3.232) and `(0.067, 0.116, −0.433, 0.250)` for the high band (ℓ¹ 0.866); rows at
//!   the boundaries, where symmetric extension folds taps, are measured by the test
//!   `gains_cover_every_boundary_row` (every line length to 40; a row reads at most three
//!   samples past its pair, so longer lines repeat rows already seen) and stay below the
//!   constants used here. Rounding adds
//!   at most 1.25 to a low and 0.75 to a high coefficient.
//!
//! The intermediate `s¹ = e + R(√3·o)` satisfies `|s¹| ≤ (1 + √3)·M + ½` and the inverse
//! steps, fed values saturated to these bounds, stay within `peak` below; the test
//! `every_bound_fits_in_i32` checks the deepest level's peak for `MAX_SAMPLE` inputs.
//!
//! The table for 8-bit input as the fusion feeds it (`M = 255 · 2^GUARD_BITS = 2040`) and
//! for `MAX_SAMPLE` is printed by
//! `cargo test -p rollfuse-core --lib -- --ignored print_bounds_table --nocapture` and
//! stated in `docs/numerics.md`.

use super::Wavelet;

/// The largest sample magnitude the forward transforms accept. It leaves every level's
/// proven peak below `i32::MAX` (see the test `every_bound_fits_in_i32`) and covers 12-bit
/// sensors with room to spare.
pub const MAX_SAMPLE: u32 = 4095;

/// Fixed-point fraction bits of the gains below.
const GQ: u32 = 16;

/// Gains of one 1-D pass, as `(G_low, G_high)` in Q16 with the rounding slack `(ε_low, ε_high)`.
struct PassGain {
    low: u64,
    high: u64,
    eps_low: u64,
    eps_high: u64,
}

const HAAR: PassGain = PassGain {
    low: 1 << GQ,
    high: 2 << GQ,
    eps_low: 0,
    eps_high: 0,
};

/// db2 gains with a margin over the measured boundary maxima (see the tests).
const DB2: PassGain = PassGain {
    low: 235_930,        // 3.6000 (measured 3.5981, at the boundaries)
    high: 7 << (GQ - 3), // 0.875  (measured 0.8660, the interior ℓ¹ norm)
    eps_low: 2,
    eps_high: 1,
};

fn gains(wavelet: Wavelet) -> &'static PassGain {
    match wavelet {
        Wavelet::Haar => &HAAR,
        Wavelet::Db2 => &DB2,
    }
}

/// Upper bounds on `|value|` for one decomposition level, in the order the forward
/// transform produces them. All are inclusive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LevelBounds {
    /// Input of this level (the image, or the LL band of the level above).
    pub input: i32,
    /// Low band of the row pass.
    pub row_low: i32,
    /// High band of the row pass.
    pub row_high: i32,
    /// LL band (low along rows and columns): the input of the next level.
    pub ll: i32,
    /// HL band (high along rows, low along columns).
    pub hl: i32,
    /// LH band (low along rows, high along columns).
    pub lh: i32,
    /// HH band.
    pub hh: i32,
    /// The largest magnitude any value reaches at any moment while this level is computed,
    /// forward or inverse (lifting intermediates included).
    pub peak: i32,
}

fn pass(g: &PassGain, m: u64) -> (u64, u64) {
    let low = (g.low * m).div_ceil(1 << GQ) + g.eps_low;
    let high = (g.high * m).div_ceil(1 << GQ) + g.eps_high;
    (low, high)
}

/// Largest magnitude inside one 1-D pass, forward or inverse, given the input bound `m` and
/// the output bounds `(low, high)`.
fn pass_peak(wavelet: Wavelet, m: u64, low: u64, high: u64) -> u64 {
    match wavelet {
        // Forward: d = o − e ≤ 2m. Inverse: s − ⌊d/2⌋ ≤ low + high/2 + 1; d + e ≤ that + high.
        Wavelet::Haar => (2 * m).max(low + high + high / 2 + 1),
        Wavelet::Db2 => {
            // Forward: s¹ ≤ 2.733 m; outputs as given.
            let s1_fwd = (m * 11) / 4 + 1;
            // Inverse: s¹ = s² + d¹; o = d¹ + R(a s¹ + b s¹′) with |a| + |b| < 0.5;
            // e = s¹ − R(√3 o) with √3 < 1.75.
            let s1_inv = low + high;
            let o_inv = high + s1_inv / 2 + 1;
            let e_inv = s1_inv + (o_inv * 7) / 4 + 1;
            s1_fwd.max(low).max(high).max(s1_inv).max(o_inv).max(e_inv)
        }
    }
}

fn to_i32(v: u64) -> i32 {
    i32::try_from(v).unwrap_or(i32::MAX)
}

/// Proven bounds for levels `1..=levels` (at most 4) when the input satisfies
/// `|x| ≤ MAX_SAMPLE`. Entries past `levels` are zero.
pub fn level_bounds(wavelet: Wavelet, levels: u8) -> [LevelBounds; 4] {
    level_bounds_for(wavelet, levels, MAX_SAMPLE)
}

/// As [`level_bounds`], for inputs bounded by `max_input` instead of `MAX_SAMPLE` (e.g.
/// 255 for 8-bit images).
pub fn level_bounds_for(wavelet: Wavelet, levels: u8, max_input: u32) -> [LevelBounds; 4] {
    let g = gains(wavelet);
    let mut out = [LevelBounds::default(); 4];
    let mut m = u64::from(max_input);
    for b in out.iter_mut().take(levels.min(4) as usize) {
        let (row_low, row_high) = pass(g, m);
        let (ll, lh) = pass(g, row_low);
        let (hl, hh) = pass(g, row_high);
        let peak = pass_peak(wavelet, m, row_low, row_high)
            .max(pass_peak(wavelet, row_low, ll, lh))
            .max(pass_peak(wavelet, row_high, hl, hh));
        *b = LevelBounds {
            input: to_i32(m),
            row_low: to_i32(row_low),
            row_high: to_i32(row_high),
            ll: to_i32(ll),
            hl: to_i32(hl),
            lh: to_i32(lh),
            hh: to_i32(hh),
            peak: to_i32(peak),
        };
        m = ll;
    }
    out
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::lifting::{db2, haar};
    use std::{println, vec};

    /// A level-1 inverse to bytes stores its column pass unsaturated
    /// (`lifting::Unsaturated`). Its loads are the fused coefficients of 8-bit samples
    /// with the guard bits, within those bands' bounds (convex combinations of them), but
    /// LL, which a deeper level reconstructs, up to the bound that level saturates its
    /// output to. From there the column outputs and the whole row pass stay far inside
    /// `i32`, and the bytes are clamped after.
    #[test]
    fn level_one_to_bytes_needs_no_column_saturation() {
        let bytes = 255 << crate::lifting::GUARD_BITS;
        for wavelet in [Wavelet::Haar, Wavelet::Db2] {
            let b = level_bounds_for(wavelet, 1, bytes)[0];
            let deeper = level_bounds(wavelet, 2)[1].input;
            let u = |v: i32| v as u64;
            let ll = u(b.ll.max(deeper));
            let left = pass_peak(wavelet, 0, ll, u(b.lh));
            let right = pass_peak(wavelet, 0, u(b.hl), u(b.hh));
            let row = pass_peak(wavelet, 0, left, right);
            println!("{wavelet:?}: columns {left} / {right}, rows {row}");
            assert!(row < 1 << 19, "{wavelet:?}: the row pass may reach {row}");
        }
    }

    /// Largest ℓ¹ row norm of one pass, measured by lifting scaled impulses through the
    /// real integer code for every line length up to 40. An output reads at most three
    /// samples either side of its own pair, and the boundary rules look at most two
    /// samples past an end, so from length 8 on every row is either the interior row or one
    /// of the boundary rows already seen at shorter lengths: longer lines add nothing new.
    fn measured_gain(lift: fn(&mut [i32], &mut [i32])) -> (f64, f64) {
        const K: f64 = (1 << 20) as f64;
        let (mut g_low, mut g_high) = (0f64, 0f64);
        for n in 2..=40usize {
            let nl = n.div_ceil(2);
            // rows[i][j]: coefficient of input j in output i.
            let mut rows = vec![vec![0f64; n]; n];
            for j in 0..n {
                let mut x = vec![0i32; n];
                x[j] = K as i32;
                // Even samples first, then odd, as forward_line arranges them.
                let mut split = vec![0i32; n];
                for (k, &v) in x.iter().enumerate() {
                    let slot = if k % 2 == 0 { k / 2 } else { nl + k / 2 };
                    split[slot] = v;
                }
                let (lo, hi) = split.split_at_mut(nl);
                lift(lo, hi);
                for (i, v) in split.iter().enumerate() {
                    rows[i][j] = *v as f64 / K;
                }
            }
            for (i, row) in rows.iter().enumerate() {
                let l1: f64 = row.iter().map(|c| c.abs()).sum();
                if i < nl {
                    g_low = g_low.max(l1);
                } else {
                    g_high = g_high.max(l1);
                }
            }
        }
        (g_low, g_high)
    }

    #[test]
    fn gains_cover_every_boundary_row() {
        let q = (1u64 << GQ) as f64;
        for (name, lift, g) in [
            ("haar", haar::forward as fn(&mut [i32], &mut [i32]), &HAAR),
            (
                "db2",
                |lo: &mut [i32], hi: &mut [i32]| db2::forward(lo, hi, 1),
                &DB2,
            ),
        ] {
            let (low, high) = measured_gain(lift);
            println!("{name}: measured G_low {low:.4}, G_high {high:.4}");
            // 1e-4 covers the impulse method's own rounding (40 taps · 2⁻²⁰).
            assert!(low <= g.low as f64 / q + 1e-4, "{name} low gain {low}");
            assert!(high <= g.high as f64 / q + 1e-4, "{name} high gain {high}");
        }
    }

    #[test]
    fn every_bound_fits_in_i32() {
        for w in [Wavelet::Haar, Wavelet::Db2] {
            let b = level_bounds(w, 4);
            let peak = b.iter().map(|l| l.peak).max().unwrap();
            assert!(peak < i32::MAX / 2, "{w:?}: peak {peak}");
            // The fusion's Laplacian of a level input sums five of them in i32.
            assert!(b.iter().all(|l| l.input < 1 << 28), "{w:?}: {b:?}");
            // Each level's input is the previous level's LL bound.
            for k in 1..4 {
                assert_eq!(b[k].input, b[k - 1].ll);
            }
        }
    }

    #[test]
    #[ignore = "prints the table for docs/numerics.md"]
    fn print_bounds_table() {
        // 8-bit samples with the fusion's guard bits, and the largest accepted input.
        let guarded = 255 << crate::lifting::GUARD_BITS;
        println!(
            "| wavelet | level | input | LL | HL, LH, HH | peak ({guarded}) | peak ({MAX_SAMPLE}) |"
        );
        for w in [Wavelet::Haar, Wavelet::Db2] {
            let full = level_bounds(w, 4);
            for (k, b) in level_bounds_for(w, 4, guarded).iter().enumerate() {
                println!(
                    "| {w:?} | {} | {} | {} | {} | {} | {} |",
                    k + 1,
                    b.input,
                    b.ll,
                    b.hl.max(b.lh).max(b.hh),
                    b.peak,
                    full[k].peak
                );
            }
        }
    }
}
