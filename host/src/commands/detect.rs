//! `rollfuse train` and `rollfuse detect`: the fabric defect detector's model, and the
//! detector run on images (frames, fused images, strips).

use super::bars::{Bars, Show};
use crate::detect::anomaly::NormalModel;
use crate::detect::draw::{draw, outline};
use crate::detect::train::{TrainOptions, train};
use crate::detect::{Detection, Detector, UNKNOWN_FABRIC, model};
use crate::files::{Batch, NewFolder, PngLayout, add_png};
use crate::image::Planes;
use anyhow::Context;
use std::path::{Path, PathBuf};

/// Arguments of `rollfuse train`.
#[derive(Debug, clap::Args)]
pub struct TrainArgs {
    /// Where to write the model (safetensors).
    #[arg(long)]
    pub out: PathBuf,
    /// Optimizer steps.
    #[arg(long, default_value_t = TrainOptions::default().steps)]
    pub steps: usize,
    /// Simulated training rolls (fabric = seed mod 17, so 17 or a multiple covers every class).
    #[arg(long, default_value_t = TrainOptions::default().rolls)]
    pub rolls: usize,
    /// Simulated validation rolls.
    #[arg(long, default_value_t = TrainOptions::default().validation_rolls)]
    pub validation_rolls: usize,
    /// Crops a step.
    #[arg(long, default_value_t = TrainOptions::default().batch)]
    pub batch: usize,
    /// Seed of the initial weights and the crops.
    #[arg(long, default_value_t = TrainOptions::default().seed)]
    pub seed: u64,
    /// Start from this model's weights instead of new ones; with `--steps 0`, only
    /// measure it and calibrate its familiarity statistics.
    #[arg(long)]
    pub from: Option<PathBuf>,
}

/// Runs `rollfuse train`, showing progress as `show` says.
pub fn train_run(args: TrainArgs, show: Show) -> anyhow::Result<()> {
    super::check_writable(&args.out)?;
    anyhow::ensure!(
        args.out.extension().is_some_and(|e| e == "safetensors"),
        "{}: models are written as safetensors; name the file .safetensors",
        args.out.display()
    );
    let _folder = NewFolder::for_file(&args.out)?;
    let opts = TrainOptions {
        steps: args.steps,
        rolls: args.rolls,
        validation_rolls: args.validation_rolls,
        batch: args.batch,
        seed: args.seed,
        ..TrainOptions::default()
    };
    let start = match &args.from {
        Some(path) => {
            crate::files::refuse_overwriting(&[args.out.as_path()], &[("model", path)])?;
            let (net, about) = model::load(path)?;
            anyhow::ensure!(
                about.widths == opts.widths,
                "model {} has widths {:?}; training continues only the shipped widths {:?}",
                path.display(),
                about.widths.0,
                opts.widths.0
            );
            Some((net, about.made_by))
        }
        None => None,
    };
    let mut made_by = format!(
        "rollfuse train --steps {} --rolls {} --validation-rolls {} --batch {} --seed {}",
        args.steps, args.rolls, args.validation_rolls, args.batch, args.seed
    );
    if let Some((_, before)) = &start {
        made_by = format!("{before}; then {made_by} --from it");
    }
    let started = std::time::Instant::now();
    // Kept on the terminal: the loss the training ended at stays readable.
    let (net, about, report) = train(&opts, start.map(|s| s.0), &made_by, &Bars::kept(show))?;
    model::save(&args.out, &net, &about)?;
    let l = &report.losses;
    let mean = |s: &[f32]| s.iter().sum::<f32>() / s.len().max(1) as f32;
    let tail = l.len().min(50);
    let accuracy = |a: Option<f64>| a.map_or("no validation".to_string(), |a| format!("{a:.3}"));
    let familiarity = match (&report.familiarity_missing, report.validation_unfamiliar) {
        (Some(why), _) => format!("no familiarity statistics ({why})"),
        (None, Some(u)) => format!("{:.1} % of validation images called unknown", 100.0 * u),
        (None, None) => "familiarity calibrated".to_string(),
    };
    let trained = if l.is_empty() {
        "measured without training".to_string()
    } else {
        format!(
            "trained {} steps: loss {:.3} → {:.3}",
            l.len(),
            mean(&l[..tail]),
            mean(&l[l.len() - tail..])
        )
    };
    println!(
        "{trained} in {:.0} s; validation fabric accuracy {} on fused tiles, {} on frames; {familiarity} → {}",
        started.elapsed().as_secs_f64(),
        accuracy(report.validation_fused_accuracy),
        accuracy(report.validation_frame_accuracy),
        args.out.display()
    );
    Ok(())
}

/// Arguments of `rollfuse detect`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Gray images: frames, fused images or strip segments.
    #[arg(required = true)]
    pub images: Vec<PathBuf>,
    /// A model file (else the built-in model).
    #[arg(long, conflicts_with = "normal")]
    pub model: Option<PathBuf>,
    /// Anomaly mode: score each image against this normal model of one fabric
    /// (`rollfuse fit-normal`) instead of running the defect detector.
    #[arg(long)]
    pub normal: Option<PathBuf>,
    /// Write every image's results to this JSON file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write each image with its boxes drawn to DIR/STEM_detect.png.
    #[arg(long)]
    pub draw: Option<PathBuf>,
    /// Heatmap score a detection needs, 0..1.
    #[arg(long, default_value_t = crate::detect::DEFAULT_THRESHOLD, conflicts_with = "normal")]
    pub threshold: f32,
    /// Upsample the images N× first (bilinear), for images downsampled from the camera's
    /// scale, such as `rollfuse stream`'s strips from a device configured to downsample;
    /// boxes are reported in the images' own pixels.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u8).range(1..=4))]
    pub upsample: u8,
}

/// One image's results in the JSON file: the detection, its fabric probabilities by name.
#[derive(serde::Serialize)]
struct ImageResult<'a> {
    image: String,
    #[serde(flatten)]
    detection: &'a Detection,
    probabilities: std::collections::BTreeMap<&'a str, f32>,
}

/// Runs `rollfuse detect`.
pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        (0.0..=1.0).contains(&args.threshold),
        "--threshold must be in 0..=1, got {}",
        args.threshold
    );
    let drawn: Vec<PathBuf> = match &args.draw {
        Some(dir) => args
            .images
            .iter()
            .map(|i| drawn_path(dir, i))
            .collect::<anyhow::Result<_>>()?,
        None => Vec::new(),
    };
    let mut outputs: Vec<&Path> = drawn.iter().map(PathBuf::as_path).collect();
    crate::files::refuse_duplicate_outputs(&outputs, "two images of one file name drawn")?;
    outputs.extend(args.json.as_deref());
    let mut inputs: Vec<(&str, &Path)> = args
        .images
        .iter()
        .map(|i| ("input image", i.as_path()))
        .collect();
    inputs.extend(args.model.as_deref().map(|m| ("model", m)));
    inputs.extend(args.normal.as_deref().map(|m| ("normal model", m)));
    crate::files::refuse_overwriting(&outputs, &inputs)?;
    // Before any work: an output that cannot be written is said first, not after the
    // results; folders made for the outputs go again if the command fails before using them.
    let mut made = Vec::new();
    if let Some(json) = &args.json {
        super::check_writable(json)?;
        made.push(NewFolder::for_file(json)?);
    }
    if let Some(dir) = &args.draw {
        made.push(NewFolder::create(dir)?);
    }
    if let Some(normal) = &args.normal {
        return anomalies_run(&args, normal, &drawn);
    }
    let mut detector = Detector::load_or_built_in(args.model.as_deref())?;
    detector.threshold = args.threshold;
    let mut batch = Batch::new();
    let mut results = Vec::new();
    for (k, path) in args.images.iter().enumerate() {
        let image = Planes::load(path)?;
        let d = detector
            .detect_at_scale(&image, args.upsample.into())
            .with_context(|| format!("{}", path.display()))?;
        println!("{}", summary(path, &d));
        if let Some(out) = drawn.get(k) {
            let (w, h, rgb) = draw(&image, &d.defects);
            add_png(&mut batch, out, &rgb, (w, h), PngLayout::Rgb8)?;
        }
        results.push((path.display().to_string(), d));
    }
    if let Some(json) = &args.json {
        let list: Vec<ImageResult> = results
            .iter()
            .map(|(image, detection)| ImageResult {
                image: image.clone(),
                detection,
                probabilities: detector
                    .about()
                    .fabrics
                    .iter()
                    .map(String::as_str)
                    .zip(detection.probabilities.iter().copied())
                    .collect(),
            })
            .collect();
        batch.add_bytes(
            json,
            (serde_json::to_string_pretty(&list)? + "\n").as_bytes(),
        )?;
    }
    batch.commit()
}

/// `DIR/STEM_detect.png` for an input image.
fn drawn_path(dir: &Path, image: &Path) -> anyhow::Result<PathBuf> {
    let stem = image
        .file_stem()
        .and_then(|s| s.to_str())
        .with_context(|| format!("{} has no file name", image.display()))?;
    Ok(dir.join(format!("{stem}_detect.png")))
}

/// `(x0, y0)–(x1, y1)`, a box in whole pixels.
fn box_text(box_px: [f32; 4]) -> String {
    let b = box_px.map(|v| v.round() as i64);
    format!("({}, {})–({}, {})", b[0], b[1], b[2], b[3])
}

/// `N things` and, if any, `: ` and the items.
fn counted(items: &[String], thing: &str) -> String {
    format!(
        "{} {thing}{}{}{}",
        items.len(),
        if items.len() == 1 { "" } else { "s" },
        if items.is_empty() { "" } else { ": " },
        items.join(", ")
    )
}

/// One line of what was found.
fn summary(path: &Path, d: &Detection) -> String {
    let defects: Vec<String> = d
        .defects
        .iter()
        .map(|f| format!("{} {:.2} at {}", f.kind.name(), f.score, box_text(f.box_px)))
        .collect();
    format!(
        "{}: {}; {}",
        path.display(),
        fabric_text(d),
        counted(&defects, "defect")
    )
}

/// The fabric as a reader needs it: the name and its probability, or, for an image unlike
/// every fabric the model knows, that it is unknown, how far off, and what it is most like.
pub fn fabric_text(d: &Detection) -> String {
    match d.unfamiliarity {
        Some(u) if d.fabric == UNKNOWN_FABRIC => format!(
            "unknown fabric ({u:.1}× the distance of the cloth the model knows; most like {} \
             at p {:.2}, so its defects are unreliable too)",
            d.most_like, d.probability
        ),
        _ => format!("{} (p {:.2})", d.fabric, d.probability),
    }
}

/// Arguments of `rollfuse fit-normal`.
#[derive(Debug, clap::Args)]
pub struct FitNormalArgs {
    /// Defect-free gray images of one fabric, from one camera at one scale (frames, fused
    /// tiles or strip segments).
    #[arg(required = true)]
    pub images: Vec<PathBuf>,
    /// Where to write the normal model (JSON).
    #[arg(long)]
    pub out: PathBuf,
    /// Learn every row of cells alike even when the images share one height, so the model
    /// scores images of any height (the live strip's windows: `stream --normal`). By
    /// default images of one height, camera frames, have each row learned apart.
    #[arg(long)]
    pub every_row_alike: bool,
}

/// Runs `rollfuse fit-normal`.
pub fn fit_normal_run(args: FitNormalArgs) -> anyhow::Result<()> {
    let inputs: Vec<(&str, &Path)> = args
        .images
        .iter()
        .map(|i| ("input image", i.as_path()))
        .collect();
    crate::files::refuse_overwriting(&[args.out.as_path()], &inputs)?;
    super::check_writable(&args.out)?;
    let _folder = NewFolder::for_file(&args.out)?;
    let started = std::time::Instant::now();
    let images: Vec<Planes> = args
        .images
        .iter()
        .map(|p| Planes::load(p))
        .collect::<anyhow::Result<_>>()?;
    let model = if args.every_row_alike {
        NormalModel::fit_every_row_alike(&images)?
    } else {
        NormalModel::fit(&images)?
    };
    model.save(&args.out)?;
    println!(
        "learned {} images of {} × {} ({}) in {:.1} s; a cell is anomalous above {:.2} → {}",
        model.images,
        model.width,
        model.height,
        if model.any_height() {
            "every row alike"
        } else {
            "each row of cells apart"
        },
        started.elapsed().as_secs_f64(),
        model.threshold,
        args.out.display()
    );
    Ok(())
}

/// The colour anomalous regions are drawn in.
const ANOMALY_COLOUR: [u8; 3] = [255, 190, 0];

/// One image's anomalies in the JSON file.
#[derive(serde::Serialize)]
struct AnomalyResult {
    image: String,
    anomaly_score: f32,
    defects: Vec<AnomalyDefect>,
}

/// An anomalous region as `detect --json` lists defects.
#[derive(serde::Serialize)]
struct AnomalyDefect {
    kind: &'static str,
    score: f32,
    box_px: [f32; 4],
}

/// `rollfuse detect --normal`: each image scored against the normal model.
fn anomalies_run(args: &Args, normal: &Path, drawn: &[PathBuf]) -> anyhow::Result<()> {
    let model = NormalModel::load(normal)?;
    let mut batch = Batch::new();
    let mut results = Vec::new();
    for (k, path) in args.images.iter().enumerate() {
        let image = Planes::load(path)?;
        let a = model
            .detect(&image)
            .with_context(|| format!("{}", path.display()))?;
        let regions: Vec<String> = a
            .regions
            .iter()
            .map(|r| format!("{:.2} at {}", r.score, box_text(r.box_px)))
            .collect();
        println!(
            "{}: anomaly score {:.2}; {}",
            path.display(),
            a.anomaly_score,
            counted(&regions, "region")
        );
        if let Some(out) = drawn.get(k) {
            let (w, h, rgb) = outline(&image, a.regions.iter().map(|r| (r.box_px, ANOMALY_COLOUR)));
            add_png(&mut batch, out, &rgb, (w, h), PngLayout::Rgb8)?;
        }
        results.push(AnomalyResult {
            image: path.display().to_string(),
            anomaly_score: a.anomaly_score,
            defects: a
                .regions
                .iter()
                .map(|r| AnomalyDefect {
                    kind: crate::detect::anomaly::KIND,
                    score: r.score,
                    box_px: r.box_px,
                })
                .collect(),
        });
    }
    if let Some(json) = &args.json {
        batch.add_bytes(
            json,
            (serde_json::to_string_pretty(&results)? + "\n").as_bytes(),
        )?;
    }
    batch.commit()
}
