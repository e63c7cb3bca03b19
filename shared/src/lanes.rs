//! Two 16-bit samples in one 32-bit word ([`I16x2`]) and the arithmetic the Cortex-M7's
//! DSP instructions do on them, two samples an instruction.
//!
//! Where the target has the Arm DSP extension (`cfg(rollfuse_dsp)`, set by `build.rs` for
//! `thumbv7em` and `thumbv8m.main`) each operation is its one instruction through `asm!`:
//! stable Rust has no intrinsics for them, and LLVM does not find `SADD16` or `SMULWB` in
//! plain code. Everywhere else [`portable`] computes the same bits in plain Rust; the tests
//! below state each operation's result lane by lane, and on the Cortex-M7 the bench runs
//! both versions over the same operands (`tests/mcu-bench`).
//!
//! Every operation wraps each lane to 16 bits as the instruction does, except those named
//! saturating; callers keep their values in range (the db2 level-1 bounds:
//! `docs/numerics.md`).

/// Two `i16` lanes of one word: `lo` in bits 0–15, `hi` in bits 16–31.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(transparent)]
pub struct I16x2(u32);

impl I16x2 {
    /// The lanes `lo` and `hi`.
    ///
    /// ```
    /// use rollfuse_core::lanes::I16x2;
    /// let v = I16x2::new(-3, 7);
    /// assert_eq!((v.lo(), v.hi()), (-3, 7));
    /// ```
    #[inline(always)]
    pub const fn new(lo: i16, hi: i16) -> Self {
        Self((lo as u16 as u32) | ((hi as u16 as u32) << 16))
    }

    /// Both lanes `v`.
    #[inline(always)]
    pub const fn splat(v: i16) -> Self {
        Self::new(v, v)
    }

    /// The low lane.
    #[inline(always)]
    pub const fn lo(self) -> i16 {
        self.0 as u16 as i16
    }

    /// The high lane.
    #[inline(always)]
    pub const fn hi(self) -> i16 {
        (self.0 >> 16) as u16 as i16
    }

    /// The word.
    #[inline(always)]
    pub const fn to_bits(self) -> u32 {
        self.0
    }

    /// Lanes from a word.
    #[inline(always)]
    pub const fn from_bits(bits: u32) -> Self {
        Self(bits)
    }

    /// The lanes swapped (`ROR #16`).
    #[inline(always)]
    pub const fn swap(self) -> Self {
        Self(self.0.rotate_left(16))
    }

    /// `prev`'s high lane low and `next`'s low lane high: the pair that straddles two
    /// words of consecutive samples.
    #[inline(always)]
    pub const fn straddle(prev: Self, next: Self) -> Self {
        Self((prev.0 >> 16) | (next.0 << 16))
    }

    /// The four bytes of `word` (little-endian: samples `0, 1, 2, 3`) as the even samples'
    /// lanes `(0, 2)` and the odd samples' `(1, 3)` (`UXTB16`, and `UXTB16` of the word
    /// rotated by 8).
    #[inline(always)]
    pub const fn from_bytes(word: u32) -> [Self; 2] {
        [Self(word & 0x00FF_00FF), Self((word >> 8) & 0x00FF_00FF)]
    }

    /// Each lane shifted left by `bits`, for lanes in `0..2^(15 − bits)` only (bytes
    /// taking guard bits): a shift of the whole word, which carries nothing between lanes
    /// then.
    #[inline(always)]
    pub const fn shl_small(self, bits: u32) -> Self {
        Self(self.0 << bits)
    }

    /// Back to four bytes, the inverse of [`Self::from_bytes`]: each lane of `even` and
    /// `odd` rounded from `guard` fraction bits (halves up), clamped to `0..=255`, the
    /// lanes interleaved. Exactly `((v + 2^(guard − 1)) >> guard).clamp(0, 255)` for every
    /// `i16` lane `v` and `guard` in `1..=7`: the rounding offset is a saturating add, the
    /// clamp to `0..=2^(8 + guard) − 1` comes before the shift, and the bits the shift
    /// carries from a high lane into its low neighbour fall outside the byte kept.
    #[inline(always)]
    pub fn to_bytes<const GUARD: u32>(even: Self, odd: Self) -> u32 {
        let half = Self::splat(1 << (GUARD - 1));
        let byte =
            |v: Self| (v.saturating_add(half).clamp_unsigned::<GUARD>().0 >> GUARD) & 0x00FF_00FF;
        byte(even) | (byte(odd) << 8)
    }
}

/// `+`, `-` and their assignments: the wrapping lane operations (the lifting's sums).
macro_rules! wrapping_operator {
    ($op:ident, $f:ident, $op_assign:ident, $f_assign:ident, $lanes:ident) => {
        impl core::ops::$op for I16x2 {
            type Output = Self;
            #[inline(always)]
            fn $f(self, other: Self) -> Self {
                self.$lanes(other)
            }
        }
        impl core::ops::$op_assign for I16x2 {
            #[inline(always)]
            fn $f_assign(&mut self, other: Self) {
                *self = self.$lanes(other);
            }
        }
    };
}
wrapping_operator!(Add, add, AddAssign, add_assign, wrapping_add);
wrapping_operator!(Sub, sub, SubAssign, sub_assign, wrapping_sub);

/// The operations that are one DSP instruction each, on both implementations.
macro_rules! lane_ops {
    ($imp:ident) => {
        impl I16x2 {
            /// Lane by lane `a + b`, wrapped (`SADD16`).
            #[inline(always)]
            pub fn wrapping_add(self, other: Self) -> Self {
                Self($imp::sadd16(self.0, other.0))
            }

            /// Lane by lane `a − b`, wrapped (`SSUB16`).
            #[inline(always)]
            pub fn wrapping_sub(self, other: Self) -> Self {
                Self($imp::ssub16(self.0, other.0))
            }

            /// Lane by lane `a + b`, saturated to `i16` (`QADD16`).
            #[inline(always)]
            pub fn saturating_add(self, other: Self) -> Self {
                Self($imp::qadd16(self.0, other.0))
            }

            /// Lane by lane `⌊(a + b)/2⌋`, never overflowing (`SHADD16`).
            #[inline(always)]
            pub fn halving_add(self, other: Self) -> Self {
                Self($imp::shadd16(self.0, other.0))
            }

            /// Lane by lane `⌊c·v / 2¹⁶⌋` for a Q16 constant `c`, wrapped (`SMULWB`,
            /// `SMULWT`, `PKHBT`).
            #[inline(always)]
            pub fn mul_q16(self, c: i32) -> Self {
                Self::pack($imp::smulwb(c, self.0), $imp::smulwt(c, self.0))
            }

            /// Lane by lane `⌊c·v / 2¹⁶⌋ + ⌊c2·w / 2¹⁶⌋` of this `v` and `other`'s `w`, each
            /// product rounded down on its own, the sum wrapped (`SMULWB`, `SMLAWB`,
            /// `SMULWT`, `SMLAWT`, `PKHBT`).
            #[inline(always)]
            pub fn mul_q16_add(self, c: i32, other: Self, c2: i32) -> Self {
                let lo = $imp::smlawb(c2, other.0, $imp::smulwb(c, self.0));
                let hi = $imp::smlawt(c2, other.0, $imp::smulwt(c, self.0));
                Self::pack(lo, hi)
            }

            /// `⌊w₀·lo / 2¹⁶⌋` and `⌊w₁·hi / 2¹⁶⌋`: each lane by its own Q16 factor,
            /// wrapped (`SMULWB`, `SMULWT`, `PKHBT`).
            #[inline(always)]
            pub fn mul_q16_each(self, [w0, w1]: [i32; 2]) -> Self {
                Self::pack($imp::smulwb(w0, self.0), $imp::smulwt(w1, self.0))
            }

            /// `w₀·lo / 2¹⁶` and `w₁·hi / 2¹⁶` rounded to nearest (halves up), for lanes
            /// whose double fits a lane: `⌊w·2v / 2¹⁶⌋` made odd-rounded by a halving add
            /// of 1 (`SADD16`, `SMULWB`, `SMULWT`, `PKHBT`, `SHADD16`).
            #[inline(always)]
            pub fn mul_q16_each_rounded(self, w: [i32; 2]) -> Self {
                (self + self).mul_q16_each(w).halving_add(Self::splat(1))
            }

            /// Each lane clamped to `0..=2^(8 + GUARD) − 1` (`USAT16`).
            #[inline(always)]
            fn clamp_unsigned<const GUARD: u32>(self) -> Self {
                Self($imp::usat16::<GUARD>(self.0))
            }

            /// The low halves of `lo` and `hi` as the lanes (`PKHBT`).
            #[inline(always)]
            fn pack(lo: i32, hi: i32) -> Self {
                Self($imp::pkhbt(lo, hi))
            }
        }
    };
}

#[cfg(rollfuse_dsp)]
lane_ops!(dsp);
#[cfg(not(rollfuse_dsp))]
lane_ops!(portable);

/// The operations in plain Rust: the instructions' results, lane by lane (Armv7-M
/// Architecture Reference Manual, A7.7). Compiled on every target, so that the Cortex-M7
/// bench can hold the instructions to them.
pub mod portable {
    #[inline(always)]
    fn lanes(w: u32) -> [i32; 2] {
        [
            i32::from(w as u16 as i16),
            i32::from((w >> 16) as u16 as i16),
        ]
    }

    #[inline(always)]
    fn join(lo: i32, hi: i32) -> u32 {
        (lo as u32 & 0xFFFF) | ((hi as u32) << 16)
    }

    #[inline(always)]
    fn each(a: u32, b: u32, f: impl Fn(i32, i32) -> i32) -> u32 {
        let ([a0, a1], [b0, b1]) = (lanes(a), lanes(b));
        join(f(a0, b0), f(a1, b1))
    }

    /// `SADD16`.
    #[inline(always)]
    pub fn sadd16(a: u32, b: u32) -> u32 {
        each(a, b, |x, y| x + y)
    }

    /// `SSUB16`.
    #[inline(always)]
    pub fn ssub16(a: u32, b: u32) -> u32 {
        each(a, b, |x, y| x - y)
    }

    /// `QADD16`.
    #[inline(always)]
    pub fn qadd16(a: u32, b: u32) -> u32 {
        each(a, b, |x, y| (x + y).clamp(-0x8000, 0x7FFF))
    }

    /// `SHADD16`.
    #[inline(always)]
    pub fn shadd16(a: u32, b: u32) -> u32 {
        each(a, b, |x, y| (x + y) >> 1)
    }

    /// `SMULWB`: `c` times the low lane of `v`, bits 16–47 of the product.
    #[inline(always)]
    pub fn smulwb(c: i32, v: u32) -> i32 {
        ((i64::from(c) * i64::from(lanes(v)[0])) >> 16) as i32
    }

    /// `SMULWT`: the same with the high lane.
    #[inline(always)]
    pub fn smulwt(c: i32, v: u32) -> i32 {
        ((i64::from(c) * i64::from(lanes(v)[1])) >> 16) as i32
    }

    /// `SMLAWB`: [`smulwb`] plus `acc`, wrapped.
    #[inline(always)]
    pub fn smlawb(c: i32, v: u32, acc: i32) -> i32 {
        smulwb(c, v).wrapping_add(acc)
    }

    /// `SMLAWT`: [`smulwt`] plus `acc`, wrapped.
    #[inline(always)]
    pub fn smlawt(c: i32, v: u32, acc: i32) -> i32 {
        smulwt(c, v).wrapping_add(acc)
    }

    /// `USAT16` to `8 + GUARD` bits.
    #[inline(always)]
    pub fn usat16<const GUARD: u32>(v: u32) -> u32 {
        each(v, 0, |x, _| x.clamp(0, (1 << (8 + GUARD)) - 1))
    }

    /// `PKHBT` with the second operand shifted left by 16.
    #[inline(always)]
    pub fn pkhbt(lo: i32, hi: i32) -> u32 {
        join(lo, hi)
    }
}

/// The instructions (`asm!` is the only way to them on stable Rust). Each block is pure:
/// registers in, a register out, no memory, no flags the compiler relies on (the `Q` flag
/// that `QADD16` and `SMLAW*` may set is read by nothing here).
#[cfg(rollfuse_dsp)]
#[allow(unsafe_code)]
mod dsp {
    use core::arch::asm;

    macro_rules! two {
        ($name:ident, $ins:literal, $a:ty, $b:ty, $r:ty) => {
            #[inline(always)]
            pub(super) fn $name(a: $a, b: $b) -> $r {
                let r;
                // SAFETY: one DSP instruction on registers (module note).
                unsafe {
                    asm!(concat!($ins, " {r}, {a}, {b}"), r = lateout(reg) r, a = in(reg) a,
                        b = in(reg) b, options(pure, nomem, nostack, preserves_flags));
                }
                r
            }
        };
    }
    two!(sadd16, "sadd16", u32, u32, u32);
    two!(ssub16, "ssub16", u32, u32, u32);
    two!(qadd16, "qadd16", u32, u32, u32);
    two!(shadd16, "shadd16", u32, u32, u32);
    two!(smulwb, "smulwb", i32, u32, i32);
    two!(smulwt, "smulwt", i32, u32, i32);

    macro_rules! three {
        ($name:ident, $ins:literal) => {
            #[inline(always)]
            pub(super) fn $name(c: i32, v: u32, acc: i32) -> i32 {
                let r;
                // SAFETY: one DSP instruction on registers (module note).
                unsafe {
                    asm!(concat!($ins, " {r}, {c}, {v}, {acc}"), r = lateout(reg) r,
                        c = in(reg) c, v = in(reg) v, acc = in(reg) acc,
                        options(pure, nomem, nostack, preserves_flags));
                }
                r
            }
        };
    }
    three!(smlawb, "smlawb");
    three!(smlawt, "smlawt");

    #[inline(always)]
    pub(super) fn usat16<const GUARD: u32>(v: u32) -> u32 {
        let r;
        // SAFETY: one DSP instruction on registers (module note).
        unsafe {
            asm!("usat16 {r}, #{n}, {v}", r = lateout(reg) r, v = in(reg) v,
                n = const 8 + GUARD, options(pure, nomem, nostack, preserves_flags));
        }
        r
    }

    #[inline(always)]
    pub(super) fn pkhbt(lo: i32, hi: i32) -> u32 {
        let r;
        // SAFETY: one instruction on registers (module note).
        unsafe {
            asm!("pkhbt {r}, {lo}, {hi}, lsl #16", r = lateout(reg) r, lo = in(reg) lo,
                hi = in(reg) hi, options(pure, nomem, nostack, preserves_flags));
        }
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Lane values at and around every edge the operations have.
    const EDGES: [i16; 13] = [
        i16::MIN,
        i16::MIN + 1,
        -32_000,
        -2_041,
        -255,
        -1,
        0,
        1,
        4,
        255,
        2_047,
        32_000,
        i16::MAX,
    ];

    fn pairs() -> impl Iterator<Item = (I16x2, I16x2)> {
        let words = || {
            EDGES
                .iter()
                .flat_map(|&a| EDGES.iter().map(move |&b| I16x2::new(a, b)))
        };
        words().flat_map(move |x| words().map(move |y| (x, y)))
    }

    fn lanes(v: I16x2) -> [i32; 2] {
        [i32::from(v.lo()), i32::from(v.hi())]
    }

    fn wrap(v: i64) -> i32 {
        i32::from(v as i16)
    }

    #[test]
    fn each_operation_is_its_lane_by_lane_definition() {
        for (x, y) in pairs() {
            let ([a0, a1], [b0, b1]) = (lanes(x), lanes(y));
            let check = |got: I16x2, f: &dyn Fn(i32, i32) -> i64| {
                assert_eq!(
                    lanes(got),
                    [wrap(f(a0, b0)), wrap(f(a1, b1))],
                    "{x:?} {y:?}"
                );
            };
            check(x.wrapping_add(y), &|a, b| i64::from(a + b));
            check(x.wrapping_sub(y), &|a, b| i64::from(a - b));
            check(x.saturating_add(y), &|a, b| {
                i64::from((a + b).clamp(-32_768, 32_767))
            });
            check(x.halving_add(y), &|a, b| i64::from(a + b).div_euclid(2));
            for c in [113_512, 28_378, -4_392, 0, 65_536, i32::MIN, i32::MAX] {
                let q = |a: i32, c: i32| (i64::from(c) * i64::from(a)).div_euclid(1 << 16);
                check(x.mul_q16(c), &|a, _| q(a, c));
                let c2 = -(c / 7);
                check(x.mul_q16_add(c, y, c2), &|a, b| {
                    i64::from((q(a, c) as i32).wrapping_add(q(b, c2) as i32))
                });
                let each = x.mul_q16_each([c, c / 3]);
                assert_eq!(lanes(each), [wrap(q(a0, c)), wrap(q(a1, c / 3))]);
                // Rounded to nearest, for lanes whose double fits a lane.
                if [a0, a1].iter().all(|v| (2 * v).abs() < 32_768) && (0..=65_536).contains(&c) {
                    let r = |a: i32, c: i32| (i64::from(c) * i64::from(a) + (1 << 15)) >> 16;
                    let rounded = x.mul_q16_each_rounded([c, c / 3]);
                    assert_eq!(
                        lanes(rounded),
                        [wrap(r(a0, c)), wrap(r(a1, c / 3))],
                        "{x:?} {c}"
                    );
                }
            }
        }
    }

    #[test]
    fn bytes_go_into_lanes_and_back() {
        let word = u32::from_le_bytes([10, 200, 0, 255]);
        let [even, odd] = I16x2::from_bytes(word);
        assert_eq!((lanes(even), lanes(odd)), ([10, 0], [200, 255]));
        let guarded = |v: I16x2| v.shl_small(3);
        assert_eq!(I16x2::to_bytes::<3>(guarded(even), guarded(odd)), word);
        // Rounding and clamping, lane by lane, as `((v + 4) >> 3).clamp(0, 255)`.
        for (x, y) in pairs() {
            let bytes = I16x2::to_bytes::<3>(x, y).to_le_bytes();
            let byte = |v: i16| ((i32::from(v) + 4) >> 3).clamp(0, 255) as u8;
            assert_eq!(
                bytes,
                [byte(x.lo()), byte(y.lo()), byte(x.hi()), byte(y.hi())]
            );
        }
    }

    #[test]
    fn straddle_and_swap_move_whole_lanes() {
        let (a, b) = (I16x2::new(1, -2), I16x2::new(-3, 4));
        assert_eq!(I16x2::straddle(a, b), I16x2::new(-2, -3));
        assert_eq!(a.swap(), I16x2::new(-2, 1));
    }
}
