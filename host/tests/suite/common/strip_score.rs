//! How a strip of an independently rendered roll is judged (`tests/fixtures/README.md`):
//! each feature that passed under the apex is looked for in the strip by normalized
//! cross-correlation with the ideal belt's patch; one place per feature is chosen for the
//! whole roll so that consecutive features keep their order, their spacing (within 8 px
//! plus 15 %) and their sideways offset (within 10 px); each feature scores its
//! correlation there (0 where none fits) and its contrast (the ratio of standard
//! deviations); the strip's scale is the median slope of strip rows against belt rows.

use rollfuse::image::Planes;
use rustfft::{FftPlanner, num_complex::Complex};

/// A feature's box on the belt: rows `r0..r1`, columns `c0..c1`.
pub type Glyph = [usize; 4];

/// One feature's verdict.
#[derive(Debug, Clone, Copy)]
pub struct Found {
    /// Its place in the strip (row, column of the patch's corner), if any fits.
    pub at: Option<(usize, usize)>,
    /// Correlation there (0 where none fits).
    pub score: f64,
    /// Standard deviation in the strip over the ideal's there.
    pub contrast: f64,
}

/// The verdict on a strip.
#[derive(Debug, Clone)]
pub struct Verdict {
    /// Per feature that passed under the apex, in belt order.
    pub features: Vec<Found>,
    /// Median slope of strip rows against belt rows over consecutive placed features.
    pub scale: f64,
}

impl Verdict {
    /// The median and the least of the features' scores.
    pub fn scores(&self) -> (f64, f64) {
        let mut s: Vec<f64> = self.features.iter().map(|f| f.score).collect();
        s.sort_by(f64::total_cmp);
        (s[s.len() / 2], s[0])
    }
}

/// A feature's patch of the ideal belt: its corner, pixels and size (width, height).
struct Patch {
    row: usize,
    col: usize,
    pixels: Vec<f64>,
    size: (usize, usize),
}

/// A place a patch may be: correlation, row, column.
type Candidate = (f64, usize, usize);

/// Patch margin around a glyph's box.
const MARGIN: usize = 6;
/// Candidate places kept per feature.
const CANDIDATES: usize = 20;

/// Judges `strip` (gray) against `ideal` for `glyphs`, those whose centre row lies in
/// `apex_rows` (the belt rows the apex passed over).
pub fn judge(strip: &Planes, ideal: &Planes, glyphs: &[Glyph], apex_rows: (f64, f64)) -> Verdict {
    let strip_gray = strip.gray().into_owned();
    let ideal_gray = ideal.gray().into_owned();
    let mut boxes = Vec::new();
    let mut candidates = Vec::new();
    for &[r0, r1, c0, c1] in glyphs {
        let centre = (r0 + r1) as f64 / 2.0;
        if centre < apex_rows.0 || centre > apex_rows.1 {
            continue;
        }
        let (r0, c0) = (r0.saturating_sub(MARGIN), c0.saturating_sub(MARGIN));
        let (r1, c1) = (
            (r1 + MARGIN).min(ideal.height),
            (c1 + MARGIN).min(ideal.width),
        );
        let pixels = crop(&ideal_gray, ideal.width, (r0, r1, c0, c1));
        let size = (c1 - c0, r1 - r0);
        let map = ncc_map(&strip_gray, (strip.width, strip.height), &pixels, size);
        candidates.push(peaks(&map));
        boxes.push(Patch {
            row: r0,
            col: c0,
            pixels,
            size,
        });
    }
    let chosen = choose(&boxes, &candidates);
    let mut features = Vec::new();
    let mut placed = Vec::new();
    for (i, patch) in boxes.iter().enumerate() {
        let (pw, ph) = patch.size;
        let Some(j) = chosen[i] else {
            features.push(Found {
                at: None,
                score: 0.0,
                contrast: 0.0,
            });
            continue;
        };
        let (score, y, x) = candidates[i][j];
        let seen = crop(&strip_gray, strip.width, (y, y + ph, x, x + pw));
        features.push(Found {
            at: Some((y, x)),
            score,
            contrast: std(&seen) / std(&patch.pixels),
        });
        placed.push((patch.row as f64, y as f64));
    }
    let mut slopes: Vec<f64> = placed
        .windows(2)
        .map(|p| (p[1].1 - p[0].1) / (p[1].0 - p[0].0))
        .collect();
    slopes.sort_by(f64::total_cmp);
    let scale = slopes.get(slopes.len() / 2).copied().unwrap_or(f64::NAN);
    Verdict { features, scale }
}

fn crop(img: &[f32], w: usize, (r0, r1, c0, c1): (usize, usize, usize, usize)) -> Vec<f64> {
    (r0..r1)
        .flat_map(|y| (c0..c1).map(move |x| f64::from(img[y * w + x])))
        .collect()
}

fn std(v: &[f64]) -> f64 {
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / v.len() as f64).sqrt()
}

/// The normalized cross-correlation of the zero-mean `patch` (`pw × ph`) at every place it
/// fits in `img` (`w × h`): `(h − ph + 1) × (w − pw + 1)` values, row-major.
fn ncc_map(img: &[f32], (w, h): (usize, usize), patch: &[f64], (pw, ph): (usize, usize)) -> Map {
    let (fw, fh) = (w.next_power_of_two(), h.next_power_of_two());
    let mean = patch.iter().sum::<f64>() / patch.len() as f64;
    let norm = patch.iter().map(|p| (p - mean).powi(2)).sum::<f64>().sqrt();
    let mut a = vec![Complex::new(0.0, 0.0); fw * fh];
    let mut b = vec![Complex::new(0.0, 0.0); fw * fh];
    for y in 0..h {
        for x in 0..w {
            a[y * fw + x].re = f64::from(img[y * w + x]);
        }
    }
    for y in 0..ph {
        for x in 0..pw {
            b[y * fw + x].re = patch[y * pw + x] - mean;
        }
    }
    fft2(&mut a, fw, fh, false);
    fft2(&mut b, fw, fh, false);
    for (p, q) in a.iter_mut().zip(&b) {
        *p *= q.conj();
    }
    fft2(&mut a, fw, fh, true);
    let scale = 1.0 / (fw * fh) as f64;
    // Local sums of the image and its square over the patch's window.
    let integral = |f: &dyn Fn(f64) -> f64| {
        let mut s = vec![0f64; (w + 1) * (h + 1)];
        for y in 0..h {
            for x in 0..w {
                s[(y + 1) * (w + 1) + x + 1] = f(f64::from(img[y * w + x]))
                    + s[y * (w + 1) + x + 1]
                    + s[(y + 1) * (w + 1) + x]
                    - s[y * (w + 1) + x];
            }
        }
        s
    };
    let (s1, s2) = (integral(&|v| v), integral(&|v| v * v));
    let sum = |s: &[f64], y: usize, x: usize| {
        s[(y + ph) * (w + 1) + x + pw] - s[y * (w + 1) + x + pw] - s[(y + ph) * (w + 1) + x]
            + s[y * (w + 1) + x]
    };
    let (mw, mh) = (w + 1 - pw, h + 1 - ph);
    let n = (pw * ph) as f64;
    let values = (0..mh)
        .flat_map(|y| (0..mw).map(move |x| (y, x)))
        .map(|(y, x)| {
            let var = sum(&s2, y, x) - sum(&s1, y, x).powi(2) / n;
            let num = a[y * fw + x].re * scale;
            if var > 1e-9 {
                num / (var.sqrt() * norm)
            } else {
                0.0
            }
        })
        .collect();
    Map {
        width: mw,
        height: mh,
        values,
    }
}

/// A 2-D FFT in place (rows then columns); `inverse` unnormalized.
fn fft2(data: &mut [Complex<f64>], w: usize, h: usize, inverse: bool) {
    let mut planner = FftPlanner::new();
    let (rows, cols) = if inverse {
        (planner.plan_fft_inverse(w), planner.plan_fft_inverse(h))
    } else {
        (planner.plan_fft_forward(w), planner.plan_fft_forward(h))
    };
    for row in data.chunks_exact_mut(w) {
        rows.process(row);
    }
    let mut column = vec![Complex::new(0.0, 0.0); h];
    for x in 0..w {
        for y in 0..h {
            column[y] = data[y * w + x];
        }
        cols.process(&mut column);
        for y in 0..h {
            data[y * w + x] = column[y];
        }
    }
}

struct Map {
    width: usize,
    height: usize,
    values: Vec<f64>,
}

/// The local maxima (over 9 × 9) above 0.3, best first, at most [`CANDIDATES`]:
/// `(score, row, column)`.
fn peaks(map: &Map) -> Vec<Candidate> {
    let (w, h) = (map.width, map.height);
    let mut out = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let v = map.values[y * w + x];
            if v <= 0.3 {
                continue;
            }
            let is_max = (y.saturating_sub(4)..(y + 5).min(h)).all(|yy| {
                (x.saturating_sub(4)..(x + 5).min(w)).all(|xx| map.values[yy * w + xx] <= v)
            });
            if is_max {
                out.push((v, y, x));
            }
        }
    }
    out.sort_by(|a, b| b.0.total_cmp(&a.0));
    out.truncate(CANDIDATES);
    out
}

/// One candidate (or none) per feature, maximizing the total score over the choices that
/// keep consecutive placed features in order, spaced within 8 px + 15 % of their belt
/// spacing and sideways within 10 px of each other's offset.
fn choose(boxes: &[Patch], candidates: &[Vec<Candidate>]) -> Vec<Option<usize>> {
    // best[i][j]: the best total ending with feature i at candidate j, and the pick before.
    type Step = (f64, Option<(usize, usize)>);
    let mut best: Vec<Vec<Step>> = Vec::new();
    let fits = |a: (usize, usize), b: (usize, usize)| {
        let (ca, cb) = (candidates[a.0][a.1], candidates[b.0][b.1]);
        let belt = boxes[b.0].row as f64 - boxes[a.0].row as f64;
        let strip = cb.1 as f64 - ca.1 as f64;
        let side = (cb.2 as f64 - boxes[b.0].col as f64) - (ca.2 as f64 - boxes[a.0].col as f64);
        strip > 0.0 && (strip - belt).abs() <= 8.0 + 0.15 * belt && side.abs() <= 10.0
    };
    for (i, here) in candidates.iter().enumerate() {
        let row = here
            .iter()
            .enumerate()
            .map(|(j, c)| {
                let mut pick = (c.0, None);
                for (pi, prev) in best.iter().enumerate() {
                    for (pj, &(total, _)) in prev.iter().enumerate() {
                        if fits((pi, pj), (i, j)) && total + c.0 > pick.0 {
                            pick = (total + c.0, Some((pi, pj)));
                        }
                    }
                }
                pick
            })
            .collect();
        best.push(row);
    }
    let mut chosen = vec![None; candidates.len()];
    let mut at = best
        .iter()
        .enumerate()
        .flat_map(|(i, r)| r.iter().enumerate().map(move |(j, v)| (v.0, (i, j))))
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .map(|v| v.1);
    while let Some((i, j)) = at {
        chosen[i] = Some(j);
        at = best[i][j].1;
    }
    chosen
}
