//! Images for training and evaluation, from simulated rolls of textile: every frame with
//! the defects in its contact band, and the roll's contact-window strip cut into
//! frame-sized tiles with every defect whose centre they hold.
//!
//! A roll is drawn from its seed alone: the fabric, its scale, the press depth and the
//! defects' places, so the same seed always gives the same images.

use super::targets::Labelled;
use anyhow::Context;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;
use rollfuse_fullres::roll::StripInMemory;
use rollfuse_fullres::strip::{StripOptions, fuse_strip};
use rollfuse_io::image::Planes;
use rollfuse_sim::scene::{EffectParams, Lights, Object, Sensor};
use rollfuse_sim::textile::FABRICS;
use rollfuse_sim::{Effect, Scene, Simulator};

/// Where an image came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Source {
    /// One camera frame.
    Frame,
    /// A tile of the fused strip.
    Fused,
}

/// One labelled image.
#[derive(Debug, Clone)]
pub struct Sample {
    /// The gray image.
    pub image: Planes,
    /// The fabric's label.
    pub class: usize,
    /// Defects it should find.
    pub boxes: Vec<Labelled>,
    /// Defects it shows out of contact (neither to be found nor a false alarm if found).
    pub blurred: Vec<Labelled>,
    /// Frame or fused tile.
    pub source: Source,
}

/// The shape of a simulated roll.
#[derive(Debug, Clone, Copy)]
pub struct RollShape {
    /// Frames a roll.
    pub frames: usize,
    /// Belt travel between frames, mm.
    pub spacing_mm: f64,
    /// Image width and height, pixels.
    pub size: (usize, usize),
    /// Defects a roll.
    pub defects: usize,
}

impl RollShape {
    /// The rolls the shipped model is trained and measured on: 320 × 240 frames 0.6 mm
    /// apart (15 px at 0.04 mm a pixel), 32 frames, 5 defects.
    pub const STANDARD: RollShape = RollShape {
        frames: 32,
        spacing_mm: 0.6,
        size: (320, 240),
        defects: 5,
    };
}

/// The scene of roll `seed`: its fabric is `seed % 17` (so consecutive seeds cover every
/// class), its scale within ±8 %, press depth 0.25–0.45 mm, belt speed varying ±25 % and
/// position jitter of 2 px, with noise, defocus and uneven light.
pub fn roll_scene(seed: u64, shape: &RollShape) -> Scene {
    let mut rng = Pcg64Mcg::seed_from_u64(seed ^ 0xFAB1_C0DE);
    let fabric = FABRICS[class_of(seed)];
    Scene {
        name: format!("{}-{seed}", fabric.name),
        seed,
        effects: vec![
            Effect::Speed,
            Effect::Jitter,
            Effect::Contact,
            Effect::Gel,
            Effect::Gray,
            Effect::Defocus,
            Effect::Background,
            Effect::Noise,
        ],
        object: Object::Textile {
            fabric: fabric.name.to_string(),
            defects: shape.defects,
            scale: rng.random_range(0.92..1.08),
        },
        sensor: Sensor {
            roller_radius_mm: 12.0,
            gel_thickness_mm: 1.5,
            mm_per_px: 0.04,
            width_px: shape.size.0,
            height_px: shape.size.1,
            press_depth_mm: rng.random_range(0.25..0.45),
            frame_spacing_mm: shape.spacing_mm,
            frames: shape.frames,
            focal_row: None,
        },
        lights: Lights::default(),
        params: EffectParams::default(),
    }
}

/// How a roll is drawn. The detector is trained on [`Style::Standard`]; [`Style::Oblique`]
/// is a look it never saw, for measuring how it carries over and for fine-tuning
/// (`rollfuse train --images`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Style {
    /// The simulator's own: three LEDs 120° apart, 35° above the gel, seen as a camera's
    /// luma; gel smoothing a tenth of its thickness.
    Standard,
    /// One LED low (20°) from across the belt, a gel half again as soft, half the defocus and
    /// twice the read noise: shading and blur that differ from the standard look, as
    /// another sensor or renderer would.
    Oblique,
    /// A look drawn from the roll's seed, for training that carries over: a quarter of
    /// the rolls in the standard look, the others lit by one to three LEDs anywhere
    /// around, 15–55° above the gel, with gel smoothing 0.8–1.3 times, defocus 0.75–1.5
    /// times and read noise 0.5–1.5 times the standard's. [`Style::Oblique`]'s gel,
    /// defocus and noise lie outside it (softer, less, more), so it measures how far such
    /// training generalizes; its single low LED lies inside the lights' range.
    Varied,
}

impl Style {
    /// Every style, by the name `--style` takes.
    pub const NAMED: [(&str, Style); 3] = [
        ("standard", Style::Standard),
        ("oblique", Style::Oblique),
        ("varied", Style::Varied),
    ];

    /// The name `--style` takes.
    pub fn name(self) -> &'static str {
        Style::NAMED
            .iter()
            .find(|(_, s)| *s == self)
            .map_or("standard", |(n, _)| n)
    }

    /// Redraws `scene` in this style.
    pub fn apply(self, scene: &mut Scene) {
        let p = &mut scene.params;
        match self {
            Style::Standard => {}
            Style::Oblique => {
                // All three LEDs alike: the luma is that one light.
                let led = Lights::led(0.0, 20.0);
                scene.lights = Lights {
                    red: led,
                    green: led,
                    blue: led,
                };
                p.gel_sigma_per_thickness *= 1.5;
                p.defocus_sigma_px /= 2.0;
                p.read_noise *= 2.0;
            }
            Style::Varied => {
                let mut rng = Pcg64Mcg::seed_from_u64(scene.seed ^ 0x57_11E5);
                if rng.random_bool(0.25) {
                    return;
                }
                let leds = rng.random_range(1..=3);
                let mut draw =
                    || Lights::led(rng.random_range(0.0..360.0), rng.random_range(15.0..55.0));
                let red = draw();
                // Fewer LEDs: the others shine with the last one drawn.
                let green = if leds >= 2 { draw() } else { red };
                let blue = if leds == 3 { draw() } else { green };
                scene.lights = Lights { red, green, blue };
                p.gel_sigma_per_thickness *= rng.random_range(0.8..1.3);
                p.defocus_sigma_px *= rng.random_range(0.75..1.5);
                p.read_noise *= rng.random_range(0.5..1.5);
            }
        }
    }
}

impl std::str::FromStr for Style {
    type Err = String;

    fn from_str(name: &str) -> Result<Self, String> {
        Style::NAMED
            .iter()
            .find(|(n, _)| *n == name)
            .map(|&(_, s)| s)
            .ok_or_else(|| {
                let names: Vec<&str> = Style::NAMED.iter().map(|(n, _)| *n).collect();
                format!("{name:?} is not a style ({})", names.join(", "))
            })
    }
}

/// A simulated roll's labelled images.
pub struct Roll {
    /// The fabric's label.
    pub class: usize,
    /// Every frame.
    pub frames: Vec<Sample>,
    /// The fused strip in tiles of the frame's height.
    pub fused: Vec<Sample>,
    /// The whole fused strip with its defects (strip rows from 0).
    pub strip: Sample,
}

/// Every frame of `sim`'s roll of fabric `class`, labelled, and the strip row each
/// frame's top was commanded to.
pub fn frames(sim: &Simulator, class: usize) -> (Vec<Sample>, Vec<f64>) {
    let mut frames = Vec::with_capacity(sim.frames());
    let mut commanded = Vec::with_capacity(sim.frames());
    for k in 0..sim.frames() {
        let f = sim.frame(k);
        commanded.push(sim.strip_row_of_top(f.offset_mm));
        let (sharp, blurred): (Vec<_>, Vec<_>) =
            sim.defects_in(&f).into_iter().partition(|d| d.in_contact);
        let label = |d: &rollfuse_sim::render::FrameDefect| Labelled {
            kind: d.kind,
            box_px: d.box_px.map(|v| v as f32),
        };
        frames.push(Sample {
            image: f.image,
            class,
            boxes: sharp.iter().map(label).collect(),
            blurred: blurred.iter().map(label).collect(),
            source: Source::Frame,
        });
    }
    (frames, commanded)
}

/// The fabric class of roll `seed`.
pub fn class_of(seed: u64) -> usize {
    (seed % FABRICS.len() as u64) as usize
}

/// Renders and fuses roll `seed`.
pub fn roll(seed: u64, shape: &RollShape) -> crate::Result<Roll> {
    roll_in_style(seed, shape, Style::Standard)
}

/// Renders and fuses roll `seed`, drawn in `style`.
pub fn roll_in_style(seed: u64, shape: &RollShape, style: Style) -> crate::Result<Roll> {
    let mut scene = roll_scene(seed, shape);
    style.apply(&mut scene);
    let class = class_of(seed);
    let sim = Simulator::new(&scene)?;
    let (frames, commanded) = frames(&sim, class);
    let opts = StripOptions::tracked(scene.sensor.roller_geometry(), commanded);
    let (sink, _) = fuse_strip(
        frames.iter().map(|s| Ok(s.image.clone())),
        &opts,
        |_, _| Ok(StripInMemory::default()),
        |_| Ok(()),
    )?;
    let first = sink.first_row.context("the roll fused to nothing")?;
    let image = sink.image.context("the roll fused to nothing")?;
    let boxes = sim
        .strip()
        .defects
        .iter()
        .map(|d| {
            let [x0, y0, x1, y1] = d.box_px;
            let shift = first as f64;
            Labelled {
                kind: d.kind,
                box_px: [x0, y0 - shift, x1, y1 - shift].map(|v| v as f32),
            }
        })
        .collect();
    let strip = Sample {
        image,
        class,
        boxes,
        blurred: Vec::new(),
        source: Source::Fused,
    };
    let fused = cut(&strip, shape.size.1)?;
    Ok(Roll {
        class,
        frames,
        fused,
        strip,
    })
}

/// `strip` cut into tiles of `rows` (the last one ending at the strip's end), each with
/// the defects whose centre it holds, clipped to it.
pub fn cut(strip: &Sample, rows: usize) -> crate::Result<Vec<Sample>> {
    let h = strip.image.height;
    if h < rows {
        return Ok(Vec::new());
    }
    let tops: Vec<usize> = (0..h / rows)
        .map(|k| k * rows)
        .chain((!h.is_multiple_of(rows)).then_some(h - rows))
        .collect();
    tops.into_iter()
        .map(|top| {
            let (t, b) = (top as f32, (top + rows) as f32);
            let boxes = strip
                .boxes
                .iter()
                .filter(|l| (t..b).contains(&((l.box_px[1] + l.box_px[3]) / 2.0)))
                .map(|l| {
                    let [x0, y0, x1, y1] = l.box_px;
                    Labelled {
                        kind: l.kind,
                        box_px: [x0, (y0 - t).max(0.0), x1, (y1 - t).min(rows as f32)],
                    }
                })
                .collect();
            Ok(Sample {
                image: strip.image.crop(top, 0, rows, strip.image.width)?,
                class: strip.class,
                boxes,
                blurred: Vec::new(),
                source: Source::Fused,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An LED's elevation above the gel, degrees.
    fn elevation(led: [f64; 3]) -> f64 {
        led[2].asin().to_degrees()
    }

    #[test]
    fn varied_looks_stay_in_their_ranges_and_the_oblique_lies_outside() {
        let shape = RollShape::STANDARD;
        let standard = roll_scene(1, &shape);
        let (mut as_standard, mut one_led) = (0, 0);
        for seed in 0..100 {
            let mut scene = roll_scene(seed, &shape);
            Style::Varied.apply(&mut scene);
            if scene == roll_scene(seed, &shape) {
                as_standard += 1;
                continue;
            }
            let l = &scene.lights;
            for led in [l.red, l.green, l.blue] {
                assert!((15.0..55.0).contains(&elevation(led)), "{seed}: {l:?}");
            }
            one_led += usize::from(l.red == l.blue);
            let gel =
                scene.params.gel_sigma_per_thickness / standard.params.gel_sigma_per_thickness;
            assert!((0.8..1.3).contains(&gel), "{seed}: {gel}");
            // The same seed, the same look.
            let mut again = roll_scene(seed, &shape);
            Style::Varied.apply(&mut again);
            assert_eq!(scene, again);
        }
        // About a quarter in the standard look, about a third of the rest lit by one LED.
        assert!((15..=35).contains(&as_standard), "{as_standard} of 100");
        assert!((15..=35).contains(&one_led), "{one_led} of 100");
        let mut oblique = roll_scene(1, &shape);
        Style::Oblique.apply(&mut oblique);
        assert!((elevation(oblique.lights.red) - 20.0).abs() < 1e-9);
        assert_eq!(oblique.lights.red, oblique.lights.blue);
        let gel = oblique.params.gel_sigma_per_thickness / standard.params.gel_sigma_per_thickness;
        assert!(!(0.8..1.3).contains(&gel));
        let names: Vec<Style> = Style::NAMED
            .iter()
            .map(|(n, _)| n.parse().unwrap())
            .collect();
        assert_eq!(names, [Style::Standard, Style::Oblique, Style::Varied]);
        assert!(
            "glossy"
                .parse::<Style>()
                .unwrap_err()
                .contains("standard, oblique, varied")
        );
    }
}
