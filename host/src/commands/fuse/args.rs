//! The arguments of `rollfuse fuse`.

use crate::commands::named;
use rollfuse::fullres::Precision;
use rollfuse::fullres::register::TrackParams;
use rollfuse_core::{Ablation, LlWeighting, Wavelet};
use std::path::PathBuf;

/// `--align`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum AlignArg {
    /// Frames are already aligned: all at the same place.
    None,
    /// Each frame matched against the previous one (normalized cross-correlation).
    Template,
    /// Belt offsets from the acquisition's manifest.json (commanded motion).
    Motion,
}

/// `--mode`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ModeArg {
    /// A roll when the frames cannot all see one object (they span more than a frame
    /// height), otherwise a mosaic.
    Auto,
    /// Contact-window fusion of a roll into a strip, streamed.
    Roll,
    /// Every frame fused over its whole footprint into one image (a few frames of one
    /// object).
    Mosaic,
}

/// `--out-bits`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum OutBits {
    /// 8-bit PNG.
    #[value(name = "8")]
    Eight,
    /// 16-bit PNG (the 8-bit scale times 257).
    #[value(name = "16")]
    Sixteen,
}

impl OutBits {
    /// Bits a sample.
    pub fn bits(self) -> u8 {
        match self {
            OutBits::Eight => 8,
            OutBits::Sixteen => 16,
        }
    }
}

/// Arguments of `rollfuse fuse`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The frames, in acquisition order (PNG, 8- or 16-bit, gray or RGB), or a folder:
    /// its `frame_*.png` files (if none, its `.png` files) in name order.
    #[arg(required = true)]
    pub frames: Vec<PathBuf>,
    /// The fused image: PNG, or a mosaic as .npy (f32, the values unrounded). A roll
    /// longer than --segment-rows is written as numbered segments OUT_STEM.0000.png …
    /// listed with their belt rows in OUT_STEM.json.
    #[arg(long)]
    pub out: PathBuf,
    /// Roll or mosaic.
    #[arg(long, value_enum, default_value = "auto")]
    pub mode: ModeArg,
    /// Roll: rows of the contact window, centred on the middle row (default: from the
    /// manifest's roller geometry, else measured on the first frames).
    #[arg(long)]
    pub window_rows: Option<usize>,
    /// Roll: rows per fused band.
    #[arg(long, default_value_t = 32)]
    pub band_rows: usize,
    /// Roll: rows over which neighbouring bands are cross-faded (even, at most --band-rows).
    #[arg(long, default_value_t = 8)]
    pub blend_rows: usize,
    /// Roll: most rows per output segment.
    #[arg(long, default_value_t = rollfuse::strip_file::DEFAULT_SEGMENT_ROWS)]
    pub segment_rows: usize,
    /// Roll, --align template: rows searched either side of the predicted position
    /// (default: 3 plus 30 % of the predicted step).
    #[arg(long)]
    pub search_rows: Option<usize>,
    /// Roll, --align template: whole-row positions only (no sub-pixel refinement).
    #[arg(long)]
    pub no_subpixel: bool,
    /// Roll, --align template: columns the belt may drift sideways between matched frames
    /// (default 0: the belt moves along the frame only).
    #[arg(long, default_value_t = 0)]
    pub max_drift_cols: usize,
    /// Roll, --align template: exit 0 even when the placement cannot be trusted (the belt
    /// lost, frames that matched nothing); the strip is written and marked either way.
    #[arg(long)]
    pub accept_untrusted: bool,
    /// Bits per sample of the output PNG: 8, or 16 to keep the fused values' fractions.
    #[arg(long, value_enum, default_value = "8")]
    pub out_bits: OutBits,
    /// Wavelet.
    #[arg(long, value_parser = named::<Wavelet>(), default_value = "db2")]
    pub wavelet: Wavelet,
    /// Decomposition levels, 1..=4.
    #[arg(long, default_value_t = 1)]
    pub levels: u8,
    /// How frames are placed on the common canvas.
    #[arg(long, value_enum, default_value = "template")]
    pub align: AlignArg,
    /// With --align motion: the manifest (default: manifest.json beside the first frame).
    /// Given with --align template on a roll, its commanded rows predict each position.
    #[arg(long)]
    pub manifest: Option<PathBuf>,
    /// With --align template: the template band, as fractions of the frame height.
    #[arg(long, value_delimiter = ',', default_values_t = [1.0 / 3.0, 2.0 / 3.0])]
    pub template_rows: Vec<f64>,
    /// With --align template: the largest shift searched along the belt, pixels (a roll:
    /// before the motion is known; default half a frame).
    #[arg(long)]
    pub max_shift: Option<usize>,
    /// With --align template: the lowest correlation accepted, 0..1 (default 0.5).
    #[arg(long)]
    pub min_score: Option<f32>,
    /// Remove one part of the method (paper Table II).
    #[arg(long, value_parser = named::<Ablation>(), default_value = "none")]
    pub ablation: Ablation,
    /// f32 (host) or fixed (the MCU's integer path, on 8-bit data).
    #[arg(long, value_parser = named::<Precision>(), default_value = "f32")]
    pub precision: Precision,
    /// How the LL band weighs each frame.
    #[arg(long, value_parser = named::<LlWeighting>(), default_value = "paper")]
    pub ll_weighting: LlWeighting,
    /// Roll: where the roll is kept in the inspection records.
    #[command(flatten)]
    pub record: crate::commands::rolls::RecordTo,
    /// Roll, with --records: belt millimetres a frame pixel, for the records' positions
    /// (default: the manifest's, where there is one).
    #[arg(long, requires = "records")]
    pub mm_per_px: Option<f64>,
}

impl Args {
    /// The aligner's settings from the command line, for frames `height` rows high.
    pub fn track_params(&self, height: usize) -> TrackParams {
        let mut p = TrackParams::for_height(height);
        p.search_rows = self.search_rows;
        if let Some(m) = self.max_shift {
            p.first_search_rows = m;
        }
        if let Some(m) = self.min_score {
            p.min_score = m;
        }
        p.subpixel = !self.no_subpixel;
        p.max_drift_cols = self.max_drift_cols;
        p
    }
}
