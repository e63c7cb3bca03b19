//! `rollfuse depth` and `rollfuse calibrate` from the command line: the outputs, and one
//! clear line with a non-zero exit for each kind of bad input.

use rollfuse::depth::lights::Lights;
use rollfuse::depth::synthetic::ball;
use std::path::Path;

use crate::common::{fails, rollfuse};

fn lights() -> Lights {
    Lights::product(0.02)
}

/// A folder with `lights.toml` and `ball.png`, a 240×200 image of a 2 mm ball pressed
/// 0.4 mm under those lights.
fn ball_and_lights() -> (tempfile::TempDir, Lights) {
    let tmp = tempfile::tempdir().unwrap();
    let l = lights();
    l.save(&tmp.path().join("lights.toml")).unwrap();
    let (_, img) = ball((240, 200), (120.0, 100.0), 2.0, 0.4, &l, 180.0);
    img.save_png(&tmp.path().join("ball.png")).unwrap();
    (tmp, l)
}

#[test]
fn depth_and_calibrate_write_their_outputs() {
    let (tmp, l) = ball_and_lights();
    let p = |f: &str| tmp.path().join(f).to_str().unwrap().to_string();
    let run = rollfuse(&[
        "depth",
        &p("ball.png"),
        "--lights",
        &p("lights.toml"),
        "--out",
        &p("d"),
        "--ply",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let npy = std::fs::read(p("d.npy")).unwrap();
    assert_eq!(&npy[..6], b"\x93NUMPY");
    assert_eq!(npy.len(), 128 + 240 * 200 * 4);
    let png = image::open(p("d.png")).unwrap();
    assert!(
        png.width() > 240 && png.height() >= 200,
        "picture and scale bar"
    );
    let ply = std::fs::read(p("d.ply")).unwrap();
    assert!(ply.starts_with(b"ply\nformat binary_little_endian 1.0"));

    let run = rollfuse(&[
        "calibrate",
        &p("ball.png"),
        "--radius-mm",
        "2",
        "--mm-per-px",
        "0.02",
        "--out",
        &p("fitted.toml"),
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let fitted = Lights::load(Path::new(&p("fitted.toml"))).unwrap();
    let dot: f64 = fitted.red.iter().zip(l.red).map(|(a, b)| a * b).sum();
    assert!(dot.acos().to_degrees() < 2.0);
}

#[test]
fn bad_input_gets_one_clear_line() {
    let (tmp, l) = ball_and_lights();
    let p = |f: &str| tmp.path().join(f).to_str().unwrap().to_string();
    image::GrayImage::new(240, 200).save(p("gray.png")).unwrap();
    image::RgbImage::new(240, 200).save(p("dark.png")).unwrap();
    image::RgbImage::from_pixel(230, 200, image::Rgb([180, 180, 180]))
        .save(p("small_bg.png"))
        .unwrap();
    let collinear = Lights { green: l.red, ..l };
    std::fs::write(p("collinear.toml"), toml::to_string(&collinear).unwrap()).unwrap();
    let depth = |image: &str, lights: &str, extra: &[&str]| {
        let mut a = vec![
            "depth".to_string(),
            p(image),
            "--lights".into(),
            p(lights),
            "--out".into(),
            p("o"),
        ];
        a.extend(extra.iter().map(|s| s.to_string()));
        a
    };
    let run =
        |a: Vec<String>, says: &str| fails(&a.iter().map(String::as_str).collect::<Vec<_>>(), says);
    run(depth("gray.png", "lights.toml", &[]), "RGB");
    run(depth("ball.png", "collinear.toml", &[]), "condition number");
    run(
        depth(
            "ball.png",
            "lights.toml",
            &["--background", &p("small_bg.png")],
        ),
        "must match",
    );
    run(depth("dark.png", "lights.toml", &[]), "dark");
    run(depth("missing.png", "lights.toml", &[]), "missing.png");
    run(depth("ball.png", "nope.toml", &[]), "nope.toml");
    fails(
        &[
            "calibrate",
            &p("gray.png"),
            "--radius-mm",
            "2",
            "--mm-per-px",
            "0.02",
            "--out",
            &p("x.toml"),
        ],
        "RGB",
    );
    fails(
        &[
            "calibrate",
            &p("ball.png"),
            "--radius-mm",
            "0.5",
            "--mm-per-px",
            "0.02",
            "--out",
            &p("x.toml"),
        ],
        "wider than the ball",
    );
    // A ball far too large for its disc (1e300 once overflowed and blamed a light).
    fails(
        &[
            "calibrate",
            &p("ball.png"),
            "--radius-mm",
            "1e300",
            "--mm-per-px",
            "0.02",
            "--out",
            &p("x.toml"),
        ],
        "is too large for its contact disc",
    );
    fails(
        &[
            "calibrate",
            &p("ball.png"),
            "--radius-mm",
            "2",
            "--mm-per-px",
            "0.02",
            "--circle",
            "1,2,-3",
            "--out",
            &p("x.toml"),
        ],
        "--circle",
    );
    assert!(
        !tmp.path().join("o.npy").exists(),
        "nothing written by failed runs"
    );
}
