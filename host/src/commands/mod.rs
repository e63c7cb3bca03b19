//! The `rollfuse` subcommands: argument parsing (clap) and what each one does.

pub mod bars;
pub mod demo;
pub mod depth;
pub mod detect;
pub mod eval;
pub mod fuse;
pub mod metrics;
pub mod side_files;
pub mod simulate;
pub mod splice;
pub mod stream;
pub mod tradeoff;

use clap::ValueEnum;
use rollfuse_core::{Ablation, LlWeighting, Wavelet};

/// A command wrote its output, but the output rests on evidence it cannot trust (a
/// roll's placement with the belt lost, say): the process exits with
/// [`Untrusted::EXIT_CODE`], not 0, unless the user accepted that.
#[derive(Debug)]
pub struct Untrusted(pub String);

impl Untrusted {
    /// The exit code of an untrusted output (1 is any other failure).
    pub const EXIT_CODE: u8 = 3;
}

impl std::fmt::Display for Untrusted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Untrusted {}

/// `--wavelet`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum WaveletArg {
    /// Haar.
    Haar,
    /// Daubechies-4.
    Db2,
}

impl From<rollfuse_core::protocol::WaveletId> for WaveletArg {
    fn from(w: rollfuse_core::protocol::WaveletId) -> Self {
        match w {
            rollfuse_core::protocol::WaveletId::Haar => WaveletArg::Haar,
            rollfuse_core::protocol::WaveletId::Db2 => WaveletArg::Db2,
        }
    }
}

impl From<WaveletArg> for Wavelet {
    fn from(w: WaveletArg) -> Self {
        match w {
            WaveletArg::Haar => Wavelet::Haar,
            WaveletArg::Db2 => Wavelet::Db2,
        }
    }
}

/// `--ablation` (paper Table II).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum AblationArg {
    /// The full method.
    None,
    /// Pixel average instead of the wavelet transform.
    NoWavelet,
    /// Keep one image's LL band instead of the mean.
    SingleLl,
    /// Max-|coefficient| instead of saliency weights.
    MaxHigh,
}

impl From<AblationArg> for Ablation {
    fn from(a: AblationArg) -> Self {
        match a {
            AblationArg::None => Ablation::None,
            AblationArg::NoWavelet => Ablation::NoWavelet,
            AblationArg::SingleLl => Ablation::SingleLl,
            AblationArg::MaxHigh => Ablation::MaxHigh,
        }
    }
}

/// `--ll-weighting`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum LlWeightingArg {
    /// The paper's pairwise mean: the newest frame weighs ½.
    Paper,
    /// Every frame weighs 1/n: independent of order.
    Equal,
}

impl From<LlWeightingArg> for LlWeighting {
    fn from(l: LlWeightingArg) -> Self {
        match l {
            LlWeightingArg::Paper => LlWeighting::Paper,
            LlWeightingArg::Equal => LlWeighting::Equal,
        }
    }
}

pub use crate::files::check_writable;
