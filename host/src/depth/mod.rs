//! Surface depth from an RGB tactile image: photometric stereo from the three LEDs, then
//! exact Poisson integration of the slopes.
//!
//! - [`lights`]: the light file (scale, LED directions, gains) and its checks.
//! - [`stereo`]: background, normals, slopes.
//! - [`poisson`]: least-squares integration with Neumann boundaries by the DCT.
//! - [`calibrate`]: light directions and gains from an image of a ball of known radius.
//! - [`output`]: `.npy`, a colour-mapped PNG with a scale bar, a PLY point cloud.
//! - [`synthetic`]: a ball rendered with known lights, for tests and benches.

pub mod calibrate;
pub mod lights;
pub mod output;
pub mod poisson;
pub mod stereo;
pub mod synthetic;

use crate::image::Planes;
use lights::Lights;

/// Slopes below this (about 1.1°) are taken as the flat gel (or three times the image's
/// median slope, if noise is above it).
pub const CONTACT_SLOPE: f64 = 0.02;

/// The contact mask is grown by this many pixels, to keep the foot of every slope.
const CONTACT_MARGIN: usize = 3;

/// A height map.
#[derive(Debug, Clone)]
pub struct DepthMap {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Millimetres per pixel.
    pub mm_per_px: f64,
    /// Height toward the camera, mm, row-major; 0 is the undisturbed gel.
    pub height_mm: Vec<f32>,
    /// Pixels in contact (smoothed slope above the flat gel's, grown by a few pixels).
    pub contact: Vec<bool>,
}

/// The height map of an RGB tactile image. `background` is the no-contact frame (else a
/// smooth estimate from the image itself).
pub fn reconstruct(
    image: &Planes,
    background: Option<&Planes>,
    lights: &Lights,
) -> anyhow::Result<DepthMap> {
    let estimated;
    let background = match background {
        Some(b) => b,
        None => {
            anyhow::ensure!(
                image.is_rgb(),
                "depth needs an RGB image (one LED per channel), this one is gray"
            );
            estimated = stereo::smooth_background(image);
            &estimated
        }
    };
    let s = stereo::slopes(image, background, lights)?;
    let (w, h) = (s.width, s.height);
    let contact = contact_mask(&s.p, &s.q, w, h);
    // Slopes between pixel centres: the mean of the two pixels' slopes, in mm per pixel;
    // zero on the flat gel so its noise does not integrate into a tilt.
    let k = lights.mm_per_px;
    let slope = |v: &[f64], i: usize, j: usize| {
        if contact[i] || contact[j] {
            0.5 * (v[i] + v[j]) * k
        } else {
            0.0
        }
    };
    let mut gx = vec![0f64; w * h];
    let mut gy = vec![0f64; w * h];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if x + 1 < w {
                gx[i] = slope(&s.p, i, i + 1);
            }
            if y + 1 < h {
                gy[i] = slope(&s.q, i, i + w);
            }
        }
    }
    let heights = poisson::integrate(&gx, &gy, w, h)?;
    // Zero at the undisturbed gel: the median height off contact (or the lowest point when
    // contact covers almost everything).
    let off_contact = contact.iter().filter(|c| !**c).count();
    let base = if off_contact * 10 >= w * h {
        let flat = heights.iter().zip(&contact).filter(|(_, c)| !**c);
        median(flat.map(|(v, _)| *v)).unwrap_or(0.0)
    } else {
        heights.iter().copied().fold(f64::INFINITY, f64::min)
    };
    Ok(DepthMap {
        width: w,
        height: h,
        mm_per_px: k,
        height_mm: heights.iter().map(|v| (v - base) as f32).collect(),
        contact,
    })
}

/// Where the gel is pressed: the slope magnitude, averaged over 5×5 pixels so sensor
/// noise does not speckle it, above [`CONTACT_SLOPE`] or three times its median (the noise
/// floor, when contact covers less than half the image), grown by a few pixels.
fn contact_mask(p: &[f64], q: &[f64], w: usize, h: usize) -> Vec<bool> {
    let magnitude: Vec<f64> = p
        .iter()
        .zip(q)
        .map(|(a, b)| (a * a + b * b).sqrt())
        .collect();
    let smooth = box_mean(&magnitude, w, h, 2);
    let floor = median(smooth.iter().copied()).unwrap_or(0.0);
    let threshold = CONTACT_SLOPE.max(3.0 * floor);
    let steep: Vec<bool> = smooth.iter().map(|&m| m > threshold).collect();
    grow(&steep, w, h, CONTACT_MARGIN)
}

/// The mean over a `(2r+1)²` square, shrunk at the borders: running sums along rows,
/// then along columns.
fn box_mean(v: &[f64], w: usize, h: usize, r: usize) -> Vec<f64> {
    let mut rows = vec![0f64; w * h];
    for (src, dst) in v.chunks_exact(w).zip(rows.chunks_exact_mut(w)) {
        window_means(src, dst, r);
    }
    // Columns: a running sum of whole rows (row-major, so it streams through memory).
    let mut out = vec![0f64; w * h];
    let mut acc = vec![0f64; w];
    for row in rows.chunks_exact(w).take(r.min(h - 1) + 1) {
        acc.iter_mut().zip(row).for_each(|(a, v)| *a += v);
    }
    for y in 0..h {
        let count = ((y + r).min(h - 1) - y.saturating_sub(r) + 1) as f64;
        out[y * w..(y + 1) * w]
            .iter_mut()
            .zip(&acc)
            .for_each(|(o, a)| *o = a / count);
        if y + r + 1 < h {
            let add = &rows[(y + r + 1) * w..(y + r + 2) * w];
            acc.iter_mut().zip(add).for_each(|(a, v)| *a += v);
        }
        if y >= r {
            let sub = &rows[(y - r) * w..(y - r + 1) * w];
            acc.iter_mut().zip(sub).for_each(|(a, v)| *a -= v);
        }
    }
    out
}

/// `dst[i]` = the mean of `src[i−r ..= i+r]` (clipped to the line), by a running sum.
fn window_means(src: &[f64], dst: &mut [f64], r: usize) {
    let n = src.len();
    let mut sum: f64 = src[..r.min(n - 1) + 1].iter().sum();
    for i in 0..n {
        let (a, b) = (i.saturating_sub(r), (i + r).min(n - 1));
        dst[i] = sum / (b - a + 1) as f64;
        if i + r + 1 < n {
            sum += src[i + r + 1];
        }
        if i >= r {
            sum -= src[i - r];
        }
    }
}

/// The median of `v`, from every fourth value (a threshold and a baseline need no more).
fn median(v: impl Iterator<Item = f64>) -> Option<f64> {
    let mut sample: Vec<f64> = v.step_by(4).collect();
    if sample.is_empty() {
        return None;
    }
    let mid = sample.len() / 2;
    Some(*sample.select_nth_unstable_by(mid, f64::total_cmp).1)
}

/// `mask` grown by `r` pixels (a square neighbourhood): a pixel is set when the box mean
/// of the mask around it is above zero.
fn grow(mask: &[bool], w: usize, h: usize, r: usize) -> Vec<bool> {
    let as_f64: Vec<f64> = mask.iter().map(|&m| f64::from(u8::from(m))).collect();
    box_mean(&as_f64, w, h, r)
        .iter()
        .map(|&m| m > 1e-9)
        .collect()
}
