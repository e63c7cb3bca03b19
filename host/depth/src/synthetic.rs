//! A ball pressed into a flat gel, rendered with the Lambertian model of
//! [`super::stereo`] from exact normals: the ground truth the depth tests and benches
//! measure against.

use super::lights::Lights;
use rollfuse_io::image::Planes;

/// A ball of `radius_mm` pressed `press_mm` deep at pixel `centre`, seen `w × h` at
/// `lights.mm_per_px`, the flat gel at gray level `flat` in every channel. Returns the
/// true height map (mm, row-major) and the RGB image.
pub fn ball(
    (w, h): (usize, usize),
    centre: (f64, f64),
    radius_mm: f64,
    press_mm: f64,
    lights: &Lights,
    flat: f64,
) -> (Vec<f64>, Planes) {
    let k = lights.mm_per_px;
    let r2 = radius_mm * radius_mm;
    let mut height = vec![0f64; w * h];
    let mut planes = vec![vec![0f32; w * h]; 3];
    for y in 0..h {
        for x in 0..w {
            let (rx, ry) = ((x as f64 - centre.0) * k, (y as f64 - centre.1) * k);
            let rho2 = rx * rx + ry * ry;
            let z = (r2 - rho2).max(0.0).sqrt() - (radius_mm - press_mm);
            let n = if z > 0.0 {
                height[y * w + x] = z;
                [
                    rx / radius_mm,
                    ry / radius_mm,
                    (r2 - rho2).sqrt() / radius_mm,
                ]
            } else {
                [0.0, 0.0, 1.0]
            };
            for (c, l) in lights.directions().iter().enumerate() {
                let ndotl = (n[0] * l[0] + n[1] * l[1] + n[2] * l[2]).max(0.0);
                planes[c][y * w + x] = (flat * lights.gains[c] * ndotl / l[2]) as f32;
            }
        }
    }
    (
        height,
        Planes {
            width: w,
            height: h,
            planes,
        },
    )
}
