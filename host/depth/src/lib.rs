//! Surface depth from an RGB tactile image: photometric stereo from the three LEDs, then
//! exact Poisson integration of the slopes.
//!
//! - [`lights`]: the light file (scale, LED directions, gains) and its checks.
//! - [`stereo`]: background, normals, slopes.
//! - [`poisson`]: least-squares integration with Neumann boundaries by the DCT.
//! - [`calibrate`]: light directions and gains from an image of a ball of known radius.
//! - [`output`]: `.npy`, a colour-mapped PNG with a scale bar, a PLY point cloud.
//! - [`synthetic`]: a ball rendered with known lights, for tests and benches.
//!
//! Every fallible function returns [`Error`]: input that cannot give a height map, a
//! light file that could not be read, an output that could not be written.

pub mod calibrate;
mod error;
pub mod lights;
pub mod output;
pub mod poisson;
pub mod stereo;
pub mod synthetic;

pub use error::Error;
use lights::Lights;
use rollfuse_io::image::Planes;

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
///
/// ```
/// use rollfuse_depth::{lights::Lights, reconstruct, synthetic};
///
/// // A 2 mm ball pressed 0.4 mm deep, seen by the product's LEDs at 0.02 mm a pixel.
/// let lights = Lights::product(0.02);
/// let ball = |press| synthetic::ball((160, 160), (80.0, 80.0), 2.0, press, &lights, 180.0);
/// let ((truth, image), (_, flat)) = (ball(0.4), ball(0.0));
/// let depth = reconstruct(&image, Some(&flat), &lights)?;
/// let peak = depth.height_mm.iter().copied().fold(f32::MIN, f32::max);
/// let true_peak = truth.iter().copied().fold(f64::MIN, f64::max);
/// assert!((f64::from(peak) - true_peak).abs() < 0.02, "{peak} mm against {true_peak} mm");
/// # Ok::<(), rollfuse_depth::Error>(())
/// ```
pub fn reconstruct(
    image: &Planes,
    background: Option<&Planes>,
    lights: &Lights,
) -> Result<DepthMap, Error> {
    let estimated;
    let background = match background {
        Some(b) => b,
        None => {
            rollfuse_io::require!(
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
    // zero on the flat gel so its noise does not integrate into a tilt. Taken straight
    // into the Poisson right-hand side, without gradient arrays.
    let k = lights.mm_per_px;
    let between = |v: &[f64], i: usize, j: usize| {
        if contact[i] || contact[j] {
            (0.5 * (v[i] + v[j]) * k) as f32
        } else {
            0.0
        }
    };
    let rhs = poisson::divergence(
        w,
        h,
        |i| between(&s.p, i, i + 1),
        |i| between(&s.q, i, i + w),
    );
    let heights = poisson::solve_neumann(rhs, w, h)?;
    if heights.iter().any(|v| !v.is_finite()) {
        rollfuse_io::invalid!("the slopes did not integrate to finite heights");
    }
    // Zero at the undisturbed gel: the median height off contact (or the lowest point when
    // contact covers almost everything).
    let off_contact = contact.iter().filter(|c| !**c).count();
    let base = if off_contact * 10 >= w * h {
        let flat = heights.iter().zip(&contact).filter(|(_, c)| !**c);
        median(flat.map(|(v, _)| f64::from(*v))).unwrap_or(0.0) as f32
    } else {
        heights.iter().copied().fold(f32::INFINITY, f32::min)
    };
    let mut height_mm = heights;
    height_mm.iter_mut().for_each(|v| *v -= base);
    Ok(DepthMap {
        width: w,
        height: h,
        mm_per_px: k,
        height_mm,
        contact,
    })
}

/// Where the gel is pressed: the slope magnitude, averaged over 5×5 pixels so sensor
/// noise does not speckle it, above [`CONTACT_SLOPE`] or three times its median (the noise
/// floor, when contact covers less than half the image), grown by a few pixels.
fn contact_mask(p: &[f64], q: &[f64], w: usize, h: usize) -> Vec<bool> {
    // f32 and bytes keep the working arrays small: fresh pages cost more than arithmetic.
    let magnitude: Vec<f32> = p
        .iter()
        .zip(q)
        .map(|(a, b)| (a * a + b * b).sqrt() as f32)
        .collect();
    let smooth = box_sum(&magnitude, w, h, 2);
    let area = 25.0;
    let floor = median(smooth.iter().map(|&v| f64::from(v) / area)).unwrap_or(0.0);
    let threshold = (CONTACT_SLOPE.max(3.0 * floor) * area) as f32;
    let steep: Vec<f32> = smooth
        .iter()
        .map(|&m| f32::from(u8::from(m > threshold)))
        .collect();
    // Grown: any steep pixel in the (2r+1)² square.
    box_sum(&steep, w, h, CONTACT_MARGIN)
        .iter()
        .map(|&n| n > 0.5)
        .collect()
}

/// The sum over a `(2r+1)²` square clipped at the borders (at the borders the square holds
/// fewer pixels; the contact threshold is a little stricter there): running sums along
/// rows, then running sums of whole rows.
fn box_sum(v: &[f32], w: usize, h: usize, r: usize) -> Vec<f32> {
    let mut rows = vec![0f32; w * h];
    for (src, dst) in v.chunks_exact(w).zip(rows.chunks_exact_mut(w)) {
        let mut sum: f32 = src[..r.min(w - 1) + 1].iter().sum();
        for i in 0..w {
            dst[i] = sum;
            if i + r + 1 < w {
                sum += src[i + r + 1];
            }
            if i >= r {
                sum -= src[i - r];
            }
        }
    }
    let mut out = vec![0f32; w * h];
    let mut acc = vec![0f32; w];
    for row in rows.chunks_exact(w).take(r.min(h - 1) + 1) {
        acc.iter_mut().zip(row).for_each(|(a, v)| *a += v);
    }
    for y in 0..h {
        out[y * w..(y + 1) * w].copy_from_slice(&acc);
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

/// The median of `v`, from every fourth value (a threshold and a baseline need no more).
fn median(v: impl Iterator<Item = f64>) -> Option<f64> {
    let mut sample: Vec<f64> = v.step_by(4).collect();
    if sample.is_empty() {
        return None;
    }
    let mid = sample.len() / 2;
    Some(*sample.select_nth_unstable_by(mid, f64::total_cmp).1)
}
