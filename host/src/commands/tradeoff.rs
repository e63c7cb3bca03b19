//! `rollfuse tradeoff`: the accuracy/time study over the device configurations
//! (docs/tradeoff.md).

use super::bars::{Bars, Show};
use anyhow::ensure;
use rollfuse::tradeoff::bench::McuTable;
use rollfuse::tradeoff::{acquire, report, study, sweep};
use std::path::PathBuf;

/// Arguments of `rollfuse tradeoff`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Folder for tradeoff.md, tradeoff.csv and pareto.svg.
    #[arg(long, default_value = "out/tradeoff")]
    pub out: PathBuf,
    /// Scenes to fuse (default: the built-in letters scene, as the virtual device streams).
    #[arg(long)]
    pub scene: Vec<PathBuf>,
    /// The Cortex-M7 bench's CSV (written by `bash tests/mcu-bench/run.sh`); without it
    /// the study reports host time only.
    #[arg(long, default_value = DEFAULT_BENCH)]
    pub bench: PathBuf,
    /// Timed runs per configuration and scene; the fastest counts.
    #[arg(long, default_value_t = 3)]
    pub repeats: usize,
}

/// Where `tests/mcu-bench/run.sh` writes by default, relative to the repository's root
/// (where the docs' commands run).
pub const DEFAULT_BENCH: &str = "target/mcu-bench/mcu-bench.csv";

/// Runs the command, showing progress as `show` says.
pub fn run(args: Args, show: Show) -> anyhow::Result<()> {
    ensure!(
        (1..=100).contains(&args.repeats),
        "--repeats must be 1..=100, not {}",
        args.repeats
    );
    let scenes = super::eval::scenes_or(&args.scene, &["letters"])?;
    let mcu = if args.bench.exists() {
        McuTable::load(&args.bench)?
    } else {
        eprintln!(
            "note: no MCU bench results at {}: run `bash tests/mcu-bench/run.sh` for the \
             instruction counts; reporting host time only",
            args.bench.display()
        );
        McuTable::empty()
    };
    let _folder = rollfuse::files::NewFolder::create(&args.out)?;
    let mut acquisitions = Vec::new();
    for scene in &scenes {
        acquisitions.push(acquire(scene)?);
    }
    let setups = sweep();
    let rows = study(&acquisitions, &setups, args.repeats, &mcu, &Bars::new(show))?;
    let names: Vec<String> = acquisitions.iter().map(|a| a.name.clone()).collect();
    let md = report::markdown(&rows, &names, mcu.build.as_deref());
    let mut batch = rollfuse::files::Batch::new();
    batch.add_bytes(
        &args.out.join("tradeoff.csv"),
        report::csv(&rows).as_bytes(),
    )?;
    batch.add_bytes(
        &args.out.join("pareto.svg"),
        report::pareto_svg(&rows)?.as_bytes(),
    )?;
    batch.add_bytes(&args.out.join("tradeoff.md"), md.as_bytes())?;
    batch.commit()?;
    print!("{md}");
    println!(
        "\nwritten: {}/tradeoff.md, tradeoff.csv, pareto.svg",
        args.out.display()
    );
    Ok(())
}
