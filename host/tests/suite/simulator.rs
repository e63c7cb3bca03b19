//! The simulator: every built-in scene renders, each effect does what it says and only when
//! listed, bad scenes are refused with the field named, and runs are deterministic.

use rollfuse::progress::Silent;
use rollfuse::sim::{Effect, Manifest, Scene, Simulator, output};
use std::path::Path;

/// A small scene around `object` (TOML for the `[object]` table) with `effects`.
fn scene(effects: &[&str], object: &str, extra: &str) -> Scene {
    let effects: Vec<String> = effects.iter().map(|e| format!("\"{e}\"")).collect();
    let text = format!(
        r#"
seed = 7
effects = [{}]
{extra}
[object]
{object}

[sensor]
roller_radius_mm = 12.0
gel_thickness_mm = 1.5
mm_per_px = 0.05
width_px = 96
height_px = 120
press_depth_mm = 0.8
frame_spacing_mm = 1.0
frames = 5
"#,
        effects.join(", ")
    );
    Scene::parse(&text, "test").unwrap()
}

/// A flat-topped box covering the whole field of view: contact depth alone shapes the image.
const PLATE: &str = r#"kind = "primitives"
shapes = [{ shape = "box", x_mm = 2.4, y_mm = 2.0, width_mm = 40.0, length_mm = 40.0, height_mm = 1.0 }]"#;

const DOTS: &str = r#"kind = "dots""#;

fn mean(v: &[f32]) -> f64 {
    v.iter().map(|&x| x as f64).sum::<f64>() / v.len() as f64
}

fn rows(img: &[f32], w: usize, y0: usize, y1: usize) -> &[f32] {
    &img[y0 * w..y1 * w]
}

/// Mean squared 4-neighbour Laplacian over rows y0..y1: high-frequency energy.
fn hf_energy(img: &[f32], w: usize, y0: usize, y1: usize) -> f64 {
    let mut sum = 0.0;
    let mut n = 0.0;
    for y in y0.max(1)..y1.min(img.len() / w - 1) {
        for x in 1..w - 1 {
            let c = img[y * w + x];
            let l = img[y * w + x - 1]
                + img[y * w + x + 1]
                + img[(y - 1) * w + x]
                + img[(y + 1) * w + x]
                - 4.0 * c;
            sum += (l as f64).powi(2);
            n += 1.0;
        }
    }
    sum / n
}

#[test]
fn every_built_in_scene_renders() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let names = [
        "letters",
        "dots",
        "lines",
        "curves",
        "spheres",
        "fabric",
        "screw",
        "paperclip",
    ];
    for name in names {
        let mut s = Scene::load(&dir.join(format!("{name}.toml"))).unwrap();
        s.sensor.frames = 3;
        let sim = Simulator::new(&s).unwrap();
        let f = sim.frame(1);
        let planes = if name == "spheres" { 3 } else { 1 };
        assert_eq!(f.image.planes.len(), planes, "{name}");
        // Something is in contact: the frame is not flat.
        let p = &f.image.planes[0];
        let (lo, hi) = p
            .iter()
            .fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
        assert!(hi - lo > 20.0, "{name}: range {lo}..{hi}");
        let expected: Vec<Effect> = Effect::ALL.into_iter().filter(|e| s.has(*e)).collect();
        assert_eq!(f.stages, expected, "{name}");
    }
    let spheres = Scene::load(&dir.join("spheres.toml")).unwrap();
    let sim = Simulator::new(&spheres).unwrap();
    assert_eq!(sim.strip().regions.len(), 3);
    let fabric = Scene::load(&dir.join("fabric.toml")).unwrap();
    let names: Vec<_> = Simulator::new(&fabric)
        .unwrap()
        .strip()
        .regions
        .iter()
        .map(|r| r.0.clone())
        .collect();
    assert_eq!(names, ["hole", "knot", "broken_yarn"]);
}

#[test]
fn only_listed_effects_run_in_stage_order() {
    // Listed out of order: stages still run in pipeline order, and nothing unlisted runs.
    let s = scene(&["noise", "contact"], DOTS, "");
    assert_eq!(
        Simulator::new(&s).unwrap().frame(0).stages,
        [Effect::Contact, Effect::Noise]
    );
    let none = scene(&[], DOTS, "");
    assert!(Simulator::new(&none).unwrap().frame(2).stages.is_empty());
    let all = scene(
        &[
            "contact",
            "gel",
            "rgb",
            "defocus",
            "noise",
            "jitter",
            "background",
            "speed",
            "wander",
        ],
        DOTS,
        "",
    );
    let ran = Simulator::new(&all).unwrap().frame(0).stages;
    let expected: Vec<Effect> = Effect::ALL
        .into_iter()
        .filter(|e| *e != Effect::Gray)
        .collect();
    assert_eq!(ran, expected);
}

#[test]
fn contact_makes_the_apex_press_deepest() {
    // No shading: the image is the indentation itself.
    let (w, h) = (96, 120);
    for (effects, curved) in [(vec!["contact"], true), (vec![], false)] {
        let img = Simulator::new(&scene(&effects, PLATE, ""))
            .unwrap()
            .frame(2)
            .image
            .planes[0]
            .clone();
        let apex = mean(rows(&img, w, h / 2 - 5, h / 2 + 5));
        let edge = mean(rows(&img, w, 0, 10));
        if curved {
            assert!(apex > edge + 20.0, "apex {apex} edge {edge}");
        } else {
            assert!(
                (apex - edge).abs() < 1e-3,
                "flat press: apex {apex} edge {edge}"
            );
        }
    }
}

#[test]
fn gel_smooths_the_indentation() {
    let (w, h) = (96, 120);
    let sharp = Simulator::new(&scene(&["contact"], DOTS, ""))
        .unwrap()
        .frame(2)
        .image
        .planes[0]
        .clone();
    let soft = Simulator::new(&scene(&["contact", "gel"], DOTS, ""))
        .unwrap()
        .frame(2)
        .image
        .planes[0]
        .clone();
    let (e_sharp, e_soft) = (hf_energy(&sharp, w, 0, h), hf_energy(&soft, w, 0, h));
    assert!(e_soft < 0.5 * e_sharp, "gel: {e_soft} vs {e_sharp}");
    // Smoothing moves material, it does not remove it.
    assert!((mean(&soft) - mean(&sharp)).abs() < 0.05 * mean(&sharp));
}

#[test]
fn defocus_blurs_away_from_the_focal_line() {
    let (w, h) = (96, 120);
    // A flat press (no contact stage) so every row shows the dots in full, on a belt long
    // enough for dots to fill the frame.
    let render = |effects: &[&str]| {
        let mut s = scene(effects, DOTS, "");
        s.sensor.frames = 20;
        Simulator::new(&s).unwrap().frame(10).image.planes[0].clone()
    };
    let (plain, blurred) = (render(&["gray"]), render(&["gray", "defocus"]));
    let ratio = |y0, y1| hf_energy(&blurred, w, y0, y1) / hf_energy(&plain, w, y0, y1);
    let (near, far) = (ratio(h / 2 - 6, h / 2 + 6), ratio(h / 2 + 30, h / 2 + 45));
    assert!(near > 0.8, "focal band keeps its detail: {near}");
    assert!(far < 0.5 * near, "far rows lose detail: {far} vs {near}");
}

#[test]
fn noise_changes_with_the_seed_and_only_with_it() {
    let render = |seed: u64, effects: &[&str]| {
        let mut s = scene(effects, DOTS, "");
        s.seed = seed;
        Simulator::new(&s).unwrap().frame(1).image.to_u8()
    };
    assert_eq!(
        render(1, &["contact", "gray", "noise"]),
        render(1, &["contact", "gray", "noise"])
    );
    assert_ne!(
        render(1, &["contact", "gray", "noise"]),
        render(2, &["contact", "gray", "noise"])
    );
    // Without the noise stage the seed has no effect.
    assert_eq!(
        render(1, &["contact", "gray"]),
        render(2, &["contact", "gray"])
    );
    let clean = render(1, &["contact", "gray"]);
    let noisy = render(1, &["contact", "gray", "noise"]);
    let rms = (clean
        .iter()
        .zip(&noisy)
        .map(|(a, b)| (*a as f64 - *b as f64).powi(2))
        .sum::<f64>()
        / clean.len() as f64)
        .sqrt();
    // Read noise 2 plus shot noise at ~120 gray levels: √(4 + 0.05·120) ≈ 3.2.
    assert!((2.5..4.0).contains(&rms), "noise rms {rms}");
}

#[test]
fn jitter_moves_frames_within_its_bound() {
    let s = scene(&["contact", "jitter"], DOTS, "[params]\njitter_px = 3.0");
    let sim = Simulator::new(&s).unwrap();
    let bound = 3.0 * s.sensor.mm_per_px;
    let moved: Vec<f64> = (0..5)
        .map(|k| {
            let f = sim.frame(k);
            f.actual_offset_mm - f.offset_mm
        })
        .collect();
    assert!(moved.iter().all(|d| d.abs() <= bound + 1e-12), "{moved:?}");
    assert!(moved.iter().any(|d| d.abs() > 1e-6), "{moved:?}");
    let steady = Simulator::new(&scene(&["contact"], DOTS, "")).unwrap();
    assert!((0..5).all(|k| {
        let f = steady.frame(k);
        f.actual_offset_mm == f.offset_mm
    }));
}

#[test]
fn background_darkens_the_corners() {
    let (w, h) = (96, 120);
    // The only shape lies far outside the field of view: the frame is undisturbed gel.
    let flat = scene(
        &["gray", "background"],
        r#"kind = "primitives"
shapes = [{ shape = "box", x_mm = 100.0, y_mm = 2.0, width_mm = 1.0, length_mm = 1.0, height_mm = 0.1 }]"#,
        "",
    );
    let img = Simulator::new(&flat).unwrap().frame(0).image.planes[0].clone();
    let centre = img[(h / 2) * w + w / 2];
    let corner = img[0];
    assert!(corner < 0.85 * centre, "corner {corner} centre {centre}");
}

#[test]
fn rgb_gives_three_channels_that_differ_on_slopes() {
    let img = Simulator::new(&scene(&["contact", "rgb"], r#"kind = "spheres""#, ""))
        .unwrap()
        .frame(2)
        .image;
    assert_eq!(img.planes.len(), 3);
    let diff = img.planes[0]
        .iter()
        .zip(&img.planes[1])
        .filter(|(r, g)| (*r - *g).abs() > 10.0)
        .count();
    assert!(diff > 100, "{diff} pixels where red and green differ");
}

fn refuse(text: &str, field: &str) {
    let err = Scene::parse(text, "bad").expect_err("must be refused");
    let msg = format!("{err:#}");
    assert!(msg.contains(field), "message {msg:?} should name {field:?}");
}

const GOOD: &str = r#"
effects = ["contact", "gray"]
[object]
kind = "dots"
[sensor]
roller_radius_mm = 12.0
gel_thickness_mm = 1.5
mm_per_px = 0.05
width_px = 96
height_px = 120
press_depth_mm = 0.8
frame_spacing_mm = 1.0
frames = 5
"#;

#[test]
fn bad_scenes_are_refused_with_the_field_named() {
    assert!(Scene::parse(GOOD, "good").is_ok());
    refuse(
        &GOOD.replace("frames = 5", "frames = 5\nspeed = 3"),
        "speed",
    );
    refuse(
        &GOOD.replace("roller_radius_mm = 12.0\n", ""),
        "roller_radius_mm",
    );
    refuse(
        &GOOD.replace("roller_radius_mm = 12.0", "roller_radius_mm = -3.0"),
        "sensor.roller_radius_mm",
    );
    refuse(
        &GOOD.replace("width_px = 96", "width_px = 100000"),
        "sensor.width_px",
    );
    refuse(&GOOD.replace("\"gray\"]", "\"gray\", \"blur\"]"), "blur");
    refuse(
        &GOOD.replace("kind = \"dots\"", "kind = \"teapot\""),
        "teapot",
    );
    refuse(
        &GOOD.replace(
            "kind = \"dots\"",
            "kind = \"dots\"\npitch_mm = 0.5\nsize_mm = 1.0",
        ),
        "object.size_mm",
    );
    refuse(&GOOD.replace("\"gray\"]", "\"gray\", \"rgb\"]"), "effects");
    refuse(&GOOD.replace("frames = 5", "frames = 0"), "sensor.frames");
    refuse(
        &format!(
            "{GOOD}\n[lights]\nred = [1.0, 0.0, 0.0]\ngreen = [0.0, 0.0, 1.0]\nblue = [0.0, 0.0, 1.0]"
        ),
        "lights.red",
    );
    refuse("this is not toml", "");
    // Limits that keep memory bounded and the layout well defined.
    refuse(
        &GOOD
            .replace("frames = 5", "frames = 10000")
            .replace("mm_per_px = 0.05", "mm_per_px = 0.01"),
        "frame_spacing_mm",
    );
    refuse(
        &GOOD.replace(
            "kind = \"dots\"",
            "kind = \"dots\"\npitch_mm = 0.01\nsize_mm = 0.005",
        ),
        "object.pitch_mm",
    );
    refuse(
        &format!("{GOOD}\n[params]\ndefocus_sigma_px = 1e6"),
        "params.defocus_sigma_px",
    );
    let shapes = r#"kind = "primitives"
shapes = [{ shape = "box", x_mm = 1.0, y_mm = 1.0, width_mm = 1.0, length_mm = 1.0, height_mm = 1.0, region = "a" },
          { shape = "box", x_mm = 3.0, y_mm = 1.0, width_mm = 1.0, length_mm = 1.0, height_mm = 1.0, region = "a" }]"#;
    refuse(&GOOD.replace("kind = \"dots\"", shapes), "used twice");
    refuse(
        &GOOD.replace(
            "kind = \"dots\"",
            &shapes.replace("region = \"a\" }]", "region = \"../x\" }]"),
        ),
        "region must be",
    );
}

#[test]
fn same_scene_and_seed_give_the_same_bytes() {
    let s = scene(
        &[
            "contact",
            "gel",
            "gray",
            "defocus",
            "noise",
            "jitter",
            "background",
        ],
        r#"kind = "letters"
text = "AB""#,
        "",
    );
    let sim = Simulator::new(&s).unwrap();
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let written = output::write(&sim, a.path(), &Silent).unwrap();
    output::write(&Simulator::new(&s).unwrap(), b.path(), &Silent).unwrap();
    // The manifest reads back as written, the scene with it.
    let read = Manifest::read(&a.path().join("manifest.json")).unwrap();
    assert_eq!(read, written);
    assert_eq!(read.scene_file.as_ref(), Some(sim.scene()));
    let mut files: Vec<_> = walk(a.path());
    files.sort();
    assert!(files.len() >= 5 + 4);
    for f in files {
        let rel = f.strip_prefix(a.path()).unwrap();
        assert_eq!(
            std::fs::read(&f).unwrap(),
            std::fs::read(b.path().join(rel)).unwrap(),
            "{}",
            rel.display()
        );
    }
}

fn walk(dir: &Path) -> Vec<std::path::PathBuf> {
    std::fs::read_dir(dir)
        .unwrap()
        .flat_map(|e| {
            let p = e.unwrap().path();
            if p.is_dir() { walk(&p) } else { vec![p] }
        })
        .collect()
}

#[test]
fn speed_varies_each_frames_travel_within_its_bound_and_the_commands_follow() {
    let steps = |effects: &[&str]| {
        let mut sc = scene(effects, DOTS, "[params]\nspeed_jitter = 0.25");
        sc.sensor.frames = 40;
        let sim = Simulator::new(&sc).unwrap();
        let frames: Vec<_> = (0..40).map(|k| sim.frame(k)).collect();
        // Commanded and true positions agree: the motion system counts the varied steps.
        assert!(frames.iter().all(|f| f.offset_mm == f.actual_offset_mm));
        frames
            .windows(2)
            .map(|w| w[1].offset_mm - w[0].offset_mm)
            .collect::<Vec<f64>>()
    };
    let steady = steps(&["contact", "gray"]);
    assert!(steady.iter().all(|s| (s - 1.0).abs() < 1e-9), "{steady:?}");
    let varied = steps(&["speed", "contact", "gray"]);
    assert!(
        varied
            .iter()
            .all(|s| (0.75 - 1e-9..=1.25 + 1e-9).contains(s)),
        "{varied:?}"
    );
    let spread = varied.iter().fold(0f64, |m, s| m.max((s - 1.0).abs()));
    assert!(spread > 0.15, "speed barely varies: {spread}");
}

/// A defect is called in contact where its frame shows it pressed into the gel: the
/// texture in and around its box stands well above the bare rows' noise. The roller
/// presses relative to the roll's tallest point (here a snag's loop), so the cloth touches
/// over a narrower band than that point does, and a slub standing above the cloth over a
/// wider one.
#[test]
fn a_defect_is_in_contact_only_where_its_frame_shows_it_pressed() {
    use rollfuse::detect::data::{RollShape, roll_scene};
    use rollfuse::sim::scene::Object;
    let shape = RollShape {
        frames: 60,
        defects: 6,
        ..RollShape::STANDARD
    };
    let mut scene = roll_scene(2, &shape);
    scene.object = Object::Textile {
        fabric: "twill_2_2".into(),
        defects: 6,
        scale: 1.0,
    };
    scene.sensor.press_depth_mm = 0.35;
    let sim = Simulator::new(&scene).unwrap();
    let (w, h) = (scene.sensor.width_px, scene.sensor.height_px);
    let (mut inside, mut outside) = (Vec::new(), 0);
    for k in 0..sim.frames() {
        let frame = sim.frame(k);
        let band = band_passed(&frame.image.planes[0], w);
        // The texture in a box as a fraction of the way from the bare rows' (the
        // frame's first and last tenth, noise alone) to the apex rows'.
        let rows = |y0: usize, y1: usize| box_energy(&band, w, [0, y0, w, y1]);
        let bare = (rows(0, h / 10) + rows(h - h / 10, h)) / 2.0;
        let apex = rows(h / 2 - 10, h / 2 + 10);
        for d in sim.defects_in(&frame) {
            // The defect's box widened by half its size each way: a hole shows the
            // bare belt, the cloth around it its texture.
            let [x0, y0, x1, y1] = d.box_px;
            let (dx, dy) = ((x1 - x0) / 2.0, (y1 - y0) / 2.0);
            let clip = |v: f64, n: usize| v.clamp(0.0, n as f64) as usize;
            let around = [
                clip(x0 - dx, w),
                clip(y0 - dy, h),
                clip(x1 + dx, w),
                clip(y1 + dy, h),
            ];
            if around[3] < around[1] + 8 {
                continue;
            }
            let seen = (box_energy(&band, w, around) - bare) / (apex - bare);
            if d.in_contact {
                inside.push(seen);
            } else {
                assert!(
                    seen <= 0.25,
                    "frame {k}: a defect at row {:.0} called out of contact shows {seen:.2} of the \
                     apex's texture around it",
                    (y0 + y1) / 2.0
                );
                outside += 1;
            }
        }
    }
    // A defect whose centre only grazes the gel (a snag's thin loop, a slub's crown) is
    // in contact but shows little: most show plainly.
    let plain = inside.iter().filter(|&&s| s >= 0.25).count();
    assert!(
        plain as f64 >= 0.8 * inside.len() as f64 && outside > 10,
        "{plain} of {} defects in contact show a quarter of the apex's texture; {outside} out \
         of contact",
        inside.len()
    );
}

/// `img` (`w` wide) band-passed to a yarn's scale: its 5 × 5 box mean less its 21 × 21
/// box mean (noise and uneven light taken out).
fn band_passed(img: &[f32], w: usize) -> Vec<f64> {
    let h = img.len() / w;
    // Integral image with a zero row and column in front.
    let mut sum = vec![0f64; (w + 1) * (h + 1)];
    for y in 0..h {
        for x in 0..w {
            sum[(y + 1) * (w + 1) + x + 1] =
                f64::from(img[y * w + x]) + sum[y * (w + 1) + x + 1] + sum[(y + 1) * (w + 1) + x]
                    - sum[y * (w + 1) + x];
        }
    }
    let mean = |x: usize, y: usize, r: usize| {
        let (x0, y0, x1, y1) = (
            x.saturating_sub(r),
            y.saturating_sub(r),
            (x + r + 1).min(w),
            (y + r + 1).min(h),
        );
        let total = sum[y1 * (w + 1) + x1] - sum[y0 * (w + 1) + x1] - sum[y1 * (w + 1) + x0]
            + sum[y0 * (w + 1) + x0];
        total / ((x1 - x0) * (y1 - y0)) as f64
    };
    (0..h * w)
        .map(|i| mean(i % w, i / w, 2) - mean(i % w, i / w, 10))
        .collect()
}

/// Mean square of `band` (`w` wide) inside `[x0, y0, x1, y1]`.
fn box_energy(band: &[f64], w: usize, [x0, y0, x1, y1]: [usize; 4]) -> f64 {
    let (mut total, mut n) = (0.0, 0.0);
    for y in y0..y1 {
        for v in &band[y * w + x0..y * w + x1] {
            total += v * v;
            n += 1.0;
        }
    }
    total / n
}
