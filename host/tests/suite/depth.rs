//! Depth on a synthetic ball rendered with known lights (the Lambertian model, no noise):
//! the recovered height matches the true cap, calibration recovers the lights, and bad
//! input is refused clearly.

use rollfuse::depth::calibrate::{Circle, calibrate};
use rollfuse::depth::lights::Lights;
use rollfuse::depth::reconstruct;
use rollfuse::depth::synthetic::ball;
use rollfuse::image::Planes;

const K: f64 = 0.02; // mm per pixel
const R: f64 = 2.0; // ball radius, mm
const PRESS: f64 = 0.4; // cap height, mm
const FLAT: f64 = 180.0; // background level

fn product_lights() -> Lights {
    Lights::product(K)
}

/// The cap's true height (mm) and an RGB image of it, `w × h`, centred at `(cx, cy)`.
fn render(w: usize, h: usize, centre: (f64, f64), lights: &Lights) -> (Vec<f64>, Planes) {
    ball((w, h), centre, R, PRESS, lights, FLAT)
}

fn flat_background(w: usize, h: usize) -> Planes {
    Planes {
        width: w,
        height: h,
        planes: vec![vec![FLAT as f32; w * h]; 3],
    }
}

#[test]
fn a_ball_is_recovered_within_three_percent_of_its_height() {
    let (w, h) = (201, 163);
    let lights = product_lights();
    let (truth, image) = render(w, h, (95.0, 80.0), &lights);
    for background in [Some(flat_background(w, h)), None] {
        let depth = reconstruct(&image, background.as_ref(), &lights).unwrap();
        let rms = (truth
            .iter()
            .zip(&depth.height_mm)
            .map(|(t, &d)| (t - f64::from(d)).powi(2))
            .sum::<f64>()
            / truth.len() as f64)
            .sqrt();
        let peak = depth.height_mm.iter().copied().fold(f32::MIN, f32::max);
        println!(
            "background {}: RMS error {rms:.4} mm ({:.2} % of the cap), peak {peak:.3} of {PRESS}",
            if background.is_some() {
                "given"
            } else {
                "estimated"
            },
            100.0 * rms / PRESS
        );
        assert!(rms <= 0.03 * PRESS, "RMS {rms} mm");
    }
}

fn angle_deg(a: [f64; 3], b: [f64; 3]) -> f64 {
    let dot: f64 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
    dot.clamp(-1.0, 1.0).acos().to_degrees()
}

#[test]
fn calibration_recovers_the_lights_within_two_degrees() {
    let (w, h) = (220, 180);
    // Lights other than the defaults, to show they are found, not assumed.
    let norm = |v: [f64; 3]| {
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        [v[0] / n, v[1] / n, v[2] / n]
    };
    let truth = Lights {
        red: norm([0.2, 0.8, 0.6]),
        green: norm([-0.75, -0.3, 0.55]),
        blue: norm([0.65, -0.5, 0.7]),
        ..product_lights()
    };
    let (_, image) = render(w, h, (100.0, 95.0), &truth);
    for background in [Some(flat_background(w, h)), None] {
        for circle in [
            None,
            Some(Circle {
                x: 100.0,
                y: 95.0,
                r: 60.0,
            }),
        ] {
            let (got, disc) = calibrate(&image, background.as_ref(), R, K, circle).unwrap();
            for (name, a, b) in [
                ("red", got.red, truth.red),
                ("green", got.green, truth.green),
                ("blue", got.blue, truth.blue),
            ] {
                let err = angle_deg(a, b);
                assert!(err < 2.0, "{name}: {err:.2}° off (disc {disc:?})");
            }
            for g in got.gains {
                assert!((g - 1.0).abs() < 0.05, "gain {g}");
            }
        }
    }
}

#[test]
fn bad_input_is_refused_clearly() {
    let (w, h) = (80, 60);
    let lights = product_lights();
    let (_, image) = render(w, h, (40.0, 30.0), &lights);
    let gray = Planes {
        width: w,
        height: h,
        planes: vec![image.planes[0].clone()],
    };
    // Each is the input's fault, and says why.
    let msg = |r: Result<rollfuse::depth::DepthMap, rollfuse::depth::Error>| {
        let e = r.unwrap_err();
        assert!(matches!(e, rollfuse::depth::Error::Invalid(_)), "{e:?}");
        e.to_string()
    };
    assert!(msg(reconstruct(&gray, None, &lights)).contains("RGB"));
    let small_bg = flat_background(w - 1, h);
    assert!(msg(reconstruct(&image, Some(&small_bg), &lights)).contains("must match"));
    let collinear = Lights {
        green: lights.red,
        ..lights
    };
    assert!(msg(reconstruct(&image, None, &collinear)).contains("condition number"));
    let dark = Planes {
        width: w,
        height: h,
        planes: vec![vec![0.0; w * h]; 3],
    };
    assert!(msg(reconstruct(&dark, None, &lights)).contains("dark"));
    assert!(
        msg(reconstruct(&dark, Some(&flat_background(w, h)), &lights)).contains("usable normal")
    );
}
