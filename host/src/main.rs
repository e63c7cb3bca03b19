//! `rollfuse`: the command-line tool of the rollfuse tactile sensor module.

use clap::{Parser, Subcommand};

/// Cyclic wavelet fusion of tactile images from a rolling, curved elastomer sensor.
#[derive(Parser)]
#[command(name = "rollfuse", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run the whole system on simulated data and write a report (coming: see README).
    Demo,
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Demo => {
            println!("{}", DEMO_PLAN);
            Ok(())
        }
    }
}

const DEMO_PLAN: &str = "\
rollfuse demo is not built yet. When it is, it will:
  1. simulate a rolling acquisition of the letters scene,
  2. stream it through the virtual device and stitch the fused strip,
  3. fuse the raw frames at full resolution on the host,
  4. reconstruct depth from the three-sphere RGB scene,
  5. write out/demo/report.html with images, metric tables and timings.
What exists today: the rollfuse-core fusion library (run `cargo test` to check it).";
