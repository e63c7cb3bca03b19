//! Surface depth from an RGB tactile image: photometric stereo from the three LEDs, then
//! exact Poisson integration of the slopes.
//!
//! - [`lights`]: the light file (scale, LED directions, gains) and its checks.
//! - [`stereo`]: background, normals, slopes.
//! - [`poisson`]: least-squares integration with Neumann boundaries by the DCT.
//! - [`calibrate`]: light directions and gains from an image of a ball of known radius.
//! - [`output`]: `.npy`, a colour-mapped PNG with a scale bar, a PLY point cloud.

pub mod calibrate;
pub mod lights;
pub mod output;
pub mod poisson;
pub mod stereo;

use crate::image::Planes;
use lights::Lights;

/// Slopes below this (about 1.1°) are taken as the flat gel.
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
    /// Pixels in contact (slope above [`CONTACT_SLOPE`], grown by a few pixels).
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
    let steep: Vec<bool> =
        s.p.iter()
            .zip(&s.q)
            .map(|(p, q)| p.hypot(*q) > CONTACT_SLOPE)
            .collect();
    let contact = grow(&steep, w, h, CONTACT_MARGIN);
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
    let mut flat: Vec<f64> = heights
        .iter()
        .zip(&contact)
        .filter(|(_, c)| !**c)
        .map(|(v, _)| *v)
        .collect();
    let base = if flat.len() * 10 >= w * h {
        let mid = flat.len() / 2;
        *flat.select_nth_unstable_by(mid, f64::total_cmp).1
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

/// `mask` grown by `r` pixels (a square neighbourhood).
fn grow(mask: &[bool], w: usize, h: usize, r: usize) -> Vec<bool> {
    // Rows, then columns: a separable square dilation.
    let mut rows = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            let (a, b) = (x.saturating_sub(r), (x + r).min(w - 1));
            rows[y * w + x] = mask[y * w + a..=y * w + b].iter().any(|&m| m);
        }
    }
    let mut out = vec![false; w * h];
    for y in 0..h {
        let (a, b) = (y.saturating_sub(r), (y + r).min(h - 1));
        for x in 0..w {
            out[y * w + x] = (a..=b).any(|yy| rows[yy * w + x]);
        }
    }
    out
}
