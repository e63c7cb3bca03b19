//! db2's lifting constants for the 16-bit lanes: Q16, the operand of `SMULWB`/`SMLAWB`.

/// The db2 constants in Q16, the 32-bit operand of `SMULWB`/`SMLAWB`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Constants {
    /// √3.
    pub(crate) sqrt3: i32,
    /// √3/4.
    pub(crate) a: i32,
    /// (√3 − 2)/4 (negative).
    pub(crate) b: i32,
}

/// [`Constants`]' values: `round(c · 2¹⁶)`.
pub(crate) const CONSTANTS: Constants = Constants {
    sqrt3: 113_512,
    a: 28_378,
    b: -4_390,
};
