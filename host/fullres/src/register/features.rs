//! What a frame is matched by: its residual (the frame minus the frame-fixed background)
//! over the band of rows where moving features are visible, in groups of a few columns.

use crate::contact::ContactProfile;

/// Rows with at least this visibility are matched.
const MIN_VISIBILITY: f32 = 0.25;
/// The fewest rows a band may have.
pub const MIN_BAND_ROWS: usize = 12;
/// The most rows a band may have: where the whole frame is in contact, the rows nearest
/// the apex are enough to match by, and the cost grows with every row.
pub const MAX_BAND_ROWS: usize = 128;
/// Columns a frame is cut into at most: wider frames average neighbouring columns.
const MAX_GROUPS: usize = 80;
/// How far the background follows a frame, gray levels a frame: slow enough that a
/// feature passing in a few frames does not enter it, fast enough for lighting drift.
const BACKGROUND_RATE: f32 = 0.25;
/// Width (standard deviation, a fraction of the band) of the weight given to belt rows
/// by how evenly their two views straddle the apex.
const EVEN_WIDTH: f32 = 0.5;

/// The rows a frame is matched over and their visibility.
#[derive(Debug, Clone, PartialEq)]
pub struct Band {
    /// First frame row.
    pub top: usize,
    /// Visibility of each row from `top` on (its length is the band's height).
    pub weights: Vec<f32>,
}

impl Band {
    /// The run of rows around the most visible one whose visibility reaches
    /// [`MIN_VISIBILITY`], widened to [`MIN_BAND_ROWS`] (as far as the frame allows) and
    /// narrowed to the [`MAX_BAND_ROWS`] most visible.
    pub fn of(visibility: &[f32]) -> Self {
        let h = visibility.len();
        let peak = visibility
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .map_or(0, |(i, _)| i);
        let (mut top, mut end) = (peak, (peak + 1).min(h));
        while top > 0 && visibility[top - 1] >= MIN_VISIBILITY {
            top -= 1;
        }
        while end < h && visibility[end] >= MIN_VISIBILITY {
            end += 1;
        }
        while end - top < MIN_BAND_ROWS.min(h) {
            top = top.saturating_sub(1);
            if end - top < MIN_BAND_ROWS.min(h) && end < h {
                end += 1;
            }
        }
        // Narrowed toward the centroid of visibility (the middle, where it is even).
        let mass: f32 = visibility[top..end].iter().map(|v| v * v).sum();
        let centre = (top..end)
            .map(|y| y as f32 * visibility[y] * visibility[y])
            .sum::<f32>()
            / mass.max(f32::MIN_POSITIVE);
        while end - top > MAX_BAND_ROWS {
            if centre - top as f32 > (end - 1) as f32 - centre {
                top += 1;
            } else {
                end -= 1;
            }
        }
        Self {
            top,
            weights: visibility[top..end]
                .iter()
                .map(|&v| v.max(MIN_VISIBILITY))
                .collect(),
        }
    }

    /// Rows in the band.
    pub fn rows(&self) -> usize {
        self.weights.len()
    }

    /// The band row where features are most visible (the apex).
    pub fn apex(&self) -> usize {
        self.weights
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .map_or(0, |(i, _)| i)
    }

    /// The weight of a belt row by how evenly its two views straddle the apex, given the
    /// band row midway between them: a Gaussian of [`EVEN_WIDTH`] of the band around
    /// the apex. Where the views straddle it evenly, the contrast profile pulls neither
    /// way; toward the band's ends a feature is cut off where the gel lifts from it.
    pub fn evenness(&self) -> impl Fn(f32) -> f32 + use<> {
        let (apex, tau) = (self.apex() as f32, EVEN_WIDTH * self.rows() as f32);
        move |mid: f32| (-((mid - apex) / tau).powi(2)).exp()
    }
}

/// A frame's residual over the band: `band rows × groups`, and how much it holds above
/// the noise.
#[derive(Debug, Clone)]
pub struct Features {
    /// Residual gray levels, row-major.
    pub data: Vec<f32>,
    /// Mean square of the residual weighted by visibility and by closeness to the apex
    /// (as matches weigh rows), in units of the noise's.
    pub content: f32,
}

/// Makes [`Features`] from frames, keeping the background up to date.
#[derive(Debug, Clone)]
pub struct Featurizer {
    width: usize,
    group: usize,
    groups: usize,
    band: Band,
    /// The band's background in groups: `band rows × groups`.
    background: Vec<f32>,
    /// Variance of the noise in one group's mean.
    noise_var: f32,
}

impl Featurizer {
    /// A featurizer for frames of the profile's size, starting from its background.
    pub fn new(profile: &ContactProfile) -> Self {
        let width = profile.width.max(1);
        let group = width.div_ceil(MAX_GROUPS).max(1);
        let groups = (width / group).max(1);
        let band = Band::of(&profile.visibility);
        let mut me = Self {
            width,
            group,
            groups,
            band,
            background: Vec::new(),
            noise_var: profile.noise * profile.noise / group as f32,
        };
        me.background = me.grouped(&profile.background);
        me
    }

    /// The band matched over.
    pub fn band(&self) -> &Band {
        &self.band
    }

    /// Column groups per row.
    pub fn groups(&self) -> usize {
        self.groups
    }

    /// Columns averaged into a group.
    pub fn group_width(&self) -> usize {
        self.group
    }

    /// The band rows of `gray` (a whole frame) in column groups.
    fn grouped(&self, gray: &[f32]) -> Vec<f32> {
        let (w, g, n) = (self.width, self.group, self.groups);
        let mut out = Vec::with_capacity(self.band.rows() * n);
        for y in self.band.top..self.band.top + self.band.rows() {
            let row = gray.get(y * w..(y + 1) * w).unwrap_or(&[]);
            out.extend(
                row.chunks_exact(g)
                    .take(n)
                    .map(|c| c.iter().sum::<f32>() / g as f32),
            );
            out.resize((y + 1 - self.band.top) * n, 0.0);
        }
        out
    }

    /// The features of `gray` (a whole frame, `width ×` the profile's height); the
    /// background moves toward the frame by at most [`BACKGROUND_RATE`].
    pub fn features(&mut self, gray: &[f32]) -> Features {
        let mut data = self.grouped(gray);
        for (v, b) in data.iter_mut().zip(self.background.iter_mut()) {
            let residual = *v - *b;
            *b += BACKGROUND_RATE * residual.signum().min(residual.abs());
            *v = residual;
        }
        // Weighted as the matches weigh rows: texture only at the band's ends, which no
        // match can use, is not texture to match.
        let evenness = self.band.evenness();
        let (mut sum, mut weights) = (0f64, 0f64);
        let rows = data.chunks_exact(self.groups).zip(&self.band.weights);
        for (r, (row, &w)) in rows.enumerate() {
            let w2 = f64::from((w * evenness(r as f32)).powi(2));
            let mean_square = row.iter().map(|&v| f64::from(v * v)).sum::<f64>() / row.len() as f64;
            sum += w2 * mean_square;
            weights += w2;
        }
        let mean_square = if weights > 0.0 { sum / weights } else { 0.0 };
        Features {
            data,
            content: (mean_square / f64::from(self.noise_var.max(1e-6))) as f32,
        }
    }
}
