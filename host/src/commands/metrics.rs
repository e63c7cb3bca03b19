//! `rollfuse metrics`: IE, MS-SSIM against a reference, and their regional spread.

use anyhow::ensure;
use rollfuse::eval::metrics::StripAxis;
use rollfuse::eval::report::measure;
use rollfuse::image::{PixelLimit, Planes};
use std::path::PathBuf;

/// Arguments of `rollfuse metrics`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The image to measure.
    pub image: PathBuf,
    /// Reference for MS-SSIM (e.g. a simulation's truth/ideal.png): the same size as the
    /// image, or as wide and taller (then cut to the image's rows: `--reference-rows`, or
    /// where the strip index beside a strip says it lies).
    #[arg(long)]
    pub reference: Option<PathBuf>,
    /// The reference row of the image's first row: the image is compared with the
    /// reference's rows from there (default: the belt row the strip's index `STEM.json`
    /// gives it, for a strip `fuse` wrote; none for an image of the reference's size).
    #[arg(long, value_name = "ROW", requires = "reference")]
    pub reference_rows: Option<usize>,
    /// Number of equal strips for the regional std (eqs. 8–9).
    #[arg(long, default_value_t = 10)]
    pub strips: usize,
    /// Cut the strips as bands of rows (along the belt, default) or of columns.
    #[arg(long, value_parser = crate::commands::named::<StripAxis>(), default_value = "rows")]
    pub axis: StripAxis,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// Runs the command.
pub fn run(args: Args, limit: PixelLimit) -> anyhow::Result<()> {
    let image = Planes::load(&args.image, limit)?;
    let reference = match args.reference.as_deref() {
        Some(path) => Some(cut_to_image(Planes::load(path, limit)?, &image, &args)?),
        None => None,
    };
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

/// The reference's rows the image covers: from `--reference-rows`, else from the strip's
/// index when the sizes differ (said on stderr), else the whole reference.
fn cut_to_image(reference: Planes, image: &Planes, args: &Args) -> anyhow::Result<Planes> {
    let same_size = (reference.width, reference.height) == (image.width, image.height);
    let first = match args.reference_rows {
        Some(row) => row,
        None if same_size => return Ok(reference),
        None => match rollfuse::strip_file::first_row_of(&args.image) {
            Some((index, row)) => {
                let row = usize::try_from(row).map_err(|_| {
                    anyhow::anyhow!(
                        "{} places {} at belt row {row}, before the reference's first row",
                        index.display(),
                        args.image.display()
                    )
                })?;
                eprintln!(
                    "reference rows {row}..{} (where {} places the strip)",
                    row + image.height,
                    index.display()
                );
                row
            }
            // `measure` says the sizes differ.
            None => return Ok(reference),
        },
    };
    let end = first.saturating_add(image.height);
    ensure!(
        reference.width == image.width && end <= reference.height,
        "the reference ({}×{}) has no rows {first}..{end} of the image's width {}",
        reference.width,
        reference.height,
        image.width
    );
    Ok(reference.crop(first, 0, image.height, image.width)?)
}
