//! Textiles for the defect detector: 17 weaves and knits, and defects of three kinds placed
//! at random (`[object] kind = "textile"`; every parameter is documented in
//! `docs/simulator.md`, Textiles).
//!
//! Coordinates are the object canvas's: `x` across the belt, `y` along it, mm. The warp
//! runs along the belt (columns `i`, spacing `pitch[0]`), the weft across it (rows `j`,
//! spacing `pitch[1]`).

use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// How the yarns interlace.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Structure {
    /// Woven: whether the warp is on top at crossing `(i, j)`.
    Woven(Interlacing),
    /// Knitted: rows of loops.
    Knit(Stitch),
}

/// A woven crossing pattern.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Interlacing {
    /// Over one, under one.
    Plain,
    /// Warp over `up` wefts, under `down`, the pattern stepping one crossing a row.
    Twill {
        /// Floats of the warp on top.
        up: u8,
        /// Floats under.
        down: u8,
    },
    /// A 2/2 twill whose diagonal turns every `zig` warps.
    Herringbone {
        /// Warps between turns.
        zig: u8,
    },
    /// A 2/2 twill mirrored along both directions every `zig` yarns (diamonds).
    Diamond {
        /// Yarns between mirrors.
        zig: u8,
    },
    /// Warp on top once in `n` crossings, moving `step` a row (long floats, smooth face).
    Satin {
        /// Repeat.
        n: u8,
        /// Move number.
        step: u8,
    },
    /// Plain weave of yarns in groups of `n`.
    Basket {
        /// Yarns a group.
        n: u8,
    },
    /// Concentric squares of floats, `n` yarns a cell (ridges and hollows).
    Waffle {
        /// Cell size, yarns.
        n: u8,
    },
    /// A fixed irregular pattern (crêpe).
    Crepe,
}

/// A knitted stitch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Stitch {
    /// Face of single jersey: columns of V-shaped legs.
    Jersey,
    /// 1×1 rib: jersey columns alternating with purl columns.
    Rib,
}

/// One fabric class.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fabric {
    /// Its name (the classifier's label).
    pub name: &'static str,
    /// How its yarns interlace.
    pub structure: Structure,
    /// Yarn spacing across and along the belt, mm.
    pub pitch_mm: [f64; 2],
    /// Yarn thickness of warp and weft, mm (height of a yarn on top).
    pub yarn_mm: [f64; 2],
    /// Height of a yarn where it passes under, as a share of its top height: low is a
    /// strongly crimped yarn, high a flat one.
    pub crimp: f64,
    /// How much the relief flattens under the gel's pressure, 0 (rigid) to 1.
    pub compliance: f64,
}

const fn woven(name: &'static str, weave: Interlacing, pitch: [f64; 2], yarn: [f64; 2]) -> Fabric {
    Fabric {
        name,
        structure: Structure::Woven(weave),
        pitch_mm: pitch,
        yarn_mm: yarn,
        crimp: 0.45,
        compliance: 0.2,
    }
}

/// The fabric classes, in label order.
pub const FABRICS: [Fabric; 17] = [
    woven("plain", Interlacing::Plain, [0.8, 0.8], [0.3, 0.3]),
    woven("voile", Interlacing::Plain, [0.5, 0.5], [0.18, 0.18]),
    Fabric {
        crimp: 0.7,
        compliance: 0.1,
        ..woven("canvas", Interlacing::Plain, [1.2, 1.2], [0.45, 0.45])
    },
    woven("warp_rib", Interlacing::Plain, [0.5, 1.1], [0.2, 0.4]),
    woven(
        "twill_2_1",
        Interlacing::Twill { up: 2, down: 1 },
        [0.7, 0.7],
        [0.3, 0.3],
    ),
    woven(
        "twill_2_2",
        Interlacing::Twill { up: 2, down: 2 },
        [0.7, 0.7],
        [0.3, 0.3],
    ),
    woven(
        "twill_3_1",
        Interlacing::Twill { up: 3, down: 1 },
        [0.6, 0.8],
        [0.32, 0.26],
    ),
    woven(
        "herringbone",
        Interlacing::Herringbone { zig: 6 },
        [0.7, 0.7],
        [0.3, 0.3],
    ),
    woven(
        "diamond",
        Interlacing::Diamond { zig: 6 },
        [0.7, 0.7],
        [0.3, 0.3],
    ),
    Fabric {
        crimp: 0.75,
        ..woven(
            "satin_5",
            Interlacing::Satin { n: 5, step: 2 },
            [0.55, 0.55],
            [0.25, 0.25],
        )
    },
    Fabric {
        crimp: 0.8,
        ..woven(
            "satin_8",
            Interlacing::Satin { n: 8, step: 3 },
            [0.5, 0.5],
            [0.22, 0.22],
        )
    },
    woven(
        "basket_2",
        Interlacing::Basket { n: 2 },
        [0.6, 0.6],
        [0.28, 0.28],
    ),
    woven(
        "basket_3",
        Interlacing::Basket { n: 3 },
        [0.55, 0.55],
        [0.26, 0.26],
    ),
    woven(
        "waffle",
        Interlacing::Waffle { n: 6 },
        [0.6, 0.6],
        [0.3, 0.3],
    ),
    woven("crepe", Interlacing::Crepe, [0.6, 0.6], [0.28, 0.28]),
    knit("jersey", Stitch::Jersey),
    knit("rib_knit", Stitch::Rib),
];

/// A knit of 0.3 mm yarn, wales 0.9 mm apart and courses 0.7 mm, softer than a weave.
const fn knit(name: &'static str, stitch: Stitch) -> Fabric {
    Fabric {
        name,
        structure: Structure::Knit(stitch),
        pitch_mm: [0.9, 0.7],
        yarn_mm: [0.3, 0.3],
        crimp: 0.5,
        compliance: 0.4,
    }
}

/// The fabric named `name`.
pub fn fabric(name: &str) -> Option<&'static Fabric> {
    FABRICS.iter().find(|f| f.name == name)
}

/// The kinds of defect, in label order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DefectKind {
    /// Missing yarns: a hole down to the belt.
    Hole,
    /// A yarn pulled up into a raised loop.
    Snag,
    /// A thick lump along a yarn (a knot or slub).
    Slub,
}

impl DefectKind {
    /// Every kind, in label order.
    pub const ALL: [DefectKind; 3] = [DefectKind::Hole, DefectKind::Snag, DefectKind::Slub];

    /// The name used in files.
    pub fn name(self) -> &'static str {
        match self {
            DefectKind::Hole => "hole",
            DefectKind::Snag => "snag",
            DefectKind::Slub => "slub",
        }
    }
}

/// One defect on the canvas.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Defect {
    /// Its kind.
    pub kind: DefectKind,
    /// Bounding box in canvas mm: `[x0, y0, x1, y1]`.
    pub box_mm: [f64; 4],
    /// Centre, mm.
    centre: [f64; 2],
    /// Half extents along its own axes, mm.
    half: [f64; 2],
    /// Whether its long axis runs along the belt (else across).
    along_belt: bool,
}

impl Defect {
    fn new(kind: DefectKind, centre: [f64; 2], half: [f64; 2], along_belt: bool) -> Self {
        let [hx, hy] = if along_belt {
            [half[1], half[0]]
        } else {
            [half[0], half[1]]
        };
        Self {
            kind,
            box_mm: [
                centre[0] - hx,
                centre[1] - hy,
                centre[0] + hx,
                centre[1] + hy,
            ],
            centre,
            half,
            along_belt,
        }
    }

    /// `(along, across)` offsets of `(x, y)` from the centre in units of the half extents.
    fn local(&self, x: f64, y: f64) -> (f64, f64) {
        let (dx, dy) = (x - self.centre[0], y - self.centre[1]);
        let (a, c) = if self.along_belt { (dy, dx) } else { (dx, dy) };
        (a / self.half[0], c / self.half[1])
    }
}

/// A laid-out textile: the fabric, its random phase and its defects.
pub struct Textile {
    fabric: Fabric,
    scale: f64,
    phase: [f64; 2],
    /// The defects, in placement order.
    pub defects: Vec<Defect>,
}

impl Textile {
    /// Lays `fabric` (yarns and pitches times `scale`) over a `w × l` mm canvas with
    /// `count` defects placed at random from `seed`, kept a defect's size from the edges
    /// and from each other.
    pub fn new(fabric: Fabric, scale: f64, count: usize, (w, l): (f64, f64), seed: u64) -> Self {
        let mut rng = Pcg64Mcg::seed_from_u64(seed ^ 0x7E47_11E5);
        let phase = [rng.random_range(0.0..1.0), rng.random_range(0.0..1.0)];
        let mut defects: Vec<Defect> = Vec::new();
        let mut tries = 0;
        while defects.len() < count && tries < 200 * count.max(1) {
            tries += 1;
            let kind = DefectKind::ALL[rng.random_range(0..3)];
            let half = match kind {
                DefectKind::Hole => {
                    let r = rng.random_range(0.5..1.0);
                    [r * rng.random_range(0.8..1.25), r]
                }
                DefectKind::Snag => [rng.random_range(0.8..1.6), rng.random_range(0.25..0.35)],
                DefectKind::Slub => [rng.random_range(0.6..1.1), rng.random_range(0.35..0.5)],
            };
            let along_belt = rng.random_bool(0.5);
            let reach = half[0] + 0.3;
            if w < 2.0 * reach || l < 2.0 * reach {
                break;
            }
            let centre = [
                rng.random_range(reach..w - reach),
                rng.random_range(reach..l - reach),
            ];
            let d = Defect::new(kind, centre, half, along_belt);
            let apart = defects.iter().all(|o| {
                let gap = 1.0;
                d.box_mm[0] > o.box_mm[2] + gap
                    || o.box_mm[0] > d.box_mm[2] + gap
                    || d.box_mm[1] > o.box_mm[3] + gap
                    || o.box_mm[1] > d.box_mm[3] + gap
            });
            if apart {
                defects.push(d);
            }
        }
        Self {
            fabric,
            scale,
            phase,
            defects,
        }
    }

    /// Height above the belt at `(x, y)`, mm.
    pub fn height(&self, x: f64, y: f64) -> f64 {
        let mut h = self.cloth(x, y);
        for d in &self.defects {
            let (a, c) = d.local(x, y);
            if a.abs() > 1.6 || c.abs() > 1.6 {
                continue;
            }
            let yarn = self.fabric.yarn_mm[0].max(self.fabric.yarn_mm[1]) * self.scale;
            h = match d.kind {
                // Missing yarns: nothing inside the ellipse, frayed ends at its rim.
                DefectKind::Hole => {
                    let r2 = a * a + c * c;
                    if r2 < 1.0 {
                        0.0
                    } else {
                        h * (r2 - 1.0).min(0.5) * 2.0
                    }
                }
                // A loop standing up from the surface, its top at the middle.
                DefectKind::Snag => {
                    let rise = if a.abs() < 1.0 {
                        (PI * (a + 1.0) / 2.0).sin()
                    } else {
                        0.0
                    };
                    let across = (1.0 - c * c).max(0.0).sqrt();
                    h.max(yarn * (1.0 + 0.6 * rise) * across)
                }
                // A thick lump: an ellipsoid of yarn.
                DefectKind::Slub => {
                    let k2 = a * a + c * c;
                    h.max(1.35 * yarn * (1.0 - k2).max(0.0).sqrt())
                }
            };
        }
        h * (1.0 - 0.3 * self.fabric.compliance)
    }

    /// The undamaged fabric's height at `(x, y)`, mm.
    fn cloth(&self, x: f64, y: f64) -> f64 {
        let f = &self.fabric;
        let (px, py) = (f.pitch_mm[0] * self.scale, f.pitch_mm[1] * self.scale);
        let (s, t) = (x / px + self.phase[0], y / py + self.phase[1]);
        let yarn = [f.yarn_mm[0] * self.scale, f.yarn_mm[1] * self.scale];
        match f.structure {
            Structure::Woven(weave) => woven_height(weave, s, t, yarn, f.crimp),
            Structure::Knit(stitch) => knit_height(stitch, s, t, yarn[0]),
        }
    }
}

/// Round yarn cross-section at `u` pitches from its axis (yarns fill 0.8 of the pitch).
fn profile(u: f64) -> f64 {
    (1.0 - (2.5 * u).powi(2)).max(0.0).sqrt()
}

/// Eases 0 → 1 over `t` in 0..1 (a yarn's crimp between two crossings).
fn ease(t: f64) -> f64 {
    (1.0 - (PI * t).cos()) / 2.0
}

/// Whether the warp is on top at crossing `(i, j)`.
fn warp_on_top(weave: Interlacing, i: i64, j: i64) -> bool {
    let twill = |i: i64, j: i64, up: i64, down: i64| (i + j).rem_euclid(up + down) < up;
    let mirror = |k: i64, zig: i64| {
        let m = k.rem_euclid(2 * zig);
        if m < zig { m } else { 2 * zig - 1 - m }
    };
    match weave {
        Interlacing::Plain => (i + j).rem_euclid(2) == 0,
        Interlacing::Twill { up, down } => twill(i, j, up.into(), down.into()),
        Interlacing::Herringbone { zig } => {
            let turned = i.div_euclid(zig.into()).rem_euclid(2) == 1;
            twill(if turned { -i } else { i }, j, 2, 2)
        }
        Interlacing::Diamond { zig } => twill(mirror(i, zig.into()), mirror(j, zig.into()), 2, 2),
        Interlacing::Satin { n, step } => (i * i64::from(step) - j).rem_euclid(n.into()) == 0,
        Interlacing::Basket { n } => {
            (i.div_euclid(n.into()) + j.div_euclid(n.into())).rem_euclid(2) == 0
        }
        Interlacing::Waffle { n } => {
            let n = i64::from(n);
            let half = n / 2;
            let ring = (i.rem_euclid(n) - half)
                .abs()
                .max((j.rem_euclid(n) - half).abs());
            ring % 2 == 0
        }
        Interlacing::Crepe => {
            let mut z = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (j as u64);
            z = (z ^ (z >> 29)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            (z >> 61) & 1 == 1
        }
    }
}

/// Woven height at `(s, t)` in yarn pitches: each yarn rises over the crossings it is on
/// top of and sinks to `crimp` of its height under the others, easing between them.
fn woven_height(weave: Interlacing, s: f64, t: f64, yarn: [f64; 2], crimp: f64) -> f64 {
    let (i, j) = (s.floor() as i64, t.floor() as i64);
    let (u, v) = (s - i as f64 - 0.5, t - j as f64 - 0.5);
    let level = |on_top: bool| if on_top { 1.0 } else { crimp };
    // The warp of column i between the crossings of rows j0 and j0 + 1.
    let j0 = (t - 0.5).floor() as i64;
    let tw = t - 0.5 - j0 as f64;
    let warp = level(warp_on_top(weave, i, j0)) * (1.0 - ease(tw))
        + level(warp_on_top(weave, i, j0 + 1)) * ease(tw);
    let i0 = (s - 0.5).floor() as i64;
    let sw = s - 0.5 - i0 as f64;
    let weft = level(!warp_on_top(weave, i0, j)) * (1.0 - ease(sw))
        + level(!warp_on_top(weave, i0 + 1, j)) * ease(sw);
    (yarn[0] * warp * profile(u)).max(yarn[1] * weft * profile(v))
}

/// Knitted height at `(s, t)` in stitch pitches (wales across, courses along the belt).
fn knit_height(stitch: Stitch, s: f64, t: f64, yarn: f64) -> f64 {
    let (i, j) = (s.floor() as i64, t.floor() as i64);
    let (u, v) = (s - i as f64, t - j as f64);
    let purl = stitch == Stitch::Rib && i.rem_euclid(2) == 1;
    let d = if purl {
        // A loop's head: an arc across the wale.
        ((u - 0.5).powi(2) + ((v - 0.55) * 1.3).powi(2)).sqrt() - 0.32
    } else {
        // Two legs leaning in to the wale's centre: a V.
        let leg = |x0: f64| {
            let (dx, dy) = (0.5 - x0, 1.0);
            let k = (((u - x0) * dx + v * dy) / (dx * dx + dy * dy)).clamp(0.0, 1.0);
            ((u - x0 - k * dx).powi(2) + (v - k * dy).powi(2)).sqrt()
        };
        leg(0.1).min(leg(0.9))
    };
    let r = 0.2;
    if d.abs() < r {
        let rise = if purl { 1.0 } else { 0.8 + 0.2 * ease(v) };
        yarn * rise * (1.0 - (d / r).powi(2)).sqrt()
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_distinct() {
        for (k, f) in FABRICS.iter().enumerate() {
            assert!(FABRICS[..k].iter().all(|g| g.name != f.name), "{}", f.name);
            assert_eq!(fabric(f.name), Some(f));
        }
    }

    #[test]
    fn weaves_differ_in_their_crossings() {
        // Over an 24 × 24 crossing patch no two woven interlacings agree everywhere.
        let patterns: Vec<(&str, Vec<bool>)> = FABRICS
            .iter()
            .filter_map(|f| match f.structure {
                Structure::Woven(w) => Some((w, f.name)),
                _ => None,
            })
            .map(|(w, name)| {
                let bits = (0..24 * 24)
                    .map(|k| warp_on_top(w, k % 24, k / 24))
                    .collect();
                (name, bits)
            })
            .collect();
        for (k, (name, bits)) in patterns.iter().enumerate() {
            for (other, theirs) in &patterns[..k] {
                let same_weave = FABRICS.iter().find(|f| f.name == *name).unwrap().structure
                    == FABRICS.iter().find(|f| f.name == *other).unwrap().structure;
                assert!(same_weave || bits != theirs, "{name} and {other}");
            }
        }
    }

    #[test]
    fn defects_are_placed_apart_and_inside() {
        let t = Textile::new(FABRICS[0], 1.0, 6, (12.8, 40.0), 9);
        assert_eq!(t.defects.len(), 6);
        for d in &t.defects {
            assert!(d.box_mm[0] >= 0.0 && d.box_mm[2] <= 12.8, "{d:?}");
            assert!(d.box_mm[1] >= 0.0 && d.box_mm[3] <= 40.0, "{d:?}");
        }
        // A hole reaches the belt at its centre; a snag and a slub stand above the cloth.
        for d in &t.defects {
            let (x, y) = (d.centre[0], d.centre[1]);
            match d.kind {
                DefectKind::Hole => assert_eq!(t.height(x, y), 0.0),
                _ => assert!(t.height(x, y) > t.cloth(x, y), "{d:?}"),
            }
        }
    }

    #[test]
    fn same_seed_same_layout() {
        let a = Textile::new(FABRICS[3], 1.0, 4, (12.8, 30.0), 5);
        let b = Textile::new(FABRICS[3], 1.0, 4, (12.8, 30.0), 5);
        assert_eq!(a.defects, b.defects);
        assert_eq!(a.height(3.3, 7.7), b.height(3.3, 7.7));
    }
}
