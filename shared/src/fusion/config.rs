//! What a fuse step is asked to do: its wavelet, depth, ablation and LL weighting.

use crate::Wavelet;
use crate::saliency::SaliencyNorm;

/// The ablations of the paper's Table II: each removes one part of the method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Ablation {
    /// The full method.
    #[default]
    None,
    /// No wavelet transform: the pixels themselves are averaged (with the LL weighting).
    NoWavelet,
    /// The LL band is not fused: the fused image keeps the first input's (in cyclic use,
    /// the running result's, so the first frame's low frequencies).
    SingleLl,
    /// High bands by max-|coefficient| selection instead of saliency weights.
    MaxHigh,
}

/// How the LL band of a new frame is weighted against the running result.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LlWeighting {
    /// The paper's pairwise mean: the newest frame weighs ½, the first `1/2ⁿ⁻¹`.
    #[default]
    Paper,
    /// Frame `n` weighs `1/n` against the running result, so every frame weighs `1/n` in
    /// the end and the LL band does not depend on the order (up to rounding: the weight
    /// is Q15 and the integer path rounds its running result to 8 bits every cycle).
    Equal,
}

/// Everything that defines a fuse step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FuseConfig {
    /// The wavelet.
    pub wavelet: Wavelet,
    /// Decomposition levels, 1..=4.
    pub levels: u8,
    /// Which part of the method to remove, if any.
    pub ablation: Ablation,
    /// How the Laplacian is normalized.
    pub norm: SaliencyNorm,
    /// How the LL band weighs each frame in cyclic use.
    pub ll_weighting: LlWeighting,
}

impl Ablation {
    /// Whether the high bands take saliency weights (not so without the wavelet, or
    /// with max-|coefficient| selection).
    pub(crate) fn uses_saliency(self) -> bool {
        !matches!(self, Ablation::NoWavelet | Ablation::MaxHigh)
    }
}

impl Default for FuseConfig {
    /// db2, one level (the paper's setting), full method, per-image normalization.
    fn default() -> Self {
        Self {
            wavelet: Wavelet::Db2,
            levels: 1,
            ablation: Ablation::None,
            norm: SaliencyNorm::Local,
            ll_weighting: LlWeighting::Paper,
        }
    }
}

/// Weight of the second input's LL band, Q15 (`32768` = 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LlWeight(pub(crate) u16);

impl LlWeight {
    /// The paper's mean: ½.
    pub const HALF: Self = Self(1 << 14);

    /// The weight of frame number `n` (1-based) under `weighting`.
    pub fn for_frame(weighting: LlWeighting, n: u32) -> Self {
        match weighting {
            LlWeighting::Paper => Self::HALF,
            LlWeighting::Equal => Self(((1u32 << 15) / n.max(1)) as u16),
        }
    }

    /// As a fraction in 0..=1.
    pub fn as_f32(self) -> f32 {
        f32::from(self.0) / 32768.0
    }
}
