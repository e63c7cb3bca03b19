//! Training: simulated rolls (frames and fused tiles), random crops, CenterNet's losses
//! plus cross-entropy for the fabric, AdamW with a cosine-decaying rate, on the CPU.
//!
//! Seeds: training rolls are `TRAIN_SEEDS + k`, validation rolls `VALIDATION_SEEDS + k`;
//! `rollfuse eval --detect` measures on seeds below [`TRAIN_SEEDS`], which training never
//! touches.

use super::data::{Roll, RollShape, Sample, Source, Style, roll_in_style};
use super::familiar::{Familiarity, Kind, Places};
use super::model::About;
use super::net::{Net, Widths};
use super::targets::{KINDS, Labelled, Targets, encode};
use super::{floats, normalized};
use burn::module::Module;
use burn::nn::loss::CrossEntropyLossConfig;
use burn::optim::{AdamWConfig, GradientsParams};
use burn::tensor::{Device, Int, Tensor, TensorData, activation::log_sigmoid, activation::sigmoid};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;
use rollfuse_io::progress::Progress;
use rollfuse_sim::textile::FABRICS;

/// First seed of the training rolls.
pub const TRAIN_SEEDS: u64 = 1_000_000;
/// First seed of the validation rolls.
pub const VALIDATION_SEEDS: u64 = 2_000_000;

/// The most rolls of either kind a training run simulates (the training seeds then stay
/// below the validation seeds, with room to spare).
pub const MAX_ROLLS: usize = 10_000;
/// The most crops in a step's batch.
pub const MAX_BATCH: usize = 256;
/// The most optimizer steps.
pub const MAX_STEPS: usize = 1_000_000;

/// How to train.
#[derive(Debug, Clone)]
pub struct TrainOptions {
    /// Training rolls.
    pub rolls: usize,
    /// Validation rolls.
    pub validation_rolls: usize,
    /// Optimizer steps.
    pub steps: usize,
    /// Crops a step.
    pub batch: usize,
    /// Crop side, pixels (a multiple of 8).
    pub crop: usize,
    /// Peak learning rate.
    pub rate: f64,
    /// Seed of the initial weights and the crops.
    pub seed: u64,
    /// The network's widths.
    pub widths: Widths,
    /// The rolls' shape.
    pub shape: RollShape,
    /// How the rolls are drawn.
    pub style: Style,
    /// Each crop given a random look ([`super::augment`]).
    pub augment: bool,
}

impl Default for TrainOptions {
    /// The shipped model's recipe.
    fn default() -> Self {
        Self {
            rolls: 68,
            validation_rolls: 17,
            steps: 2500,
            batch: 16,
            crop: 160,
            rate: 2e-3,
            seed: 1,
            widths: Widths::SHIPPED,
            shape: RollShape::STANDARD,
            style: Style::Standard,
            augment: false,
        }
    }
}

/// What training measured.
#[derive(Debug, Clone, serde::Serialize)]
pub struct TrainReport {
    /// Loss of each step.
    pub losses: Vec<f32>,
    /// Fabric accuracy on the validation rolls' fused tiles (none without such tiles).
    pub validation_fused_accuracy: Option<f64>,
    /// Fabric accuracy on the validation rolls' frames (none without validation rolls).
    pub validation_frame_accuracy: Option<f64>,
    /// Why the model carries no familiarity statistics, if it does not.
    pub familiarity_missing: Option<String>,
    /// Share of the validation images the calibrated model finds unfamiliar.
    pub validation_unfamiliar: Option<f64>,
}

/// Simulates `count` rolls from `first_seed` in parallel.
pub fn rolls(
    first_seed: u64,
    count: usize,
    shape: &RollShape,
    style: Style,
    mut done: impl FnMut(usize),
) -> crate::Result<Vec<Roll>> {
    let (tx, rx) = std::sync::mpsc::channel();
    let made = std::thread::scope(|s| {
        let worker = s.spawn(move || {
            (0..count as u64)
                .into_par_iter()
                .map(|k| {
                    let r = roll_in_style(first_seed + k, shape, style);
                    let _ = tx.send(());
                    r
                })
                .collect::<crate::Result<Vec<_>>>()
        });
        for n in 1..=count {
            if rx.recv().is_err() {
                break;
            }
            done(n);
        }
        worker.join()
    });
    made.map_err(|_| anyhow::anyhow!("a simulation thread panicked"))?
}

/// Trains a network — a new one, or `start` further (fine-tuning) — then measures its
/// fabric accuracy on the validation rolls and calibrates its familiarity statistics
/// ([`super::familiar`]: fitted on the training images, the limit from the validation
/// images). Returns it with its model description and what was measured. `progress` sees
/// the rolls simulated, the optimizer's steps and the calibration. With `start`, 0 steps
/// only measures and calibrates it.
pub fn train(
    opts: &TrainOptions,
    start: Option<Net>,
    made_by: &str,
    progress: &dyn Progress,
) -> crate::Result<(Net, About, TrainReport)> {
    rollfuse_io::require!(
        opts.crop >= 32 && opts.crop.is_multiple_of(8),
        "the crop side must be a multiple of 8, at least 32"
    );
    rollfuse_io::require!(
        opts.rolls > 0 && opts.batch > 0 && (opts.steps > 0 || start.is_some()),
        "training needs at least one roll, one step and one crop a step"
    );
    // Each roll is simulated and held; each step's batch is held with its activations.
    rollfuse_io::require!(
        opts.rolls <= MAX_ROLLS && opts.validation_rolls <= MAX_ROLLS,
        "at most {MAX_ROLLS} training and {MAX_ROLLS} validation rolls"
    );
    rollfuse_io::require!(opts.batch <= MAX_BATCH, "at most {MAX_BATCH} crops a step");
    rollfuse_io::require!(opts.steps <= MAX_STEPS, "at most {MAX_STEPS} steps");
    let (w, h) = opts.shape.size;
    rollfuse_io::require!(
        opts.crop <= w.min(h),
        "the crop ({}) is larger than the frames ({w}×{h})",
        opts.crop
    );
    let total = opts.rolls + opts.validation_rolls;
    progress.start("simulating and fusing", Some(total as u64), "rolls");
    let train_rolls = rolls(TRAIN_SEEDS, opts.rolls, &opts.shape, opts.style, |n| {
        progress.advance_to(n as u64)
    })?;
    let validation = rolls(
        VALIDATION_SEEDS,
        opts.validation_rolls,
        &opts.shape,
        opts.style,
        |n| progress.advance_to((opts.rolls + n) as u64),
    )?;
    progress.finish();
    let frames: Vec<&Sample> = train_rolls.iter().flat_map(|r| &r.frames).collect();
    let fused: Vec<&Sample> = train_rolls.iter().flat_map(|r| &r.fused).collect();
    rollfuse_io::require!(!fused.is_empty(), "the training rolls fused to no tiles");

    let device = Device::flex().autodiff();
    device.seed(opts.seed);
    let net = match start {
        Some(net) => net.to_device(&device),
        None => Net::new(opts.widths, FABRICS.len(), &device),
    };
    let schedule = Schedule {
        steps: opts.steps,
        rate: opts.rate,
    };
    let (net, losses) = optimize(net, &schedule, opts.seed, progress, |rng| {
        let crops: Vec<Crop> = (0..opts.batch)
            .map(|_| {
                // Half the crops from fused tiles, half from frames.
                let pool = if rng.random_bool(0.5) {
                    &fused
                } else {
                    &frames
                };
                let sample = pool[rng.random_range(0..pool.len())];
                crop(sample, opts.crop, opts.augment, rng)
            })
            .collect();
        Batch::new(&crops, &device)
    })?;
    let about = About {
        widths: opts.widths,
        fabrics: FABRICS.iter().map(|f| f.name.to_string()).collect(),
        made_by: made_by.to_string(),
        familiarity: None,
        threshold: None,
    };
    let validation: Vec<&Sample> = validation
        .iter()
        .flat_map(|r| r.frames.iter().chain(&r.fused))
        .collect();
    let seen: Vec<&Sample> = frames.iter().chain(&fused).copied().collect();
    let (about, report) = measure(&net, about, &seen, &validation, losses, progress)?;
    Ok((net, about, report))
}

/// The trained network's fabric accuracy on the `validation` images, and its familiarity
/// statistics calibrated on the images it was trained on (`seen`) and those.
fn measure(
    net: &Net,
    mut about: About,
    seen: &[&Sample],
    validation: &[&Sample],
    losses: Vec<f32>,
    progress: &dyn Progress,
) -> crate::Result<(About, TrainReport)> {
    let detector = super::Detector::from_net(net.clone(), about.clone());
    let accuracy = |source: Source| -> crate::Result<Option<f64>> {
        let samples: Vec<&&Sample> = validation.iter().filter(|s| s.source == source).collect();
        let mut right = 0;
        for s in &samples {
            let d = detector.detect(&s.image)?;
            right += usize::from(d.most_like == FABRICS[s.class].name);
        }
        Ok((!samples.is_empty()).then(|| right as f64 / samples.len() as f64))
    };
    let mut report = TrainReport {
        validation_fused_accuracy: accuracy(Source::Fused)?,
        validation_frame_accuracy: accuracy(Source::Frame)?,
        losses,
        familiarity_missing: None,
        validation_unfamiliar: None,
    };
    match calibrate(seen, validation, progress) {
        Ok((familiarity, unfamiliar)) => {
            report.validation_unfamiliar = Some(unfamiliar);
            about.familiarity = Some(familiarity);
        }
        Err(e) => report.familiarity_missing = Some(format!("{e:#}")),
    }
    Ok((about, report))
}

/// The familiarity statistics of the training cloth — fitted on the images the network
/// was trained on, the limit from `held_out` images, frames and fused tiles apart — and
/// the share of the held-out images they call unfamiliar.
fn calibrate(
    trained_on: &[&Sample],
    held_out: &[&Sample],
    progress: &dyn Progress,
) -> crate::Result<(Familiarity, f64)> {
    let total = (trained_on.len() + held_out.len()) as u64;
    progress.start("calibrating familiarity", Some(total), "images");
    let mut kinds = [Kind::default(), Kind::default()];
    let kind = |s: &Sample| usize::from(s.source == Source::Fused);
    let mut done = 0;
    for s in trained_on {
        kinds[kind(s)].fit.push((Places::of(&s.image)?, s.class));
        done += 1;
        progress.advance_to(done);
    }
    for s in held_out {
        kinds[kind(s)].held_out.push(Places::of(&s.image)?);
        done += 1;
        progress.advance_to(done);
    }
    progress.finish();
    let familiarity = Familiarity::fit(&kinds, FABRICS.len())?;
    let mut unfamiliar = 0;
    for places in kinds.iter().flat_map(|k| &k.held_out) {
        unfamiliar += usize::from(familiarity.judge(places)?.unfamiliar());
    }
    Ok((
        familiarity,
        unfamiliar as f64 / held_out.len().max(1) as f64,
    ))
}

/// How many optimizer steps, at what peak rate.
pub struct Schedule {
    /// Optimizer steps.
    pub steps: usize,
    /// Peak learning rate; it decays to 10⁻⁵ by a cosine.
    pub rate: f64,
}

/// Trains `net` (on an autodiff device) for the schedule's steps with AdamW, each step on
/// the batch `draw` makes from the crops' random source (seeded by `seed`). Returns the
/// network for inference and the loss of every step; `progress` sees the steps.
pub fn optimize(
    net: Net,
    schedule: &Schedule,
    seed: u64,
    progress: &dyn Progress,
    mut draw: impl FnMut(&mut Pcg64Mcg) -> Batch,
) -> crate::Result<(Net, Vec<f32>)> {
    // A loaded network's parameters are frozen until put back in training.
    let mut net = net.train();
    let mut optim = AdamWConfig::new().init();
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let mut losses = Vec::with_capacity(schedule.steps);
    progress.start("training", Some(schedule.steps as u64), "steps");
    for step in 0..schedule.steps {
        let batch = draw(&mut rng);
        let loss = losses_of(&net, &batch);
        let value = floats(loss.clone())?.first().copied().unwrap_or(f32::NAN);
        rollfuse_io::require!(
            value.is_finite(),
            "training diverged at step {}: the loss is {value}",
            step + 1
        );
        losses.push(value);
        let grads = GradientsParams::from_grads(loss.backward(), &net);
        let t = step as f64 / schedule.steps.max(1) as f64;
        let peak = schedule.rate;
        let rate = 1e-5 + (peak - 1e-5) * (1.0 + (std::f64::consts::PI * t).cos()) / 2.0;
        net = optim.step(rate, net, grads);
        progress.advance_to(step as u64 + 1);
        progress.message(&format!("loss {value:.3}"));
    }
    progress.finish();
    Ok((net.valid(), losses))
}

/// A training crop: normalized pixels, targets and the fabric's label.
pub struct Crop {
    pixels: Vec<f32>,
    side: usize,
    targets: Targets,
    /// None where the fabric is not known (the user's labelled images).
    class: Option<usize>,
}

impl Crop {
    /// The crop without its fabric's label: it trains the defect heads only.
    pub fn without_fabric(self) -> Self {
        Self {
            class: None,
            ..self
        }
    }
}

/// A random `side × side` crop of `s`; half the time placed to hold one of its defects;
/// given a random look when `augment` ([`super::augment`]).
pub fn crop(s: &Sample, side: usize, augment: bool, rng: &mut Pcg64Mcg) -> Crop {
    let (w, h) = (s.image.width, s.image.height);
    let mut x0 = rng.random_range(0..=w - side);
    let mut y0 = rng.random_range(0..=h - side);
    if !s.boxes.is_empty() && rng.random_bool(0.5) {
        let b = s.boxes[rng.random_range(0..s.boxes.len())].box_px;
        let (cx, cy) = (
            ((b[0] + b[2]) / 2.0) as usize,
            ((b[1] + b[3]) / 2.0) as usize,
        );
        let around = |c: usize, limit: usize| {
            let lo = c.saturating_sub(side - 8).min(limit - side);
            let hi = c.saturating_sub(8).min(limit - side).max(lo);
            (lo, hi)
        };
        let (lx, hx) = around(cx, w);
        let (ly, hy) = around(cy, h);
        x0 = rng.random_range(lx..=hx);
        y0 = rng.random_range(ly..=hy);
    }
    let shift = |boxes: &[Labelled]| -> Vec<Labelled> {
        boxes
            .iter()
            .map(|l| {
                let [a, b, c, d] = l.box_px;
                let (x, y) = (x0 as f32, y0 as f32);
                Labelled {
                    kind: l.kind,
                    box_px: [a - x, b - y, c - x, d - y],
                }
            })
            .collect()
    };
    let mut pixels: Vec<f32> = (y0..y0 + side)
        .flat_map(|y| {
            s.image.planes[0][y * w + x0..y * w + x0 + side]
                .iter()
                .copied()
        })
        .collect();
    let (mut boxes, mut blurred) = (shift(&s.boxes), shift(&s.blurred));
    if augment {
        super::augment::apply(&mut pixels, side, &mut boxes, &mut blurred, rng);
    }
    Crop {
        pixels: normalized(&pixels),
        side,
        targets: encode(&boxes, &blurred, side, side),
        class: Some(s.class),
    }
}

/// A batch as tensors.
pub struct Batch {
    images: Tensor<4>,
    heat: Tensor<4>,
    size: Tensor<4>,
    offset: Tensor<4>,
    mask: Tensor<4>,
    counted: Tensor<4>,
    /// The fabrics, where every crop's is known.
    classes: Option<Tensor<1, Int>>,
}

impl Batch {
    /// Stacks `crops` (all of one side) on `device`.
    pub fn new(crops: &[Crop], device: &Device) -> Self {
        let b = crops.len();
        let side = crops[0].side;
        let (gw, gh) = crops[0].targets.cells;
        let stack = |f: &dyn Fn(&Crop) -> &[f32], c: usize, hw: (usize, usize)| {
            let v: Vec<f32> = crops.iter().flat_map(|k| f(k).iter().copied()).collect();
            Tensor::<4>::from_data(TensorData::new(v, [b, c, hw.1, hw.0]), device)
        };
        let cells = (gw, gh);
        Self {
            images: stack(&|k| &k.pixels, 1, (side, side)),
            heat: stack(&|k| &k.targets.heat, KINDS, cells),
            size: stack(&|k| &k.targets.size, 2, cells),
            offset: stack(&|k| &k.targets.offset, 2, cells),
            mask: stack(&|k| &k.targets.mask, 1, cells),
            counted: stack(&|k| &k.targets.counted, 1, cells),
            classes: crops
                .iter()
                .map(|k| k.class.map(|c| c as i64))
                .collect::<Option<Vec<_>>>()
                .map(|c| Tensor::<1, Int>::from_data(TensorData::new(c, [b]), device)),
        }
    }
}

/// The training loss of a batch: CenterNet's focal loss on the heatmap (negatives near a
/// blurred defect not counted), L1 on sizes (weighted 0.1) and offsets at the centres,
/// and cross-entropy on the fabric where the crops' fabrics are known.
fn losses_of(net: &Net, batch: &Batch) -> Tensor<1> {
    let raw = net.forward(batch.images.clone());
    let positives = batch.mask.clone().sum().clamp_min(1.0);
    let is_peak = batch.heat.clone().equal_elem(1.0).float();
    // log p and log (1 - p) straight from the logits: no log of 0 however sure the net is.
    let log_p = log_sigmoid(raw.heat.clone());
    let log_not_p = log_sigmoid(raw.heat.clone().neg());
    let p = sigmoid(raw.heat);
    let not_p = p.clone().neg().add_scalar(1.0);
    let pos = (log_p * not_p.powi_scalar(2) * is_peak.clone()).sum();
    let far = batch.heat.clone().neg().add_scalar(1.0).powi_scalar(4);
    let neg = (log_not_p
        * p.powi_scalar(2)
        * far
        * is_peak.neg().add_scalar(1.0)
        * batch.counted.clone())
    .sum();
    let heat = (pos + neg).neg() / positives.clone();
    let l1 = |out: Tensor<4>, want: Tensor<4>| {
        ((out - want).abs() * batch.mask.clone()).sum() / positives.clone()
    };
    let size = l1(raw.size, batch.size.clone()).mul_scalar(0.1);
    let offset = l1(raw.offset, batch.offset.clone());
    let loss = heat + size + offset;
    match &batch.classes {
        Some(classes) => {
            let fabric = CrossEntropyLossConfig::new()
                .init(&raw.fabric.device())
                .forward(raw.fabric, classes.clone());
            loss + fabric
        }
        None => loss,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tiny_network_learns_tiny_rolls() {
        let opts = TrainOptions {
            rolls: 2,
            validation_rolls: 1,
            steps: 40,
            batch: 4,
            crop: 48,
            rate: 3e-3,
            seed: 3,
            widths: Widths([4, 8, 8, 8]),
            shape: RollShape {
                frames: 6,
                spacing_mm: 0.6,
                size: (64, 64),
                defects: 1,
            },
            style: Style::Standard,
            augment: true,
        };
        let (net, about, report) =
            train(&opts, None, "test", &rollfuse_io::progress::Silent).unwrap();
        assert_eq!(about.fabrics.len(), 17);
        // Too few images to calibrate familiarity: said, not faked.
        assert!(about.familiarity.is_none());
        let why = report.familiarity_missing.as_deref().unwrap_or_default();
        assert!(why.contains("at least"), "{why}");
        let l = &report.losses;
        assert!(l.iter().all(|v| v.is_finite()), "{l:?}");
        let first: f32 = l[..5].iter().sum::<f32>() / 5.0;
        let last: f32 = l[l.len() - 5..].iter().sum::<f32>() / 5.0;
        assert!(last < 0.7 * first, "loss {first} → {last}");
        // Continued for no steps on more rolls: the same network, measured and calibrated.
        let more = TrainOptions {
            rolls: 4,
            validation_rolls: 4,
            steps: 0,
            ..opts.clone()
        };
        let silent = &rollfuse_io::progress::Silent;
        let (_, again, measured) = train(&more, Some(net), "test", silent).unwrap();
        assert!(measured.losses.is_empty());
        assert!(again.familiarity.is_some(), "{measured:?}");
        assert!(
            measured.validation_unfamiliar.unwrap() < 0.1,
            "{measured:?}"
        );
        // A new network needs steps.
        assert!(train(&more, None, "test", silent).is_err());
    }
}
