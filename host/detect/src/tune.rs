//! Fine-tuning: the detector adapted to the user's own labelled images
//! (`rollfuse train --images DIR --labels COCO.json`).
//!
//! The images are split into training and validation at random (seeded); the network —
//! the built-in model or another — is trained further on crops of the training images
//! with the detector's own losses, the fabric's left out (the user's images name no
//! fabric), at a lower rate than training from scratch. The validation images are
//! measured before and after, kind-aware at IoU ≥ [`MIN_IOU`], so the user sees what
//! the fine-tuning bought. The model keeps its familiarity statistics: cloth unlike the
//! simulator's is still reported as an unknown fabric, and its defects are those the
//! user's labels taught.

use super::data::{Sample, Source};
use super::labels::LabelledImage;
use super::model::About;
use super::net::Net;
use super::targets::{MIN_IOU, Tally, tally};
use super::train::{Batch, Crop, MAX_BATCH, MAX_STEPS, Schedule, crop, optimize};
use super::{Detector, MIN_SIDE};
use burn::module::Module;
use burn::tensor::Device;
use rand::seq::SliceRandom;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;
use rollfuse_io::progress::Progress;

/// How to fine-tune.
#[derive(Debug, Clone)]
pub struct TuneOptions {
    /// Optimizer steps.
    pub steps: usize,
    /// Crops a step.
    pub batch: usize,
    /// Largest crop side, pixels (smaller images take smaller crops).
    pub crop: usize,
    /// Peak learning rate.
    pub rate: f64,
    /// Seed of the split and the crops.
    pub seed: u64,
    /// Share of the images held out for validation (0: none).
    pub validation: f64,
}

impl Default for TuneOptions {
    fn default() -> Self {
        Self {
            steps: 400,
            batch: 8,
            crop: 128,
            rate: 2e-3,
            seed: 1,
            validation: 0.2,
        }
    }
}

/// What fine-tuning measured.
#[derive(Debug, Clone, serde::Serialize)]
pub struct TuneReport {
    /// Loss of each step.
    pub losses: Vec<f32>,
    /// Images trained on.
    pub trained_on: usize,
    /// Images held out.
    pub validated_on: usize,
    /// The starting model on the validation images (none without them).
    pub before: Option<Tally>,
    /// The fine-tuned model on them.
    pub after: Option<Tally>,
}

/// Trains `start` further on `images` (see the module's docs); returns the network, its
/// description (`made_by` recorded) and what was measured. `progress` sees the steps.
pub fn tune(
    start: (Net, About),
    images: Vec<LabelledImage>,
    opts: &TuneOptions,
    made_by: &str,
    progress: &dyn Progress,
) -> crate::Result<(Net, About, TuneReport)> {
    rollfuse_io::require!(
        (0.0..0.9).contains(&opts.validation),
        "the validation share must be in 0..0.9, got {}",
        opts.validation
    );
    rollfuse_io::require!(
        opts.steps > 0 && opts.batch > 0,
        "fine-tuning needs steps and crops"
    );
    rollfuse_io::require!(opts.batch <= MAX_BATCH, "at most {MAX_BATCH} crops a step");
    rollfuse_io::require!(opts.steps <= MAX_STEPS, "at most {MAX_STEPS} steps");
    let (training, validation) = split(images, opts);
    rollfuse_io::require!(
        training.iter().any(|s| !s.boxes.is_empty()),
        "none of the {} training images has a labelled defect: nothing to learn from",
        training.len()
    );
    let side = crop_side(&training, opts.crop);
    let (net, mut about) = start;
    // The start's own threshold was chosen for the cloth it learned; the tuned model, and
    // its measures before and after, use the default unless told otherwise.
    about.threshold = None;
    let before = measure(&net, &about, &validation)?;
    let device = Device::flex().autodiff();
    device.seed(opts.seed);
    let schedule = Schedule {
        steps: opts.steps,
        rate: opts.rate,
    };
    let (net, losses) = optimize(
        net.to_device(&device),
        &schedule,
        opts.seed,
        progress,
        |rng| {
            let crops: Vec<Crop> = (0..opts.batch)
                .map(|_| {
                    let s = &training[rng.random_range(0..training.len())];
                    crop(s, side, false, rng).without_fabric()
                })
                .collect();
            Batch::new(&crops, &device)
        },
    )?;
    let net = net.to_device(&Device::flex());
    let after = measure(&net, &about, &validation)?;
    about.made_by = made_by.to_string();
    let report = TuneReport {
        losses,
        trained_on: training.len(),
        validated_on: validation.len(),
        before,
        after,
    };
    Ok((net, about, report))
}

/// The images as samples, split at random into training and validation.
fn split(images: Vec<LabelledImage>, opts: &TuneOptions) -> (Vec<Sample>, Vec<Sample>) {
    let mut samples: Vec<Sample> = images
        .into_iter()
        .map(|i| Sample {
            image: i.image,
            // Not used: the crops drop the fabric.
            class: 0,
            boxes: i.boxes,
            blurred: Vec::new(),
            source: Source::Fused,
        })
        .collect();
    samples.shuffle(&mut Pcg64Mcg::seed_from_u64(opts.seed));
    let n = samples.len();
    let held = ((n as f64 * opts.validation).round() as usize).min(n.saturating_sub(1));
    let validation = samples.split_off(n - held);
    (samples, validation)
}

/// The crop side: `largest`, or the smallest image's side if less, a multiple of 8.
fn crop_side(images: &[Sample], largest: usize) -> usize {
    let smallest = images
        .iter()
        .map(|s| s.image.width.min(s.image.height))
        .min()
        .unwrap_or(MIN_SIDE);
    (smallest.min(largest) / 8 * 8).max(MIN_SIDE)
}

/// Kind-aware hits, false alarms and misses of the network on `images`.
fn measure(net: &Net, about: &About, images: &[Sample]) -> crate::Result<Option<Tally>> {
    if images.is_empty() {
        return Ok(None);
    }
    let detector = Detector::from_net(net.clone(), about.clone());
    let mut t = Tally::default();
    for s in images {
        t.add(tally(
            &detector.detect(&s.image)?.defects,
            &s.boxes,
            MIN_IOU,
        ));
    }
    Ok(Some(t))
}
