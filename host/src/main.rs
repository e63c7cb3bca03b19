//! `rollfuse`: the command-line tool of the rollfuse tactile sensor module.

mod commands;

use clap::{Parser, Subcommand};
use commands::bars::{Mode, Show};
use commands::{
    demo, depth, detect, eval, fuse, metrics, rolls, simulate, splice, stream, tradeoff,
};
use std::process::ExitCode;
use std::time::Duration;

/// Cyclic wavelet fusion of tactile images from a rolling, curved elastomer sensor.
#[derive(Parser)]
#[command(name = "rollfuse", version, about)]
struct Cli {
    /// The largest image a command reads from the files it is given, or builds from them
    /// (a canvas of frames), pixels; larger ones are refused from their header before
    /// anything is decoded.
    #[arg(long, global = true, default_value_t = rollfuse::image::DEFAULT_MAX_PIXELS)]
    max_pixels: u64,
    /// How progress on long work is shown: a bar on a terminal and plain lines elsewhere
    /// (auto), or always one of them, or none.
    #[arg(long, global = true, value_enum, default_value_t = Mode::Auto)]
    progress: Mode,
    /// Plain progress lines: a stage prints none in its first SECONDS, then at most one
    /// every SECONDS, and a last one when it ends.
    #[arg(long, global = true, value_name = "SECONDS", default_value_t = 10)]
    progress_every: u64,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run the whole system on simulated data and write out/demo/report.html.
    Demo(demo::Args),
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
    /// Train the fabric defect detector on simulated rolls (see docs/detect.md).
    Train(detect::TrainArgs),
    /// Find fabric defects and classify the fabric in gray tactile images.
    Detect(detect::Args),
    /// Learn one fabric from defect-free images, for `detect --normal` (docs/detect.md).
    FitNormal(detect::FitNormalArgs),
    /// Stream fused tiles from the device (USB, virtual, or a recording) into a strip.
    Stream(stream::Args),
    /// List the rollfuse devices on USB.
    Devices,
    /// The inspection records: rolls of a line, one roll's record, its roll map
    /// (docs/records.md).
    Rolls(rolls::Args),
}

/// A command-line error as every other error is: one line on stderr (with clap's tip, if
/// it has one) and exit code 1. Help and version go to stdout with exit code 0.
fn parse() -> Result<Cli, ExitCode> {
    use clap::error::ErrorKind;
    let e = match Cli::try_parse() {
        Ok(cli) => return Ok(cli),
        Err(e) => e,
    };
    match e.kind() {
        ErrorKind::DisplayHelp | ErrorKind::DisplayVersion => e.exit(),
        ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => {
            let _ = e.print();
            return Err(ExitCode::FAILURE);
        }
        _ => {}
    }
    // clap's message runs until its usage; lines of it may list arguments, or give a tip.
    let text = e.render().to_string();
    let (mut said, mut tips) = (Vec::new(), Vec::new());
    for line in text.lines().map(str::trim).filter(|l| !l.is_empty()) {
        if line.starts_with("Usage:") || line.starts_with("For more information") {
            break;
        }
        match line.strip_prefix("tip: ") {
            Some(tip) => tips.push(tip),
            None => said.push(line),
        }
    }
    let tip = if tips.is_empty() {
        String::new()
    } else {
        format!(" ({})", tips.join("; "))
    };
    eprintln!("{}{tip}; see rollfuse --help", said.join(" "));
    Err(ExitCode::FAILURE)
}

/// The tests' full disk: outputs fail after as many bytes as
/// `ROLLFUSE_FAIL_WRITES_AFTER` says, when it is set.
fn full_disk_seam() {
    use rollfuse::files::{FAIL_WRITES_AFTER, fail_writes_after};
    if let Some(bytes) = std::env::var(FAIL_WRITES_AFTER)
        .ok()
        .and_then(|v| v.parse().ok())
    {
        fail_writes_after(bytes);
    }
}

fn main() -> ExitCode {
    let cli = match parse() {
        Ok(cli) => cli,
        Err(code) => return code,
    };
    let limit = rollfuse::image::PixelLimit(cli.max_pixels);
    full_disk_seam();
    let show = Show {
        mode: cli.progress,
        every: Duration::from_secs(cli.progress_every),
    };
    let result = match cli.command {
        Command::Demo(args) => demo::run(args, show),
        Command::Simulate(args) => simulate::run(args, show),
        Command::Fuse(args) => fuse::run(args, show, limit),
        Command::Splice(args) => splice::run(args, limit),
        Command::Metrics(args) => metrics::run(args, limit),
        Command::Eval(args) => eval::run(args, show),
        Command::Tradeoff(args) => tradeoff::run(args, show),
        Command::Depth(args) => depth::run(args, limit),
        Command::Calibrate(args) => depth::calibrate_run(args, limit),
        Command::Train(args) => detect::train_run(args, show, limit),
        Command::Detect(args) => detect::run(args, limit),
        Command::FitNormal(args) => detect::fit_normal_run(args, limit),
        Command::Stream(args) => stream::run(args, show),
        Command::Devices => stream::devices(),
        Command::Rolls(args) => rolls::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            match e.downcast_ref::<commands::Untrusted>() {
                Some(_) => ExitCode::from(commands::Untrusted::EXIT_CODE),
                None => ExitCode::FAILURE,
            }
        }
    }
}
