//! Anomaly mode: what one fabric looks like, learned from defect-free images alone, and
//! where an image departs from it.
//!
//! - **Features.** An image is brought to zero median and unit spread (its median absolute
//!   deviation), so the light's gain and offset drop out, then split by the orthonormal
//!   Haar transform into [`LEVELS`] octaves of horizontal, vertical and diagonal detail.
//!   A cell of [`CELL`] × [`CELL`] pixels, one every [`STRIDE`] pixels, is described by
//!   the log energy of each detail band over its footprint and by its mean: texture at
//!   each scale and orientation, the same wherever a cell falls on a weave's repeat.
//! - **Model.** A Gaussian over those features for each row of cells when every training
//!   image has one height (a camera frame's rows differ: contact, focus, light), one for
//!   all rows otherwise (strips and fused tiles); its covariance is shrunk toward its
//!   diagonal so that a few images suffice.
//! - **Score.** A cell's squared Mahalanobis distance from its row's Gaussian, per
//!   feature. The threshold is calibrated on the training images themselves, each scored
//!   by a model fitted without it (in folds): the largest cell score any held-out clean
//!   image reached, times [`MARGIN`]. An image's `anomaly_score` is its largest cell score
//!   over that threshold: above 1 it holds an anomaly; the anomalous cells, grouped by
//!   adjacency, are its boxes.

use crate::image::Planes;
use anyhow::{Context, bail, ensure};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Haar octaves of detail described.
pub const LEVELS: usize = 4;
/// Side of a cell, pixels: a few repeats of the coarsest weave at 0.04 mm a pixel.
pub const CELL: usize = 32;
/// Distance between cells, pixels.
pub const STRIDE: usize = 8;
/// Features per cell: three detail bands per octave and the mean.
pub const DIM: usize = 3 * LEVELS + 1;
/// The fewest training images: fewer cannot tell a fabric's spread from chance.
pub const MIN_IMAGES: usize = 4;
/// The quantile of the held-out clean images' largest cell scores the threshold starts
/// from: one clean image in ten may reach it (a fabric's own irregularities).
pub const QUANTILE: f32 = 0.9;
/// The threshold over that quantile.
pub const MARGIN: f32 = 1.0;
/// A region grows from cells above the threshold into adjacent cells above this fraction
/// of it: one defect, one region.
pub const GROW: f32 = 0.6;
/// Weight of the diagonal in the shrunk covariance.
const SHRINK: f64 = 0.1;
/// Folds the threshold is calibrated in.
const FOLDS: usize = 4;
/// The model file's format.
const FORMAT: &str = "rollfuse-normal-1";

/// Every cell's features of one image: `rows × cols` cells of [`DIM`] values.
#[derive(Debug, Clone)]
pub struct Cells {
    /// Cell rows.
    pub rows: usize,
    /// Cell columns.
    pub cols: usize,
    /// Features, cell by cell, row-major.
    pub data: Vec<f32>,
}

impl Cells {
    /// The features of cell `(r, c)`.
    pub fn at(&self, r: usize, c: usize) -> &[f32] {
        let i = (r * self.cols + c) * DIM;
        &self.data[i..i + DIM]
    }
}

/// The gray image normalized to zero median and unit spread.
fn normalized(image: &Planes) -> Vec<f32> {
    let gray = image.gray();
    // Medians by selection, in linear time: sorting every pixel was the costliest step here.
    let middle = |mut v: Vec<f32>| {
        let half = v.len() / 2;
        *v.select_nth_unstable_by(half, f32::total_cmp).1
    };
    let median = middle(gray.to_vec());
    let spread = (1.4826 * middle(gray.iter().map(|v| (v - median).abs()).collect())).max(1e-3);
    gray.iter().map(|v| (v - median) / spread).collect()
}

/// One Haar octave of a `w × h` image (even sides used): the approximation and the
/// squared horizontal, vertical and diagonal details, each `w/2 × h/2`.
fn octave(x: &[f32], w: usize, h: usize) -> (Vec<f32>, [Vec<f32>; 3]) {
    let (hw, hh) = (w / 2, h / 2);
    let mut low = Vec::with_capacity(hw * hh);
    let mut bands = [
        Vec::with_capacity(hw * hh),
        Vec::with_capacity(hw * hh),
        Vec::with_capacity(hw * hh),
    ];
    for y in 0..hh {
        for i in 0..hw {
            let at = |dy: usize, dx: usize| x[(2 * y + dy) * w + 2 * i + dx];
            let (a, b, c, d) = (at(0, 0), at(0, 1), at(1, 0), at(1, 1));
            low.push(0.5 * (a + b + c + d));
            bands[0].push((0.5 * (a - b + c - d)).powi(2));
            bands[1].push((0.5 * (a + b - c - d)).powi(2));
            bands[2].push((0.5 * (a - b - c + d)).powi(2));
        }
    }
    (low, bands)
}

/// Integral image of `v` (`w × h`), `(w + 1) × (h + 1)`.
fn integral(v: &[f32], w: usize, h: usize) -> Vec<f64> {
    let mut s = vec![0f64; (w + 1) * (h + 1)];
    for y in 0..h {
        let mut run = 0f64;
        for x in 0..w {
            run += f64::from(v[y * w + x]);
            s[(y + 1) * (w + 1) + x + 1] = s[y * (w + 1) + x + 1] + run;
        }
    }
    s
}

/// The mean of `v` over the box `x0..x1 × y0..y1` from its integral `s` (width `w`).
fn box_mean(s: &[f64], w: usize, [x0, y0, x1, y1]: [usize; 4]) -> f32 {
    let at = |x: usize, y: usize| s[y * (w + 1) + x];
    let n = ((x1 - x0) * (y1 - y0)).max(1) as f64;
    ((at(x1, y1) - at(x0, y1) - at(x1, y0) + at(x0, y0)) / n) as f32
}

/// The cells of an image, or why it has none.
pub fn cells(image: &Planes) -> anyhow::Result<Cells> {
    let (w, h) = (image.width, image.height);
    ensure!(
        w >= CELL && h >= CELL,
        "the image is {w} × {h}: anomaly mode needs at least {CELL} × {CELL} pixels"
    );
    let (rows, cols) = ((h - CELL) / STRIDE + 1, (w - CELL) / STRIDE + 1);
    // Per level: its integral images (the three bands) and its size.
    let mut levels = Vec::with_capacity(LEVELS);
    let (mut x, mut lw, mut lh) = (normalized(image), w, h);
    let mean = integral(&x, w, h);
    for _ in 0..LEVELS {
        let (low, bands) = octave(&x, lw, lh);
        let (nw, nh) = (lw / 2, lh / 2);
        levels.push((bands.map(|b| integral(&b, nw, nh)), nw, nh));
        (x, lw, lh) = (low, nw, nh);
    }
    let mut data = Vec::with_capacity(rows * cols * DIM);
    for r in 0..rows {
        for c in 0..cols {
            let (x0, y0) = (c * STRIDE, r * STRIDE);
            for (k, (bands, lw, lh)) in levels.iter().enumerate() {
                let f = 2usize << k;
                // The cell's footprint at this octave, at least one coefficient.
                let bx0 = (x0 / f).min(lw.saturating_sub(1));
                let by0 = (y0 / f).min(lh.saturating_sub(1));
                let bx1 = ((x0 + CELL) / f).clamp(bx0 + 1, (*lw).max(bx0 + 1));
                let by1 = ((y0 + CELL) / f).clamp(by0 + 1, (*lh).max(by0 + 1));
                for band in bands {
                    data.push((box_mean(band, *lw, [bx0, by0, bx1, by1]) + 1e-4).ln());
                }
            }
            data.push(box_mean(&mean, w, [x0, y0, x0 + CELL, y0 + CELL]));
        }
    }
    Ok(Cells { rows, cols, data })
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

/// What anomaly mode says of one image.
#[derive(Debug, Clone, Serialize)]
pub struct Anomalies {
    /// The largest cell score over the threshold: above 1 the image holds an anomaly.
    pub anomaly_score: f32,
    /// The anomalous regions, largest score first.
    pub regions: Vec<Region>,
}

/// Gaussians for `cells` of every image: one per cell row when `per_row`.
fn fit_rows(cells: &[&Cells], per_row: bool) -> anyhow::Result<Vec<Gaussian>> {
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
            Gaussian::fit(&samples).context("the training images' features are degenerate")
        })
        .collect()
}

impl NormalModel {
    /// Learns `images` (defect-free, of one fabric at one scale). Refuses fewer than
    /// [`MIN_IMAGES`], and images of different widths.
    pub fn fit(images: &[Planes]) -> anyhow::Result<Self> {
        ensure!(
            images.len() >= MIN_IMAGES,
            "anomaly mode needs at least {MIN_IMAGES} defect-free images to learn a fabric \
             from, got {}",
            images.len()
        );
        let (width, height) = (images[0].width, images[0].height);
        if let Some(odd) = images.iter().find(|i| i.width != width) {
            bail!(
                "the training images differ in width ({} and {}): fit one camera's images",
                width,
                odd.width
            );
        }
        let per_row = images.iter().all(|i| i.height == height);
        let cells: Vec<Cells> = images.iter().map(cells).collect::<anyhow::Result<_>>()?;
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
        held_out.sort_by(f32::total_cmp);
        let typical = held_out[(QUANTILE * (held_out.len() - 1) as f32).round() as usize];
        Ok(Self {
            images: images.len(),
            ..Self::with_rows(rows, width, height, MARGIN * typical.max(1e-3))
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
    fn check(&self, image: &Planes) -> anyhow::Result<()> {
        ensure!(
            image.width == self.width,
            "the image is {} pixels wide; the normal model was fitted on images {} wide \
             (fit it on images from this camera, at this scale)",
            image.width,
            self.width
        );
        ensure!(
            self.rows.len() == 1 || image.height == self.height,
            "the image is {} rows high; the normal model learned each row of {}-row images",
            image.height,
            self.height
        );
        Ok(())
    }

    /// Scores `image` and boxes its anomalous regions.
    pub fn detect(&self, image: &Planes) -> anyhow::Result<Anomalies> {
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

    /// Reads a model written by [`Self::save`].
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read the normal model {}", path.display()))?;
        let model: Self = serde_json::from_str(&text)
            .with_context(|| format!("{} is not a normal model", path.display()))?;
        ensure!(
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
        ensure!(sound, "{} is a damaged normal model", path.display());
        Ok(model)
    }

    /// Writes the model whole or not at all.
    pub fn save(&self, path: &Path) -> anyhow::Result<()> {
        let json = serde_json::to_string(self)? + "\n";
        crate::files::write_bytes_atomic(path, json.as_bytes())
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
                (c1 * STRIDE + CELL) as f32,
                (r1 * STRIDE + CELL) as f32,
            ],
            score: best,
        });
    }
    out.sort_by(|a, b| b.score.total_cmp(&a.score));
    out
}
