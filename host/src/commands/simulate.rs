//! `rollfuse simulate`: render a scene's frames, ground truth and manifest.

use anyhow::Context;
use rollfuse::sim::{Scene, Simulator, output};
use std::path::PathBuf;

/// Arguments of `rollfuse simulate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scene file (TOML), e.g. host/scenes/letters.toml.
    pub scene: PathBuf,
    /// Output folder: frame_0000.png …, truth/, manifest.json.
    #[arg(long)]
    pub out: PathBuf,
    /// Number of frames (overrides sensor.frames).
    #[arg(long)]
    pub frames: Option<usize>,
    /// Seed of noise and jitter (overrides the scene's).
    #[arg(long)]
    pub seed: Option<u64>,
}

/// Runs the command, showing progress as `show` says.
pub fn run(args: Args, show: super::bars::Show) -> anyhow::Result<()> {
    output::refuse_overwriting(&args.scene, "scene", &args.out)?;
    let mut scene = Scene::load(&args.scene)?;
    if let Some(n) = args.frames {
        scene.sensor.frames = n;
    }
    if let Some(s) = args.seed {
        scene.seed = s;
    }
    scene
        .validate()
        .context("with the command-line overrides")?;
    for w in scene.warnings() {
        eprintln!("warning: {w}");
    }
    let sim = Simulator::new(&scene)?;
    let manifest = output::write(&sim, &args.out, &super::bars::Bars::new(show))?;
    let effects: Vec<&str> = manifest.effects.iter().map(|e| e.name()).collect();
    println!(
        "{}: {} frames of {}×{} ({}) with [{}] → {}",
        manifest.scene,
        manifest.frames.len(),
        scene.sensor.width_px,
        scene.sensor.height_px,
        manifest.color,
        effects.join(", "),
        args.out.display()
    );
    Ok(())
}
