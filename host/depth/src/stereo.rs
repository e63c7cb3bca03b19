//! Photometric stereo: surface normals from the three LED channels, and the slopes they
//! give.
//!
//! Model (the one the simulator renders): channel `c` of a pixel with unit normal `n` is
//! `I_c = k_c · max(0, n·l_c)`, `k_c` the pixel's albedo times the LED's brightness. The
//! background — the gel with nothing pressed in, `n = ẑ` — is `B_c = k_c · l_c,z`, so the
//! ratio `t_c = I_c / B_c` is free of `k_c` (vignetting, uneven LEDs) and
//! `s_c = t_c · l_c,z / gain_c = n·l_c`. With `L` the light matrix (one direction per
//! row), `n ∝ L⁻¹ s` (the inverse computed once). Slopes: `∂h/∂x = −n_x/n_z`,
//! `∂h/∂y = −n_y/n_z` (height toward the camera), clamped to [`MAX_SLOPE`].
//!
//! The background is the no-contact frame when given, else a smooth estimate: a
//! quadratic surface fitted to each channel with the contact (outliers) left out.

use super::lights::Lights;
use crate::Error;
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use rollfuse_io::image::Planes;
use rollfuse_io::{invalid, require};

/// The steepest slope kept (about 78°): beyond it the shading is too weak and too
/// sensitive to noise; steeper slopes are clamped to it.
pub const MAX_SLOPE: f64 = 5.0;

/// A background level below this (gray levels) is too dark to divide by.
pub const DARK: f32 = 4.0;

/// Slopes and where they are valid.
#[derive(Debug, Clone)]
pub struct Slopes {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// `∂h/∂x` (height per unit of x, both in the same unit).
    pub p: Vec<f64>,
    /// `∂h/∂y`.
    pub q: Vec<f64>,
    /// Pixels with a usable normal (lit, facing the camera).
    pub valid: Vec<bool>,
}

/// A smooth background per channel: a quadratic in `(x, y)` fitted by least squares,
/// twice refitted without the pixels more than 3 robust standard deviations off (the
/// contact).
pub fn smooth_background(image: &Planes) -> Planes {
    let (w, h) = (image.width, image.height);
    let planes = image
        .planes
        .iter()
        .map(|plane| {
            let mut keep = vec![true; w * h];
            let mut coef = SVector::<f64, 6>::zeros();
            for _round in 0..3 {
                let mut ata = SMatrix::<f64, 6, 6>::zeros();
                let mut atb = SVector::<f64, 6>::zeros();
                // Every other pixel is plenty for six parameters.
                for y in (0..h).step_by(2) {
                    for x in (0..w).step_by(2) {
                        if !keep[y * w + x] {
                            continue;
                        }
                        let a = basis(x, y, w, h);
                        ata += a * a.transpose();
                        atb += a * f64::from(plane[y * w + x]);
                    }
                }
                coef = match ata.try_inverse() {
                    Some(inv) => inv * atb,
                    // Too few pixels for a quadratic (a tiny image): the mean level.
                    None => {
                        let mut c = SVector::zeros();
                        c[0] =
                            plane.iter().map(|&v| f64::from(v)).sum::<f64>() / plane.len() as f64;
                        c
                    }
                };
                let residuals: Vec<f64> = (0..w * h)
                    .map(|i| f64::from(plane[i]) - coef.dot(&basis(i % w, i / w, w, h)))
                    .collect();
                let mut abs: Vec<f64> = residuals.iter().map(|r| r.abs()).collect();
                let mid = abs.len() / 2;
                let mad = *abs.select_nth_unstable_by(mid, f64::total_cmp).1;
                let limit = (3.0 * 1.4826 * mad).max(1.0);
                for (k, r) in keep.iter_mut().zip(&residuals) {
                    *k = r.abs() <= limit;
                }
            }
            (0..w * h)
                .map(|i| coef.dot(&basis(i % w, i / w, w, h)) as f32)
                .collect()
        })
        .collect();
    Planes {
        width: w,
        height: h,
        planes,
    }
}

/// `1, x, y, x², xy, y²` on coordinates scaled to about −1..1.
fn basis(x: usize, y: usize, w: usize, h: usize) -> SVector<f64, 6> {
    let u = 2.0 * x as f64 / w.max(2) as f64 - 1.0;
    let v = 2.0 * y as f64 / h.max(2) as f64 - 1.0;
    SVector::<f64, 6>::from([1.0, u, v, u * u, u * v, v * v])
}

/// Normals → slopes for an RGB `image` under `lights`, against `background` (same size).
pub fn slopes(image: &Planes, background: &Planes, lights: &Lights) -> Result<Slopes, Error> {
    if !image.is_rgb() {
        invalid!("depth needs an RGB image (one LED per channel), this one is gray");
    }
    require!(
        background.is_rgb() && (background.width, background.height) == (image.width, image.height),
        "the background is {}×{} {}, the image {}×{} RGB: they must match",
        background.width,
        background.height,
        if background.is_rgb() { "RGB" } else { "gray" },
        image.width,
        image.height
    );
    lights.check()?;
    let inv: Matrix3<f64> = lights
        .matrix()
        .try_inverse()
        .ok_or_else(|| Error::Invalid("the light matrix is singular".into()))?;
    let dirs = lights.directions();
    let scale: [f64; 3] = std::array::from_fn(|c| dirs[c][2] / lights.gains[c]);
    let (w, h) = (image.width, image.height);
    let n = w * h;
    let (mut p, mut q, mut valid) = (vec![0f64; n], vec![0f64; n], vec![false; n]);
    let mut dark = 0usize;
    for i in 0..n {
        let mut s = Vector3::zeros();
        let mut lit = true;
        for c in 0..3 {
            let b = background.planes[c][i];
            if b < DARK {
                lit = false;
            }
            s[c] = f64::from(image.planes[c][i]) / f64::from(b.max(DARK)) * scale[c];
        }
        if !lit {
            dark += 1;
            continue;
        }
        let m = inv * s;
        // A normal facing away from the camera, or a black pixel: nothing to say.
        if m[2] <= 1e-3 {
            continue;
        }
        let (mut px, mut qy) = (-m[0] / m[2], -m[1] / m[2]);
        let slope = (px * px + qy * qy).sqrt();
        if slope > MAX_SLOPE {
            px *= MAX_SLOPE / slope;
            qy *= MAX_SLOPE / slope;
        }
        p[i] = px;
        q[i] = qy;
        valid[i] = true;
    }
    if dark * 2 > n {
        invalid!(
            "the background is dark (below {DARK} gray levels) in {} % of the image: no light to work with",
            dark * 100 / n
        );
    }
    if valid.iter().filter(|&&v| v).count() * 2 < n {
        invalid!(
            "fewer than half the pixels have a usable normal: is the image dark or not lit by these LEDs?"
        );
    }
    Ok(Slopes {
        width: w,
        height: h,
        p,
        q,
        valid,
    })
}
