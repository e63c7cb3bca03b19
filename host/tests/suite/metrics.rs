//! IE and MS-SSIM against independent implementations (scikit-image's shannon_entropy and
//! a numpy transcription of Wang 2003), on the vectors of `tests/vectors/gen_metrics.py`.

use rollfuse::eval::metrics::{
    Gray, entropy, ms_ssim, ms_ssim_scales, population_std, strip_ranges,
};
use rollfuse::image::{PixelLimit, Planes};
use serde_json::Value;
use std::path::Path;

fn load(name: &str) -> Planes {
    Planes::load(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/vectors/metrics")
            .join(name),
        PixelLimit::default(),
    )
    .unwrap()
}

fn gray(p: &Planes) -> Gray {
    Gray::new(
        p.width,
        p.height,
        p.planes[0].iter().map(|&v| v as f64).collect(),
    )
    .unwrap()
}

#[test]
fn entropy_and_ms_ssim_match_the_references() {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/vectors/metrics/metrics.json"),
    )
    .unwrap();
    let doc: Value = serde_json::from_str(&text).unwrap();
    let cases = doc["cases"].as_array().unwrap();
    assert!(cases.len() >= 6);
    for case in cases {
        let name = case["image"].as_str().unwrap();
        let (img, reference) = (load(name), load(case["reference"].as_str().unwrap()));
        let ie = entropy(&img.to_u8());
        let want_ie = case["ie"].as_f64().unwrap();
        assert!((ie - want_ie).abs() <= 1e-4, "{name}: IE {ie} vs {want_ie}");
        let m = ms_ssim(&gray(&img), &gray(&reference)).unwrap();
        let want = case["ms_ssim"].as_f64().unwrap();
        assert!((m - want).abs() <= 1e-4, "{name}: MS-SSIM {m} vs {want}");
    }
}

#[test]
fn ms_ssim_of_an_image_with_itself_is_one_and_sizes_must_match() {
    let img = load("noisy_180x176.png");
    let g = gray(&img);
    assert!((ms_ssim(&g, &g).unwrap() - 1.0).abs() < 1e-12);
    let small = Gray::new(10, 10, vec![1.0; 100]).unwrap();
    assert!(ms_ssim(&small, &small).is_err(), "below one 11×11 window");
    assert!(ms_ssim(&g, &gray(&load("noisy_64x48.png"))).is_err());
    assert_eq!(ms_ssim_scales(161, 161), 5);
    assert_eq!(ms_ssim_scales(160, 400), 4);
    assert_eq!(ms_ssim_scales(11, 11), 1);
}

#[test]
fn entropy_extremes_and_regional_std() {
    assert_eq!(entropy(&[7; 100]), 0.0);
    // +0, not −0 (which prints as `-0.0000`).
    assert!(entropy(&[7; 100]).is_sign_positive());
    let all: Vec<u8> = (0..=255).collect();
    assert!((entropy(&all) - 8.0).abs() < 1e-12);
    assert_eq!(
        population_std(&[2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0]),
        2.0
    );
    let cols = strip_ranges(103, 10);
    assert_eq!(cols.len(), 10);
    assert_eq!(cols[0].start, 0);
    assert_eq!(cols[9].end, 103);
    assert!(cols.windows(2).all(|p| p[0].end == p[1].start));
}
