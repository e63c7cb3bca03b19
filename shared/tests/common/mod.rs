//! Synthetic test images shared by the integration tests.
#![allow(dead_code)]

/// A deterministic 64-bit generator (SplitMix64), so tests need no RNG crate.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A natural-looking tactile image: a smooth background, a few pressed blobs of different
/// sizes, a raised bar with sharp edges, fine texture and mild noise. `sharpness` in 0..=1
/// scales the edges' steepness and the texture, as deeper contact would.
pub fn tactile_scene(w: usize, h: usize, seed: u64, sharpness: f64) -> Vec<u8> {
    let mut rng = Rng::new(seed);
    let blobs: Vec<(f64, f64, f64, f64)> = (0..5)
        .map(|_| {
            (
                rng.unit() * w as f64,
                rng.unit() * h as f64,
                2.0 + rng.unit() * w.min(h) as f64 / 6.0,
                40.0 + rng.unit() * 60.0,
            )
        })
        .collect();
    let bar_x = w as f64 * (0.3 + 0.4 * rng.unit());
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let (fx, fy) = (x as f64, y as f64);
            let mut v = 90.0 + 25.0 * (fx / w as f64) + 15.0 * (fy / h as f64);
            for &(bx, by, r, a) in &blobs {
                let d2 = ((fx - bx).powi(2) + (fy - by).powi(2)) / (r * r);
                v += a * (-d2).exp();
            }
            // A bar whose edges sharpen with contact depth.
            let edge = 1.0 / (1.0 + (-(fx - bar_x).abs() * (0.3 + 2.0 * sharpness) + 3.0).exp());
            v += 50.0 * (1.0 - edge);
            v += 12.0 * sharpness * ((fx * 0.9).sin() * (fy * 0.7).cos());
            v += (rng.unit() - 0.5) * 4.0;
            out.push(v.clamp(0.0, 255.0).round() as u8);
        }
    }
    out
}

/// A vertical step edge: `lo` left of `x0`, `hi` from `x0` on.
pub fn step_edge(w: usize, h: usize, x0: usize, lo: u8, hi: u8) -> Vec<u8> {
    (0..w * h)
        .map(|i| if i % w < x0 { lo } else { hi })
        .collect()
}
