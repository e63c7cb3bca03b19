//! One configuration of the trade-off sweep, and the whole sweep.

use crate::names::Named;
use rollfuse_core::device::Precision;
use rollfuse_core::protocol::{DeviceConfig, NormMode, WaveletId};

/// One configuration of the sweep.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Setup {
    /// The wavelet.
    pub wavelet: WaveletId,
    /// Decomposition levels.
    pub levels: u8,
    /// Box downsampling factor.
    pub downsample: u8,
    /// The fuse step's arithmetic.
    pub precision: Precision,
    /// Saliency normalized per frame (else per tile).
    pub per_frame: bool,
}

impl Setup {
    /// The product's default: db2, 1 level, the camera's full resolution, integer, per
    /// frame.
    pub const DEFAULT: Self = Self {
        wavelet: WaveletId::Db2,
        levels: 1,
        downsample: 1,
        precision: Precision::Fixed,
        per_frame: true,
    };

    /// The device configuration, on top of `base` (tile rows, frames per tile, spacing).
    pub fn wire(&self, base: &DeviceConfig) -> DeviceConfig {
        DeviceConfig {
            wavelet: self.wavelet,
            levels: self.levels,
            downsample: self.downsample,
            norm: if self.per_frame {
                NormMode::PerFrame
            } else {
                NormMode::PerTile
            },
            ..*base
        }
    }

    /// "haar", "db2".
    pub fn wavelet_name(&self) -> &'static str {
        self.wavelet.name()
    }

    /// "fixed", "f32".
    pub fn precision_name(&self) -> &'static str {
        self.precision.name()
    }

    /// "frame", "tile".
    pub fn norm_name(&self) -> &'static str {
        if self.per_frame { "frame" } else { "tile" }
    }

    /// E.g. "db2 L2 2× fixed /frame".
    pub fn label(&self) -> String {
        format!(
            "{} L{} {}× {} /{}",
            self.wavelet_name(),
            self.levels,
            self.downsample,
            self.precision_name(),
            self.norm_name()
        )
    }
}

/// The whole sweep: 2 wavelets × 3 level counts × 3 downsampling factors × 2 precisions ×
/// 2 normalizations, in the bench's order.
pub fn sweep() -> Vec<Setup> {
    let mut all = Vec::new();
    for wavelet in [WaveletId::Haar, WaveletId::Db2] {
        for levels in 1..=3 {
            for downsample in [1, 2, 4] {
                for per_frame in [false, true] {
                    for precision in [Precision::Fixed, Precision::F32] {
                        all.push(Setup {
                            wavelet,
                            levels,
                            downsample,
                            precision,
                            per_frame,
                        });
                    }
                }
            }
        }
    }
    all
}
