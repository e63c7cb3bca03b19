//! db2's lifting constants for the 32-bit integer path: Q32 words, and their products
//! rounded as the Cortex-M7 computes them.

/// Fraction bits of the lifting constants.
pub(crate) const Q: u32 = 32;

/// The integer db2 constants in Q32, each a signed 32-bit word: the operand of one
/// `SMULL`/`SMMULR` on the Cortex-M7, where Q16 constants took a 64-bit rounding and a
/// shift after each product (five and seven instructions for the two terms, now two and
/// three: `llvm-objdump -d` of the `tests/mcu-bench` binary).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Constants {
    /// 2 − √3 (√3 itself does not fit a signed Q32 word).
    two_minus_sqrt3: i32,
    /// √3/4.
    a: i32,
    /// (√3 − 2)/4 (negative).
    b: i32,
}

/// [`Constants`]' values: `round(c · 2³²)`.
pub(crate) const CONSTANTS: Constants = Constants {
    two_minus_sqrt3: 1_150_833_018,
    a: 1_859_775_393,
    b: -287_708_255,
};

/// Rounds a Q32 value to the nearest integer, halves upward: of a single product, one
/// `SMMULR` on the Cortex-M7.
#[inline(always)]
const fn round_q(v: i64) -> i32 {
    ((v + (1 << (Q - 1))) >> Q) as i32
}

/// [`round_q`] of a sum of two products, as its high word plus the low word's top bit: one
/// addition after `SMULL` and `SMLAL`, where `(v + 2³¹) >> 32` takes a 64-bit one.
#[inline(always)]
fn round_q_sum(v: i64) -> i32 {
    ((v >> Q) as i32).wrapping_add(((v as u32) >> (Q - 1)) as i32)
}

impl Constants {
    /// `R(√3·o)` as `2o − R((2 − √3)·o)`: within ½ of the product by the Q32 constant
    /// (the bounds' rounding slack). `|o|` stays below 2³⁰ (every proven bound is below
    /// `i32::MAX / 2`, `bounds` tests), so `2o` fits.
    #[inline(always)]
    pub(crate) const fn sqrt3_times(self, o: i32) -> i32 {
        2 * o - round_q(self.two_minus_sqrt3 as i64 * o as i64)
    }

    /// `R(√3/4·s + (√3−2)/4·s_prev)`: one rounding of the two products' sum.
    #[inline(always)]
    pub(crate) fn predict(self, s: i32, s_prev: i32) -> i32 {
        round_q_sum(i64::from(self.a) * i64::from(s) + i64::from(self.b) * i64::from(s_prev))
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    #[test]
    fn constants_are_the_rounded_q32_values() {
        let s3 = 3f64.sqrt();
        let q = (1u64 << Q) as f64;
        let k = CONSTANTS;
        assert_eq!(f64::from(k.two_minus_sqrt3), ((2.0 - s3) * q).round());
        assert_eq!(f64::from(k.a), (s3 / 4.0 * q).round());
        assert_eq!(f64::from(k.b), ((s3 - 2.0) / 4.0 * q).round());
    }

    #[test]
    fn rounded_products_are_within_half_of_exact() {
        // Across the proven range (|x| < 2³⁰). The slack past ½ is the Q32 constants' own
        // error (at most 2⁻³³ each, times |x|) and f64's.
        let s3 = 3f64.sqrt();
        let slack = |x: f64| 0.5 + x / 2f64.powi(32) + 1e-6;
        let mut x = 0x2545_f491u32;
        let mut values = [0i32; 512];
        for v in values.iter_mut() {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            *v = (x as i32) >> (2 + x % 30);
        }
        values[0] = (1 << 30) - 1;
        values[1] = -(1 << 30) + 1;
        let k = CONSTANTS;
        for w in values.windows(2) {
            let (s, p) = (f64::from(w[0]), f64::from(w[1]));
            let got = f64::from(k.sqrt3_times(w[0]));
            assert!((got - s3 * s).abs() <= slack(s.abs()), "√3·{s}: {got}");
            let exact = s3 / 4.0 * s + (s3 - 2.0) / 4.0 * p;
            let got = f64::from(k.predict(w[0], w[1]));
            assert!(
                (got - exact).abs() <= slack(s.abs() + p.abs()),
                "{s}, {p}: {got}"
            );
        }
        // Halves: up for the predict term, down for √3 (2o − R(…)).
        assert_eq!(round_q(1 << 31), 1);
        assert_eq!(round_q((1 << 31) - 1), 0);
        assert_eq!(round_q(-(1 << 31)), 0);
        assert_eq!(round_q(-(1 << 31) - 1), -1);
        for v in [
            0,
            1,
            -1,
            1 << 31,
            (1 << 31) - 1,
            -(1 << 31),
            3 << 31,
            -(5 << 31),
            i64::MAX >> 1,
        ] {
            assert_eq!(round_q_sum(v), round_q(v), "{v}");
        }
    }
}
