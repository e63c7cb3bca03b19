//! Light calibration from an image of a ball of known radius pressed into the gel.
//!
//! Over the contact disc the surface is the ball, so every pixel's normal is known:
//! `n = (ρx, ρy, √(R² − ρ²)) / R` at distance `ρ` (mm) from the disc's centre; off the
//! disc it is `ẑ`. Each channel's ratio to the background is, by the model of
//! [`super::stereo`], `t_c = n · m_c` with `m_c = gain_c · l_c / l_c,z`: a linear least
//! squares fit of `m_c` over the disc (and a sample of flat gel) gives the direction
//! `l_c = m_c / |m_c|` and the gain `m_c,z`.
//!
//! The disc is found as the largest connected region whose shading departs from the
//! background, its centre the region's centroid and its radius the 98th percentile of
//! its pixels' distances from it; `--circle x,y,r` overrides.

use super::lights::Lights;
use crate::Error;
use nalgebra::{Matrix3, Vector3};
use rollfuse_io::image::Planes;
use rollfuse_io::{invalid, require};

/// A circle in pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Circle {
    /// Centre column.
    pub x: f64,
    /// Centre row.
    pub y: f64,
    /// Radius.
    pub r: f64,
}

/// The sum over channels of `|I/B − 1|`: how far each pixel's shading is from the flat gel.
fn departure(image: &Planes, background: &Planes) -> Vec<f64> {
    (0..image.width * image.height)
        .map(|i| {
            (0..3)
                .map(|c| {
                    let b = f64::from(background.planes[c][i].max(super::stereo::DARK));
                    (f64::from(image.planes[c][i]) / b - 1.0).abs()
                })
                .sum()
        })
        .collect()
}

/// Finds the contact disc automatically.
pub fn find_disc(image: &Planes, background: &Planes) -> Result<Circle, Error> {
    let (w, h) = (image.width, image.height);
    let dev = departure(image, background);
    let mut sorted = dev.clone();
    let mid = sorted.len() / 2;
    let median = *sorted.select_nth_unstable_by(mid, f64::total_cmp).1;
    let mut spread: Vec<f64> = dev.iter().map(|d| (d - median).abs()).collect();
    let mad = *spread.select_nth_unstable_by(mid, f64::total_cmp).1;
    let threshold = (median + 8.0 * 1.4826 * mad).max(0.05);
    let mask: Vec<bool> = dev.iter().map(|&d| d > threshold).collect();
    // The largest 4-connected region.
    let mut label = vec![usize::MAX; w * h];
    let mut best: Vec<usize> = Vec::new();
    for start in 0..w * h {
        if !mask[start] || label[start] != usize::MAX {
            continue;
        }
        let mut region = vec![start];
        label[start] = start;
        let mut k = 0;
        while k < region.len() {
            let i = region[k];
            k += 1;
            let (x, y) = (i % w, i / w);
            let around = [
                (x > 0).then(|| i - 1),
                (x + 1 < w).then(|| i + 1),
                (y > 0).then(|| i - w),
                (y + 1 < h).then(|| i + w),
            ];
            for j in around.into_iter().flatten() {
                if mask[j] && label[j] == usize::MAX {
                    label[j] = start;
                    region.push(j);
                }
            }
        }
        if region.len() > best.len() {
            best = region;
        }
    }
    if best.len() < 30 {
        invalid!("no contact disc found in the image: pass its position with --circle x,y,r");
    }
    let n = best.len() as f64;
    let cx = best.iter().map(|&i| (i % w) as f64).sum::<f64>() / n;
    let cy = best.iter().map(|&i| (i / w) as f64).sum::<f64>() / n;
    let mut dist: Vec<f64> = best
        .iter()
        .map(|&i| ((i % w) as f64 - cx).hypot((i / w) as f64 - cy))
        .collect();
    let k = ((dist.len() - 1) as f64 * 0.98) as usize;
    let r = *dist.select_nth_unstable_by(k, f64::total_cmp).1;
    Ok(Circle { x: cx, y: cy, r })
}

/// The least tilt of the ball's surface within the fitted disc, degrees: below it the
/// light directions cannot be told apart.
pub const MIN_TILT_DEG: f64 = 5.0;

/// Fits the lights from `image` of a ball of `radius_mm` at `mm_per_px`, with the disc
/// found automatically unless `circle` is given.
pub fn calibrate(
    image: &Planes,
    background: Option<&Planes>,
    radius_mm: f64,
    mm_per_px: f64,
    circle: Option<Circle>,
) -> Result<(Lights, Circle), Error> {
    if !image.is_rgb() {
        invalid!("calibration needs an RGB image (one LED per channel), this one is gray");
    }
    require!(
        radius_mm.is_finite() && radius_mm > 0.0,
        "--radius-mm must be positive, got {radius_mm}"
    );
    require!(
        mm_per_px.is_finite() && mm_per_px > 0.0,
        "--mm-per-px must be positive, got {mm_per_px}"
    );
    let estimated;
    let background = match background {
        Some(b) => {
            require!(
                b.is_rgb() && (b.width, b.height) == (image.width, image.height),
                "the background must be an RGB image of the same size as the ball's"
            );
            b
        }
        None => {
            estimated = super::stereo::smooth_background(image);
            &estimated
        }
    };
    let circle = match circle {
        Some(c) => c,
        None => find_disc(image, background)?,
    };
    check_disc(&circle, radius_mm, mm_per_px)?;
    let ball = Ball {
        circle,
        radius_mm,
        mm_per_px,
    };
    let (ata, atb, disc_pixels) = normal_equations(image, background, &ball);
    require!(disc_pixels >= 20, "the contact disc covers too few pixels");
    let inv = ata
        .try_inverse()
        .ok_or_else(|| Error::Invalid("the disc's normals do not determine the lights".into()))?;
    let m: [Vector3<f64>; 3] = std::array::from_fn(|c| inv * atb[c]);
    let dir = |v: &Vector3<f64>| {
        let u = v / v.norm();
        [u[0], u[1], u[2]]
    };
    let lights = Lights {
        mm_per_px,
        red: dir(&m[0]),
        green: dir(&m[1]),
        blue: dir(&m[2]),
        gains: [m[0][2], m[1][2], m[2][2]],
    };
    lights.check()?;
    Ok((lights, circle))
}

/// Refuses a contact disc too small, or one whose normals tilt too little to tell the
/// LEDs apart, for a ball of `radius_mm` seen at `mm_per_px`.
fn check_disc(circle: &Circle, radius_mm: f64, mm_per_px: f64) -> Result<(), Error> {
    require!(
        circle.r > 2.0 && circle.r.is_finite(),
        "the contact disc (radius {:.1} px) is too small to calibrate from",
        circle.r
    );
    let disc_mm = circle.r * mm_per_px;
    require!(
        disc_mm < radius_mm,
        "the contact disc ({disc_mm:.2} mm in radius) is wider than the ball ({radius_mm} mm): \
         check --radius-mm and --mm-per-px"
    );
    // The fit uses the disc's inner 90 %: its normals must tilt enough to tell the LEDs
    // apart (and a ball far larger than its disc would overflow the cap's squares).
    let tilt_deg = (0.9 * disc_mm / radius_mm).asin().to_degrees();
    require!(
        tilt_deg >= MIN_TILT_DEG,
        "the ball ({radius_mm} mm in radius) is too large for its contact disc ({disc_mm:.2} mm): \
         its surface tilts {tilt_deg:.2}° at most, under {MIN_TILT_DEG}°; check --radius-mm and \
         --mm-per-px, or press a smaller ball"
    );
    Ok(())
}

/// The calibration ball as the image shows it.
struct Ball {
    /// Its contact disc, pixels.
    circle: Circle,
    radius_mm: f64,
    mm_per_px: f64,
}

/// Normal equations of t_c = n · m_c, for the three channels at once: the disc's inner
/// 90 % with the ball's normals, and flat belt well outside it (every fourth pixel). Also
/// the disc pixels counted.
fn normal_equations(
    image: &Planes,
    background: &Planes,
    ball: &Ball,
) -> (Matrix3<f64>, [Vector3<f64>; 3], usize) {
    let (w, h) = (image.width, image.height);
    let (circle, radius_mm, mm_per_px) = (&ball.circle, ball.radius_mm, ball.mm_per_px);
    let mut ata = Matrix3::<f64>::zeros();
    let mut atb = [Vector3::<f64>::zeros(); 3];
    let mut add = |n: Vector3<f64>, i: usize| {
        ata += n * n.transpose();
        for (c, b) in atb.iter_mut().enumerate() {
            let bg = f64::from(background.planes[c][i].max(super::stereo::DARK));
            *b += n * (f64::from(image.planes[c][i]) / bg);
        }
    };
    let mut disc_pixels = 0usize;
    for y in 0..h {
        for x in 0..w {
            let (dx, dy) = (x as f64 - circle.x, y as f64 - circle.y);
            let d = dx.hypot(dy);
            let i = y * w + x;
            if d < 0.9 * circle.r {
                let (rx, ry) = (dx * mm_per_px, dy * mm_per_px);
                let z = (radius_mm * radius_mm - rx * rx - ry * ry).sqrt();
                add(Vector3::new(rx, ry, z) / radius_mm, i);
                disc_pixels += 1;
            } else if d > 1.5 * circle.r && (x + y) % 4 == 0 {
                add(Vector3::z(), i);
            }
        }
    }
    (ata, atb, disc_pixels)
}
