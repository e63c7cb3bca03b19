//! A roll rendered outside the project (`tests/fixtures/roll-narrow-contact`: a narrow
//! contact band, ±25 % speed, a texture-free stretch, no manifest) fused from its frames
//! alone with the default options, and judged as the fixture's README says: every feature
//! that passed under the apex in the strip, in order, matching the ideal belt.

use crate::common::strip_score;

use rollfuse::image::{PixelLimit, Planes};
use std::path::Path;
use std::process::Command;

fn fixture() -> &'static Path {
    Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/fixtures/roll-narrow-contact"
    ))
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn the_fixture_roll_is_placed_from_its_frames_alone() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("strip.png");
    let run = Command::new(env!("CARGO_BIN_EXE_rollfuse"))
        .args(["fuse", fixture().to_str().unwrap(), "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&run.stderr)
    );
    // The window is measured, not the middle half.
    assert!(
        stdout.contains("measured on the first 32 frames"),
        "{stdout}"
    );
    let index = json(&dir.path().join("strip.json"));
    assert_eq!(index["details"]["trusted"], true, "{index}");

    let truth = json(&fixture().join("truth.json"));
    let offsets: Vec<f64> = truth["offsets"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let glyphs: Vec<strip_score::Glyph> =
        serde_json::from_value(json(&fixture().join("glyphs.json"))).unwrap();
    let strip = Planes::load(&out, PixelLimit::default()).unwrap();
    let ideal = Planes::load(&fixture().join("ideal.png"), PixelLimit::default()).unwrap();
    let apex = 120.0;
    let verdict = strip_score::judge(
        &strip,
        &ideal,
        &glyphs,
        (offsets[0] + apex, offsets[offsets.len() - 1] + apex),
    );
    eprintln!("{verdict:#?}");
    assert_eq!(verdict.features.len(), 11, "features under the apex");
    assert!(
        verdict.features.iter().all(|f| f.at.is_some()),
        "every feature in the strip, in order: {verdict:?}"
    );
    let (median, least) = verdict.scores();
    assert!(
        median >= 0.9 && least >= 0.8,
        "correlation median {median:.3}, least {least:.3}"
    );
    assert!(
        verdict.features.iter().all(|f| f.contrast >= 0.6),
        "contrast {verdict:?}"
    );
    assert!(
        (verdict.scale - 1.0).abs() <= 0.02,
        "scale {:.4}",
        verdict.scale
    );
}
