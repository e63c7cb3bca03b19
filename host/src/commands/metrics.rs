//! `rollfuse metrics`: IE, MS-SSIM against a reference, and their regional spread.

use crate::eval::metrics::StripAxis;
pub use crate::eval::report::{Report, measure};
use crate::image::Planes;
use std::path::PathBuf;

/// Arguments of `rollfuse metrics`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The image to measure.
    pub image: PathBuf,
    /// Reference for MS-SSIM (e.g. a simulation's truth/ideal.png), same size.
    #[arg(long)]
    pub reference: Option<PathBuf>,
    /// Number of equal strips for the regional std (eqs. 8–9).
    #[arg(long, default_value_t = 10)]
    pub strips: usize,
    /// Cut the strips as bands of rows (along the belt, default) or of columns.
    #[arg(long, value_enum, default_value = "rows")]
    pub axis: StripAxis,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    let image = Planes::load(&args.image)?;
    let reference = args.reference.as_deref().map(Planes::load).transpose()?;
    let report = measure(&image, reference.as_ref(), args.strips, args.axis)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!("IE       {:.4}", report.ie);
    println!("IE_std   {:.4}   ({} strips)", report.ie_std, args.strips);
    if let (Some(m), Some(s)) = (report.ms_ssim, report.ms_ssim_std) {
        println!("MS-SSIM  {m:.4}");
        println!("MS-SSIM_std {s:.4}");
    }
    Ok(())
}
