//! What the first frames of a roll show about contact, measured before anything is known
//! of where the frames lie on the belt.
//!
//! - **Background.** The frame-fixed part of every frame — the gel's own shading,
//!   vignetting, the band that the pressed gel makes across the frame — is the per-pixel
//!   median over the frames: the belt moves, so any one of its features covers a pixel in
//!   only a few of them. What is left, the residual, is the belt's features and noise.
//! - **Energy.** The residual smoothed over 3 × 3 pixels, its gradient's energy per frame
//!   row, averaged over the frames: the noise's energy where the gel does not touch the
//!   belt, more where features press in and are in focus.
//! - **Floor.** The energy's 10th percentile: the quietest rows, where the gel does not
//!   touch the belt.
//! - **Visibility** of each row, 0 at the floor to 1 at the peak: `√((E − floor)/(peak −
//!   floor))`, the contrast at which moving features appear there.
//! - **Window.** The run of rows around the peak at least half-way from the floor to the
//!   peak: where features are pressed in and sharp. When the peak does not stand out of
//!   the floor by [`STANDS_OUT`] times the spread of the quietest half of the rows (and by
//!   5 % of the floor), nothing varies along the frame — no features at all (a bare or
//!   still belt), or features equally visible on every row — and no window is measured.

use super::window::ContactWindow;
use rollfuse_io::image::Planes;

/// Why no contact window could be measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum NoContact {
    /// Fewer than [`ContactProfile::MIN_FRAMES`] frames.
    TooFewFrames,
    /// Frames under 8 × 12 pixels.
    TooSmall,
    /// No row shows moving features more than the others: a bare belt, one that did not
    /// move, or one equally visible on every row.
    NothingVaries,
}

impl NoContact {
    /// The reason, as printed.
    pub fn describe(self) -> &'static str {
        match self {
            NoContact::TooFewFrames => "too few frames to tell the belt from the gel",
            NoContact::TooSmall => "frames too small to measure",
            NoContact::NothingVaries => {
                "no rows show moving features more than the others (a bare or still belt, or \
                 features equally visible on every row)"
            }
        }
    }
}

/// The contact measured on a roll's first frames.
#[derive(Debug, Clone)]
pub struct ContactProfile {
    /// Frame width.
    pub width: usize,
    /// Frame height.
    pub height: usize,
    /// The frame-fixed gray levels: the per-pixel median, `width × height`.
    pub background: Vec<f32>,
    /// The sensor's noise, gray levels (a standard deviation, from the median absolute
    /// difference of neighbouring residual pixels).
    pub noise: f32,
    /// Per frame row, the visibility of moving features, 0..=1 (all 1 when nothing could be
    /// measured).
    pub visibility: Vec<f32>,
    /// The contact window, or why none was measured.
    pub window: Result<ContactWindow, NoContact>,
}

/// Frames of a roll the contact is measured over before the first is placed.
pub const MEASURE_FRAMES: usize = 32;

/// The peak must stand this many times the quiet rows' spread above the floor for the
/// energy to count as varying (the spread of a mean over many pixels and frames is small:
/// sparse features a few frames show are still many times it).
pub const STANDS_OUT: f64 = 20.0;

impl ContactProfile {
    /// Frames the measurement needs at least.
    pub const MIN_FRAMES: usize = 3;

    /// Measures the profile on `frames` (one size, in acquisition order).
    pub fn measure(frames: &[&Planes]) -> Self {
        let Some(first) = frames.first() else {
            return Self::unmeasured(0, 0, Vec::new(), NoContact::TooFewFrames);
        };
        let (w, h) = (first.width, first.height);
        let grays: Vec<_> = frames.iter().map(|f| f.gray()).collect();
        let background = median_frame(&grays, w * h);
        if frames.len() < Self::MIN_FRAMES {
            return Self::unmeasured(w, h, background, NoContact::TooFewFrames);
        }
        if w < 8 || h < 12 {
            return Self::unmeasured(w, h, background, NoContact::TooSmall);
        }
        let noise = noise_sigma(&grays, &background, w, h);
        let energy = smoothed(&row_energy(&grays, &background, w, h), 4);
        let mut sorted = energy.clone();
        sorted.sort_by(f64::total_cmp);
        let floor = sorted[sorted.len() / 10];
        let quiet = &sorted[..sorted.len() / 2];
        let quiet_median = quiet[quiet.len() / 2];
        let mut deviations: Vec<f64> = quiet.iter().map(|e| (e - quiet_median).abs()).collect();
        deviations.sort_by(f64::total_cmp);
        let spread = deviations[deviations.len() / 2];
        let (peak_row, peak) = energy
            .iter()
            .copied()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap_or((0, 0.0));
        if !(peak - floor > STANDS_OUT * spread && peak > 1.05 * floor && peak > 0.0) {
            return Self {
                noise,
                ..Self::unmeasured(w, h, background, NoContact::NothingVaries)
            };
        }
        let visibility = energy
            .iter()
            .map(|&e| (((e - floor) / (peak - floor)).clamp(0.0, 1.0)).sqrt() as f32)
            .collect();
        let half = floor + 0.5 * (peak - floor);
        let mut top = peak_row;
        while top > 0 && energy[top - 1] >= half {
            top -= 1;
        }
        let mut bottom = peak_row + 1;
        while bottom < h && energy[bottom] >= half {
            bottom += 1;
        }
        Self {
            width: w,
            height: h,
            background,
            noise,
            visibility,
            window: Ok(ContactWindow {
                top,
                rows: bottom - top,
            }),
        }
    }

    fn unmeasured(w: usize, h: usize, background: Vec<f32>, why: NoContact) -> Self {
        Self {
            width: w,
            height: h,
            background,
            noise: 0.0,
            visibility: vec![1.0; h],
            window: Err(why),
        }
    }
}

/// The per-pixel median of `grays`.
fn median_frame(grays: &[std::borrow::Cow<'_, [f32]>], pixels: usize) -> Vec<f32> {
    let mut values = Vec::with_capacity(grays.len());
    (0..pixels)
        .map(|i| {
            values.clear();
            values.extend(grays.iter().filter_map(|g| g.get(i).copied()));
            if values.is_empty() {
                return 0.0;
            }
            let mid = values.len() / 2;
            *values.select_nth_unstable_by(mid, f32::total_cmp).1
        })
        .collect()
}

/// The noise's standard deviation: the median absolute difference of horizontally
/// neighbouring residual pixels (every fourth row), scaled to a Gaussian's σ.
fn noise_sigma(grays: &[std::borrow::Cow<'_, [f32]>], bg: &[f32], w: usize, h: usize) -> f32 {
    let mut diffs: Vec<f32> = Vec::new();
    for g in grays {
        for y in (0..h).step_by(4) {
            let (row, b) = (&g[y * w..(y + 1) * w], &bg[y * w..(y + 1) * w]);
            diffs.extend((1..w).map(|x| ((row[x] - b[x]) - (row[x - 1] - b[x - 1])).abs()));
        }
    }
    if diffs.is_empty() {
        return 0.0;
    }
    let mid = diffs.len() / 2;
    let mad = *diffs.select_nth_unstable_by(mid, f32::total_cmp).1;
    // The difference of two samples has √2 times their σ; a Gaussian's MAD is 0.6745 σ.
    mad / (0.6745 * std::f32::consts::SQRT_2)
}

/// Per frame row, the residual's gradient energy after a 3 × 3 box, averaged over the
/// frames and the row (the first and last rows copy their neighbours).
fn row_energy(grays: &[std::borrow::Cow<'_, [f32]>], bg: &[f32], w: usize, h: usize) -> Vec<f64> {
    let mut energy = vec![0f64; h];
    let mut boxed = vec![0f32; w * h];
    for g in grays {
        box3(g, bg, w, h, &mut boxed);
        for (y, e) in energy.iter_mut().enumerate().take(h - 2).skip(1) {
            let (row, next) = (&boxed[y * w..(y + 1) * w], &boxed[(y + 1) * w..(y + 2) * w]);
            let sum: f32 = (1..w - 1)
                .map(|x| (next[x] - row[x]).powi(2) + (row[x + 1] - row[x]).powi(2))
                .sum();
            *e += f64::from(sum) / (w - 2) as f64;
        }
    }
    energy[0] = energy[1];
    energy[h - 2] = energy[h - 3];
    energy[h - 1] = energy[h - 3];
    let n = grays.len().max(1) as f64;
    energy.iter().map(|e| e / n).collect()
}

/// `out` = the 3 × 3 mean of `g − bg` (edges clamped).
fn box3(g: &[f32], bg: &[f32], w: usize, h: usize, out: &mut [f32]) {
    let at = |x: isize, y: isize| {
        let i = y.clamp(0, h as isize - 1) as usize * w + x.clamp(0, w as isize - 1) as usize;
        g[i] - bg[i]
    };
    for y in 0..h as isize {
        for x in 0..w as isize {
            let mut s = 0.0;
            for dy in -1..=1 {
                for dx in -1..=1 {
                    s += at(x + dx, y + dy);
                }
            }
            out[y as usize * w + x as usize] = s / 9.0;
        }
    }
}

/// `values` averaged over `2r + 1` neighbours (fewer at the ends).
fn smoothed(values: &[f64], r: usize) -> Vec<f64> {
    let n = values.len();
    (0..n)
        .map(|i| {
            let (lo, hi) = (i.saturating_sub(r), (i + r + 1).min(n));
            values[lo..hi].iter().sum::<f64>() / (hi - lo) as f64
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Frames of `w × h` with noise, a fixed dark band across rows 40..60, and a textured
    /// belt moving `step` rows a frame whose texture's contrast peaks at row 50 and fades
    /// 15 rows either side.
    fn rolled(w: usize, h: usize, step: usize, frames: usize, textured: bool) -> Vec<Planes> {
        let hash = |a: usize, b: usize| {
            (a.wrapping_mul(2_654_435_761) ^ b.wrapping_mul(40_503)).wrapping_mul(2_246_822_519)
                >> 7
        };
        (0..frames)
            .map(|k| Planes {
                width: w,
                height: h,
                planes: vec![
                    (0..w * h)
                        .map(|i| {
                            let (x, y) = (i % w, i / w);
                            let band = if (40..60).contains(&y) { -20.0 } else { 0.0 };
                            let amp = 30.0 / (1.0 + ((y as f32 - 50.0) / 15.0).powi(2));
                            let belt = (hash(x / 3, (y + k * step) / 3) % 3) as f32 - 1.0;
                            let noise = (hash(i, k + 7) % 1000) as f32 / 1000.0 * 6.0 - 3.0;
                            let texture = if textured { amp * belt } else { 0.0 };
                            128.0 + band + texture + noise
                        })
                        .collect(),
                ],
            })
            .collect()
    }

    #[test]
    fn the_window_is_where_moving_features_stand_out() {
        let frames = rolled(60, 100, 5, 24, true);
        let refs: Vec<&Planes> = frames.iter().collect();
        let p = ContactProfile::measure(&refs);
        let win = p.window.unwrap();
        assert!((win.centre() - 50.0).abs() <= 3.0, "{win:?}");
        assert!((16..=44).contains(&win.rows), "{win:?}");
        // The band fixed to the frame is background, not contact: rows far from the
        // texture's peak stay near zero visibility although the band's edges are sharp.
        assert!(
            p.visibility[5] < 0.25 && p.visibility[95] < 0.25,
            "{:?}",
            p.visibility
        );
    }

    #[test]
    fn a_bare_belt_a_still_one_and_too_few_frames_are_said_so() {
        let bare = rolled(60, 100, 5, 24, false);
        let refs: Vec<&Planes> = bare.iter().collect();
        let p = ContactProfile::measure(&refs);
        assert_eq!(p.window, Err(NoContact::NothingVaries));
        // Uniform noise of ±3 has σ √3 ≈ 1.73.
        assert!((p.noise - 1.73).abs() < 0.3, "noise {}", p.noise);
        let still = rolled(60, 100, 0, 24, true);
        let refs: Vec<&Planes> = still.iter().collect();
        assert_eq!(
            ContactProfile::measure(&refs).window,
            Err(NoContact::NothingVaries)
        );
        let few = rolled(60, 100, 5, 2, true);
        let refs: Vec<&Planes> = few.iter().collect();
        let p = ContactProfile::measure(&refs);
        assert_eq!(p.window, Err(NoContact::TooFewFrames));
        assert!(p.visibility.iter().all(|&v| v == 1.0));
    }
}
