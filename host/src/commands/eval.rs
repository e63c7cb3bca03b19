//! `rollfuse eval`: Tables II and III on the simulated standardized samples.

use super::bars::{Bars, Show};
use rollfuse::eval::depth;
use rollfuse::eval::tables::{csv, evaluate_scene, markdown};
use rollfuse::files::Batch;
use rollfuse::progress::Progress;
use rollfuse::sim::{Scene, built_in};

use rollfuse_core::FuseConfig;
use std::path::PathBuf;

/// Arguments of `rollfuse eval`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Folder for eval.md and eval.csv.
    #[arg(long, default_value = "out/eval")]
    pub out: PathBuf,
    /// Scenes to evaluate (default: the built-in dot, line and curve matrices; with
    /// --depth, the three-sphere scene).
    #[arg(long)]
    pub scene: Vec<PathBuf>,
    /// Table IV instead: depth from single and fused frames of the three-sphere scene.
    #[arg(long)]
    pub depth: bool,
    /// The whole-roll table instead: each scene rolled with a varying belt speed, four
    /// ways to a strip against the ideal contact (default scenes: letters and the three
    /// matrices).
    #[arg(long, conflicts_with = "depth")]
    pub roll: bool,
    /// The defect-detection table instead: the detector on every frame and on the fused
    /// tiles of held-out textile rolls (seeds training never uses).
    #[arg(long, conflicts_with_all = ["depth", "roll"])]
    pub detect: bool,
    /// With --detect: a model file (else the built-in model).
    #[arg(long, requires = "detect")]
    pub model: Option<PathBuf>,
    /// With --detect: anomaly mode instead of the detector, each held-out roll (180
    /// frames) fitted on 20 of its own defect-free frames and scored on the others.
    #[arg(long, requires = "detect", conflicts_with = "model")]
    pub normal: bool,
    /// With --detect: how the held-out rolls are drawn — `standard` (the simulator's own
    /// look, which the built-in model was trained on), `oblique` (one low LED, softer gel:
    /// a look it never saw) or `varied`.
    #[arg(
        long,
        default_value = "standard",
        requires = "detect",
        conflicts_with = "normal"
    )]
    pub style: rollfuse::detect::data::Style,
    /// With --detect: the heatmap score a detection needs, 0..1, as `detect --threshold`
    /// [default: the model's own].
    #[arg(long, requires = "detect", conflicts_with = "normal")]
    pub threshold: Option<f32>,
    /// With --detect: held-out rolls to simulate (fabric = seed mod 17).
    #[arg(long, default_value_t = 34, requires = "detect")]
    pub rolls: usize,
}

/// The built-in standardized samples.
pub const SAMPLES: [&str; 3] = ["dots", "lines", "curves"];

/// The scene files at `paths`, loaded, or without any the built-in scenes `names`.
pub fn scenes_or(paths: &[PathBuf], names: &[&str]) -> anyhow::Result<Vec<Scene>> {
    if paths.is_empty() {
        Ok(names
            .iter()
            .map(|n| built_in::scene(n))
            .collect::<Result<_, _>>()?)
    } else {
        Ok(paths
            .iter()
            .map(|p| Scene::load(p))
            .collect::<Result<_, _>>()?)
    }
}

/// Runs `rollfuse eval --depth`.
fn run_depth(args: &Args) -> anyhow::Result<()> {
    anyhow::ensure!(args.scene.len() <= 1, "--depth takes one scene");
    let scene = built_in::scene_or(args.scene.first().map(PathBuf::as_path), "spheres")?;
    let _folder = rollfuse::files::NewFolder::create(&args.out)?;
    let rows = depth::evaluate_depth(&scene)?;
    let mut batch = Batch::new();
    for (r, name) in rows.iter().zip(["single", "fused3", "fused2"]) {
        let path = args.out.join(format!("depth_{name}.png"));
        rollfuse::depth::output::write_png(&r.depth, &mut batch, &path)?;
    }
    let md = depth::markdown(&rows);
    batch.add_bytes(&args.out.join("depth.csv"), depth::csv(&rows).as_bytes())?;
    batch.add_bytes(&args.out.join("depth.md"), md.as_bytes())?;
    batch.commit()?;
    print!("{md}");
    println!(
        "\nwritten: {}/depth.md, depth.csv, depth_{{single,fused3,fused2}}.png",
        args.out.display()
    );
    Ok(())
}

/// Runs `rollfuse eval --roll`.
fn run_roll(args: &Args, show: Show) -> anyhow::Result<()> {
    let [dots, lines, curves] = SAMPLES;
    let loaded = scenes_or(&args.scene, &["letters", dots, lines, curves])?;
    let bars = Bars::new(show);
    bars.start("rolling", Some(loaded.len() as u64), "scenes");
    let mut rows = Vec::new();
    for (k, scene) in loaded.iter().enumerate() {
        rows.extend(rollfuse::eval::roll::evaluate_roll(scene, 10)?);
        bars.advance_to(k as u64 + 1);
    }
    bars.finish();
    let _folder = rollfuse::files::NewFolder::create(&args.out)?;
    let md = rollfuse::eval::roll::markdown(&rows);
    let mut batch = Batch::new();
    batch.add_bytes(&args.out.join("roll.csv"), csv(&rows).as_bytes())?;
    batch.add_bytes(&args.out.join("roll.md"), md.as_bytes())?;
    batch.commit()?;
    print!("{md}");
    println!("\nwritten: {}/roll.md, roll.csv", args.out.display());
    Ok(())
}

/// Runs `rollfuse eval --detect --normal`.
fn run_anomaly(args: &Args, show: Show) -> anyhow::Result<()> {
    use rollfuse::eval::anomaly::{evaluate_anomaly, markdown};
    let rows = evaluate_anomaly(args.rolls, &Bars::new(show))?;
    let _folder = rollfuse::files::NewFolder::create(&args.out)?;
    let md = format!(
        "Anomaly mode on held-out rolls: {}\n\n{}",
        held_out(args.rolls),
        markdown(&rows)
    );
    write_table(&args.out, "anomaly", &rows, &md)
}

/// `rolls` held-out rolls and their seeds, as the tables' headers say them.
fn held_out(rolls: usize) -> String {
    let first = rollfuse::eval::detect::EVAL_SEEDS;
    format!("{rolls} (seeds {first}..{})", first + rolls as u64)
}

/// Writes `NAME.md` and `NAME.json` (the rows) into `out` whole, and prints the table.
fn write_table(
    out: &std::path::Path,
    name: &str,
    rows: &impl serde::Serialize,
    md: &str,
) -> anyhow::Result<()> {
    let mut batch = Batch::new();
    batch.add_bytes(
        &out.join(format!("{name}.json")),
        serde_json::to_string_pretty(rows)?.as_bytes(),
    )?;
    batch.add_bytes(&out.join(format!("{name}.md")), md.as_bytes())?;
    batch.commit()?;
    print!("{md}");
    println!("\nwritten: {}/{name}.md, {name}.json", out.display());
    Ok(())
}

/// Runs `rollfuse eval --detect`.
fn run_detect(args: &Args, show: Show) -> anyhow::Result<()> {
    use rollfuse::eval::detect::{evaluate_detect, markdown};
    if args.normal {
        return run_anomaly(args, show);
    }
    args.threshold
        .map(rollfuse::detect::check_threshold)
        .transpose()?;
    let mut detector = rollfuse::detect::Detector::load_or_built_in(args.model.as_deref())?;
    detector.threshold = args.threshold.unwrap_or(detector.threshold);
    let shape = rollfuse::detect::data::RollShape::STANDARD;
    let rows = evaluate_detect(&detector, args.rolls, &shape, args.style, &Bars::new(show))?;
    let _folder = rollfuse::files::NewFolder::create(&args.out)?;
    let md = format!(
        "Held-out rolls: {}, drawn in the {} style, model: {}, threshold {}\n\n{}",
        held_out(args.rolls),
        args.style.name(),
        args.model
            .as_ref()
            .map_or("built in".to_string(), |m| m.display().to_string()),
        detector.threshold,
        markdown(&rows)
    );
    write_table(&args.out, "detect", &rows, &md)
}

/// Runs the command, showing progress as `show` says.
pub fn run(args: Args, show: Show) -> anyhow::Result<()> {
    if args.detect {
        return run_detect(&args, show);
    }
    if args.depth {
        return run_depth(&args);
    }
    if args.roll {
        return run_roll(&args, show);
    }
    let scenes = scenes_or(&args.scene, &SAMPLES)?;
    let _folder = rollfuse::files::NewFolder::create(&args.out)?;
    let bars = Bars::new(show);
    bars.start("evaluating", Some(scenes.len() as u64), "scenes");
    let mut rows = Vec::new();
    for (k, scene) in scenes.iter().enumerate() {
        rows.extend(evaluate_scene(scene, &FuseConfig::default(), 10)?);
        bars.advance_to(k as u64 + 1);
    }
    bars.finish();
    let md = markdown(&rows);
    let mut batch = Batch::new();
    batch.add_bytes(&args.out.join("eval.csv"), csv(&rows).as_bytes())?;
    batch.add_bytes(&args.out.join("eval.md"), md.as_bytes())?;
    batch.commit()?;
    print!("{md}");
    println!("\nwritten: {}/eval.md, eval.csv", args.out.display());
    Ok(())
}
