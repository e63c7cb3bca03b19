//! The light file: the image scale and the three LEDs' directions (and gains).
//!
//! ```toml
//! mm_per_px = 0.05
//! red = [0.0, 0.819152, 0.573576]      # unit vectors toward each LED, image-aligned:
//! green = [-0.709406, -0.409576, 0.573576]  # x along columns (right), y along rows (down),
//! blue = [0.709406, -0.409576, 0.573576]    # z out of the gel toward the camera
//! gains = [1.0, 1.0, 1.0]              # optional: each channel's shading contrast
//! ```
//!
//! A light set whose direction matrix is ill-conditioned (lights nearly in one plane, or
//! two nearly the same) cannot separate the three components of a normal: it is refused
//! with its condition number.

use crate::Error;
use nalgebra::Matrix3;
use rollfuse_io::{invalid, require};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The largest condition number of the light matrix accepted: beyond it, a gray level of
/// noise moves the normal by degrees.
pub const MAX_CONDITION: f64 = 30.0;

/// The scale and the lights, as in the file.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Lights {
    /// Millimetres per pixel of the image.
    pub mm_per_px: f64,
    /// Direction toward the red LED.
    pub red: [f64; 3],
    /// Direction toward the green LED.
    pub green: [f64; 3],
    /// Direction toward the blue LED.
    pub blue: [f64; 3],
    /// Shading contrast per channel (1 = as the Lambertian model says).
    #[serde(default = "unit_gains")]
    pub gains: [f64; 3],
}

fn unit_gains() -> [f64; 3] {
    [1.0; 3]
}

impl Lights {
    /// The module's three LEDs: 35° above the gel, 120° apart around it (red along +y),
    /// equal gains, at `mm_per_px`.
    pub fn product(mm_per_px: f64) -> Self {
        Self {
            mm_per_px,
            red: [0.0, 0.819152, 0.573576],
            green: [-0.709406, -0.409576, 0.573576],
            blue: [0.709406, -0.409576, 0.573576],
            gains: [1.0; 3],
        }
    }

    /// Reads and checks a light file.
    pub fn load(path: &Path) -> Result<Self, Error> {
        let text = std::fs::read_to_string(path).map_err(|source| Error::Read {
            path: path.to_path_buf(),
            source,
        })?;
        let lights: Self = toml::from_str(&text).map_err(|e| {
            Error::Invalid(format!(
                "{} is not a valid light file: {}",
                path.display(),
                e.to_string().trim_end()
            ))
        })?;
        lights
            .check()
            .map_err(|e| Error::Invalid(format!("light file {}: {e}", path.display())))?;
        Ok(lights)
    }

    /// The file's text.
    pub fn to_toml(&self) -> Result<String, Error> {
        toml::to_string(self).map_err(|e| Error::Invalid(format!("lights as TOML: {e}")))
    }

    /// Writes the file, whole or not at all.
    pub fn save(&self, path: &Path) -> Result<(), Error> {
        Ok(rollfuse_io::files::write_bytes_atomic(
            path,
            self.to_toml()?.as_bytes(),
        )?)
    }

    /// The three directions, red, green, blue.
    pub fn directions(&self) -> [[f64; 3]; 3] {
        [self.red, self.green, self.blue]
    }

    /// Checks the scale, that each direction is a unit vector (±2 %) pointing toward the
    /// camera side, the gains, and the light matrix's condition number.
    pub fn check(&self) -> Result<(), Error> {
        require!(
            self.mm_per_px.is_finite() && self.mm_per_px > 0.0 && self.mm_per_px < 10.0,
            "mm_per_px must be in (0, 10), got {}",
            self.mm_per_px
        );
        for (name, d) in ["red", "green", "blue"].iter().zip(self.directions()) {
            let norm = d.iter().map(|v| v * v).sum::<f64>().sqrt();
            require!(
                d.iter().all(|v| v.is_finite()) && (norm - 1.0).abs() <= 0.02,
                "{name} = {d:?} is not a unit vector (length {norm:.3})"
            );
            require!(
                d[2] > 0.05,
                "{name} = {d:?} does not light the gel from the camera's side (z ≤ 0.05)"
            );
        }
        for (name, g) in ["red", "green", "blue"].iter().zip(self.gains) {
            require!(
                g.is_finite() && (0.05..=20.0).contains(&g),
                "gain of {name} must be in 0.05..=20, got {g}"
            );
        }
        let c = self.condition();
        if c.is_nan() || c > MAX_CONDITION {
            invalid!(
                "the light directions are too close to each other or to one plane: condition \
                 number {c:.1} (at most {MAX_CONDITION} is accepted)"
            );
        }
        Ok(())
    }

    /// The light matrix (one direction per row).
    pub fn matrix(&self) -> Matrix3<f64> {
        let [r, g, b] = self.directions();
        Matrix3::new(r[0], r[1], r[2], g[0], g[1], g[2], b[0], b[1], b[2])
    }

    /// Condition number of the light matrix (ratio of its largest to smallest singular
    /// value); infinite for a singular one.
    pub fn condition(&self) -> f64 {
        let sv = self.matrix().singular_values();
        let (max, min) = (sv.max(), sv.min());
        if min > 0.0 { max / min } else { f64::INFINITY }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_light_file_s_errors_say_whose_fault_they_are() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("lights.toml");
        assert!(matches!(Lights::load(&missing), Err(Error::Read { .. })));
        std::fs::write(&missing, "mm_per_px = -1\n").unwrap();
        let e = Lights::load(&missing).unwrap_err();
        assert!(matches!(e, Error::Invalid(_)), "{e:?}");
        assert!(e.to_string().contains("lights.toml"), "{e}");
    }

    fn product_lights() -> Lights {
        Lights::product(0.05)
    }

    #[test]
    fn the_product_lights_pass_and_collinear_ones_are_refused() {
        let l = product_lights();
        l.check().unwrap();
        assert!(l.condition() < 3.0, "{}", l.condition());
        let flat = Lights { green: l.red, ..l };
        let err = flat.check().unwrap_err().to_string();
        assert!(err.contains("condition number"), "{err}");
        // Three lights all nearly overhead: nearly one direction.
        let s = (1.0f64 - 0.02f64 * 0.02).sqrt();
        let close = Lights {
            red: [0.02, 0.0, s],
            green: [-0.01, 0.017, s],
            blue: [-0.01, -0.017, s],
            ..l
        };
        assert!(
            close
                .check()
                .unwrap_err()
                .to_string()
                .contains("condition number")
        );
        let long = Lights {
            red: [0.0, 1.6, 1.2],
            ..l
        };
        assert!(
            long.check()
                .unwrap_err()
                .to_string()
                .contains("unit vector")
        );
        let below = Lights {
            red: [0.0, 0.819152, -0.573576],
            ..l
        };
        assert!(below.check().is_err());
    }

    #[test]
    fn a_file_round_trips() {
        let tmp = tempfile::tempdir().unwrap();
        let p = tmp.path().join("lights.toml");
        product_lights().save(&p).unwrap();
        assert_eq!(Lights::load(&p).unwrap(), product_lights());
        std::fs::write(&p, "mm_per_px = 0.05\nred = [0, 0, 1]\n").unwrap();
        assert!(Lights::load(&p).is_err());
    }
}
