//! The paper's metrics (§III.B): information entropy, MS-SSIM, and their regional spread
//! (eqs. 8–9). Definitions are fixed in `docs/fusion.md` (Metrics); both are checked against
//! independent implementations (scikit-image, and a numpy MS-SSIM after Wang 2003) on
//! committed vectors.

/// Shannon entropy, base 2, of the 256-bin histogram of an 8-bit image (IE).
pub fn entropy(pixels: &[u8]) -> f64 {
    let mut hist = [0u64; 256];
    for &p in pixels {
        hist[p as usize] += 1;
    }
    let n = pixels.len() as f64;
    hist.iter()
        .filter(|&&c| c > 0)
        .map(|&c| {
            let p = c as f64 / n;
            -p * p.log2()
        })
        .sum::<f64>()
        // Every term is ≥ 0: this only turns a one-valued image's −0 into 0.
        .abs()
}

/// Stretches an image to the full 0..=255 range (min → 0, max → 255), as the paper
/// normalizes gray values before comparing; a flat image maps to 0.
pub fn gray_normalize(pixels: &[f64]) -> Vec<f64> {
    let (lo, hi) = pixels
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
        return vec![0.0; pixels.len()];
    }
    pixels
        .iter()
        .map(|v| (v - lo) * 255.0 / (hi - lo))
        .collect()
}

/// MS-SSIM scale weights (Wang, Simoncelli & Bovik 2003).
pub const MS_SSIM_WEIGHTS: [f64; 5] = [0.0448, 0.2856, 0.3001, 0.2363, 0.1333];
/// Side of the SSIM window, pixels: the least an image (and each scale) must measure.
pub const WINDOW: usize = 11;
const SIGMA: f64 = 1.5;
const C1: f64 = (0.01 * 255.0) * (0.01 * 255.0);
const C2: f64 = (0.03 * 255.0) * (0.03 * 255.0);

/// A gray image of `f64` values.
#[derive(Debug, Clone)]
pub struct Gray {
    /// Width.
    pub width: usize,
    /// Height.
    pub height: usize,
    /// Row-major values.
    pub data: Vec<f64>,
}

impl Gray {
    /// Wraps row-major values; fails if the sizes disagree.
    pub fn new(width: usize, height: usize, data: Vec<f64>) -> anyhow::Result<Self> {
        anyhow::ensure!(
            data.len() == width * height && width > 0 && height > 0,
            "image data ({} values) does not match {width}×{height}",
            data.len()
        );
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// 2×2 average, the odd last row/column padded by repeating it.
    fn downsample(&self) -> Gray {
        let (w, h) = (self.width.div_ceil(2), self.height.div_ceil(2));
        let at = |x: usize, y: usize| {
            self.data[y.min(self.height - 1) * self.width + x.min(self.width - 1)]
        };
        let data = (0..w * h)
            .map(|i| {
                let (x, y) = (2 * (i % w), 2 * (i / w));
                (at(x, y) + at(x + 1, y) + at(x, y + 1) + at(x + 1, y + 1)) / 4.0
            })
            .collect();
        Gray {
            width: w,
            height: h,
            data,
        }
    }

    /// 11×11 Gaussian (σ 1.5) filtering, 'valid': `(w − 10) × (h − 10)`.
    fn filter_valid(&self, taps: &[f64]) -> Gray {
        let (w, h) = (self.width - WINDOW + 1, self.height - WINDOW + 1);
        let mut rows = vec![0.0; w * self.height];
        for y in 0..self.height {
            let src = &self.data[y * self.width..(y + 1) * self.width];
            for x in 0..w {
                rows[y * w + x] = taps
                    .iter()
                    .zip(&src[x..x + WINDOW])
                    .map(|(t, v)| t * v)
                    .sum();
            }
        }
        let mut data = vec![0.0; w * h];
        for y in 0..h {
            for (k, t) in taps.iter().enumerate() {
                let src = &rows[(y + k) * w..(y + k + 1) * w];
                for (d, v) in data[y * w..(y + 1) * w].iter_mut().zip(src) {
                    *d += t * v;
                }
            }
        }
        Gray {
            width: w,
            height: h,
            data,
        }
    }
}

fn gaussian_taps() -> Vec<f64> {
    let r = (WINDOW / 2) as f64;
    let t: Vec<f64> = (0..WINDOW)
        .map(|i| (-((i as f64 - r).powi(2)) / (2.0 * SIGMA * SIGMA)).exp())
        .collect();
    let s: f64 = t.iter().sum();
    t.iter().map(|v| v / s).collect()
}

/// Mean luminance term and mean contrast-structure term of SSIM at one scale.
fn ssim_terms(a: &Gray, b: &Gray, taps: &[f64]) -> (f64, f64) {
    let mul = |p: &Gray, q: &Gray| Gray {
        width: p.width,
        height: p.height,
        data: p.data.iter().zip(&q.data).map(|(x, y)| x * y).collect(),
    };
    let (mu_a, mu_b) = (a.filter_valid(taps), b.filter_valid(taps));
    let (aa, bb, ab) = (
        mul(a, a).filter_valid(taps),
        mul(b, b).filter_valid(taps),
        mul(a, b).filter_valid(taps),
    );
    let n = mu_a.data.len() as f64;
    let (mut lum, mut cs) = (0.0, 0.0);
    for i in 0..mu_a.data.len() {
        let (ma, mb) = (mu_a.data[i], mu_b.data[i]);
        let va = aa.data[i] - ma * ma;
        let vb = bb.data[i] - mb * mb;
        let cov = ab.data[i] - ma * mb;
        lum += (2.0 * ma * mb + C1) / (ma * ma + mb * mb + C1);
        cs += (2.0 * cov + C2) / (va + vb + C2);
    }
    (lum / n, cs / n)
}

/// The number of MS-SSIM scales an image of this size allows (each scale's image must
/// hold the 11×11 window): 5 for images of at least 161 px a side, fewer for smaller ones.
pub fn ms_ssim_scales(width: usize, height: usize) -> usize {
    let mut side = width.min(height);
    let mut scales = 0;
    while scales < 5 && side >= WINDOW {
        scales += 1;
        side = side.div_ceil(2);
    }
    scales
}

/// MS-SSIM of `image` against `reference` after gray-normalizing both (Wang 2003: 5
/// scales, 11×11 Gaussian σ 1.5, K1 0.01, K2 0.03, L 255, 2×2 average downsampling,
/// 'valid' filtering). Negative contrast-structure terms count as 0. An image too small for
/// five scales uses as many as fit, with their weights renormalized to sum to 1.
pub fn ms_ssim(image: &Gray, reference: &Gray) -> anyhow::Result<f64> {
    let a = Gray::new(image.width, image.height, gray_normalize(&image.data))?;
    let b = Gray::new(
        reference.width,
        reference.height,
        gray_normalize(&reference.data),
    )?;
    ms_ssim_raw(&a, &b)
}

/// MS-SSIM without the gray normalization (for strips of an image normalized as a whole).
pub fn ms_ssim_raw(image: &Gray, reference: &Gray) -> anyhow::Result<f64> {
    anyhow::ensure!(
        (image.width, image.height) == (reference.width, reference.height),
        "MS-SSIM: image is {}×{} but the reference is {}×{}",
        image.width,
        image.height,
        reference.width,
        reference.height
    );
    let scales = ms_ssim_scales(image.width, image.height);
    anyhow::ensure!(
        scales > 0,
        "MS-SSIM needs at least {WINDOW}×{WINDOW} pixels, got {}×{}",
        image.width,
        image.height
    );
    let weights = &MS_SSIM_WEIGHTS[..scales];
    let total: f64 = weights.iter().sum();
    let taps = gaussian_taps();
    let (mut a, mut b) = (image.clone(), reference.clone());
    let mut result = 1.0;
    for (j, w) in weights.iter().enumerate() {
        let (lum, cs) = ssim_terms(&a, &b, &taps);
        let w = w / total;
        result *= cs.max(0.0).powf(w);
        if j + 1 == scales {
            result *= lum.max(0.0).powf(w);
        } else {
            a = a.downsample();
            b = b.downsample();
        }
    }
    Ok(result)
}

/// Population standard deviation (eqs. 8–9).
pub fn population_std(values: &[f64]) -> f64 {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt()
}

/// Which way an image is cut into strips for the regional std.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum StripAxis {
    /// Bands of rows: along the belt, the direction contact depth varies in rollfuse's
    /// frames (the paper's "width", its motion direction).
    Rows,
    /// Bands of columns: across the belt.
    Columns,
}

/// Index ranges of `strips` nearly equal strips over `len` (`k·len/strips` to
/// `(k+1)·len/strips`; widths differ by at most one when it does not divide).
pub fn strip_ranges(len: usize, strips: usize) -> Vec<std::ops::Range<usize>> {
    (0..strips)
        .map(|k| k * len / strips..(k + 1) * len / strips)
        .collect()
}

/// The strip `range` of a gray image along `axis`.
pub fn strip(img: &Gray, axis: StripAxis, range: std::ops::Range<usize>) -> Gray {
    match axis {
        StripAxis::Rows => Gray {
            width: img.width,
            height: range.len(),
            data: img.data[range.start * img.width..range.end * img.width].to_vec(),
        },
        StripAxis::Columns => {
            let data = (0..img.height)
                .flat_map(|y| {
                    img.data[y * img.width + range.start..y * img.width + range.end]
                        .iter()
                        .copied()
                })
                .collect();
            Gray {
                width: range.len(),
                height: img.height,
                data,
            }
        }
    }
}
