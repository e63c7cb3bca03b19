//! Height maps of the objects on the belt, in belt millimetres.
//!
//! The canvas: `x` across the belt from the image's left edge (`0..width_mm`), `y` along
//! the belt (`0..length_mm`). Built-in objects lay themselves out inside it with a margin;
//! every height is in mm above the belt.

use super::scene::{Object, Shape};
use super::textile::{self, Defect, Textile};
use rollfuse_io::font;
use std::f64::consts::PI;

/// Edge rounding of raised features, mm: how wide the shoulder of a 1 mm step is.
const EDGE_MM: f64 = 0.12;

/// The canvas an object is laid out in.
#[derive(Debug, Clone, Copy)]
pub struct Canvas {
    /// Across the belt, mm.
    pub width_mm: f64,
    /// Along the belt, mm.
    pub length_mm: f64,
}

/// A labelled region of the object (for masks), as a predicate on belt mm.
pub struct Region {
    /// Its name.
    pub name: String,
    /// Whether a point (x, y) in mm lies in it.
    pub contains: Box<dyn Fn(f64, f64) -> bool + Send + Sync>,
}

/// A laid-out object: its height at any point, and its regions.
pub struct Layout {
    height: Height,
    /// The regions the object defines (may be empty).
    pub regions: Vec<Region>,
    /// The defects placed on a textile (empty for other objects).
    pub defects: Vec<Defect>,
}

impl Layout {
    /// Height above the belt at `(x, y)` mm; 0 off the object.
    pub fn height(&self, x: f64, y: f64) -> f64 {
        (self.height)(x, y)
    }
}

/// A raised profile: `h` inside (distance ≤ 0), falling smoothly to 0 over `EDGE_MM`.
fn shoulder(h: f64, outside_by: f64) -> f64 {
    if outside_by <= 0.0 {
        h
    } else if outside_by >= EDGE_MM {
        0.0
    } else {
        let t = outside_by / EDGE_MM;
        h * (1.0 - t * t * (3.0 - 2.0 * t))
    }
}

/// Distance from `(px, py)` to the segment `a–b`.
fn segment_distance(px: f64, py: f64, (ax, ay): (f64, f64), (bx, by): (f64, f64)) -> f64 {
    let (dx, dy) = (bx - ax, by - ay);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((px - ax) * dx + (py - ay) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    ((px - ax - t * dx).powi(2) + (py - ay - t * dy).powi(2)).sqrt()
}

/// Height of a round wire of radius `r` lying on the belt, at distance `d` from its axis.
fn wire(r: f64, d: f64) -> f64 {
    if d < r {
        r + (r * r - d * d).sqrt()
    } else {
        0.0
    }
}

/// A glyph's width across the belt, font cells.
const GLYPH_COLS: i64 = 5;
/// A glyph's length along the belt, font cells.
const GLYPH_ROWS: i64 = 7;
/// Blank font cells between one glyph and the next along the belt.
const GLYPH_GAP: i64 = 2;
/// The share of the canvas's width the letters may take.
const LETTERS_WIDTH_SHARE: f64 = 0.6;
/// The share of the canvas's length the letters may take.
const LETTERS_LENGTH_SHARE: f64 = 0.9;
/// The largest font cell, mm.
const LETTERS_MAX_CELL_MM: f64 = 0.8;

/// Half a line's length, as a share of the grid pitch.
const LINE_HALF_LENGTH: f64 = 0.35;
/// A curve's radius, as a share of the grid pitch.
const CURVE_RADIUS: f64 = 0.3;
/// Spheres, on the canvas's diagonal.
const SPHERES: usize = 3;

/// Where the screw's head ends and its threads begin, as a share of the canvas length.
const SCREW_SHANK_START: f64 = 0.15;
/// Where the screw's threads end, as a share of the canvas length.
const SCREW_TIP: f64 = 0.85;
/// The screw head's length, as a share of the canvas length.
const SCREW_HEAD_LENGTH: f64 = 0.25;
/// The head's radius, as a multiple of the shank's.
const SCREW_HEAD_RADIUS: f64 = 1.6;
/// How far the head's top stands above the threads' crests, mm.
const SCREW_HEAD_ABOVE_MM: f64 = 0.05;
/// The slot's half width across the head, as a multiple of the shank's radius.
const SCREW_SLOT_HALF_WIDTH: f64 = 0.2;
/// The slot's depth, as a multiple of the shank's radius.
const SCREW_SLOT_DEPTH: f64 = 0.6;
/// The threads' root radius, as a share of their crest's.
const THREAD_ROOT: f64 = 0.85;
/// The threads' depth, as a share of their crest's radius (crest = root + depth).
const THREAD_DEPTH: f64 = 0.15;

/// Lays `object` out in `canvas`; `seed` places what a scene leaves to chance.
pub fn layout(object: &Object, canvas: Canvas, seed: u64) -> Layout {
    let (w, l) = (canvas.width_mm, canvas.length_mm);
    match object.clone() {
        Object::Letters { text, height_mm } => surface(letters(&text, height_mm, w, l)),
        Object::Dots {
            height_mm,
            pitch_mm,
            size_mm,
        } => surface(matrix(w, l, pitch_mm, dot(height_mm, size_mm))),
        Object::Lines {
            height_mm,
            pitch_mm,
            size_mm,
        } => surface(matrix(w, l, pitch_mm, line(height_mm, pitch_mm, size_mm))),
        Object::Curves {
            height_mm,
            pitch_mm,
            size_mm,
        } => surface(matrix(w, l, pitch_mm, curve(height_mm, pitch_mm, size_mm))),
        Object::Spheres { diameter_mm } => spheres(diameter_mm, w, l),
        Object::Fabric { yarn_mm, pitch_mm } => fabric(w, l, yarn_mm, pitch_mm),
        Object::Screw {
            diameter_mm,
            pitch_mm,
        } => surface(screw(diameter_mm, pitch_mm, w, l)),
        Object::Paperclip { wire_mm } => surface(paperclip(wire_mm, w, l)),
        Object::Primitives { shapes } => primitives(shapes),
        Object::Textile {
            fabric,
            defects,
            scale,
        } => textile_layout(&fabric, defects, scale, (w, l), seed),
    }
}

/// A height map, boxed.
type Height = Box<dyn Fn(f64, f64) -> f64 + Send + Sync>;

/// An object that is only a height map: no regions, no defects.
fn surface(height: Height) -> Layout {
    Layout {
        height,
        regions: Vec::new(),
        defects: Vec::new(),
    }
}

/// `text` raised `height_mm`, its glyphs one after another along the belt, as large as the
/// canvas allows, centred.
fn letters(text: &str, height_mm: f64, w: f64, l: f64) -> Height {
    let chars: Vec<char> = text.chars().collect();
    let n = chars.len() as f64;
    let (cols, rows, gap) = (GLYPH_COLS as f64, GLYPH_ROWS as f64, GLYPH_GAP as f64);
    // Font cells along the belt: every glyph and the gaps between them.
    let length_cells = n * (rows + gap) - gap;
    let cell = (LETTERS_WIDTH_SHARE * w / cols)
        .min(LETTERS_LENGTH_SHARE * l / length_cells.max(1.0))
        .min(LETTERS_MAX_CELL_MM);
    let x0 = (w - cols * cell) / 2.0;
    let y0 = (l - length_cells * cell) / 2.0;
    Box::new(move |x, y| {
        let (cx, cy) = ((x - x0) / cell, (y - y0) / cell);
        shoulder(height_mm, raised_cell_distance(&chars, cx, cy) * cell)
    })
}

/// Distance, in font cells, from the point `(cx, cy)` (font cells from the text's corner)
/// to the nearest raised cell of the 3×3 around it (infinite when none is raised).
fn raised_cell_distance(chars: &[char], cx: f64, cy: f64) -> f64 {
    let (ci, cj) = (cx.floor() as i64, cy.floor() as i64);
    let mut d = f64::INFINITY;
    for j in cj - 1..=cj + 1 {
        for i in ci - 1..=ci + 1 {
            if i < 0 || j < 0 || i >= GLYPH_COLS {
                continue;
            }
            let pitch = GLYPH_ROWS + GLYPH_GAP;
            let (k, row) = ((j / pitch) as usize, (j % pitch) as usize);
            let raised = row < GLYPH_ROWS as usize
                && chars
                    .get(k)
                    .is_some_and(|&c| font::cell(c, i as usize, row));
            if raised {
                let ox = (i as f64 - cx).max(cx - (i + 1) as f64).max(0.0);
                let oy = (j as f64 - cy).max(cy - (j + 1) as f64).max(0.0);
                d = d.min((ox * ox + oy * oy).sqrt());
            }
        }
    }
    d
}

/// A grid unit: a round dot `size_mm` across, raised `height_mm`.
fn dot(height_mm: f64, size_mm: f64) -> impl Fn(f64, f64) -> f64 + Send + Sync + 'static {
    let r = size_mm / 2.0;
    move |u, v| shoulder(height_mm, (u * u + v * v).sqrt() - r)
}

/// A grid unit: a line across the belt, `size_mm` wide, raised `height_mm`.
fn line(
    height_mm: f64,
    pitch_mm: f64,
    size_mm: f64,
) -> impl Fn(f64, f64) -> f64 + Send + Sync + 'static {
    let half = LINE_HALF_LENGTH * pitch_mm;
    move |u, v| {
        shoulder(
            height_mm,
            segment_distance(u, v, (-half, 0.0), (half, 0.0)) - size_mm / 2.0,
        )
    }
}

/// A grid unit: a half ring opening toward +y, `size_mm` wide, raised `height_mm`.
fn curve(
    height_mm: f64,
    pitch_mm: f64,
    size_mm: f64,
) -> impl Fn(f64, f64) -> f64 + Send + Sync + 'static {
    let radius = CURVE_RADIUS * pitch_mm;
    move |u, v| {
        let ring = ((u * u + (v - radius / 2.0).powi(2)).sqrt() - radius).abs();
        let d = if v - radius / 2.0 <= 0.0 {
            ring
        } else {
            ((u.abs() - radius).powi(2) + (v - radius / 2.0).powi(2)).sqrt()
        };
        shoulder(height_mm, d - size_mm / 2.0)
    }
}

/// [`SPHERES`] balls of `diameter_mm` lying on the belt, each a region.
fn spheres(diameter_mm: f64, w: f64, l: f64) -> Layout {
    let r = diameter_mm / 2.0;
    // Diagonal across the canvas, so each passes the apex at a different frame.
    let parts = (SPHERES + 1) as f64;
    let centres: Vec<(f64, f64)> = (1..=SPHERES)
        .map(|k| (w * k as f64 / parts, l * k as f64 / parts))
        .collect();
    let regions = centres
        .iter()
        .enumerate()
        .map(|(k, &(cx, cy))| Region {
            name: format!("sphere_{}", k + 1),
            contains: Box::new(move |x, y| (x - cx).powi(2) + (y - cy).powi(2) <= r * r),
        })
        .collect();
    Layout {
        regions,
        ..surface(Box::new(move |x, y| {
            centres
                .iter()
                .map(|&(cx, cy)| wire(r, ((x - cx).powi(2) + (y - cy).powi(2)).sqrt()))
                .fold(0.0, f64::max)
        }))
    }
}

/// A screw of `diameter_mm` lying along the belt in the middle of the canvas: a slotted
/// head, then a shank threaded at `pitch_mm`.
fn screw(diameter_mm: f64, pitch_mm: f64, w: f64, l: f64) -> Height {
    let r = diameter_mm / 2.0;
    let cx = w / 2.0;
    let (y_head, y_tip) = (SCREW_SHANK_START * l, SCREW_TIP * l);
    Box::new(move |x, y| {
        let d = (x - cx).abs();
        if (y_head - SCREW_HEAD_LENGTH * l..y_head).contains(&y) {
            // The head: wider than the shank; lying on its side the screw rests on both,
            // so the head's top is cut level with the threads'.
            let head = wire(SCREW_HEAD_RADIUS * r, d).min(2.0 * r + SCREW_HEAD_ABOVE_MM);
            let slot_centre = y_head - SCREW_HEAD_LENGTH / 2.0 * l;
            let slot = (y - slot_centre).abs() < SCREW_SLOT_HALF_WIDTH * r;
            return if slot {
                head - SCREW_SLOT_DEPTH * r
            } else {
                head
            };
        }
        if !(y_head..y_tip).contains(&y) {
            return 0.0;
        }
        // Threads: the radius swings between root and crest along a helix.
        let phase = (y / pitch_mm + (x - cx) / (2.0 * PI * r)).fract();
        let tooth = 1.0 - 2.0 * (phase - 0.5).abs();
        wire(r * (THREAD_ROOT + THREAD_DEPTH * tooth), d)
    })
}

/// A paperclip bent from wire `wire_mm` thick.
fn paperclip(wire_mm: f64, w: f64, l: f64) -> Height {
    let r = wire_mm / 2.0;
    let path = paperclip_path(w, l);
    Box::new(move |x, y| {
        let d = path
            .windows(2)
            .map(|s| segment_distance(x, y, s[0], s[1]))
            .fold(f64::INFINITY, f64::min);
        wire(r, d)
    })
}

/// A textile of the fabric named `fabric` (the first fabric if the name is unknown:
/// validation refuses those) with `defects` placed from `seed`.
fn textile_layout(fabric: &str, defects: usize, scale: f64, size: (f64, f64), seed: u64) -> Layout {
    let fabric = *textile::fabric(fabric).unwrap_or(&textile::FABRICS[0]);
    let t = Textile::new(fabric, scale, defects, size, seed);
    let defects = t.defects.clone();
    Layout {
        height: Box::new(move |x, y| t.height(x, y)),
        regions: Vec::new(),
        defects,
    }
}

/// A pattern repeated on a square grid of `pitch` inside the canvas (one pitch of margin);
/// `unit(u, v)` is the height at offset `(u, v)` from the nearest grid point.
fn matrix(
    w: f64,
    l: f64,
    pitch: f64,
    unit: impl Fn(f64, f64) -> f64 + Send + Sync + 'static,
) -> Height {
    let (nx, ny) = (
        ((w / pitch) as i64 - 1).max(1),
        ((l / pitch) as i64 - 1).max(1),
    );
    let (x0, y0) = (
        (w - (nx - 1) as f64 * pitch) / 2.0,
        (l - (ny - 1) as f64 * pitch) / 2.0,
    );
    Box::new(move |x, y| {
        let i = ((x - x0) / pitch).round().clamp(0.0, (nx - 1) as f64);
        let j = ((y - y0) / pitch).round().clamp(0.0, (ny - 1) as f64);
        unit(x - x0 - i * pitch, y - y0 - j * pitch)
    })
}

/// Three weaves side by side across the belt (plain 1/1, twill 2/2, satin 4/1) and three
/// defects along it: a hole (missing crossings), a knot (a lump of yarn) and a broken warp
/// yarn. Each defect is a region.
fn fabric(w: f64, l: f64, yarn: f64, pitch: f64) -> Layout {
    let band = w / 3.0;
    // Is the warp (the yarn along the belt) on top at crossing (i, j)?
    let warp_on_top = move |i: i64, j: i64, weave: usize| match weave {
        0 => (i + j).rem_euclid(2) == 0,
        1 => (i + j).rem_euclid(4) < 2,
        _ => (i * 2 + j).rem_euclid(5) == 0,
    };
    let hole = (band * 0.5, l * 0.3, 1.6 * pitch);
    let knot = (band * 1.5, l * 0.5, 1.2 * pitch);
    let broken_x = band * 2.5;
    let broken = (l * 0.6, l * 0.8);
    let regions = vec![
        Region {
            name: "hole".into(),
            contains: Box::new(move |x, y| {
                (x - hole.0).abs() < hole.2 && (y - hole.1).abs() < hole.2
            }),
        },
        Region {
            name: "knot".into(),
            contains: Box::new(move |x, y| {
                (x - knot.0).powi(2) + (y - knot.1).powi(2) < knot.2 * knot.2
            }),
        },
        Region {
            name: "broken_yarn".into(),
            contains: Box::new(move |x, y| {
                (x - broken_x).abs() < pitch && (broken.0..broken.1).contains(&y)
            }),
        },
    ];
    let height = move |x: f64, y: f64| {
        if (x - hole.0).abs() < hole.2 && (y - hole.1).abs() < hole.2 {
            return 0.0;
        }
        let (i, j) = ((x / pitch).floor() as i64, (y / pitch).floor() as i64);
        let (u, v) = (x / pitch - i as f64 - 0.5, y / pitch - j as f64 - 0.5);
        let weave = ((x / band) as usize).min(2);
        // Round yarn cross-sections, a little narrower than the pitch.
        let profile = |t: f64| (1.0 - (2.2 * t).powi(2)).max(0.0).sqrt();
        let mut warp = yarn * profile(u);
        let weft = yarn * profile(v);
        let warp_missing = (x - broken_x).abs() < pitch / 2.0 && (broken.0..broken.1).contains(&y);
        if warp_missing {
            warp = 0.0;
        }
        let h = if warp_on_top(i, j, weave) {
            warp.max(0.5 * weft)
        } else {
            weft.max(0.5 * warp)
        };
        let k2 = ((x - knot.0).powi(2) + (y - knot.1).powi(2)) / (knot.2 * knot.2);
        let lump = if k2 < 1.0 {
            1.4 * yarn * (1.0 - k2).sqrt()
        } else {
            0.0
        };
        h.max(lump)
    };
    Layout {
        height: Box::new(height),
        regions,
        defects: Vec::new(),
    }
}

/// The classic clip: nested U-turns of straight wire, as a polyline (mm).
fn paperclip_path(w: f64, l: f64) -> Vec<(f64, f64)> {
    let (cx, half_w) = (w / 2.0, (0.18 * w).min(0.12 * l));
    let (y0, y1) = (0.12 * l, 0.88 * l);
    let mut path = Vec::new();
    let arc = |cxa: f64, cya: f64, r: f64, from: f64, to: f64, path: &mut Vec<(f64, f64)>| {
        for k in 0..=16 {
            let a = from + (to - from) * k as f64 / 16.0;
            path.push((cxa + r * a.cos(), cya + r * a.sin()));
        }
    };
    // Outer loop: down the left side, around the bottom, up the right, around the top,
    // then the inner loop.
    path.push((cx - half_w, y0 + half_w));
    arc(cx, y1 - half_w, half_w, PI, 0.0, &mut path);
    arc(
        cx - 0.2 * half_w,
        y0 + 0.8 * half_w,
        0.8 * half_w,
        0.0,
        -PI,
        &mut path,
    );
    arc(
        cx - 0.1 * half_w,
        y1 - 2.5 * half_w,
        0.6 * half_w,
        PI,
        0.0,
        &mut path,
    );
    path.push((cx + 0.5 * half_w, y0 + 2.0 * half_w));
    path
}

fn primitives(shapes: Vec<Shape>) -> Layout {
    let regions = shapes
        .iter()
        .filter_map(|s| match s.clone() {
            Shape::Sphere {
                x_mm,
                y_mm,
                radius_mm,
                region: Some(name),
                ..
            } => Some(Region {
                name,
                contains: Box::new(move |x, y| {
                    (x - x_mm).powi(2) + (y - y_mm).powi(2) <= radius_mm * radius_mm
                }),
            }),
            Shape::Box {
                x_mm,
                y_mm,
                width_mm,
                length_mm,
                region: Some(name),
                ..
            } => Some(Region {
                name,
                contains: Box::new(move |x, y| {
                    (x - x_mm).abs() <= width_mm / 2.0 && (y - y_mm).abs() <= length_mm / 2.0
                }),
            }),
            _ => None,
        })
        .collect();
    let height = move |x: f64, y: f64| {
        shapes
            .iter()
            .map(|s| match *s {
                Shape::Sphere {
                    x_mm,
                    y_mm,
                    radius_mm,
                    height_mm,
                    ..
                } => {
                    let top = height_mm.unwrap_or(radius_mm);
                    let d2 = (x - x_mm).powi(2) + (y - y_mm).powi(2);
                    if d2 < radius_mm * radius_mm {
                        ((radius_mm * radius_mm - d2).sqrt() - (radius_mm - top)).max(0.0)
                    } else {
                        0.0
                    }
                }
                Shape::Box {
                    x_mm,
                    y_mm,
                    width_mm,
                    length_mm,
                    height_mm,
                    ..
                } => {
                    let ox = ((x - x_mm).abs() - width_mm / 2.0).max(0.0);
                    let oy = ((y - y_mm).abs() - length_mm / 2.0).max(0.0);
                    shoulder(height_mm, (ox * ox + oy * oy).sqrt())
                }
            })
            .sum()
    };
    Layout {
        height: Box::new(height),
        regions,
        defects: Vec::new(),
    }
}
