//! Shared helpers for the end-to-end tests: synthetic rolling acquisitions until the
//! simulator exists.

/// `n` frames of a dot pattern seen through a rolling, curved gel, already in belt
/// coordinates: frame `k` presses hardest (full contrast) around row `(k + ½)·h/n`, the
/// roller's apex at that moment, and ever more weakly away from it, as contact depth falls
/// off on a cylinder.
pub fn rolling_frames(w: usize, h: usize, n: usize) -> Vec<Vec<u8>> {
    let band = h as f64 / n as f64;
    (0..n)
        .map(|k| {
            let apex = (k as f64 + 0.5) * band;
            (0..w * h)
                .map(|i| {
                    let (x, y) = (i % w, i / w);
                    let depth = (-((y as f64 - apex) / band).powi(2)).exp();
                    let dot = if (x % 8 < 3) && (y % 8 < 3) { 1.0 } else { 0.0 };
                    (110.0 + 120.0 * depth * dot).round() as u8
                })
                .collect()
        })
        .collect()
}

/// Mean absolute 4-neighbour Laplacian over rows `y0..y1`: the local contrast a pressed
/// pattern shows.
pub fn strip_contrast(img: &[u8], w: usize, y0: usize, y1: usize) -> f64 {
    let at = |x: usize, y: usize| f64::from(img[y * w + x]);
    let mut sum = 0.0;
    let mut count = 0.0;
    for y in y0.max(1)..y1.min(img.len() / w - 1) {
        for x in 1..w - 1 {
            sum +=
                (at(x - 1, y) + at(x + 1, y) + at(x, y - 1) + at(x, y + 1) - 4.0 * at(x, y)).abs();
            count += 1.0;
        }
    }
    sum / count
}
