//! `rollfuse demo`: the whole system on simulated data, and `report.html`.

use rollfuse::demo::{self, Files, Options};
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `rollfuse demo`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output folder: report.html and every image and table it shows.
    #[arg(long, default_value = "out/demo")]
    pub out: PathBuf,
    /// The gray scene rolled under the sensor (default: the built-in letters scene).
    #[arg(long)]
    pub letters: Option<PathBuf>,
    /// The RGB three-sphere scene for depth (default: the built-in one).
    #[arg(long)]
    pub spheres: Option<PathBuf>,
    /// Cortex-M7 bench results for the trade-off plot (`bash tests/mcu-bench/run.sh`
    /// writes them to the default path, relative to the folder the command runs in);
    /// without them the plot shows host time only.
    #[arg(long, default_value = super::tradeoff::DEFAULT_BENCH)]
    pub bench: PathBuf,
}

/// Runs the command, showing progress as `show` says.
pub fn run(args: Args, show: super::bars::Show) -> anyhow::Result<()> {
    let mut inputs = vec![("bench CSV", args.bench.as_path())];
    inputs.extend(args.letters.as_deref().map(|p| ("letters scene", p)));
    inputs.extend(args.spheres.as_deref().map(|p| ("spheres scene", p)));
    rollfuse::files::refuse_inside(&args.out, &inputs)?;
    if !args.bench.exists() {
        eprintln!(
            "note: no MCU bench results at {}: the trade-off shows host time only \
             (`bash tests/mcu-bench/run.sh` measures the instruction counts)",
            args.bench.display()
        );
    }
    let started = Instant::now();
    let bars = super::bars::Bars::new(show);
    // The report's folder is replaced whole: a failed run leaves the last report as it was.
    let result = rollfuse::files::replace_folder(&args.out, |staging| {
        let opts = Options {
            out: staging.to_path_buf(),
            letters: args.letters.clone(),
            spheres: args.spheres.clone(),
            bench: Some(args.bench.clone()),
        };
        demo::run(&opts, &bars)
    });
    let d = result?;
    for s in &d.stages {
        println!("{:>16}  {:>6.2} s  {}", s.name, s.secs, s.what);
    }
    if let Some(single) = d.eval.iter().find(|r| r.method == "single image")
        && let Some(fused) = d.eval.iter().find(|r| r.method == "fusion of 4")
    {
        println!(
            "fusion of 4 vs the single frame: IE {:.3} → {:.3} ({:+.1} %), IE_std {:.3} → {:.3} ({:+.1} %)",
            single.report.ie,
            fused.report.ie,
            100.0 * (fused.report.ie - single.report.ie) / single.report.ie,
            single.report.ie_std,
            fused.report.ie_std,
            100.0 * (fused.report.ie_std - single.report.ie_std) / single.report.ie_std,
        );
    }
    if let Some(rec) = rollfuse::tradeoff::report::recommended(&d.tradeoff) {
        println!(
            "recommended device configuration: {} ({:.2} dB)",
            rec.setup.label(),
            rec.accuracy.psnr_db
        );
    }
    println!(
        "done in {:.1} s → {}",
        started.elapsed().as_secs_f64(),
        args.out.join(Files::REPORT).display()
    );
    Ok(())
}
