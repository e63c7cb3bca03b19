//! `rollfuse`: the command-line tool of the rollfuse tactile sensor module.

use clap::{Parser, Subcommand};
use rollfuse::commands::{depth, eval, fuse, metrics, simulate, splice, stream, tradeoff};
use std::process::ExitCode;

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
    /// Render a scene's frames, ground truth and manifest (see docs/simulator.md).
    Simulate(simulate::Args),
    /// Fuse frames at full resolution into one image (see docs/fusion.md).
    Fuse(fuse::Args),
    /// The time-splicing baseline: central strips by motion offsets, seams blended.
    Splice(splice::Args),
    /// IE, MS-SSIM and their regional std (eqs. 8–9) of an image.
    Metrics(metrics::Args),
    /// Tables II and III (ablations; single, fused, spliced) on simulated samples.
    Eval(eval::Args),
    /// Accuracy against time over the device configurations (see docs/tradeoff.md).
    Tradeoff(tradeoff::Args),
    /// Height map (mm) of an RGB tactile image by photometric stereo (see docs/depth.md).
    Depth(depth::Args),
    /// Fit the light file from an image of a ball of known radius.
    Calibrate(depth::CalibrateArgs),
    /// Stream fused tiles from the device (USB, virtual, or a recording) into a strip.
    Stream(stream::Args),
    /// List the rollfuse devices on USB.
    Devices,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Demo => {
            println!("{DEMO_PLAN}");
            Ok(())
        }
        Command::Simulate(args) => simulate::run(args),
        Command::Fuse(args) => fuse::run(args),
        Command::Splice(args) => splice::run(args),
        Command::Metrics(args) => metrics::run(args),
        Command::Eval(args) => eval::run(args),
        Command::Tradeoff(args) => tradeoff::run(args),
        Command::Depth(args) => depth::run(args),
        Command::Calibrate(args) => depth::calibrate_run(args),
        Command::Stream(args) => stream::run(args),
        Command::Devices => stream::devices(),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
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
What exists today: the fusion core, the simulator, full-resolution fusion and metrics:
  cargo run --release -- simulate host/scenes/letters.toml --out out/letters
  cargo run --release -- fuse out/letters/frame_*.png --out out/letters_fused.png
  cargo run --release -- metrics out/letters_fused.png";
