//! Anomaly mode: what one fabric looks like, learned from defect-free images alone, and
//! where an image departs from it.
//!
//! - **Features** ([`super::cells`], [`ANOMALY`]): a cell of 48 × 48 pixels every 8,
//!   after the image's median and spread are taken out, described by the log energy of 4
//!   Haar octaves in 3 orientations, the darkest and brightest of the first 3 octaves'
//!   smoothed image and the mean; and the same features less the median of its cell
//!   row's, so that a change common to the row (a contact band narrowed by a tall defect
//!   elsewhere) is told from a local one.
//! - **Model.** A Gaussian over those features for each row of cells when every training
//!   image has one height (a camera frame's rows differ: contact, focus, light), one for
//!   all rows otherwise (strips and fused tiles); its covariance is shrunk toward its
//!   diagonal so that a few images suffice.
//! - **Score.** A cell's squared Mahalanobis distance from its row's Gaussian, per
//!   feature. The threshold is calibrated on the training images themselves, each scored
//!   by a model fitted without it (in folds): the largest cell score any held-out clean
//!   image reached. An image's `anomaly_score` is its largest cell score over that
//!   threshold: above 1 it holds an anomaly; the anomalous cells, grouped by adjacency,
//!   are its boxes.

use anyhow::Context;
use rollfuse_io::image::Planes;
use serde::{Deserialize, Serialize};
use std::path::Path;

use super::cells::{ANOMALY, Cells, STRIDE};

/// Features a cell: [`ANOMALY`]'s and the same less their cell row's median.
pub const DIM: usize = 2 * ANOMALY.dim();
/// The fewest training images: fewer cannot tell a fabric's spread from chance.
pub const MIN_IMAGES: usize = 4;
/// A region grows from cells above the threshold into adjacent cells above this fraction
/// of it: one defect, one region.
pub const GROW: f32 = 0.6;
/// Weight of the diagonal in the shrunk covariance.
const SHRINK: f64 = 0.1;
/// Folds the threshold is calibrated in.
const FOLDS: usize = 4;
/// The kind anomaly mode gives every region it reports.
pub const KIND: &str = "anomaly";
/// The model file's format.
const FORMAT: &str = "rollfuse-normal-2";

/// Anomaly mode's cells of an image.
fn cells(image: &Planes) -> crate::Result<Cells> {
    Ok(super::cells::cells(image, ANOMALY)?.with_row_relative())
}

/// A Gaussian over cell features: its mean and the inverse of its shrunk covariance.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Gaussian {
    /// Mean, [`DIM`] values.
    pub mean: Vec<f32>,
    /// Inverse covariance, `DIM × DIM`, row-major.
    pub precision: Vec<f32>,
}

impl Gaussian {
    /// Fitted on `samples` (each [`DIM`] values); `None` for fewer than two.
    fn fit(samples: &[&[f32]]) -> Option<Self> {
        let n = samples.len();
        if n < 2 {
            return None;
        }
        let mut mean = [0f64; DIM];
        for s in samples {
            for (m, &v) in mean.iter_mut().zip(*s) {
                *m += f64::from(v) / n as f64;
            }
        }
        let mut cov = vec![0f64; DIM * DIM];
        for s in samples {
            for i in 0..DIM {
                let di = f64::from(s[i]) - mean[i];
                for j in 0..DIM {
                    cov[i * DIM + j] += di * (f64::from(s[j]) - mean[j]) / (n - 1) as f64;
                }
            }
        }
        // Shrunk toward the diagonal, with a floor so a constant feature stays invertible.
        for i in 0..DIM {
            for j in 0..DIM {
                if i != j {
                    cov[i * DIM + j] *= 1.0 - SHRINK;
                }
            }
            cov[i * DIM + i] += 1e-3;
        }
        Some(Self {
            mean: mean.iter().map(|&m| m as f32).collect(),
            precision: inverse(cov)?.iter().map(|&v| v as f32).collect(),
        })
    }

    /// Squared Mahalanobis distance of `x`, per feature.
    fn distance(&self, x: &[f32]) -> f32 {
        let d: Vec<f32> = x.iter().zip(&self.mean).map(|(a, m)| a - m).collect();
        let mut sum = 0f32;
        for (i, di) in d.iter().enumerate() {
            let row = &self.precision[i * DIM..(i + 1) * DIM];
            sum += di * row.iter().zip(&d).map(|(p, dj)| p * dj).sum::<f32>();
        }
        sum.max(0.0) / DIM as f32
    }
}

/// Inverse of the symmetric positive definite `DIM × DIM` matrix `a` (Gauss–Jordan with
/// partial pivoting); `None` if it is singular.
fn inverse(mut a: Vec<f64>) -> Option<Vec<f64>> {
    let n = DIM;
    let mut inv = vec![0f64; n * n];
    for i in 0..n {
        inv[i * n + i] = 1.0;
    }
    for col in 0..n {
        let pivot =
            (col..n).max_by(|&p, &q| a[p * n + col].abs().total_cmp(&a[q * n + col].abs()))?;
        if a[pivot * n + col].abs() < 1e-12 {
            return None;
        }
        for k in 0..n {
            a.swap(col * n + k, pivot * n + k);
            inv.swap(col * n + k, pivot * n + k);
        }
        let p = a[col * n + col];
        for k in 0..n {
            a[col * n + k] /= p;
            inv[col * n + k] /= p;
        }
        for r in (0..n).filter(|&r| r != col) {
            let f = a[r * n + col];
            for k in 0..n {
                a[r * n + k] -= f * a[col * n + k];
                inv[r * n + k] -= f * inv[col * n + k];
            }
        }
    }
    Some(inv)
}

/// What one fabric looks like: the file `rollfuse fit-normal` writes.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct NormalModel {
    /// The file's format.
    pub format: String,
    /// Size of the images fitted on (the first one's), pixels.
    pub width: usize,
    /// See `width`.
    pub height: usize,
    /// Images fitted on.
    pub images: usize,
    /// One Gaussian per cell row (images of the training height), or one for all.
    pub rows: Vec<Gaussian>,
    /// Cell score at which a cell is anomalous.
    pub threshold: f32,
}

/// An anomalous region: a box in image pixels and its largest cell score over the
/// threshold.
#[derive(Debug, Clone, Serialize)]
pub struct Region {
    /// `[x0, y0, x1, y1]`, pixels.
    pub box_px: [f32; 4],
    /// Largest cell score in it over the model's threshold (above 1).
    pub score: f32,
}

impl super::Boxed for Anomalies {
    fn boxes_mut(&mut self) -> impl Iterator<Item = &mut [f32; 4]> {
        self.regions.iter_mut().map(|r| &mut r.box_px)
    }
}

/// What anomaly mode says of one image.
#[derive(Debug, Clone, Serialize)]
pub struct Anomalies {
    /// The largest cell score over the threshold: above 1 the image holds an anomaly.
    pub anomaly_score: f32,
    /// The anomalous regions, largest score first.
    pub regions: Vec<Region>,
}

/// Gaussians for `cells` of every image: one per cell row when `per_row`.
fn fit_rows(cells: &[&Cells], per_row: bool) -> crate::Result<Vec<Gaussian>> {
    let rows = if per_row { cells[0].rows } else { 1 };
    (0..rows)
        .map(|r| {
            let samples: Vec<&[f32]> = cells
                .iter()
                .flat_map(|c| {
                    let span = if per_row { r..r + 1 } else { 0..c.rows };
                    span.flat_map(move |rr| (0..c.cols).map(move |cc| c.at(rr, cc)))
                })
                .collect();
            Ok(Gaussian::fit(&samples).context("the training images' features are degenerate")?)
        })
        .collect()
}

impl NormalModel {
    /// Learns `images` (defect-free, of one fabric at one scale): each row of cells apart
    /// when they share one height (camera frames), every row alike otherwise. Refuses
    /// fewer than [`MIN_IMAGES`], and images of different widths.
    pub fn fit(images: &[Planes]) -> crate::Result<Self> {
        let one_height = images.windows(2).all(|p| p[0].height == p[1].height);
        Self::fit_rows_apart(images, one_height)
    }

    /// Learns `images` with every row of cells alike whatever their heights: a model for
    /// images of any height, such as the live strip's windows.
    pub fn fit_every_row_alike(images: &[Planes]) -> crate::Result<Self> {
        Self::fit_rows_apart(images, false)
    }

    fn fit_rows_apart(images: &[Planes], per_row: bool) -> crate::Result<Self> {
        rollfuse_io::require!(
            images.len() >= MIN_IMAGES,
            "anomaly mode needs at least {MIN_IMAGES} defect-free images to learn a fabric \
             from, got {}",
            images.len()
        );
        let (width, height) = (images[0].width, images[0].height);
        if let Some(odd) = images.iter().find(|i| i.width != width) {
            rollfuse_io::invalid!(
                "the training images differ in width ({} and {}): fit one camera's images",
                width,
                odd.width
            );
        }
        let cells: Vec<Cells> = images.iter().map(cells).collect::<crate::Result<_>>()?;
        let all: Vec<&Cells> = cells.iter().collect();
        let rows = fit_rows(&all, per_row)?;
        // Each image scored by a model that has not seen it.
        let folds = FOLDS.min(images.len());
        let mut held_out = Vec::with_capacity(images.len());
        for fold in 0..folds {
            let (held, kept): (Vec<_>, Vec<_>) =
                all.iter().enumerate().partition(|(i, _)| i % folds == fold);
            let kept: Vec<&Cells> = kept.into_iter().map(|(_, c)| *c).collect();
            let model = Self::with_rows(fit_rows(&kept, per_row)?, width, height, 1.0);
            held_out.extend(held.into_iter().map(|(_, c)| model.largest(c)));
        }
        let largest = held_out.into_iter().fold(0f32, f32::max);
        Ok(Self {
            images: images.len(),
            ..Self::with_rows(rows, width, height, largest.max(1e-3))
        })
    }

    fn with_rows(rows: Vec<Gaussian>, width: usize, height: usize, threshold: f32) -> Self {
        Self {
            format: FORMAT.to_string(),
            width,
            height,
            images: 0,
            rows,
            threshold,
        }
    }

    /// The Gaussian for cell row `r`.
    fn row(&self, r: usize) -> &Gaussian {
        &self.rows[r.min(self.rows.len() - 1)]
    }

    /// Every cell's score, row-major.
    fn scores(&self, c: &Cells) -> Vec<f32> {
        (0..c.rows)
            .flat_map(|r| (0..c.cols).map(move |cc| (r, cc)))
            .map(|(r, cc)| self.row(r).distance(c.at(r, cc)))
            .collect()
    }

    fn largest(&self, c: &Cells) -> f32 {
        self.scores(c).into_iter().fold(0f32, f32::max)
    }

    /// Whether `image` can be scored: its width is the training images', and so is its
    /// height where the model has a Gaussian per cell row.
    fn check(&self, image: &Planes) -> crate::Result<()> {
        rollfuse_io::require!(
            image.width == self.width,
            "the image is {} pixels wide; the normal model was fitted on images {} wide \
             (fit it on images from this camera, at this scale)",
            image.width,
            self.width
        );
        rollfuse_io::require!(
            self.rows.len() == 1 || image.height == self.height,
            "the image is {} rows high; the normal model learned each row of {}-row images",
            image.height,
            self.height
        );
        Ok(())
    }

    /// Scores `image` and boxes its anomalous regions.
    pub fn detect(&self, image: &Planes) -> crate::Result<Anomalies> {
        self.check(image)?;
        let c = cells(image)?;
        let scores: Vec<f32> = self
            .scores(&c)
            .into_iter()
            .map(|s| s / self.threshold)
            .collect();
        let anomaly_score = scores.iter().copied().fold(0f32, f32::max);
        Ok(Anomalies {
            anomaly_score,
            regions: regions(&scores, c.rows, c.cols),
        })
    }

    /// Scores `image` taken at `1/d` of the model's scale (a device strip downsampled by
    /// `d`): upsampled first, its boxes given in its own pixels.
    pub fn detect_at_scale(&self, image: &Planes, d: usize) -> crate::Result<Anomalies> {
        super::at_camera_scale(image, d, |i| self.detect(i))
    }

    /// Whether the model scores images of any height (every row of cells alike).
    pub fn any_height(&self) -> bool {
        self.rows.len() == 1
    }

    /// Reads a model written by [`Self::save`].
    pub fn load(path: &Path) -> crate::Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read the normal model {}", path.display()))?;
        let model: Self = serde_json::from_str(&text)
            .with_context(|| format!("{} is not a normal model", path.display()))?;
        rollfuse_io::require!(
            model.format == FORMAT,
            "{} is a normal model of format `{}`; this tool reads `{FORMAT}`",
            path.display(),
            model.format
        );
        let sound = !model.rows.is_empty()
            && model.threshold > 0.0
            && model
                .rows
                .iter()
                .all(|g| g.mean.len() == DIM && g.precision.len() == DIM * DIM);
        rollfuse_io::require!(sound, "{} is a damaged normal model", path.display());
        Ok(model)
    }

    /// Writes the model whole or not at all.
    pub fn save(&self, path: &Path) -> crate::Result<()> {
        let json = serde_json::to_string(self)? + "\n";
        Ok(rollfuse_io::files::write_bytes_atomic(
            path,
            json.as_bytes(),
        )?)
    }
}

/// Boxes around the cells scoring above 1 and the adjacent cells above [`GROW`] they
/// reach, largest score first.
fn regions(scores: &[f32], rows: usize, cols: usize) -> Vec<Region> {
    let mut seen = vec![false; scores.len()];
    let mut out = Vec::new();
    for start in 0..scores.len() {
        if seen[start] || scores[start] <= 1.0 {
            continue;
        }
        let (mut stack, mut bounds, mut best) = (vec![start], [usize::MAX, usize::MAX, 0, 0], 0f32);
        seen[start] = true;
        while let Some(i) = stack.pop() {
            let (r, c) = (i / cols, i % cols);
            best = best.max(scores[i]);
            bounds = [
                bounds[0].min(c),
                bounds[1].min(r),
                bounds[2].max(c),
                bounds[3].max(r),
            ];
            for (dr, dc) in [
                (-1, -1),
                (-1, 0),
                (-1, 1),
                (0, -1),
                (0, 1),
                (1, -1),
                (1, 0),
                (1, 1),
            ] {
                let (nr, nc) = (r as isize + dr, c as isize + dc);
                if nr < 0 || nc < 0 || nr >= rows as isize || nc >= cols as isize {
                    continue;
                }
                let j = nr as usize * cols + nc as usize;
                if !seen[j] && scores[j] > GROW {
                    seen[j] = true;
                    stack.push(j);
                }
            }
        }
        let [c0, r0, c1, r1] = bounds;
        out.push(Region {
            box_px: [
                (c0 * STRIDE) as f32,
                (r0 * STRIDE) as f32,
                (c1 * STRIDE + ANOMALY.cell) as f32,
                (r1 * STRIDE + ANOMALY.cell) as f32,
            ],
            score: best,
        });
    }
    out.sort_by(|a, b| b.score.total_cmp(&a.score));
    out
}
