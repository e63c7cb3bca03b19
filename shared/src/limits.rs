//! The largest sizes the core accepts.

/// The largest width or height the core accepts. It keeps every index and every
/// `width × height` product far inside `u32`, which the bounds proofs rely on.
pub const MAX_DIMENSION: usize = 1 << 14;

/// The deepest decomposition the core offers.
pub const MAX_LEVELS: u8 = 4;
