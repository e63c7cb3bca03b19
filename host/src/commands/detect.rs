//! `rollfuse train` and `rollfuse detect`: the fabric defect detector's model, and the
//! detector run on images (frames, fused images, strips).

use super::bars::{Bars, Show};
use anyhow::Context;
use rollfuse::detect::anomaly::NormalModel;
use rollfuse::detect::draw::{draw, outline};
use rollfuse::detect::labels::read_labels;
use rollfuse::detect::targets::MIN_IOU;
use rollfuse::detect::train::{TrainOptions, train};
use rollfuse::detect::tune::{TuneOptions, tune};
use rollfuse::detect::{Detection, Detector, UNKNOWN_FABRIC, model};
use rollfuse::files::{Batch, NewFolder, PngLayout, add_png};
use rollfuse::image::{PixelLimit, Planes};
use rollfuse_records::Records;
use std::path::{Path, PathBuf};

/// Arguments of `rollfuse train`.
#[derive(Debug, clap::Args)]
pub struct TrainArgs {
    /// Where to write the model (safetensors).
    #[arg(long)]
    pub out: PathBuf,
    /// Optimizer steps [default: 2500 on simulated rolls, 400 fine-tuning].
    #[arg(long)]
    pub steps: Option<usize>,
    /// Simulated training rolls (fabric = seed mod 17, so 17 or a multiple covers every class).
    #[arg(long, default_value_t = TrainOptions::default().rolls, conflicts_with = "images")]
    pub rolls: usize,
    /// Simulated validation rolls.
    #[arg(long, default_value_t = TrainOptions::default().validation_rolls, conflicts_with = "images")]
    pub validation_rolls: usize,
    /// How the simulated rolls are drawn: `standard` (the simulator's own look) or
    /// `varied` (lights, gel, defocus and noise drawn for each roll; see docs/detect.md).
    #[arg(long, default_value = "standard", conflicts_with = "images")]
    pub style: rollfuse::detect::data::Style,
    /// Give each training crop a random look: half turned, its tone, light, blur and noise
    /// changed (see docs/detect.md).
    #[arg(long, conflicts_with = "images")]
    pub augment: bool,
    /// The heatmap score the model's detections need unless `detect --threshold` says
    /// otherwise, kept in the model (choose it on held-out rolls of the look it learned:
    /// `eval --detect --style S --model M --threshold T`) [default: none kept: 0.3].
    #[arg(long, conflicts_with = "images")]
    pub threshold: Option<f32>,
    /// Crops a step [default: 16 on simulated rolls, 8 fine-tuning].
    #[arg(long)]
    pub batch: Option<usize>,
    /// Seed of the initial weights and the crops (and, fine-tuning, of the split).
    #[arg(long, default_value_t = TrainOptions::default().seed)]
    pub seed: u64,
    /// Start from this model's weights instead of new ones (fine-tuning: instead of the
    /// built-in model); with `--steps 0`, only measure it and calibrate its familiarity
    /// statistics.
    #[arg(long)]
    pub from: Option<PathBuf>,
    /// Fine-tune on your own labelled images in DIR (with `--labels`) instead of training
    /// on simulated rolls.
    #[arg(long, requires = "labels")]
    pub images: Option<PathBuf>,
    /// The labels of `--images`: a COCO detection file (categories hole, snag, slub), or a
    /// folder of YOLO labels (a STEM.txt for each image; class names in classes.txt).
    #[arg(long, requires = "images")]
    pub labels: Option<PathBuf>,
    /// Fine-tuning: share of the labelled images held out to measure the model on.
    #[arg(long, default_value_t = TuneOptions::default().validation, requires = "images")]
    pub validation: f64,
}

/// Runs `rollfuse train`, showing progress as `show` says; labelled images are read
/// within `limit`.
pub fn train_run(args: TrainArgs, show: Show, limit: PixelLimit) -> anyhow::Result<()> {
    super::check_writable(&args.out)?;
    anyhow::ensure!(
        args.out.extension().is_some_and(|e| e == "safetensors"),
        "{}: models are written as safetensors; name the file .safetensors",
        args.out.display()
    );
    let inputs: Vec<(&str, &Path)> = [("model", &args.from), ("labels", &args.labels)]
        .into_iter()
        .filter_map(|(what, path)| Some((what, path.as_deref()?)))
        .collect();
    rollfuse::files::refuse_overwriting(&[args.out.as_path()], &inputs)?;
    let _folder = NewFolder::for_file(&args.out)?;
    let started = std::time::Instant::now();
    let done = match (&args.images, &args.labels) {
        (Some(images), Some(labels)) => tune_run(&args, images, labels, limit, show)?,
        _ => train_on_rolls(&args, show)?,
    };
    println!(
        "{done} in {:.0} s → {}",
        started.elapsed().as_secs_f64(),
        args.out.display()
    );
    Ok(())
}

/// Trains on simulated rolls and writes the model; what was measured, in words.
fn train_on_rolls(args: &TrainArgs, show: Show) -> anyhow::Result<String> {
    let opts = TrainOptions {
        steps: args.steps.unwrap_or(TrainOptions::default().steps),
        rolls: args.rolls,
        validation_rolls: args.validation_rolls,
        batch: args.batch.unwrap_or(TrainOptions::default().batch),
        seed: args.seed,
        style: args.style,
        augment: args.augment,
        ..TrainOptions::default()
    };
    let start = match &args.from {
        Some(path) => {
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
        "rollfuse train --steps {} --rolls {} --validation-rolls {} --batch {} --seed {} --style {}",
        opts.steps,
        args.rolls,
        args.validation_rolls,
        opts.batch,
        args.seed,
        args.style.name()
    );
    if args.augment {
        made_by.push_str(" --augment");
    }
    if let Some(t) = args.threshold {
        made_by.push_str(&format!(" --threshold {t}"));
    }
    if let Some((_, before)) = &start {
        made_by = format!("{before}; then {made_by} --from it");
    }
    // Kept on the terminal: the loss the training ended at stays readable.
    args.threshold
        .map(rollfuse::detect::check_threshold)
        .transpose()?;
    let (net, mut about, report) = train(&opts, start.map(|s| s.0), &made_by, &Bars::kept(show))?;
    about.threshold = args.threshold;
    model::save(&args.out, &net, &about)?;
    let accuracy = |a: Option<f64>| a.map_or("no validation".to_string(), |a| format!("{a:.3}"));
    let familiarity = match (&report.familiarity_missing, report.validation_unfamiliar) {
        (Some(why), _) => format!("no familiarity statistics ({why})"),
        (None, Some(u)) => format!("{:.1} % of validation images called unknown", 100.0 * u),
        (None, None) => "familiarity calibrated".to_string(),
    };
    Ok(format!(
        "{}; validation fabric accuracy {} on fused tiles, {} on frames; {familiarity}",
        trained(&report.losses),
        accuracy(report.validation_fused_accuracy),
        accuracy(report.validation_frame_accuracy),
    ))
}

/// Fine-tunes a model on the user's labelled images and writes it; what was measured, in
/// words.
fn tune_run(
    args: &TrainArgs,
    images: &Path,
    labels: &Path,
    limit: PixelLimit,
    show: Show,
) -> anyhow::Result<String> {
    let opts = TuneOptions {
        steps: args.steps.unwrap_or(TuneOptions::default().steps),
        batch: args.batch.unwrap_or(TuneOptions::default().batch),
        seed: args.seed,
        validation: args.validation,
        ..TuneOptions::default()
    };
    let labelled = read_labels(labels, images, limit)?;
    let start = match &args.from {
        Some(path) => model::load(path)?,
        None => model::built_in()?,
    };
    let made_by = format!(
        "{}; then rollfuse train --images {} --labels {} --steps {} --batch {} --seed {} --validation {} from it",
        start.1.made_by,
        images.display(),
        labels.display(),
        opts.steps,
        opts.batch,
        opts.seed,
        opts.validation
    );
    let (net, about, report) = tune(start, labelled, &opts, &made_by, &Bars::kept(show))?;
    model::save(&args.out, &net, &about)?;
    let measured = match (report.before, report.after) {
        (Some(b), Some(a)) => format!(
            "on the {} held-out images precision {:.2} → {:.2}, recall {:.2} → {:.2} (kind-aware, IoU ≥ {MIN_IOU})",
            report.validated_on,
            b.precision(),
            a.precision(),
            b.recall(),
            a.recall()
        ),
        _ => "no images held out to measure it on".to_string(),
    };
    Ok(format!(
        "{} on {} images; {measured}",
        trained(&report.losses),
        report.trained_on
    ))
}

/// The losses in words: how many steps, and the loss from the first to the last 50.
fn trained(losses: &[f32]) -> String {
    if losses.is_empty() {
        return "measured without training".to_string();
    }
    let mean = |s: &[f32]| s.iter().sum::<f32>() / s.len().max(1) as f32;
    let tail = losses.len().min(50);
    format!(
        "trained {} steps: loss {:.3} → {:.3}",
        losses.len(),
        mean(&losses[..tail]),
        mean(&losses[losses.len() - tail..])
    )
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
    /// Heatmap score a detection needs, 0..1 [default: the model's own (the built-in
    /// model's 0.4), else 0.3].
    #[arg(long, conflicts_with = "normal")]
    pub threshold: Option<f32>,
    /// Upsample the images N× first (bilinear), for images downsampled from the camera's
    /// scale, such as `rollfuse stream`'s strips from a device configured to downsample;
    /// boxes are reported in the images' own pixels.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u8).range(1..=4))]
    pub upsample: u8,
    /// Keep the defects found on a recorded roll's strip segments in these inspection
    /// records (a SQLite file or a `postgres://` URL), replacing what an earlier run kept
    /// for the segment; an image that is no recorded segment is said and skipped.
    #[arg(long, value_name = "DB")]
    pub records: Option<String>,
}

/// Keeps the defects `found` (kind, score, box) on `path` in `records`, if `path` is a
/// segment of a recorded roll.
fn record_found<'a>(
    records: Option<&mut Records>,
    path: &Path,
    image: &Planes,
    found: impl Iterator<Item = (&'a str, f32, [f32; 4])>,
) -> anyhow::Result<()> {
    let Some(records) = records else {
        return Ok(());
    };
    let Some((roll, segment)) = records.segment_at(path)? else {
        eprintln!(
            "warning: {} is no recorded roll's segment: its defects are not recorded",
            path.display()
        );
        return Ok(());
    };
    let defects: Vec<_> = found
        .map(|(kind, score, box_px)| {
            rollfuse::records::defect(kind, score, box_px, image, segment.first_row)
        })
        .collect();
    records.replace_defects(roll, segment.seq, &defects)?;
    println!(
        "records: roll {roll} segment {}: {} defect{}",
        segment.seq,
        defects.len(),
        if defects.len() == 1 { "" } else { "s" }
    );
    Ok(())
}

/// One image's results in the JSON file: the detection, its fabric probabilities by name.
#[derive(serde::Serialize)]
struct ImageResult<'a> {
    image: String,
    #[serde(flatten)]
    detection: &'a Detection,
    probabilities: std::collections::BTreeMap<&'a str, f32>,
}

/// Runs `rollfuse detect`, reading images within `limit`.
pub fn run(args: Args, limit: PixelLimit) -> anyhow::Result<()> {
    args.threshold
        .map(rollfuse::detect::check_threshold)
        .transpose()?;
    let drawn: Vec<PathBuf> = match &args.draw {
        Some(dir) => args
            .images
            .iter()
            .map(|i| drawn_path(dir, i))
            .collect::<anyhow::Result<_>>()?,
        None => Vec::new(),
    };
    let mut outputs: Vec<&Path> = drawn.iter().map(PathBuf::as_path).collect();
    rollfuse::files::refuse_duplicate_outputs(&outputs, "two images of one file name drawn")?;
    outputs.extend(args.json.as_deref());
    let mut inputs: Vec<(&str, &Path)> = args
        .images
        .iter()
        .map(|i| ("input image", i.as_path()))
        .collect();
    inputs.extend(args.model.as_deref().map(|m| ("model", m)));
    inputs.extend(args.normal.as_deref().map(|m| ("normal model", m)));
    inputs.extend(args.records.as_deref().and_then(super::rolls::records_file));
    rollfuse::files::refuse_overwriting(&outputs, &inputs)?;
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
    let mut records = args
        .records
        .as_deref()
        .map(super::rolls::open)
        .transpose()?;
    if let Some(normal) = &args.normal {
        return anomalies_run(&args, normal, limit, &drawn, records.as_mut());
    }
    let mut detector = Detector::load_or_built_in(args.model.as_deref())?;
    detector.threshold = args.threshold.unwrap_or(detector.threshold);
    let mut batch = Batch::new();
    let mut results = Vec::new();
    for (k, path) in args.images.iter().enumerate() {
        let image = Planes::load(path, limit)?;
        let d = detector
            .detect_at_scale(&image, args.upsample.into())
            .with_context(|| format!("{}", path.display()))?;
        println!("{}", summary(path, &d));
        let found = d.defects.iter().map(|f| (f.kind.name(), f.score, f.box_px));
        record_found(records.as_mut(), path, &image, found)?;
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
    Ok(batch.commit()?)
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

/// Runs `rollfuse fit-normal`, reading images within `limit`.
pub fn fit_normal_run(args: FitNormalArgs, limit: PixelLimit) -> anyhow::Result<()> {
    let inputs: Vec<(&str, &Path)> = args
        .images
        .iter()
        .map(|i| ("input image", i.as_path()))
        .collect();
    rollfuse::files::refuse_overwriting(&[args.out.as_path()], &inputs)?;
    super::check_writable(&args.out)?;
    let _folder = NewFolder::for_file(&args.out)?;
    let started = std::time::Instant::now();
    let images: Vec<Planes> = args
        .images
        .iter()
        .map(|p| Ok(Planes::load(p, limit)?))
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
fn anomalies_run(
    args: &Args,
    normal: &Path,
    limit: PixelLimit,
    drawn: &[PathBuf],
    mut records: Option<&mut Records>,
) -> anyhow::Result<()> {
    let model = NormalModel::load(normal)?;
    let mut batch = Batch::new();
    let mut results = Vec::new();
    for (k, path) in args.images.iter().enumerate() {
        let image = Planes::load(path, limit)?;
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
        let found = a.regions.iter();
        let found = found.map(|r| (rollfuse::detect::anomaly::KIND, r.score, r.box_px));
        record_found(records.as_deref_mut(), path, &image, found)?;
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
                    kind: rollfuse::detect::anomaly::KIND,
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
    Ok(batch.commit()?)
}
