//! `rollfuse`: the command-line tool of the rollfuse tactile sensor module.

use anyhow::Context;
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use rollfuse::sim::{Scene, Simulator, output};
use std::path::PathBuf;
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
    Simulate {
        /// The scene file (TOML), e.g. host/scenes/letters.toml.
        scene: PathBuf,
        /// Output folder: frame_0000.png …, truth/, manifest.json.
        #[arg(long)]
        out: PathBuf,
        /// Number of frames (overrides sensor.frames).
        #[arg(long)]
        frames: Option<usize>,
        /// Seed of noise and jitter (overrides the scene's).
        #[arg(long)]
        seed: Option<u64>,
    },
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Demo => {
            println!("{DEMO_PLAN}");
            Ok(())
        }
        Command::Simulate {
            scene,
            out,
            frames,
            seed,
        } => simulate(scene, out, frames, seed),
    }
}

fn simulate(
    path: PathBuf,
    out: PathBuf,
    frames: Option<usize>,
    seed: Option<u64>,
) -> anyhow::Result<()> {
    let mut scene = Scene::load(&path)?;
    if let Some(n) = frames {
        scene.sensor.frames = n;
    }
    if let Some(s) = seed {
        scene.seed = s;
    }
    scene
        .validate()
        .context("with the command-line overrides")?;
    let sim = Simulator::new(&scene)?;
    let bar = ProgressBar::new(sim.frames() as u64).with_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} frames ({per_sec}, {eta} left)")
            .expect("valid template")
            .progress_chars("=> "),
    );
    bar.set_message(format!("simulating {}", scene.name));
    let manifest = output::write(&sim, &out, |done, _| bar.set_position(done as u64))?;
    bar.finish_and_clear();
    println!(
        "{}: {} frames of {}×{} ({}) with [{}] → {}",
        manifest.scene,
        manifest.frames.len(),
        manifest.image_size[0],
        manifest.image_size[1],
        manifest.color,
        manifest.effects.join(", "),
        out.display()
    );
    Ok(())
}

const DEMO_PLAN: &str = "\
rollfuse demo is not built yet. When it is, it will:
  1. simulate a rolling acquisition of the letters scene,
  2. stream it through the virtual device and stitch the fused strip,
  3. fuse the raw frames at full resolution on the host,
  4. reconstruct depth from the three-sphere RGB scene,
  5. write out/demo/report.html with images, metric tables and timings.
What exists today: the fusion core (`cargo test`) and the simulator:
  cargo run --release -- simulate host/scenes/letters.toml --out out/letters";
