//! The rendering pipeline: each effect a separate stage that runs only when the scene
//! lists it (the physical model of each is in `docs/simulator.md`).

use super::object::{Canvas, layout};
use super::scene::{Effect, Scene};
use super::textile::DefectKind;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};
use rand_pcg::Pcg64Mcg;
pub use rollfuse_io::image::Planes;

/// Gray level of undisturbed gel under the shading model.
const FLAT_LEVEL: f32 = 120.0;

/// One simulated frame.
#[derive(Debug, Clone)]
pub struct Frame {
    /// Frame number, from 0.
    pub index: usize,
    /// The roller apex's belt position the motion system commanded, mm.
    pub offset_mm: f64,
    /// Where it really was (differs only with `jitter`), mm.
    pub actual_offset_mm: f64,
    /// How far the belt lay sideways (with `wander`): image column `x` shows strip column
    /// `x + sideways_px`.
    pub sideways_px: f64,
    /// The image.
    pub image: Planes,
    /// The stages that ran, in order.
    pub stages: Vec<Effect>,
}

/// The height map of the belt strip every frame of the scene sees.
#[derive(Debug, Clone)]
pub struct Strip {
    /// Across the belt, pixels (the image width).
    pub width: usize,
    /// Along the belt, pixels.
    pub rows: usize,
    /// Belt position of row 0, mm (the object's canvas starts at 0).
    pub origin_mm: f64,
    /// Height above the belt, mm, row-major.
    pub height_mm: Vec<f32>,
    /// Region masks (name, one byte per pixel: 255 inside).
    pub regions: Vec<(String, Vec<u8>)>,
    /// A textile's defects, boxes in strip pixels (`[x0, y0, x1, y1]`, edges).
    pub defects: Vec<StripDefect>,
}

/// A defect on the strip.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct StripDefect {
    /// Its kind.
    pub kind: DefectKind,
    /// Bounding box on the object's canvas, mm.
    pub box_mm: [f64; 4],
    /// Bounding box in strip pixels (column and row edges).
    pub box_px: [f64; 4],
    /// How high what the gel meets at it stands, mm ([`contact_top_mm`]).
    #[serde(skip)]
    pub contact_top_mm: f64,
}

/// A defect as one frame shows it.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct FrameDefect {
    /// Its place in [`Strip::defects`].
    pub index: usize,
    /// Its kind.
    pub kind: DefectKind,
    /// Bounding box in the frame's pixels, clipped to the image.
    pub box_px: [f64; 4],
    /// Whether it, or the cloth around it, presses into the gel at its centre (a frame
    /// shows a defect sharply only there): its centre within the band where the roller's
    /// surface stays below [`StripDefect::contact_top_mm`].
    pub in_contact: bool,
}

/// A scene ready to render: the object rasterized once, frames on demand.
pub struct Simulator {
    scene: Scene,
    strip: Strip,
    apex_mm: Vec<f64>,
    /// Each frame's sideways offset, pixels (all 0 without `wander`).
    sideways_px: Vec<f64>,
    /// Belt height of the gel's apex surface, mm.
    apex_height_mm: f64,
}

/// How high what the gel meets at a defect stands: the 90th percentile of the belt's
/// height over the defect's box, or over that box widened by half its size each way if
/// higher (`box_px` in strip pixels). A slub or a snag's loop stands above the cloth and
/// touches the gel farther from the apex; a hole is seen where the cloth around it
/// touches. The roller presses relative to the roll's tallest point, often another
/// defect, so the cloth elsewhere touches over a narrower band than that point.
fn contact_top_mm(height_mm: &[f32], width: usize, box_px: [f64; 4]) -> f64 {
    let [x0, y0, x1, y1] = box_px;
    let (dx, dy) = ((x1 - x0) / 2.0, (y1 - y0) / 2.0);
    let own = percentile_90(height_mm, width, box_px);
    own.max(percentile_90(
        height_mm,
        width,
        [x0 - dx, y0 - dy, x1 + dx, y1 + dy],
    ))
}

/// The 90th percentile of `height_mm` (rows of `width`) over `box_px`, clipped to it; 0
/// for an empty box.
fn percentile_90(height_mm: &[f32], width: usize, box_px: [f64; 4]) -> f64 {
    let rows = height_mm.len() / width.max(1);
    let clip = |v: f64, n: usize| v.clamp(0.0, n as f64) as usize;
    let (c0, c1) = (clip(box_px[0], width), clip(box_px[2], width));
    let (r0, r1) = (clip(box_px[1], rows), clip(box_px[3], rows));
    let mut heights: Vec<f32> = (r0..r1)
        .flat_map(|r| height_mm[r * width + c0..r * width + c1].iter().copied())
        .collect();
    if heights.is_empty() {
        return 0.0;
    }
    let k = heights.len() * 9 / 10;
    f64::from(*heights.select_nth_unstable_by(k, f32::total_cmp).1)
}

impl Simulator {
    /// Lays out and rasterizes the scene's object over every belt row its frames can see.
    pub fn new(scene: &Scene) -> Result<Self, crate::Error> {
        scene.validate()?;
        let s = &scene.sensor;
        let mmpp = s.mm_per_px;
        let fov_mm = s.height_px as f64 * mmpp;
        let steps = Self::steps_mm(scene);
        let travel: f64 = steps.iter().sum();
        let sideways_px = Self::sideways_px(scene);
        let canvas = Canvas {
            width_mm: s.width_px as f64 * mmpp,
            length_mm: travel.max(0.5 * fov_mm),
        };
        let first_apex = (canvas.length_mm - travel) / 2.0;
        let apex_mm: Vec<f64> = std::iter::once(first_apex)
            .chain(steps.iter().scan(first_apex, |at, step| {
                *at += step;
                Some(*at)
            }))
            .collect();
        let jitter_mm = if scene.has(Effect::Jitter) {
            scene.params.jitter_px * mmpp
        } else {
            0.0
        };
        let centre = s.height_px as f64 / 2.0;
        // Whole pixels before the first frame's top row, so commanded frames fall on rows.
        let margin_px = (centre + jitter_mm / mmpp + 2.0).ceil();
        let origin_mm = apex_mm[0] - margin_px * mmpp;
        let end_mm =
            apex_mm[s.frames - 1] + (s.height_px as f64 - centre) * mmpp + jitter_mm + 2.0 * mmpp;
        let rows = ((end_mm - origin_mm) / mmpp).ceil() as usize + 1;
        let width = s.width_px;
        let object = layout(&scene.object, canvas, scene.seed);
        let mut height_mm = vec![0f32; rows * width];
        for r in 0..rows {
            let y = origin_mm + r as f64 * mmpp;
            for (x, h) in height_mm[r * width..(r + 1) * width].iter_mut().enumerate() {
                *h = object.height((x as f64 + 0.5) * mmpp, y) as f32;
            }
        }
        let regions = object
            .regions
            .iter()
            .map(|reg| {
                let mask = (0..rows * width)
                    .map(|i| {
                        let (x, r) = (i % width, i / width);
                        if (reg.contains)((x as f64 + 0.5) * mmpp, origin_mm + r as f64 * mmpp) {
                            255
                        } else {
                            0
                        }
                    })
                    .collect();
                (reg.name.clone(), mask)
            })
            .collect();
        let defects = object
            .defects
            .iter()
            .map(|d| {
                let [x0, y0, x1, y1] = d.box_mm;
                let row = |y: f64| (y - origin_mm) / mmpp;
                let box_px = [x0 / mmpp, row(y0), x1 / mmpp, row(y1)];
                StripDefect {
                    kind: d.kind,
                    box_mm: d.box_mm,
                    box_px,
                    contact_top_mm: contact_top_mm(&height_mm, width, box_px),
                }
            })
            .collect();
        let top = height_mm.iter().copied().fold(0f32, f32::max) as f64;
        Ok(Self {
            scene: scene.clone(),
            strip: Strip {
                width,
                rows,
                origin_mm,
                height_mm,
                regions,
                defects,
            },
            apex_mm,
            sideways_px,
            apex_height_mm: top - s.press_depth_mm,
        })
    }

    /// Each frame's travel from the one before, mm: steady, or varied by `speed`.
    fn steps_mm(scene: &Scene) -> Vec<f64> {
        let s = &scene.sensor;
        let j = scene.params.speed_jitter;
        (1..s.frames)
            .map(|k| {
                let change = if scene.has(Effect::Speed) && j > 0.0 {
                    Self::draw(scene.seed, k, Effect::Speed).random_range(-j..=j)
                } else {
                    0.0
                };
                s.frame_spacing_mm * (1.0 + change)
            })
            .collect()
    }

    /// Each frame's sideways offset, pixels: a walk of up to `wander_px` a frame with
    /// `wander`, else 0.
    fn sideways_px(scene: &Scene) -> Vec<f64> {
        let wander = if scene.has(Effect::Wander) {
            scene.params.wander_px
        } else {
            0.0
        };
        (0..scene.sensor.frames)
            .scan(0.0, |at, k| {
                if k > 0 && wander > 0.0 {
                    *at += Self::draw(scene.seed, k, Effect::Wander).random_range(-wander..=wander);
                }
                Some(*at)
            })
            .collect()
    }

    /// The scene.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The belt strip's height map and regions.
    pub fn strip(&self) -> &Strip {
        &self.strip
    }

    /// Number of frames.
    pub fn frames(&self) -> usize {
        self.apex_mm.len()
    }

    /// Strip row (fractional) that image row 0 of a frame with apex at `offset_mm` shows.
    pub fn strip_row_of_top(&self, offset_mm: f64) -> f64 {
        let s = &self.scene.sensor;
        (offset_mm - self.strip.origin_mm) / s.mm_per_px - s.height_px as f64 / 2.0
    }

    /// The strip's defects that `frame` shows, boxes in its pixels. Without `contact` the
    /// gel is pressed flat and every defect in view is in contact.
    pub fn defects_in(&self, frame: &Frame) -> Vec<FrameDefect> {
        let s = &self.scene.sensor;
        let (w, h) = (s.width_px as f64, s.height_px as f64);
        let top = self.strip_row_of_top(frame.actual_offset_mm);
        // Where the roller's surface, `apex_height_mm` at the apex and rising by
        // d²/2R at d from it, stays below what the gel meets at the defect.
        let half_band = |d: &StripDefect| {
            if self.scene.has(Effect::Contact) {
                let pressed = (d.contact_top_mm - self.apex_height_mm).max(0.0);
                (2.0 * s.roller_radius_mm * pressed).sqrt() / s.mm_per_px
            } else {
                f64::INFINITY
            }
        };
        // The roller's apex is at the image's middle row (see `strip_row_of_top`).
        let apex = h / 2.0;
        self.strip
            .defects
            .iter()
            .enumerate()
            .filter_map(|(index, d)| {
                let [x0, y0, x1, y1] = d.box_px;
                let (y0, y1) = (y0 - top, y1 - top);
                if y1 <= 0.0 || y0 >= h {
                    return None;
                }
                let centre = (y0 + y1) / 2.0;
                Some(FrameDefect {
                    index,
                    kind: d.kind,
                    box_px: [x0.max(0.0), y0.max(0.0), x1.min(w), y1.min(h)],
                    in_contact: (centre - apex).abs() < half_band(d) && (0.0..h).contains(&centre),
                })
            })
            .collect()
    }

    /// A seeded generator for `stage` of frame `k`: frames and stages draw independently,
    /// so the same scene and seed give the same bytes however frames are rendered.
    fn rng(&self, k: usize, stage: Effect) -> Pcg64Mcg {
        Self::draw(self.scene.seed, k, stage)
    }

    /// [`Self::rng`] before the simulator exists.
    fn draw(seed: u64, k: usize, stage: Effect) -> Pcg64Mcg {
        let mix = (seed ^ 0x5DEE_CE66_D1CE_4E5B)
            .wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .wrapping_add(((k as u64) << 8) | stage as u64);
        Pcg64Mcg::seed_from_u64(mix)
    }

    /// Renders frame `k` (0-based, below [`Self::frames`]).
    pub fn frame(&self, k: usize) -> Frame {
        let scene = &self.scene;
        let s = &scene.sensor;
        let (w, h) = (s.width_px, s.height_px);
        let mut stages = Vec::new();
        let offset_mm = self.apex_mm[k];
        let mut actual = offset_mm;
        if scene.has(Effect::Speed) {
            stages.push(Effect::Speed);
        }
        if scene.has(Effect::Jitter) {
            stages.push(Effect::Jitter);
            let j = scene.params.jitter_px * s.mm_per_px;
            if j > 0.0 {
                actual += self.rng(k, Effect::Jitter).random_range(-j..=j);
            }
        }
        if scene.has(Effect::Wander) {
            stages.push(Effect::Wander);
        }
        // Indentation of the object into the gel, mm.
        let curved = scene.has(Effect::Contact);
        if curved {
            stages.push(Effect::Contact);
        }
        let sideways_px = self.sideways_px[k];
        let mut depth = self.indentation(actual, sideways_px, curved, h);
        if scene.has(Effect::Gel) {
            stages.push(Effect::Gel);
            let sigma = scene.params.gel_sigma_per_thickness * s.gel_thickness_mm / s.mm_per_px;
            gaussian_blur(&mut depth, w, h, |_| sigma as f32);
        }
        let mut image = self.shade(&depth, w, h, &mut stages);
        if scene.has(Effect::Defocus) {
            stages.push(Effect::Defocus);
            let focal = s.focal_row.unwrap_or(h / 2) as f32;
            let far = focal.max(h as f32 - 1.0 - focal).max(1.0);
            let peak = scene.params.defocus_sigma_px as f32;
            for plane in &mut image.planes {
                gaussian_blur(plane, w, h, |y| peak * (y as f32 - focal).abs() / far);
            }
        }
        if scene.has(Effect::Background) {
            stages.push(Effect::Background);
            let (v, g) = (scene.params.vignetting as f32, scene.params.gradient as f32);
            let (cx, cy) = (w as f32 / 2.0, h as f32 / 2.0);
            let r2max = cx * cx + cy * cy;
            for plane in &mut image.planes {
                for (i, px) in plane.iter_mut().enumerate() {
                    let (x, y) = ((i % w) as f32, (i / w) as f32);
                    let r2 = ((x - cx).powi(2) + (y - cy).powi(2)) / r2max;
                    *px *= (1.0 - v * r2) * (1.0 + g * (x / w as f32 - 0.5));
                }
            }
        }
        if scene.has(Effect::Noise) {
            stages.push(Effect::Noise);
            let mut rng = self.rng(k, Effect::Noise);
            let unit = Normal::new(0.0f32, 1.0).expect("unit normal");
            let (read, shot) = (
                scene.params.read_noise as f32,
                scene.params.shot_noise as f32,
            );
            for plane in &mut image.planes {
                for px in plane.iter_mut() {
                    let sd = (read * read + shot * px.max(0.0)).sqrt();
                    *px += sd * unit.sample(&mut rng);
                }
            }
        }
        Frame {
            index: k,
            offset_mm,
            actual_offset_mm: actual,
            sideways_px,
            image,
            stages,
        }
    }

    /// Indentation `clamp(h − z_gel, 0, t)` for the `rows` image rows of a frame with the
    /// apex at belt position `apex_mm` and the belt `sideways` pixels across (beyond the
    /// strip's sides its edge columns repeat); `curved` adds the roller's curvature to
    /// `z_gel`.
    fn indentation(&self, apex_mm: f64, sideways: f64, curved: bool, rows: usize) -> Vec<f32> {
        let s = &self.scene.sensor;
        let (w, strip) = (s.width_px, &self.strip);
        let top = self.strip_row_of_top(apex_mm);
        let t = s.gel_thickness_mm as f32;
        let r = s.roller_radius_mm;
        let mut out = vec![0f32; w * rows];
        for y in 0..rows {
            // Gap between the gel and the apex plane at this row: R − √(R² − u²).
            let u = (y as f64 - rows as f64 / 2.0 + 0.5) * s.mm_per_px;
            let gap = if curved {
                r - (r * r - u * u).max(0.0).sqrt()
            } else {
                0.0
            };
            let z_gel = (self.apex_height_mm + gap) as f32;
            let pos = top + y as f64;
            let r0 = pos.floor().clamp(0.0, (strip.rows - 1) as f64) as usize;
            let r1 = (r0 + 1).min(strip.rows - 1);
            let f = (pos - pos.floor()) as f32;
            let (a, b) = (
                &strip.height_mm[r0 * w..(r0 + 1) * w],
                &strip.height_mm[r1 * w..(r1 + 1) * w],
            );
            let at = |x: usize| {
                let hgt = a[x] + f * (b[x] - a[x]);
                (hgt - z_gel).clamp(0.0, t)
            };
            if sideways == 0.0 {
                for (x, o) in out[y * w..(y + 1) * w].iter_mut().enumerate() {
                    *o = at(x);
                }
                continue;
            }
            for (x, o) in out[y * w..(y + 1) * w].iter_mut().enumerate() {
                let c = (x as f64 + sideways).clamp(0.0, (w - 1) as f64);
                let (c0, fc) = (c.floor() as usize, (c - c.floor()) as f32);
                let c1 = (c0 + 1).min(w - 1);
                *o = at(c0) + fc * (at(c1) - at(c0));
            }
        }
        out
    }

    /// The shading stage: `gray` (all three LEDs, as a camera's luma), `rgb` (one LED per channel),
    /// or, with neither listed, the indentation itself as gray (0 = none, 255 = the full
    /// gel thickness).
    fn shade(&self, depth: &[f32], w: usize, h: usize, stages: &mut Vec<Effect>) -> Planes {
        let scene = &self.scene;
        let lights = [scene.lights.red, scene.lights.green, scene.lights.blue];
        let mmpp = scene.sensor.mm_per_px as f32;
        let lambert = |l: [f64; 3]| -> Vec<f32> {
            let (lx, ly, lz) = (l[0] as f32, l[1] as f32, l[2] as f32);
            let mut out = vec![0f32; w * h];
            for y in 0..h {
                let (yu, yd) = (y.saturating_sub(1), (y + 1).min(h - 1));
                for x in 0..w {
                    let (xl, xr) = (x.saturating_sub(1), (x + 1).min(w - 1));
                    // The gel surface rises toward the camera by the indentation.
                    let gx =
                        (depth[y * w + xr] - depth[y * w + xl]) / ((xr - xl).max(1) as f32 * mmpp);
                    let gy =
                        (depth[yd * w + x] - depth[yu * w + x]) / ((yd - yu).max(1) as f32 * mmpp);
                    let ndotl = (-gx * lx - gy * ly + lz) / (gx * gx + gy * gy + 1.0).sqrt();
                    out[y * w + x] = FLAT_LEVEL * ndotl.max(0.0) / lz;
                }
            }
            out
        };
        let planes = if scene.has(Effect::Rgb) {
            stages.push(Effect::Rgb);
            lights.iter().map(|&l| lambert(l)).collect()
        } else if scene.has(Effect::Gray) {
            stages.push(Effect::Gray);
            // A monochrome image of the three-LED scene, as a camera's luma (Rec. 601):
            // the unequal weights keep first-order slope shading, where an equal sum of
            // three symmetric LEDs would cancel it.
            let mut gray = vec![0f32; w * h];
            for (&l, weight) in lights.iter().zip([0.299f32, 0.587, 0.114]) {
                gray.iter_mut()
                    .zip(lambert(l))
                    .for_each(|(g, v)| *g += weight * v);
            }
            vec![gray]
        } else {
            let scale = 255.0 / scene.sensor.gel_thickness_mm as f32;
            vec![depth.iter().map(|d| d * scale).collect()]
        };
        Planes {
            width: w,
            height: h,
            planes,
        }
    }

    /// The ideal contact image over the whole strip: the object pressed flat at the apex
    /// depth (no curvature, defocus, light falloff, noise or jitter), with the gel and
    /// shading stages the scene lists. The reference for MS-SSIM.
    pub fn ideal(&self) -> Planes {
        let (w, rows) = (self.strip.width, self.strip.rows);
        let t = self.scene.sensor.gel_thickness_mm as f32;
        let z = self.apex_height_mm as f32;
        let mut depth: Vec<f32> = self
            .strip
            .height_mm
            .iter()
            .map(|hgt| (hgt - z).clamp(0.0, t))
            .collect();
        if self.scene.has(Effect::Gel) {
            let s = &self.scene;
            let sigma =
                s.params.gel_sigma_per_thickness * s.sensor.gel_thickness_mm / s.sensor.mm_per_px;
            gaussian_blur(&mut depth, w, rows, |_| sigma as f32);
        }
        self.shade(&depth, w, rows, &mut Vec::new())
    }
}

/// Normalized Gaussian taps for `sigma` (pixels), radius `⌈3σ⌉`.
fn kernel(sigma: f32) -> Vec<f32> {
    let radius = (3.0 * sigma).ceil() as usize;
    let taps: Vec<f32> = (0..=2 * radius)
        .map(|i| {
            let d = i as f32 - radius as f32;
            (-(d * d) / (2.0 * sigma * sigma)).exp()
        })
        .collect();
    let sum: f32 = taps.iter().sum();
    taps.iter().map(|t| t / sum).collect()
}

/// Separable Gaussian blur, in place, with σ chosen per output row by `sigma_of_row` (a
/// constant for the gel, growing away from the focal line for defocus). Borders repeat
/// the edge pixel; σ below 0.05 px leaves a row as it is.
fn gaussian_blur(img: &mut [f32], w: usize, h: usize, sigma_of_row: impl Fn(usize) -> f32) {
    // One kernel per distinct σ (the gel's is constant; defocus changes row by row), built
    // once and used by both passes; `None` leaves the row as it is.
    let mut kernels: Vec<(f32, Vec<f32>)> = Vec::new();
    let which: Vec<Option<usize>> = (0..h)
        .map(|y| {
            let sigma = sigma_of_row(y);
            if sigma < 0.05 {
                return None;
            }
            if kernels.last().is_none_or(|(s, _)| *s != sigma) {
                kernels.push((sigma, kernel(sigma)));
            }
            Some(kernels.len() - 1)
        })
        .collect();
    let mut tmp = vec![0f32; w * h];
    // Along rows.
    for y in 0..h {
        let row = &img[y * w..(y + 1) * w];
        let out = &mut tmp[y * w..(y + 1) * w];
        let Some(k) = which[y].map(|i| &kernels[i].1) else {
            out.copy_from_slice(row);
            continue;
        };
        let r = k.len() / 2;
        for (x, o) in out.iter_mut().enumerate() {
            *o = k
                .iter()
                .enumerate()
                .map(|(i, c)| c * row[(x + i).saturating_sub(r).min(w - 1)])
                .sum();
        }
    }
    // Along columns, with the output row's σ.
    for y in 0..h {
        let Some(k) = which[y].map(|i| &kernels[i].1) else {
            img[y * w..(y + 1) * w].copy_from_slice(&tmp[y * w..(y + 1) * w]);
            continue;
        };
        let r = k.len() / 2;
        let out = &mut img[y * w..(y + 1) * w];
        out.fill(0.0);
        for (i, c) in k.iter().enumerate() {
            let src = (y + i).saturating_sub(r).min(h - 1);
            for (o, v) in out.iter_mut().zip(&tmp[src * w..(src + 1) * w]) {
                *o += c * v;
            }
        }
    }
}
