//! Changes a training crop may undergo (`train --augment`), so that the network learns
//! cloth and defects rather than one renderer's light, contrast, blur and noise: a real
//! line's gel, LEDs and camera differ from any simulator's.
//!
//! Each crop is, independently: turned half a turn half the time (the light then comes
//! from the other side; a turn, unlike a mirror, keeps a twill's hand, so the fabric stays
//! the one it is, and a defect the kind it is), bent in tone by a gamma of 0.6–1.65, lit
//! unevenly by a linear tilt of up to ±30 % across it, blurred half the time (σ 0.3–1.2
//! px) and given read noise (σ up to 4 gray levels).

use super::targets::Labelled;
use rand::RngExt;
use rand_distr::{Distribution, Normal};
use rand_pcg::Pcg64Mcg;

/// Largest tilt of the light across a crop, a fraction of its brightness.
const TILT: f32 = 0.3;
/// The range of ln(gamma).
const LOG_GAMMA: f32 = 0.5;
/// Blur, pixels (standard deviation), when a crop is blurred.
const BLUR: std::ops::Range<f32> = 0.3..1.2;
/// Most read noise, gray levels (standard deviation).
const NOISE: f32 = 4.0;

/// Applies a random look to the `side × side` crop `pixels` (0–255 gray), turning its
/// `boxes` and `blurred` boxes with it.
pub fn apply(
    pixels: &mut [f32],
    side: usize,
    boxes: &mut [Labelled],
    blurred: &mut [Labelled],
    rng: &mut Pcg64Mcg,
) {
    if rng.random_bool(0.5) {
        turn(pixels, side, boxes.iter_mut().chain(blurred.iter_mut()));
    }
    let gamma = rng.random_range(-LOG_GAMMA..LOG_GAMMA).exp();
    let tilt = [rng.random_range(-TILT..TILT), rng.random_range(-TILT..TILT)];
    relight(pixels, side, gamma, tilt);
    if rng.random_bool(0.5) {
        blur(pixels, side, rng.random_range(BLUR));
    }
    let noise = rng.random_range(0.0..NOISE);
    if let Ok(normal) = Normal::new(0.0f32, noise) {
        pixels.iter_mut().for_each(|p| *p += normal.sample(rng));
    }
}

/// Turns a `side × side` image half a turn, and `labels` on it with it.
fn turn<'a>(pixels: &mut [f32], side: usize, labels: impl Iterator<Item = &'a mut Labelled>) {
    // Row by row, a half turn reverses the image's samples.
    pixels.reverse();
    let s = side as f32;
    for l in labels {
        let [x0, y0, x1, y1] = l.box_px;
        l.box_px = [s - x1, s - y1, s - x0, s - y0];
    }
}

/// Bends the tone by `gamma` and tilts the light by `tilt` (its change across the crop
/// left to right and top to bottom, a fraction of the brightness at its middle).
fn relight(pixels: &mut [f32], side: usize, gamma: f32, tilt: [f32; 2]) {
    let s = side as f32;
    for (y, row) in pixels.chunks_exact_mut(side).enumerate() {
        let along = tilt[1] * ((y as f32 + 0.5) / s - 0.5);
        for (x, p) in row.iter_mut().enumerate() {
            let light = 1.0 + along + tilt[0] * ((x as f32 + 0.5) / s - 0.5);
            *p = 255.0 * (*p / 255.0).clamp(0.0, 1.0).powf(gamma) * light;
        }
    }
}

/// A Gaussian blur of standard deviation `sigma` pixels.
fn blur(pixels: &mut [f32], side: usize, sigma: f32) {
    let Some(image) = image::ImageBuffer::<image::Luma<f32>, _>::from_raw(
        side as u32,
        side as u32,
        pixels.to_vec(),
    ) else {
        return;
    };
    let blurred = imageproc::filter::gaussian_blur_f32(&image, sigma);
    pixels.copy_from_slice(blurred.as_raw());
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rollfuse_sim::textile::DefectKind;

    #[test]
    fn a_turn_moves_the_pixels_and_their_boxes_together() {
        let side = 4;
        let original: Vec<f32> = (0..16).map(|v| v as f32).collect();
        let mut p = original.clone();
        // The pixel at (1, 0) — box [1, 0, 2, 1] — goes to the turned box's corner.
        let at = [1.0, 0.0, 2.0, 1.0];
        let mut label = Labelled {
            kind: DefectKind::Hole,
            box_px: at,
        };
        turn(&mut p, side, std::iter::once(&mut label));
        let [x0, y0, ..] = label.box_px;
        assert_eq!(p[y0 as usize * side + x0 as usize], original[1]);
        turn(&mut p, side, std::iter::once(&mut label));
        assert_eq!((p, label.box_px), (original, at), "twice is once undone");
    }

    #[test]
    fn a_look_keeps_the_crop_finite_and_its_boxes_inside() {
        let side = 32;
        let mut rng = Pcg64Mcg::seed_from_u64(7);
        for _ in 0..20 {
            let mut pixels: Vec<f32> = (0..side * side).map(|i| (i % 251) as f32).collect();
            let defect = Labelled {
                kind: DefectKind::Hole,
                box_px: [3.0, 5.0, 10.0, 9.0],
            };
            let mut boxes = [defect];
            apply(&mut pixels, side, &mut boxes, &mut [], &mut rng);
            assert!(pixels.iter().all(|p| p.is_finite()));
            let [x0, y0, x1, y1] = boxes[0].box_px;
            assert!(0.0 <= x0 && x0 < x1 && x1 <= side as f32);
            assert!(0.0 <= y0 && y0 < y1 && y1 <= side as f32);
            assert_eq!((x1 - x0, y1 - y0), (7.0, 4.0), "a turn keeps a box's size");
        }
    }
}
