//! The arithmetic of the lifting steps, integer and float, and the guard bits of the
//! 8-bit fusion's integers.

use super::{q16, q32};
use crate::lanes::I16x2;
use q32::CONSTANTS;

/// Fraction bits the 8-bit fusion keeps below the pixel's integer part while it works.
///
/// The unscaled lifting stores high bands at about half the orthonormal scale and the
/// inverse amplifies their rounding; three guard bits (samples × 8, at most 2040, well
/// inside `MAX_SAMPLE`) keep the fused 8-bit result within a gray level of exact
/// arithmetic, at no cost in bounds.
pub const GUARD_BITS: u32 = 3;

/// `R(√3·o)` ([`Constants::sqrt3_times`]) of every 8-bit value with the fusion's guard
/// bits, `o = v·2^GUARD_BITS`: the row pass from bytes looks it up (one load where the
/// product took three instructions and a register for the constant).
pub(crate) const SQRT3_OF_GUARDED_BYTES: [i32; 256] = sqrt3_of_guarded_bytes();

// `table[v]` with `v < 256` by the loop guard, in const evaluation only.
#[allow(clippy::indexing_slicing)]
const fn sqrt3_of_guarded_bytes() -> [i32; 256] {
    let mut table = [0; 256];
    let mut v = 0;
    while v < 256 {
        let o = (v as i32) << GUARD_BITS;
        table[v] = CONSTANTS.sqrt3_times(o);
        v += 1;
    }
    table
}

/// The arithmetic of the lifting steps: integers rounded in every step (`i32`, the MCU's
/// reversible transform) or exact reals (`f32`, the host's float path; `f64`, the reference). Both run the same
/// steps with the same boundary rule, so their coefficients differ only by rounding.
pub(crate) trait Lift:
    Copy
    + Default
    + core::ops::Add<Output = Self>
    + core::ops::Sub<Output = Self>
    + core::ops::AddAssign
    + core::ops::SubAssign
{
    /// Whether db2 lifts a row in two passes over whole channels
    /// ([`super::db2::forward_row_two_pass`]) rather than in one sweep over sample pairs
    /// ([`super::db2::forward_line`]). Floats do: each pass vectorizes, where the sweep carries
    /// each pair's `s¹` and `d¹` into the next. Integers sweep once: it saves the
    /// Cortex-M7 loads and stores (the device pipeline, `tests/mcu-bench`), and their
    /// rounded 64-bit products do not vectorize anyway. Haar's sweep carries nothing, so
    /// both take it; columns always sweep once (each step runs along whole rows, which
    /// vectorizes).
    const ROW_PASSES: bool;
    /// Haar's update term: `⌊d/2⌋`, or `d/2`.
    fn half(self) -> Self;
    /// What db2's [`Lift::sqrt3`] and [`Lift::predict`] multiply by, taken once per line,
    /// row or column sweep ([`Lift::constants`]) and handed to every step.
    type Constants: Copy;
    /// The db2 constants. The integer ones reach the steps through `black_box`, as
    /// values the compiler cannot see: it then multiplies by them as the 32-bit words
    /// they are (one `SMULL`, `SMLAL` or `SMMULR` on the Cortex-M7), where for known
    /// constants of 31 bits it builds each 64-bit product from three instructions.
    fn constants() -> Self::Constants;
    /// db2's first update term: `R(√3·o)`.
    fn sqrt3(self, k: Self::Constants) -> Self;
    /// db2's predict term: `R(√3/4·s + (√3−2)/4·s_prev)`.
    fn predict(s: Self, s_prev: Self, k: Self::Constants) -> Self;
    /// Saturates to `±bound`, `bound ≥ 0` (the integer inverse's guard; floats pass
    /// unchanged).
    fn saturate(self, bound: i32) -> Self;
    /// Whether [`Lift::saturate`] does anything: only then does an inverse to bytes take
    /// its own copy of the column pass that stores unsaturated ([`Unsaturated`]).
    const SATURATES: bool;
    /// The sample of an 8-bit value with the fusion's guard bits
    /// ([`crate::fusion::GUARD_BITS`]): `v·2^GUARD_BITS`.
    fn from_guarded_byte(v: u8) -> Self;
    /// db2's first update term of an 8-bit value with the guard bits:
    /// `Self::from_guarded_byte(v).sqrt3(k)` (the integer lifting looks it up).
    #[inline(always)]
    fn sqrt3_of_guarded_byte(v: u8, k: Self::Constants) -> Self {
        Self::from_guarded_byte(v).sqrt3(k)
    }
    /// A sample with guard bits back to 8 bits: rounded to nearest (halves up) and clamped
    /// to `0..=255`.
    fn to_byte(self) -> u8;
}

/// Whether `|v| ≤ bound` (`bound ≥ 0`), in one unsigned compare: `v + bound` lies in
/// `0..=2·bound` exactly then, both taken modulo 2³² (a true sum below 0 or past
/// `2·bound` wraps past `2·bound`, which is below 2³²).
#[inline(always)]
pub(super) fn within(v: i32, bound: i32) -> bool {
    (v.wrapping_add(bound) as u32) <= (bound as u32).wrapping_mul(2)
}

/// `v` saturated to `±bound` (`bound ≥ 0`): as it is, where [`within`] says so.
#[inline(always)]
pub(super) fn saturate_by_range_test(v: i32, bound: i32) -> i32 {
    if within(v, bound) {
        v
    } else {
        clamp_past(v, bound)
    }
}

/// `v` saturated to `±bound`. Not `clamp`: its `min ≤ max` check is a panic path; bounds
/// are never negative. Out of line on the Cortex-M7, where [`within`] keeps it off the
/// common path.
#[cfg_attr(target_arch = "arm", cold, inline(never))]
#[cfg_attr(not(target_arch = "arm"), inline(always))]
pub(super) fn clamp_past(v: i32, bound: i32) -> i32 {
    v.max(-bound).min(bound)
}

impl Lift for i32 {
    const ROW_PASSES: bool = false;
    #[inline(always)]
    fn half(self) -> Self {
        self >> 1
    }
    type Constants = q32::Constants;
    #[inline(always)]
    fn constants() -> q32::Constants {
        core::hint::black_box(q32::CONSTANTS)
    }
    #[inline(always)]
    fn sqrt3(self, k: q32::Constants) -> Self {
        k.sqrt3_times(self)
    }
    #[inline(always)]
    fn predict(s: Self, s_prev: Self, k: q32::Constants) -> Self {
        k.predict(s, s_prev)
    }
    #[inline(always)]
    fn saturate(self, bound: i32) -> Self {
        // On the Cortex-M7 a value within the bound (nearly all of them) costs one add,
        // one unsigned compare and a branch not taken, where the two-sided clamp took
        // two compare/IT/move triples (Haar's inverse columns, `tests/mcu-bench`). Where
        // there are vector units the branch-free clamp vectorizes.
        if cfg!(target_arch = "arm") {
            saturate_by_range_test(self, bound)
        } else {
            clamp_past(self, bound)
        }
    }
    const SATURATES: bool = true;
    #[inline(always)]
    fn from_guarded_byte(v: u8) -> Self {
        i32::from(v) << GUARD_BITS
    }
    #[inline(always)]
    fn sqrt3_of_guarded_byte(v: u8, _: q32::Constants) -> Self {
        // A `u8` index is always inside the 256 entries: no check is left.
        SQRT3_OF_GUARDED_BYTES
            .get(usize::from(v))
            .copied()
            .unwrap_or_default()
    }
    #[inline(always)]
    fn to_byte(self) -> u8 {
        ((self + (1 << (GUARD_BITS - 1))) >> GUARD_BITS).clamp(0, 255) as u8
    }
}

/// Two samples a word in 16-bit lanes ([`I16x2`]), each product by a Q16 constant and
/// rounded down on its own (what `SMULWB`/`SMLAWB` give): level 1 of the 8-bit fuse
/// step, two samples an instruction on the Cortex-M7 (`lanes`). The column
/// sweeps run on whole rows of such words through the generic code (two columns a word);
/// a word holding one sample in both lanes is the scalar version of the same arithmetic.
/// Every value of that level fits a lane (`docs/numerics.md`), so nothing is saturated.
impl Lift for I16x2 {
    const ROW_PASSES: bool = false;
    #[inline(always)]
    fn half(self) -> Self {
        self.halving_add(Self::default())
    }
    type Constants = q16::Constants;
    #[inline(always)]
    fn constants() -> q16::Constants {
        core::hint::black_box(q16::CONSTANTS)
    }
    #[inline(always)]
    fn sqrt3(self, k: q16::Constants) -> Self {
        self.mul_q16(k.sqrt3)
    }
    #[inline(always)]
    fn predict(s: Self, s_prev: Self, k: q16::Constants) -> Self {
        s.mul_q16_add(k.a, s_prev, k.b)
    }
    #[inline(always)]
    fn saturate(self, _bound: i32) -> Self {
        self
    }
    const SATURATES: bool = false;
    #[inline(always)]
    fn from_guarded_byte(v: u8) -> Self {
        Self::splat(i16::from(v) << GUARD_BITS)
    }
    #[inline(always)]
    fn to_byte(self) -> u8 {
        Self::to_bytes::<GUARD_BITS>(self, self) as u8
    }
}

/// The float lifting: the integer steps without rounding, to the type's precision.
macro_rules! float_lift {
    ($t:ty, $sqrt3:expr, $floor:path) => {
        impl Lift for $t {
            const ROW_PASSES: bool = true;
            #[inline(always)]
            fn half(self) -> Self {
                0.5 * self
            }
            type Constants = ();
            #[inline(always)]
            fn constants() {}
            #[inline(always)]
            fn sqrt3(self, _: ()) -> Self {
                $sqrt3 * self
            }
            #[inline(always)]
            fn predict(s: Self, s_prev: Self, _: ()) -> Self {
                const A: $t = $sqrt3 / 4.0;
                const B: $t = ($sqrt3 - 2.0) / 4.0;
                A * s + B * s_prev
            }
            #[inline(always)]
            fn saturate(self, _bound: i32) -> Self {
                self
            }
            const SATURATES: bool = false;
            #[inline(always)]
            fn from_guarded_byte(v: u8) -> Self {
                <$t>::from(v) * <$t>::from(1u8 << GUARD_BITS)
            }
            #[inline(always)]
            fn to_byte(self) -> u8 {
                // `as` saturates (NaN to 0).
                $floor(self / <$t>::from(1u8 << GUARD_BITS) + 0.5) as u8
            }
        }
    };
}

float_lift!(f32, 1.732_050_8_f32, libm::floorf);
float_lift!(f64, 1.732_050_807_568_877_2_f64, libm::floor);

#[cfg(test)]
mod tests {
    use super::*;

    /// The looked-up `R(√3·o)` of every 8-bit value with the guard bits is the product's.
    #[test]
    fn sqrt3_table_holds_the_products() {
        for v in 0..=255u8 {
            let o = i32::from(v) << GUARD_BITS;
            assert_eq!(
                SQRT3_OF_GUARDED_BYTES[usize::from(v)],
                CONSTANTS.sqrt3_times(o)
            );
            assert_eq!(i32::sqrt3_of_guarded_byte(v, CONSTANTS), o.sqrt3(CONSTANTS));
        }
    }
}
