//! Height from gradients: the exact least-squares integration with Neumann boundaries,
//! solved by the discrete cosine transform.
//!
//! Given forward differences `gx[y][x] ≈ h[y][x+1] − h[y][x]` (`x < W − 1`) and
//! `gy[y][x] ≈ h[y+1][x] − h[y][x]` (`y < H − 1`), the height map minimizing
//! `Σ (Dx h − gx)² + Σ (Dy h − gy)²` solves the normal equations
//! `(DxᵀDx + DyᵀDy) h = Dxᵀgx + Dyᵀgy`. `DxᵀDx` is the 1-D Laplacian with Neumann
//! (reflecting) ends, diagonalized by the DCT-II with eigenvalues
//! `μₖ = 2 − 2·cos(πk/N)`, `k = 0 … N−1` — starting at 0 for the constant, which the
//! gradients cannot see: it is set so the mean height is 0. So: DCT-II of the right-hand
//! side along both axes, divide by `μₖ + μₗ`, inverse transform. Exact up to rounding: a
//! height map is recovered from its own forward differences (test
//! `recovers_a_height_map_from_its_own_differences`, 1e-6 relative, odd sizes too).

use crate::Error;
use rayon::prelude::*;
use rollfuse_io::{invalid, require};
use rustdct::{DctNum, DctPlanner};

/// Integrates forward-difference gradients (`w × h` each, row-major; the last column of
/// `gx` and the last row of `gy` are ignored) into heights with mean 0, in the
/// gradients' units times pixels. Refuses non-finite gradients, and gradients so large
/// that the heights would overflow.
pub fn integrate(gx: &[f64], gy: &[f64], w: usize, h: usize) -> Result<Vec<f64>, Error> {
    require!(w >= 1 && h >= 1, "an empty gradient field");
    require!(
        gx.len() == w * h && gy.len() == w * h,
        "gradient fields of {} and {} values for a {w}×{h} map",
        gx.len(),
        gy.len()
    );
    if let Some(i) = gx.iter().chain(gy).position(|v| !v.is_finite()) {
        invalid!("gradient {i} is not finite: refusing to integrate NaN or infinity");
    }
    let f = divergence(w, h, |i| gx[i], |i| gy[i]);
    let heights = solve_neumann(f, w, h)?;
    // Finite gradients near f64::MAX still overflow the transform's sums.
    require!(
        heights.iter().all(|v| v.is_finite()),
        "gradients too large to integrate: the heights overflow f64"
    );
    Ok(heights)
}

/// The right-hand side `Dxᵀgx + Dyᵀgy` of the normal equations, for gradients given by
/// `gx(i)` (pixel `i`'s difference to its right neighbour, asked only where there is
/// one) and `gy(i)` (to the one below): each difference leaves pixel `i` and enters its
/// neighbour, `(Dxᵀg)[x] = g[x−1] − g[x]`.
pub fn divergence<T: DctNum>(
    w: usize,
    h: usize,
    gx: impl Fn(usize) -> T,
    gy: impl Fn(usize) -> T,
) -> Vec<T> {
    let mut f = vec![T::zero(); w * h];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if x + 1 < w {
                let g = gx(i);
                f[i] = f[i] - g;
                f[i + 1] = f[i + 1] + g;
            }
            if y + 1 < h {
                let g = gy(i);
                f[i] = f[i] - g;
                f[i + w] = f[i + w] + g;
            }
        }
    }
    f
}

/// Solves `(DxᵀDx + DyᵀDy) h = f` for the height map with mean 0, `f` being the
/// right-hand side (`w × h`, row-major; its values must sum to zero, as a divergence does),
/// in place of `f`. In `f64` (what the exactness test holds to 1e-6) or `f32` (twice the
/// vector width, what depth maps use: their heights are good to far less).
pub fn solve_neumann<T: DctNum>(mut f: Vec<T>, w: usize, h: usize) -> Result<Vec<T>, Error> {
    require!(
        f.len() == w * h && w >= 1 && h >= 1,
        "a {w}×{h} map needs {} values",
        w * h
    );
    let mut planner = DctPlanner::new();
    let (dct_w, dct_h) = (planner.plan_dct2(w), planner.plan_dct2(h));
    // Each worker keeps one scratch buffer for all its rows (rustdct's plain `process_*`
    // would allocate one per row).
    let scratch_len = dct_w.get_scratch_len().max(dct_h.get_scratch_len());
    let rows = |data: &mut [T], len: usize, f: &(dyn Fn(&mut [T], &mut [T]) + Sync)| {
        data.par_chunks_mut(len)
            .for_each_init(|| vec![T::zero(); scratch_len], |scratch, r| f(r, scratch));
    };
    // Forward: rows, transpose, rows (now along y), spectrum laid out [kx][ky].
    rows(&mut f, w, &|r, s| dct_w.process_dct2_with_scratch(r, s));
    let mut t = vec![T::zero(); w * h];
    transpose(&f, &mut t, w, h);
    rows(&mut t, h, &|r, s| dct_h.process_dct2_with_scratch(r, s));
    let mu = |k: usize, n: usize| 2.0 - 2.0 * (std::f64::consts::PI * k as f64 / n as f64).cos();
    let mu_y: Vec<f64> = (0..h).map(|k| mu(k, h)).collect();
    // rustdct's DCT-III of a DCT-II gives the signal times N/2, per axis: folded in here.
    let scale = 4.0 / (w as f64 * h as f64);
    t.par_chunks_mut(h).enumerate().for_each(|(kx, row)| {
        let mx = mu(kx, w);
        for (v, &my) in row.iter_mut().zip(&mu_y) {
            let d = mx + my;
            let factor = if d > 0.0 { scale / d } else { 0.0 };
            *v = *v * T::from_f64(factor).unwrap_or_else(T::zero);
        }
    });
    // Inverse: DCT-III along y, transpose back (into `f`'s memory), DCT-III along x.
    rows(&mut t, h, &|r, s| dct_h.process_dct3_with_scratch(r, s));
    transpose(&t, &mut f, h, w);
    rows(&mut f, w, &|r, s| dct_w.process_dct3_with_scratch(r, s));
    Ok(f)
}

/// Writes the transpose of the `w × h` row-major `src` into `dst`, in cache-sized blocks.
fn transpose<T: Copy>(src: &[T], dst: &mut [T], w: usize, h: usize) {
    const B: usize = 32;
    for y0 in (0..h).step_by(B) {
        for x0 in (0..w).step_by(B) {
            for y in y0..(y0 + B).min(h) {
                for x in x0..(x0 + B).min(w) {
                    dst[x * h + y] = src[y * w + x];
                }
            }
        }
    }
}

/// Forward differences of `heights` (`w × h`): the gradients [`integrate`] takes.
pub fn forward_differences(heights: &[f64], w: usize, h: usize) -> (Vec<f64>, Vec<f64>) {
    let mut gx = vec![0f64; w * h];
    let mut gy = vec![0f64; w * h];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if x + 1 < w {
                gx[i] = heights[i + 1] - heights[i];
            }
            if y + 1 < h {
                gy[i] = heights[i + w] - heights[i];
            }
        }
    }
    (gx, gy)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    /// A smooth random surface: a few random cosines and Gaussian bumps.
    fn smooth(w: usize, h: usize, seed: u64) -> Vec<f64> {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        let waves: Vec<[f64; 4]> = (0..6)
            .map(|_| {
                [
                    rng.random_range(-3.0..3.0),
                    rng.random_range(0.0..0.2),
                    rng.random_range(0.0..0.2),
                    rng.random_range(0.0..6.3),
                ]
            })
            .collect();
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                waves
                    .iter()
                    .map(|[a, fx, fy, p]| a * (fx * x + fy * y + p).cos())
                    .sum::<f64>()
                    + 5.0
                        * (-((x - w as f64 / 3.0).powi(2) + (y - h as f64 / 2.0).powi(2)) / 40.0)
                            .exp()
            })
            .collect()
    }

    #[test]
    fn recovers_a_height_map_from_its_own_differences() {
        for (k, (w, h)) in [(64, 48), (33, 17), (1, 9), (7, 1), (101, 77)]
            .into_iter()
            .enumerate()
        {
            let truth = smooth(w, h, k as u64);
            let (gx, gy) = forward_differences(&truth, w, h);
            let got = integrate(&gx, &gy, w, h).unwrap();
            let mean = truth.iter().sum::<f64>() / truth.len() as f64;
            let range = truth.iter().fold(f64::MIN, |m, &v| m.max(v))
                - truth.iter().fold(f64::MAX, |m, &v| m.min(v));
            let worst = truth
                .iter()
                .zip(&got)
                .map(|(t, g)| (t - mean - g).abs())
                .fold(0.0, f64::max);
            assert!(
                worst <= 1e-6 * range.max(1e-12),
                "{w}×{h}: worst error {worst:e} of a range {range}"
            );
        }
    }

    #[test]
    fn scale_is_exact_for_a_ramp() {
        // A plane of slope 0.25 per pixel: the recovered plane has the same slope.
        let (w, h) = (40, 30);
        let gx = vec![0.25; w * h];
        let gy = vec![0.0; w * h];
        let got = integrate(&gx, &gy, w, h).unwrap();
        for y in 0..h {
            for x in 0..w - 1 {
                assert!((got[y * w + x + 1] - got[y * w + x] - 0.25).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn non_finite_gradients_and_bad_sizes_are_refused() {
        let mut gx = vec![0.0; 12];
        gx[5] = f64::NAN;
        assert!(integrate(&gx, &[0.0; 12], 4, 3).is_err());
        gx[5] = f64::INFINITY;
        assert!(integrate(&gx, &[0.0; 12], 4, 3).is_err());
        assert!(integrate(&[0.0; 11], &[0.0; 12], 4, 3).is_err());
        // Huge but finite gradients integrate to finite heights.
        let huge = integrate(&[1e150; 12], &[-1e150; 12], 4, 3).unwrap();
        assert!(huge.iter().all(|v| v.is_finite()));
    }
}
