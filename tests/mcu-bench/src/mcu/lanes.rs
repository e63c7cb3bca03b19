//! The DSP instructions of `rollfuse_core::lanes` held to their plain-Rust definitions
//! (`lanes::portable`, what the host runs) on the Cortex-M7, over operands at and around
//! every edge: the host's integer fusion and the module's give the same bytes only if
//! each instruction computes what the definition says.

use cortex_m_semihosting::hprintln;
use rollfuse_core::lanes::{I16x2, portable};

/// Lane values at the edges of the operations.
const EDGES: [i16; 12] = [
    i16::MIN,
    i16::MIN + 1,
    -20_000,
    -2_041,
    -1,
    0,
    1,
    4,
    255,
    2_047,
    20_000,
    i16::MAX,
];

/// Q16 factors: the db2 constants, weights 0 and 1, the extremes.
const FACTORS: [i32; 7] = [113_512, 28_378, -4_390, 0, 65_536, i32::MIN, i32::MAX];

/// Whether every operation agrees with its definition; prints the first that does not.
pub fn agree() -> bool {
    let words = || {
        EDGES
            .iter()
            .flat_map(|&a| EDGES.iter().map(move |&b| I16x2::new(a, b)))
    };
    for x in words() {
        for y in words() {
            let (a, b) = (x.to_bits(), y.to_bits());
            let mut checks = [
                (
                    "sadd16",
                    x.wrapping_add(y).to_bits(),
                    portable::sadd16(a, b),
                ),
                (
                    "ssub16",
                    x.wrapping_sub(y).to_bits(),
                    portable::ssub16(a, b),
                ),
                (
                    "qadd16",
                    x.saturating_add(y).to_bits(),
                    portable::qadd16(a, b),
                ),
                (
                    "shadd16",
                    x.halving_add(y).to_bits(),
                    portable::shadd16(a, b),
                ),
                (
                    "to_bytes",
                    I16x2::to_bytes::<3>(x, y),
                    portable_to_bytes(x, y),
                ),
            ]
            .into_iter()
            .chain(FACTORS.iter().flat_map(|&c| {
                let pack = |lo, hi| portable::pkhbt(lo, hi);
                [
                    (
                        "mul_q16",
                        x.mul_q16(c).to_bits(),
                        pack(portable::smulwb(c, a), portable::smulwt(c, a)),
                    ),
                    (
                        "mul_q16_add",
                        x.mul_q16_add(c, y, c / 3).to_bits(),
                        pack(
                            portable::smlawb(c / 3, b, portable::smulwb(c, a)),
                            portable::smlawt(c / 3, b, portable::smulwt(c, a)),
                        ),
                    ),
                    (
                        "mul_q16_each_rounded",
                        x.mul_q16_each_rounded([c, c / 5]).to_bits(),
                        {
                            let d = portable::sadd16(a, a);
                            let t = pack(portable::smulwb(c, d), portable::smulwt(c / 5, d));
                            portable::shadd16(t, 0x0001_0001)
                        },
                    ),
                    (
                        "mul_q16_each",
                        x.mul_q16_each([c, c / 5]).to_bits(),
                        pack(portable::smulwb(c, a), portable::smulwt(c / 5, a)),
                    ),
                ]
            }));
            if let Some((name, got, want)) = checks.find(|(_, got, want)| got != want) {
                hprintln!(
                    "# lanes: {} of {:#010x}, {:#010x} gave {:#010x}, not {:#010x}",
                    name,
                    a,
                    b,
                    got,
                    want
                );
                return false;
            }
        }
    }
    true
}

/// `I16x2::to_bytes::<3>` from the definitions: each lane `((v + 4) >> 3)` clamped.
fn portable_to_bytes(even: I16x2, odd: I16x2) -> u32 {
    let byte = |v: i16| ((i32::from(v) + 4) >> 3).clamp(0, 255) as u32;
    byte(even.lo()) | byte(odd.lo()) << 8 | byte(even.hi()) << 16 | byte(odd.hi()) << 24
}
