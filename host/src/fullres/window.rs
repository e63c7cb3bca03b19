//! The contact window: the frame rows in which a belt point is pressed into the gel.
//!
//! The roller's gel is a cylinder; a belt point touches it deepest under the apex and
//! less the farther it is along the frame, until the gel lifts off. A roll is fused band
//! by band from the frames in whose window the band lay ([`super::roll`]), so that the
//! many frames in which a point is out of contact — flat gel, noise that the saliency's
//! normalization raises to full weight — never outvote the few in which it is pressed.
//!
//! The window comes from, in order of preference:
//! - the user (`--window-rows`), centred on the apex row;
//! - the geometry ([`ContactWindow::from_geometry`]): the rows where the gel surface lies
//!   within half the press depth of the apex, `|y − apex| ≤ √(R² − (R − p/2)²) / (mm/px)`;
//! - the frames themselves ([`ContactWindow::measure`]): where along the frame the
//!   Laplacian's energy, averaged over many frames, stays above half its peak.

use crate::image::Planes;

/// Frame rows `top .. top + rows` in which the belt is in contact.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct ContactWindow {
    /// First frame row of the window.
    pub top: usize,
    /// Rows in the window (at least 1).
    pub rows: usize,
}

/// Where a window came from, for the report.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum WindowSource {
    /// `--window-rows`.
    Option,
    /// Roller radius, press depth and scale.
    Geometry,
    /// The frames' sharpness profile.
    Measured,
    /// Nothing else was available: the middle half of the frame.
    Default,
}

/// The roller's geometry, as a scene or a manifest states it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Geometry {
    /// Gel surface radius, mm.
    pub roller_radius_mm: f64,
    /// How far the tallest feature presses in at the apex, mm.
    pub press_depth_mm: f64,
    /// Belt mm per pixel.
    pub mm_per_px: f64,
    /// The apex's frame row.
    pub apex_row: f64,
}

impl ContactWindow {
    /// `rows` rows centred on `apex_row`, clipped to a frame of `height` rows.
    pub fn centred(apex_row: f64, rows: usize, height: usize) -> Self {
        let rows = rows.clamp(1, height.max(1));
        let top = (apex_row - rows as f64 / 2.0).round().max(0.0) as usize;
        Self {
            top: top.min(height - rows),
            rows,
        }
    }

    /// The window of `g` in a frame of `height` rows; `None` when the values cannot
    /// describe a pressed roller (non-positive or non-finite).
    pub fn from_geometry(g: &Geometry, height: usize) -> Option<Self> {
        let (r, p, s) = (g.roller_radius_mm, g.press_depth_mm, g.mm_per_px);
        if !(r > 0.0 && p > 0.0 && s > 0.0 && r.is_finite() && p.is_finite() && s.is_finite()) {
            return None;
        }
        let sag = (p / 2.0).min(r);
        let half_mm = (r * r - (r - sag) * (r - sag)).sqrt();
        let rows = (2.0 * half_mm / s).round();
        if !rows.is_finite() || rows < 1.0 {
            return None;
        }
        Some(Self::centred(
            g.apex_row,
            rows.min(height as f64) as usize,
            height,
        ))
    }

    /// Measures the window from `frames` (one size): the mean absolute 4-neighbour
    /// Laplacian of each frame row, averaged over the frames and smoothed over 9 rows,
    /// above its floor; the window is the run of rows around the peak above half the peak.
    /// `None` when the frames show no contact that varies along the frame (flat gel, or
    /// too few frames to average).
    pub fn measure(frames: &[&Planes]) -> Option<Self> {
        let first = frames.first()?;
        let (w, h) = (first.width, first.height);
        if w < 3 || h < 12 {
            return None;
        }
        let mut energy = vec![0f64; h];
        for frame in frames {
            for plane in &frame.planes {
                for y in 1..h - 1 {
                    let row = |dy: usize| &plane[(y + dy - 1) * w..(y + dy) * w];
                    let (up, mid, down) = (row(0), row(1), row(2));
                    let sum: f32 = (1..w - 1)
                        .map(|x| (up[x] + down[x] + mid[x - 1] + mid[x + 1] - 4.0 * mid[x]).abs())
                        .sum();
                    energy[y] += f64::from(sum);
                }
            }
        }
        energy[0] = energy[1];
        energy[h - 1] = energy[h - 2];
        let smooth: Vec<f64> = (0..h)
            .map(|y| {
                let (lo, hi) = (y.saturating_sub(4), (y + 5).min(h));
                energy[lo..hi].iter().sum::<f64>() / (hi - lo) as f64
            })
            .collect();
        let (peak_row, peak) = smooth
            .iter()
            .copied()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(&b.1))?;
        let floor = smooth.iter().copied().fold(f64::INFINITY, f64::min);
        // Contact must stand out of the floor (noise, background) by a tenth of it.
        if peak - floor <= 0.1 * floor.max(f64::MIN_POSITIVE) || peak.is_nan() {
            return None;
        }
        let half = floor + 0.5 * (peak - floor);
        let mut top = peak_row;
        while top > 0 && smooth[top - 1] >= half {
            top -= 1;
        }
        let mut bottom = peak_row + 1;
        while bottom < h && smooth[bottom] >= half {
            bottom += 1;
        }
        Some(Self {
            top,
            rows: bottom - top,
        })
    }

    /// The middle half of a frame of `height` rows.
    pub fn default_for(height: usize) -> Self {
        Self::centred(height as f64 / 2.0, height.div_ceil(2), height)
    }

    /// The window's centre row.
    pub fn centre(&self) -> f64 {
        self.top as f64 + self.rows as f64 / 2.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn geometry_gives_the_half_press_chord() {
        // R 12 mm, press 0.8 mm: half-chord √(144 − 11.6²) = 3.072 mm = 61.4 px.
        let g = Geometry {
            roller_radius_mm: 12.0,
            press_depth_mm: 0.8,
            mm_per_px: 0.05,
            apex_row: 120.0,
        };
        let win = ContactWindow::from_geometry(&g, 240).unwrap();
        assert_eq!(win.rows, 123);
        assert!((win.centre() - 120.0).abs() <= 0.5, "{win:?}");
        let bad = Geometry {
            press_depth_mm: f64::NAN,
            ..g
        };
        assert_eq!(ContactWindow::from_geometry(&bad, 240), None);
    }

    #[test]
    fn a_sharp_middle_is_measured_and_a_flat_frame_is_not() {
        let (w, h) = (40, 100);
        // Texture whose amplitude peaks at row 60 and is half of it 15 rows away.
        let frame = |seed: usize| Planes {
            width: w,
            height: h,
            planes: vec![
                (0..w * h)
                    .map(|i| {
                        let (x, y) = (i % w, i / w);
                        let amp = 100.0 / (1.0 + ((y as f32 - 60.0) / 15.0).powi(2));
                        let sign = if (x + y + seed).is_multiple_of(2) {
                            1.0
                        } else {
                            -1.0
                        };
                        120.0 + amp * sign
                    })
                    .collect(),
            ],
        };
        let frames: Vec<Planes> = (0..4).map(frame).collect();
        let refs: Vec<&Planes> = frames.iter().collect();
        let win = ContactWindow::measure(&refs).unwrap();
        assert!((win.centre() - 60.0).abs() <= 2.0, "{win:?}");
        assert!((26..=34).contains(&win.rows), "{win:?}");
        let flat = Planes {
            width: w,
            height: h,
            planes: vec![vec![120.0; w * h]],
        };
        assert_eq!(ContactWindow::measure(&[&flat]), None);
    }
}
