//! Texture cells: what each place of an image looks like, in numbers that a light's gain
//! and offset do not change.
//!
//! An image is brought to zero median and unit spread (its median absolute deviation),
//! then split by the orthonormal Haar transform into [`LEVELS`] octaves of horizontal,
//! vertical and diagonal detail. A square cell, one every [`STRIDE`] pixels, is described
//! by the log energy of each detail band over its footprint — texture at each scale and
//! orientation, the same wherever a cell falls on a weave's repeat — optionally by the
//! darkest and brightest value of the first octaves' smoothed image over it (a hole or a
//! slub is darker or brighter than any yarn, though its energy may be a yarn's), and by
//! its mean.
//!
//! Two descriptions are used: [`TEXTURE`] tells one fabric from another (the detector's
//! [`super::familiar`] statistics), [`ANOMALY`] one fabric's defects from its clean cloth
//! (anomaly mode).

/// Haar octaves of detail described.
pub const LEVELS: usize = 4;
/// Distance between cells, pixels.
pub const STRIDE: usize = 8;

/// How the cells of an image are described.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Describe {
    /// Side of a cell, pixels.
    pub cell: usize,
    /// The first octaves whose smoothed image's extremes over the cell are features.
    pub extremes: usize,
}

/// Cells of 32 pixels, energies and mean: 13 features (the detector's familiarity).
pub const TEXTURE: Describe = Describe {
    cell: 32,
    extremes: 0,
};

/// Cells of 48 pixels with the extremes of 3 octaves: 19 features. Measured on the
/// simulator's twill, plain weave, jersey, satin and rib knit (docs/detect.md).
pub const ANOMALY: Describe = Describe {
    cell: 48,
    extremes: 3,
};

impl Describe {
    /// Features a cell: three detail bands an octave, two extremes an octave so described,
    /// and the mean.
    pub const fn dim(&self) -> usize {
        3 * LEVELS + 2 * self.extremes + 1
    }
}

/// Every cell's features of one image: `rows × cols` cells of `dim` values.
#[derive(Debug, Clone)]
pub struct Cells {
    /// Cell rows.
    pub rows: usize,
    /// Cell columns.
    pub cols: usize,
    /// Features a cell.
    pub dim: usize,
    /// Features, cell by cell, row-major.
    pub data: Vec<f32>,
}

impl Cells {
    /// The features of cell `(r, c)`.
    pub fn at(&self, r: usize, c: usize) -> &[f32] {
        let i = (r * self.cols + c) * self.dim;
        &self.data[i..i + self.dim]
    }

    /// Each cell's features followed by their difference from the median of its cell
    /// row's: what is left when a change common to the whole row — a contact band that
    /// narrows as a tall defect lifts the roller, a light that dims — is taken out.
    pub fn with_row_relative(self) -> Self {
        let dim = 2 * self.dim;
        let mut data = Vec::with_capacity(self.rows * self.cols * dim);
        let mut column = Vec::with_capacity(self.cols);
        for r in 0..self.rows {
            let medians: Vec<f32> = (0..self.dim)
                .map(|k| {
                    column.clear();
                    column.extend((0..self.cols).map(|c| self.at(r, c)[k]));
                    median(&mut column)
                })
                .collect();
            for c in 0..self.cols {
                let own = self.at(r, c);
                data.extend_from_slice(own);
                data.extend(own.iter().zip(&medians).map(|(v, m)| v - m));
            }
        }
        Self { dim, data, ..self }
    }
}

/// The median of `v` (the upper one of an even count), by selection in linear time.
fn median(v: &mut [f32]) -> f32 {
    let half = v.len() / 2;
    *v.select_nth_unstable_by(half, f32::total_cmp).1
}

/// The gray image normalized to zero median and unit spread.
fn normalized(image: &rollfuse_io::image::Planes) -> Vec<f32> {
    let gray = image.gray();
    // Medians by selection: sorting every pixel was the costliest step here.
    let median_of = |mut v: Vec<f32>| median(&mut v);
    let middle = median_of(gray.to_vec());
    let spread = (1.4826 * median_of(gray.iter().map(|v| (v - middle).abs()).collect())).max(1e-3);
    gray.iter().map(|v| (v - middle) / spread).collect()
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

/// The least and largest of `v` (width `w`) over the box `x0..x1 × y0..y1`.
fn box_extremes(v: &[f32], w: usize, [x0, y0, x1, y1]: [usize; 4]) -> (f32, f32) {
    (y0..y1)
        .flat_map(|y| &v[y * w + x0..y * w + x1])
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &x| {
            (lo.min(x), hi.max(x))
        })
}

/// One octave as the cells read it.
struct Level {
    /// Integral images of the squared horizontal, vertical and diagonal details.
    bands: [Vec<f64>; 3],
    /// The smoothed image in the input's units, where its extremes are described.
    low: Option<Vec<f32>>,
    width: usize,
    height: usize,
    /// Input pixels a coefficient spans.
    factor: usize,
}

impl Level {
    /// The footprint of the input box `x0, y0` of side `cell`: at least one coefficient.
    fn footprint(&self, x0: usize, y0: usize, cell: usize) -> [usize; 4] {
        let (w, h, f) = (self.width, self.height, self.factor);
        let bx0 = (x0 / f).min(w.saturating_sub(1));
        let by0 = (y0 / f).min(h.saturating_sub(1));
        let bx1 = ((x0 + cell) / f).clamp(bx0 + 1, w.max(bx0 + 1));
        let by1 = ((y0 + cell) / f).clamp(by0 + 1, h.max(by0 + 1));
        [bx0, by0, bx1, by1]
    }
}

/// The octaves of the normalized image `x` (`w × h`), the first `extremes` with their
/// smoothed images.
fn levels(mut x: Vec<f32>, mut w: usize, mut h: usize, extremes: usize) -> Vec<Level> {
    let mut out = Vec::with_capacity(LEVELS);
    for k in 0..LEVELS {
        let (low, bands) = octave(&x, w, h);
        (w, h) = (w / 2, h / 2);
        // The orthonormal approximation doubles an octave: back to the input's units.
        let scale = 0.5f32.powi(k as i32 + 1);
        out.push(Level {
            bands: bands.map(|b| integral(&b, w, h)),
            low: (k < extremes).then(|| low.iter().map(|v| v * scale).collect()),
            width: w,
            height: h,
            factor: 2 << k,
        });
        x = low;
    }
    out
}

/// The cells of an image described as `how` says, or why it has none.
pub fn cells(image: &rollfuse_io::image::Planes, how: Describe) -> crate::Result<Cells> {
    let (w, h, cell) = (image.width, image.height, how.cell);
    rollfuse_io::require!(
        w >= cell && h >= cell,
        "the image is {w} × {h}: its texture is described in cells of {cell} × {cell} pixels"
    );
    let (rows, cols) = ((h - cell) / STRIDE + 1, (w - cell) / STRIDE + 1);
    let x = normalized(image);
    let mean = integral(&x, w, h);
    let levels = levels(x, w, h, how.extremes);
    let mut data = Vec::with_capacity(rows * cols * how.dim());
    for r in 0..rows {
        for c in 0..cols {
            let (x0, y0) = (c * STRIDE, r * STRIDE);
            for level in &levels {
                let foot = level.footprint(x0, y0, cell);
                for band in &level.bands {
                    data.push((box_mean(band, level.width, foot) + 1e-4).ln());
                }
                if let Some(low) = &level.low {
                    let (lo, hi) = box_extremes(low, level.width, foot);
                    data.extend([lo, hi]);
                }
            }
            data.push(box_mean(&mean, w, [x0, y0, x0 + cell, y0 + cell]));
        }
    }
    Ok(Cells {
        rows,
        cols,
        dim: how.dim(),
        data,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rollfuse_io::image::Planes;

    fn ramp(width: usize, height: usize) -> Planes {
        Planes {
            width,
            height,
            planes: vec![
                (0..width * height)
                    .map(|i| ((i % width) * 7 % 13 + (i / width) * 3 % 11) as f32)
                    .collect(),
            ],
        }
    }

    #[test]
    fn the_light_s_gain_and_offset_do_not_change_a_cell() {
        let a = ramp(96, 64);
        let mut b = a.clone();
        b.planes[0].iter_mut().for_each(|v| *v = 3.0 * *v + 20.0);
        let (ca, cb) = (cells(&a, ANOMALY).unwrap(), cells(&b, ANOMALY).unwrap());
        assert_eq!((ca.rows, ca.cols, ca.dim), (3, 7, 19));
        for (x, y) in ca.data.iter().zip(&cb.data) {
            assert!((x - y).abs() < 1e-3, "{x} against {y}");
        }
    }

    #[test]
    fn a_row_relative_feature_is_zero_on_a_row_of_like_cells() {
        let flat = Planes {
            width: 64,
            height: 32,
            planes: vec![vec![5.0; 64 * 32]],
        };
        let c = cells(&flat, TEXTURE).unwrap().with_row_relative();
        assert_eq!(c.dim, 26);
        assert!(c.at(0, 3)[13..].iter().all(|&v| v == 0.0));
    }

    #[test]
    fn an_image_smaller_than_a_cell_is_refused_with_the_size() {
        let err = cells(&ramp(40, 60), ANOMALY).unwrap_err().to_string();
        assert!(err.contains("40 × 60") && err.contains("48 × 48"), "{err}");
    }
}
