//! Integer Haar as the S-transform: `d = o − e`, `s = e + ⌊d/2⌋ = ⌊(e + o)/2⌋`.
//!
//! `low` holds the even samples and `high` the odd ones on entry to the forward step (and
//! the low and high bands on exit). For an odd length, `low` has one more element than
//! `high`; the unpaired last sample passes to the low band unchanged.

/// Forward S-transform of the split channels, in place.
pub(crate) fn forward(low: &mut [i32], high: &mut [i32]) {
    for (s, d) in low.iter_mut().zip(high.iter_mut()) {
        *d -= *s;
        *s += *d >> 1;
    }
}

/// Inverse S-transform, exactly undoing [`forward`].
pub(crate) fn inverse(low: &mut [i32], high: &mut [i32]) {
    for (s, d) in low.iter_mut().zip(high.iter_mut()) {
        *s -= *d >> 1;
        *d += *s;
    }
}
