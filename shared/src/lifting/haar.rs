//! Haar as the S-transform: `d = o − e`, `s = e + ⌊d/2⌋ = ⌊(e + o)/2⌋` (in `f32`, without
//! the floor: `s = (e + o)/2`).
//!
//! `low` holds the even samples and `high` the odd ones on entry to the forward step (and
//! the low and high bands on exit). For an odd length, `low` has one more element than
//! `high`; the unpaired last sample passes to the low band unchanged.

use super::Lift;

/// Forward S-transform of the split channels, in place. Rows of any width lifted side by
/// side pair up element by element, so the flattened channels are all it needs.
pub(crate) fn forward<T: Lift>(low: &mut [T], high: &mut [T]) {
    for (s, d) in low.iter_mut().zip(high.iter_mut()) {
        *d -= *s;
        *s += d.half();
    }
}

/// Inverse S-transform, exactly undoing [`forward`].
pub(crate) fn inverse<T: Lift>(low: &mut [T], high: &mut [T]) {
    for (s, d) in low.iter_mut().zip(high.iter_mut()) {
        *s -= d.half();
        *d += *s;
    }
}
