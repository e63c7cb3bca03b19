//! Fabric defect detection and classification (the paper's §IV.B): a CenterNet-style
//! detector for holes, snags and slubs with a fabric classifier beside it, trained on the
//! simulator's textiles. `docs/detect.md` has the network, the data, the measured figures
//! and why it is built on burn.
//!
//! - [`targets`]: boxes to heatmaps and back, matching against the truth (plain Rust).
//! - [`net`]: the network.
//! - [`model`]: the model file.
//! - [`data`]: training and evaluation images from simulated rolls.
//! - [`draw`]: boxes drawn on the image.
//! - [`train`]: the training loop.
//! - [`labels`], [`tune`]: the user's labelled images (COCO), and fine-tuning on them.
//!
//! Every fallible function returns [`Error`]: a file that could not be read or written
//! (an I/O error among its causes) told apart from input the detector cannot take.

pub mod anomaly;
pub mod augment;
pub mod cells;
pub mod data;
pub mod draw;
mod error;
pub mod familiar;
pub mod labels;
pub mod model;
pub mod net;
pub mod targets;
pub mod train;
pub mod tune;

use anyhow::Context;
use burn::tensor::{Device, Tensor, TensorData, activation};
pub use error::{Error, Result};
use rollfuse_io::image::Planes;
use serde::Serialize;
use std::path::Path;
pub use targets::Found;

/// Smallest image side the detector takes, pixels.
pub const MIN_SIDE: usize = 32;
/// Rows run through the network at once; longer images (strips) go in overlapping tiles.
pub const TILE_ROWS: usize = 480;
/// Rows tiles overlap by: a defect is reported by the tile whose own part holds its centre.
pub const TILE_OVERLAP: usize = 64;
pub use model::{DEFAULT_THRESHOLD, check_threshold};
/// The fabric reported for an image unlike every fabric the model knows.
pub const UNKNOWN_FABRIC: &str = "unknown";
/// Most detections reported per tile.
const MAX_PER_TILE: usize = 100;

/// What the detector finds in one image.
#[derive(Debug, Clone, Serialize)]
pub struct Detection {
    /// The most probable fabric, or [`UNKNOWN_FABRIC`] when the image is unlike every
    /// fabric the model knows (`unfamiliarity` above 1).
    pub fabric: String,
    /// The fabric the classifier finds most probable, known or not.
    pub most_like: String,
    /// Its probability.
    pub probability: f32,
    /// How unlike the model's training cloth the image is, over the calibrated limit
    /// ([`familiar`]); none when the model carries no familiarity statistics.
    pub unfamiliarity: Option<f64>,
    /// Every class's probability, in the model's label order (written by name, not here).
    #[serde(skip)]
    pub probabilities: Vec<f32>,
    /// Defects, best first.
    pub defects: Vec<Found>,
}

/// A loaded detector.
pub struct Detector {
    net: net::Net,
    about: model::About,
    /// Heatmap score a detection needs (the model's own by default).
    pub threshold: f32,
}

impl Detector {
    /// Loads a model file (see [`model`]).
    pub fn load(path: &Path) -> crate::Result<Self> {
        let (net, about) = model::load(path)?;
        Ok(Self::from_net(net, about))
    }

    /// The model built into the tool.
    pub fn built_in() -> crate::Result<Self> {
        let (net, about) = model::built_in()?;
        Ok(Self::from_net(net, about))
    }

    /// The model at `path`, or the built-in one without a path.
    pub fn load_or_built_in(path: Option<&Path>) -> crate::Result<Self> {
        match path {
            Some(path) => Self::load(path),
            None => Self::built_in(),
        }
    }

    /// Wraps a network already in memory (training's validation).
    pub fn from_net(net: net::Net, about: model::About) -> Self {
        Self {
            net,
            threshold: about.threshold.unwrap_or(DEFAULT_THRESHOLD),
            about,
        }
    }

    /// What the model file says about itself.
    pub fn about(&self) -> &model::About {
        &self.about
    }

    /// Detects defects and classifies the fabric in a gray image of any length: images
    /// longer than [`TILE_ROWS`] are run in overlapping tiles, the fabric's probabilities
    /// averaged over them by rows. Boxes are clipped to the image.
    pub fn detect(&self, image: &Planes) -> crate::Result<Detection> {
        check_input(image)?;
        let (w, h) = (image.width, image.height);
        let classes = self.about.fabrics.len();
        let mut mean = vec![0f32; classes];
        let mut defects = Vec::new();
        for (top, own) in tiles(h) {
            let rows = (h - top).min(TILE_ROWS);
            let tile = &image.planes[0][top * w..(top + rows) * w];
            let out = self.run(tile, w, rows)?;
            let share = (own.end - own.start) as f32 / h as f32;
            for (m, p) in mean.iter_mut().zip(&out.probabilities) {
                *m += p * share;
            }
            defects.extend(out.found.into_iter().filter_map(|mut f| {
                let centre = (f.box_px[1] + f.box_px[3]) / 2.0 + top as f32;
                let (wf, hf) = (w as f32, h as f32);
                let [x0, y0, x1, y1] = f.box_px;
                let (y0, y1) = (y0 + top as f32, y1 + top as f32);
                f.box_px = [
                    x0.clamp(0.0, wf),
                    y0.clamp(0.0, hf),
                    x1.clamp(0.0, wf),
                    y1.clamp(0.0, hf),
                ];
                own.contains(&(centre.max(0.0) as usize)).then_some(f)
            }));
        }
        rollfuse_io::require!(
            mean.iter().all(|p| p.is_finite()),
            "the model's outputs are not finite numbers (a damaged model?)"
        );
        defects.sort_by(|a, b| b.score.total_cmp(&a.score));
        let (class, probability) = mean
            .iter()
            .copied()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .context("the model has no classes")?;
        let verdict = match &self.about.familiarity {
            Some(f) => Some(f.judge(&familiar::Places::of(image)?)?),
            None => None,
        };
        let most_like = self.about.fabrics[class].clone();
        Ok(Detection {
            fabric: if verdict.is_some_and(|v| v.unfamiliar()) {
                UNKNOWN_FABRIC.to_string()
            } else {
                most_like.clone()
            },
            most_like,
            probability,
            unfamiliarity: verdict.map(|v| v.unfamiliarity),
            probabilities: mean,
            defects,
        })
    }

    /// [`Self::detect`] on `image` upsampled `d`× (a strip downsampled on the device,
    /// brought back to the camera's scale the model knows), boxes scaled back to the
    /// image's own pixels. Images that are not gray go to the detector as they are, to be
    /// refused.
    pub fn detect_at_scale(&self, image: &Planes, d: usize) -> crate::Result<Detection> {
        at_camera_scale(image, d, |i| self.detect(i))
    }

    /// One tile through the network.
    fn run(&self, pixels: &[f32], w: usize, h: usize) -> crate::Result<TileOutput> {
        let data = TensorData::new(normalized(pixels), [1, 1, h, w]);
        let x = Tensor::<4>::from_data(data, &Device::flex());
        let raw = self.net.forward(x);
        let probabilities = floats(activation::softmax(raw.fabric, 1))?;
        let heat = floats(activation::sigmoid(raw.heat))?;
        let size = floats(raw.size)?;
        let offset = floats(raw.offset)?;
        let out = targets::Outputs {
            cells: targets::cells(w, h),
            heat: &heat,
            size: &size,
            offset: &offset,
        };
        Ok(TileOutput {
            probabilities,
            found: targets::decode(&out, self.threshold, MAX_PER_TILE),
        })
    }
}

/// What one tile gives.
struct TileOutput {
    /// Fabric probabilities.
    probabilities: Vec<f32>,
    /// Decoded boxes.
    found: Vec<Found>,
}

/// Whether the detector takes `image`: gray, at least [`MIN_SIDE`] on each side.
pub fn check_input(image: &Planes) -> crate::Result<()> {
    rollfuse_io::require!(
        image.planes.len() == 1,
        "the detector takes gray images, this one has {} channels",
        image.planes.len()
    );
    let (w, h) = (image.width, image.height);
    rollfuse_io::require!(
        w >= MIN_SIDE && h >= MIN_SIDE,
        "the image is {w}×{h}, smaller than the detector's {MIN_SIDE}×{MIN_SIDE}"
    );
    Ok(())
}

/// A tensor's values, row-major.
pub fn floats<const N: usize>(t: Tensor<N>) -> crate::Result<Vec<f32>> {
    t.into_data()
        .try_to_vec::<f32>()
        .map_err(|e| anyhow::anyhow!("cannot read the network's output: {e:?}").into())
}

/// Tiles of an image `h` rows long: each tile's first row and the rows it answers for
/// (its own part; together they cover `0..h` once).
pub fn tiles(h: usize) -> Vec<(usize, std::ops::Range<usize>)> {
    if h <= TILE_ROWS {
        return vec![(0, 0..h)];
    }
    let step = TILE_ROWS - TILE_OVERLAP;
    let mut tops: Vec<usize> = (0..)
        .map(|k| k * step)
        .take_while(|&t| t + TILE_ROWS < h)
        .collect();
    tops.push(h - TILE_ROWS);
    // Neighbours hand over in the middle of their overlap.
    let cuts: Vec<usize> = std::iter::once(0)
        .chain(tops.windows(2).map(|p| (p[0] + TILE_ROWS + p[1]) / 2))
        .chain(std::iter::once(h))
        .collect();
    tops.iter()
        .zip(cuts.windows(2))
        .map(|(&top, c)| (top, c[0]..c[1]))
        .collect()
}

/// An image standardized to zero mean and unit spread (the spread at least 1 gray level):
/// lighting and gain differ between frames and fused strips; texture is what counts.
pub fn normalized(pixels: &[f32]) -> Vec<f32> {
    let n = pixels.len().max(1) as f64;
    let mean = pixels.iter().map(|&p| f64::from(p)).sum::<f64>() / n;
    let var = pixels
        .iter()
        .map(|&p| (f64::from(p) - mean).powi(2))
        .sum::<f64>()
        / n;
    let scale = 1.0 / var.sqrt().max(1.0);
    pixels
        .iter()
        .map(|&p| ((f64::from(p) - mean) * scale) as f32)
        .collect()
}

/// A finding with boxes in image pixels.
pub trait Boxed {
    /// Every box, `[x0, y0, x1, y1]` in pixels.
    fn boxes_mut(&mut self) -> impl Iterator<Item = &mut [f32; 4]>;
}

impl Boxed for Detection {
    fn boxes_mut(&mut self) -> impl Iterator<Item = &mut [f32; 4]> {
        self.defects.iter_mut().map(|f| &mut f.box_px)
    }
}

/// `run` on `image` upsampled `d`× (a strip downsampled on the device, brought back to
/// the camera's scale a model knows), its boxes scaled back to the image's own pixels.
/// Images that are not gray go to `run` as they are, to be refused.
pub fn at_camera_scale<T: Boxed>(
    image: &Planes,
    d: usize,
    run: impl FnOnce(&Planes) -> crate::Result<T>,
) -> crate::Result<T> {
    if d <= 1 || image.planes.len() != 1 {
        return run(image);
    }
    let mut found = run(&image.upsampled(d))?;
    for b in found.boxes_mut() {
        *b = b.map(|v| v / d as f32);
    }
    Ok(found)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_cover_every_row_once() {
        for h in [32, 480, 481, 500, 900, 1000, 4321] {
            let t = tiles(h);
            let mut next = 0;
            for (top, own) in &t {
                assert_eq!(own.start, next, "h {h}: {t:?}");
                assert!(
                    *top <= own.start && own.end <= top + TILE_ROWS.min(h),
                    "{h}: {t:?}"
                );
                assert!(top + TILE_ROWS.min(h) <= h);
                next = own.end;
            }
            assert_eq!(next, h, "{t:?}");
        }
    }

    #[test]
    fn normalized_has_zero_mean_unit_spread() {
        let v: Vec<f32> = (0..100).map(|k| (k % 7) as f32 * 10.0 + 50.0).collect();
        let n = normalized(&v);
        let mean: f32 = n.iter().sum::<f32>() / 100.0;
        let var: f32 = n.iter().map(|x| (x - mean).powi(2)).sum::<f32>() / 100.0;
        assert!(mean.abs() < 1e-5 && (var - 1.0).abs() < 1e-4);
        assert!(normalized(&[5.0; 10]).iter().all(|&x| x == 0.0));
    }
}
