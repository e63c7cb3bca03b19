//! Registration without a motion record over the regimes a roll can be in: the roller's
//! contact band narrow (features touch the gel only near the apex, the belt itself pressed
//! into a band across the frame), middling or covering the whole frame; a texture-free
//! stretch in every roll; a speed varying by ±30 % from frame to frame around 7 px; a belt
//! wandering sideways; 640 × 480 frames. Each regime is tried on [`SEEDS`] rolls (the same
//! features, the speed, noise and wander drawn anew): on every roll the placement is
//! trusted, no belt is lost (every step between two matched frames within 3 px of the
//! truth) and every position is within [`WORST_DRIFT`] of the travel; over the rolls, the
//! median of the worst position error is within 2 % of the travel.

use rollfuse::fullres::contact::{ContactProfile, MEASURE_FRAMES};
use rollfuse::fullres::register::{Placement, Source, TrackParams, Tracker};
use rollfuse::sim::{Scene, Simulator};

/// One roll of the sweep.
struct Case {
    name: &'static str,
    /// Roller radius, press depth at the apex and feature height, mm.
    radius: f64,
    press: f64,
    height: f64,
    /// Frame size, pixels.
    size: (usize, usize),
    mm_per_px: f64,
    frames: usize,
    /// The belt's mean travel a frame, pixels.
    step_px: f64,
    /// Sideways moves of up to this many pixels a frame (0: none).
    wander: f64,
}

/// The rolls each regime is tried on. A roll's bare start and texture-free stretch rest
/// on the speed, and the belt's own ±30 % steps there are random: over the third of a
/// 640 × 480 roll's travel that rests on them, about 2 % of the travel by themselves. So
/// a regime is judged on the median of several rolls, and each roll on a looser bound.
const SEEDS: [u64; 3] = [5, 6, 7];
/// The largest position error allowed on any one roll, a fraction of the travel.
const WORST_DRIFT: f64 = 0.04;
/// The largest median (over [`SEEDS`]) of a roll's worst position error, a fraction of
/// the travel.
const DRIFT: f64 = 0.02;

/// Raised spheres and boxes along `length` mm of a belt `width` mm wide, none between
/// 35 % and 55 % of the length (a texture-free stretch).
fn features(length: f64, width: f64, height: f64) -> String {
    let mut shapes = Vec::new();
    let (mut y, mut k) = (3.0, 0u64);
    // A fixed sequence of pseudo-random numbers in 0..1.
    let mut next = || {
        k = k
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (k >> 11) as f64 / (1u64 << 53) as f64
    };
    while y < length {
        if (0.35 * length..0.55 * length).contains(&y) {
            y += 1.0;
            continue;
        }
        let x = 1.5 + next() * (width - 3.0);
        shapes.push(if next() < 0.35 {
            format!("{{ shape = \"sphere\", x_mm = {x:.2}, y_mm = {y:.2}, radius_mm = 1.0, height_mm = {height} }}")
        } else {
            format!(
                "{{ shape = \"box\", x_mm = {x:.2}, y_mm = {y:.2}, width_mm = {:.2}, length_mm = {:.2}, height_mm = {height} }}",
                1.0 + 2.0 * next(),
                0.8 + 2.0 * next()
            )
        });
        y += 3.0 + 3.0 * next();
    }
    shapes.join(",\n")
}

impl Case {
    fn spacing_mm(&self) -> f64 {
        self.step_px * self.mm_per_px
    }

    fn scene(&self, seed: u64) -> Scene {
        let (w, h) = self.size;
        let length = self.spacing_mm() * self.frames as f64;
        let wander = if self.wander > 0.0 {
            ", \"wander\""
        } else {
            ""
        };
        let text = format!(
            r#"
seed = {seed}
effects = ["speed"{wander}, "contact", "gel", "gray", "defocus", "noise"]
[params]
speed_jitter = 0.3
wander_px = {wander_px}
read_noise = 1.5
defocus_sigma_px = 4.0
[object]
kind = "primitives"
shapes = [{shapes}]
[sensor]
roller_radius_mm = {r}
gel_thickness_mm = 1.5
mm_per_px = {mmpp}
width_px = {w}
height_px = {h}
press_depth_mm = {press}
frame_spacing_mm = {spacing}
frames = {frames}
"#,
            wander_px = self.wander.max(0.0),
            shapes = features(length, w as f64 * self.mm_per_px, self.height),
            r = self.radius,
            mmpp = self.mm_per_px,
            press = self.press,
            spacing = self.spacing_mm(),
            frames = self.frames,
        );
        Scene::parse(&text, self.name).unwrap()
    }
}

/// Every frame of `sim` placed from its images alone, and the tracker's verdict.
fn place(sim: &Simulator, drift: usize) -> (Vec<Placement>, Vec<String>) {
    let n = sim.frames();
    let head: Vec<_> = (0..n.min(MEASURE_FRAMES))
        .map(|k| sim.frame(k).image)
        .collect();
    let profile = ContactProfile::measure(&head.iter().collect::<Vec<_>>());
    let params = TrackParams {
        max_drift_cols: drift,
        ..TrackParams::for_height(profile.height)
    };
    let mut tracker = Tracker::new(&profile, params);
    let mut placed = Vec::with_capacity(n);
    for k in 0..n {
        let image = head.get(k).cloned().unwrap_or_else(|| sim.frame(k).image);
        placed.extend(tracker.push(&image, None));
    }
    placed.extend(tracker.finish());
    (placed, tracker.summary().doubts(n))
}

/// One roll of `case`: its checks, and its worst position error as a fraction of the
/// travel.
fn one_roll(case: &Case, seed: u64) -> f64 {
    one_roll_within(case, seed, 3.0)
}

/// [`one_roll`], every step between matched frames within `step_px` of the truth.
fn one_roll_within(case: &Case, seed: u64, step_px: f64) -> f64 {
    let name = format!("{} (seed {seed})", case.name);
    let sim = Simulator::new(&case.scene(seed)).unwrap();
    let truth: Vec<f64> = (0..sim.frames())
        .map(|k| sim.strip_row_of_top(sim.frame(k).actual_offset_mm))
        .collect();
    let truth: Vec<f64> = truth.iter().map(|t| t - truth[0]).collect();
    let drift = if case.wander > 0.0 { 3 } else { 0 };
    let (placed, doubts) = place(&sim, drift);
    assert!(doubts.is_empty(), "{name}: {doubts:?}");
    let travel = truth[truth.len() - 1];
    let matched = |p: &Placement| matches!(p.source, Source::Matched | Source::First);
    let worst_step = placed
        .windows(2)
        .filter(|p| matched(&p[0]) && matched(&p[1]))
        .map(|p| {
            let (a, b) = (p[0].frame, p[1].frame);
            ((p[1].row - p[0].row) - (truth[b] - truth[a])).abs()
        })
        .fold(0f64, f64::max);
    let worst = placed
        .iter()
        .map(|p| (p.row - truth[p.frame]).abs())
        .fold(0f64, f64::max);
    let count = |s: Source| placed.iter().filter(|p| p.source == s).count();
    eprintln!(
        "{name}: worst matched step error {worst_step:.2} px, worst position error {worst:.1} px \
         of {travel:.0} ({:.2} %); {} matched, {} predicted, {} unmatched",
        100.0 * worst / travel,
        count(Source::Matched),
        count(Source::Predicted),
        count(Source::Unmatched)
    );
    assert!(
        worst_step <= step_px,
        "{name}: a step {worst_step:.2} px off"
    );
    assert!(
        worst <= WORST_DRIFT * travel,
        "{name}: {worst:.1} px off over {travel:.0} px of travel"
    );
    // The texture-free stretch was there, and so were the features.
    assert!(count(Source::Predicted) >= case.frames / 10, "{name}");
    assert!(count(Source::Matched) >= case.frames / 2, "{name}");
    if case.wander > 0.0 {
        // Sideways: the frame's column 0 lies at the belt's sideways offset, within 3
        // columns on average over the matched frames.
        let moved = |k: usize| sim.frame(k).sideways_px - sim.frame(0).sideways_px;
        let matched: Vec<&Placement> = placed
            .iter()
            .filter(|p| p.source == Source::Matched)
            .collect();
        let off = matched
            .iter()
            .map(|p| (p.col as f64 - moved(p.frame)).abs())
            .sum::<f64>()
            / matched.len() as f64;
        eprintln!("{name}: {off:.2} columns off sideways on average");
        assert!(off <= 3.0, "{name}: {off:.2} columns off sideways");
    }
    worst / travel
}

/// Every roll of `case` passes its checks, and the median of their position errors is
/// within [`DRIFT`].
fn check(case: &Case) {
    let mut errors: Vec<f64> = SEEDS.iter().map(|&seed| one_roll(case, seed)).collect();
    errors.sort_by(f64::total_cmp);
    let median = errors[errors.len() / 2];
    eprintln!(
        "{}: median position error {:.2} %",
        case.name,
        100.0 * median
    );
    assert!(
        median <= DRIFT,
        "{}: the median roll is {:.2} % of its travel off",
        case.name,
        100.0 * median
    );
}

/// Features touching the gel only within about ±50 rows of the apex, the belt itself
/// within ±30: the fixture's regime. Here the simulator's gel, smoothing a feature where
/// the gel lifts from it, makes a match of a feature cut off at the band's edge 1–3 %
/// short; without a motion record nothing tells that from the belt's own speed, so a roll
/// drifts by 1–2 % of its travel (docs/fusion.md).
const NARROW: Case = Case {
    name: "narrow contact band",
    radius: 9.0,
    press: 0.37,
    height: 0.25,
    size: (320, 240),
    mm_per_px: 0.05,
    frames: 200,
    step_px: 7.0,
    wander: 0.0,
};

#[test]
fn a_narrow_contact_band_is_followed() {
    check(&NARROW);
}

const MIDDLING: Case = Case {
    name: "middling contact band",
    radius: 12.0,
    press: 0.5,
    height: 0.4,
    ..NARROW
};

#[test]
fn a_middling_contact_band_is_followed() {
    check(&MIDDLING);
}

/// On this roll frame 1 matches nothing and frame 2 matches frame 1: counting the step
/// from 0 to 1, which no match measured, once made the speed zero, and the speed's prior
/// then outweighed every right match for a hundred frames (44 % of the travel off).
#[test]
fn a_step_no_match_measured_does_not_set_the_speed() {
    assert!(one_roll(&MIDDLING, 4) <= DRIFT);
}

const WHOLE_FRAME: Case = Case {
    name: "contact over the whole frame",
    radius: 40.0,
    press: 1.0,
    height: 0.6,
    ..NARROW
};

#[test]
fn contact_over_the_whole_frame_is_followed() {
    check(&WHOLE_FRAME);
}

/// At 3 px a frame the last feature before a bare stretch, or at the roll's end, stays in
/// view for dozens of frames while it leaves the contact band, where matches weigh rows
/// least: its matches score lower and lower, under the gate. Counted as texture that kept
/// no match, it made a lost belt of 8 to 15 frames on every one of seven such rolls, all
/// placed within 1.4 %. Texture is measured as matches weigh rows.
#[test]
fn texture_only_where_matches_cannot_use_it_is_not_a_lost_belt() {
    let slow = Case {
        name: "whole frame, 3 px a frame",
        step_px: 3.0,
        ..WHOLE_FRAME
    };
    assert!(one_roll(&slow, 5) <= DRIFT);
}

#[test]
fn a_belt_wandering_sideways_is_followed_where_allowed() {
    check(&Case {
        name: "wandering sideways",
        wander: 0.5,
        ..NARROW
    });
}

const VGA: Case = Case {
    name: "640 × 480",
    size: (640, 480),
    mm_per_px: 0.025,
    frames: 120,
    ..NARROW
};

#[test]
fn frames_of_640_by_480_are_followed() {
    check(&VGA);
}

/// On this roll the first match, made over the whole reach before the roll's typical
/// score is known, is a feature entering the contact band (1.2 rows against about 5)
/// and scores 0.71 where later matches score 0.95: kept as it was, it set the search
/// for the frames after it (a step 3.7 px off, 5.8 % of the travel). It is judged again
/// once the typical score is known, and dropped.
#[test]
fn a_first_match_is_judged_again_once_the_roll_is_known() {
    assert!(one_roll(&VGA, 4) <= DRIFT);
}

/// At 12 px a frame a feature is in the narrow band for about 8 frames. On this roll
/// frame 161 matched no frame before it, so only the speed's prior (12 ± 2 px) and longer
/// matches across it joined it to frame 160; one of those, 6.5 px short, pulled the step
/// to itself (6.9 px placed, 13.4 true). A match over several frames is now judged
/// against the fit without it. The bound is looser than 3 px: the belt's own ±30 % is
/// ±3.6 px a frame here.
#[test]
fn a_long_match_alone_across_a_weak_step_is_judged_by_the_rest() {
    let fast = Case {
        name: "narrow contact band, 12 px a frame",
        step_px: 12.0,
        ..NARROW
    };
    assert!(one_roll_within(&fast, 1, 3.5) <= WORST_DRIFT);
}

/// At 3 px a frame on 640 × 480 frames (the whole travel, 360 rows, shorter than a frame)
/// this roll's first frames match at almost no shift (scores 0.50–0.58, where its later
/// matches score 0.9), and the speed they leave places the texture-free stretch at 1.35
/// rows a frame where the belt ran 2.9: 31 % of the travel off. Not yet placed right; the
/// placement says it cannot be trusted.
#[test]
fn a_stretch_placed_at_a_speed_the_belt_did_not_have_is_a_doubt() {
    let slow = Case {
        name: "640 × 480, 3 px a frame",
        step_px: 3.0,
        ..VGA
    };
    let sim = Simulator::new(&slow.scene(3)).unwrap();
    let (_, doubts) = place(&sim, 0);
    assert!(
        doubts.iter().any(|d| d.contains("rests on a wrong speed")),
        "{doubts:?}"
    );
}
