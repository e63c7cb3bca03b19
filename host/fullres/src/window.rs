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
//! - the frames themselves ([`super::contact::ContactProfile::measure`]): where along the frame the
//!   features that move with the belt stand out of the sensor's noise by at least half
//!   as much as they do at their sharpest.

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
}
