//! The `rollfuse` subcommands: argument parsing (clap) and what each one does.

pub mod demo;
pub mod depth;
pub mod detect;
pub mod eval;
pub mod fuse;
pub mod fuse_roll;
pub mod metrics;
pub mod simulate;
pub mod splice;
pub mod stream;
pub mod tradeoff;

use clap::ValueEnum;
use rollfuse_core::{Ablation, LlWeighting, Wavelet};

/// `--wavelet`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum WaveletArg {
    /// Haar.
    Haar,
    /// Daubechies-4.
    Db2,
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

/// Fails early, with the path in the message, if `path` cannot be written, before any
/// long work starts. Leaves an existing file as it is and creates nothing.
pub fn check_writable(path: &std::path::Path) -> anyhow::Result<()> {
    let parent = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(std::path::Path::new("."));
    anyhow::ensure!(
        parent.is_dir(),
        "cannot write {}: folder {} does not exist",
        path.display(),
        parent.display()
    );
    let probe = if path.exists() {
        std::fs::OpenOptions::new()
            .append(true)
            .open(path)
            .map(|_| ())
    } else {
        let tmp = parent.join(format!(".rollfuse-write-check-{}", std::process::id()));
        std::fs::File::create(&tmp).and_then(|_| std::fs::remove_file(&tmp))
    };
    probe.map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))
}
