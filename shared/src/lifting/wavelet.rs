//! Which wavelet a transform uses.

/// The wavelet of a transform.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Wavelet {
    /// Haar, as the integer S-transform (low band = floor of the pair mean).
    Haar,
    /// Daubechies-4 (two vanishing moments), by the Daubechies–Sweldens lifting steps.
    Db2,
}
