//! Inputs whose sizes come from outside are checked against the pixel limit before
//! anything is allocated: an image's header, a manifest's offsets.

use crate::common::rollfuse;
use std::path::Path;

/// A PNG whose header says `w × h` gray pixels, with an empty compressed stream for its
/// pixel data.
fn png_header(path: &Path, w: u32, h: u32) {
    let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);
    let chunk = |kind: &[u8], data: &[u8]| {
        let mut c = (data.len() as u32).to_be_bytes().to_vec();
        let body = [kind, data].concat();
        c.extend_from_slice(&body);
        c.extend_from_slice(&crc.checksum(&body).to_be_bytes());
        c
    };
    let ihdr = [&w.to_be_bytes()[..], &h.to_be_bytes(), &[8, 0, 0, 0, 0]].concat();
    let bytes = [
        &b"\x89PNG\r\n\x1a\n"[..],
        &chunk(b"IHDR", &ihdr),
        &chunk(b"IDAT", &[0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01]),
        &chunk(b"IEND", &[]),
    ]
    .concat();
    std::fs::write(path, bytes).unwrap();
}

/// `n` frames of the letters scene simulated into `dir/sim`: the folder and the frames'
/// paths.
fn letters_frames(dir: &Path, n: usize) -> (std::path::PathBuf, Vec<String>) {
    let sim = dir.join("sim");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/letters.toml");
    let frames = n.to_string();
    let made = rollfuse(&[
        "simulate",
        scene,
        "--out",
        sim.to_str().unwrap(),
        "--frames",
        &frames,
    ]);
    assert!(made.status.success());
    let paths = (0..n)
        .map(|k| {
            sim.join(format!("frame_{k:04}.png"))
                .to_str()
                .unwrap()
                .to_string()
        })
        .collect();
    (sim, paths)
}

fn fails_saying(args: &[&str], says: &str) {
    let run = rollfuse(args);
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success(), "{args:?} succeeded");
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.contains(says), "{args:?}: {err}");
}

#[test]
fn an_image_over_the_pixel_limit_is_refused_from_its_header() {
    let tmp = tempfile::tempdir().unwrap();
    let big = tmp.path().join("big.png");
    png_header(&big, 16_000, 16_000);
    let f = big.to_str().unwrap();
    fails_saying(
        &["metrics", f, "--reference", f],
        "16000×16000 = 256000000 pixels, over the limit of 33554432 (--max-pixels)",
    );
    let out = tmp.path().join("o.png");
    fails_saying(
        &["fuse", f, f, "--out", out.to_str().unwrap()],
        "over the limit",
    );
    // Under a raised limit the header passes and the missing pixels are the error.
    fails_saying(
        &["--max-pixels", "300000000", "metrics", f, "--reference", f],
        "cannot read image",
    );
}

#[test]
fn a_manifest_offset_far_off_is_refused_before_the_canvas_is_allocated() {
    let tmp = tempfile::tempdir().unwrap();
    let (sim, frames) = letters_frames(tmp.path(), 4);
    // A typo in one frame's strip row: 300 000 rows instead of 150 (a 96 Mpx canvas).
    let manifest = sim.join("manifest.json");
    let mut doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&manifest).unwrap()).unwrap();
    doc["frames"][2]["strip_row"] = serde_json::json!(3e5);
    std::fs::write(&manifest, doc.to_string()).unwrap();
    let out = tmp.path().join("spliced.png");
    let args: Vec<&str> = ["splice"]
        .into_iter()
        .chain(frames.iter().map(String::as_str))
        .chain(["--out", out.to_str().unwrap()])
        .collect();
    fails_saying(&args, "larger than the limit");
    assert!(!out.exists());
    // A strip row that is not a number is said to be one, not missing.
    doc["frames"][2]["strip_row"] = serde_json::json!("NaN");
    std::fs::write(&manifest, doc.to_string()).unwrap();
    fails_saying(&args, "invalid type: string \"NaN\", expected f64");
    doc["frames"][2]
        .as_object_mut()
        .unwrap()
        .remove("strip_row");
    std::fs::write(&manifest, doc.to_string()).unwrap();
    fails_saying(&args, "missing field `strip_row`");
}

/// `letters.toml` with `edit` applied, written into `dir`.
fn letters_with(dir: &Path, edit: impl FnOnce(&mut toml::Table)) -> String {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/letters.toml"))
        .unwrap();
    let mut scene: toml::Table = text.parse().unwrap();
    edit(&mut scene);
    let path = dir.join("scene.toml");
    std::fs::write(&path, toml::to_string(&scene).unwrap()).unwrap();
    path.to_str().unwrap().to_string()
}

#[test]
fn scene_values_that_would_overflow_are_refused_and_a_scene_without_contact_is_said() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("sim");
    let o = out.to_str().unwrap();
    let huge = letters_with(tmp.path(), |s| {
        s["object"]["height_mm"] = toml::Value::Float(1e300);
    });
    fails_saying(
        &["simulate", &huge, "--out", o, "--frames", "2"],
        "object.height_mm must be a positive number of at most 1e6, got 1e300",
    );
    assert!(!out.exists(), "a refused scene made its output folder");
    let too_deep = letters_with(tmp.path(), |s| {
        s["sensor"]["press_depth_mm"] = toml::Value::Float(2.0);
    });
    let run = rollfuse(&["simulate", &too_deep, "--out", o, "--frames", "2"]);
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{err}");
    assert!(
        err.contains("warning: sensor.press_depth_mm (2) is deeper than the gel"),
        "{err}"
    );
}

#[test]
fn an_image_output_of_no_known_format_is_refused_before_any_work_and_touches_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let (_, frames) = letters_frames(tmp.path(), 3);
    for command in ["fuse", "splice"] {
        let out = tmp.path().join("precious.tiff");
        std::fs::write(&out, b"precious").unwrap();
        let args: Vec<&str> = [command]
            .into_iter()
            .chain(frames.iter().map(String::as_str))
            .chain(["--out", out.to_str().unwrap()])
            .collect();
        fails_saying(&args, "images are written as .png or .npy files");
        assert_eq!(std::fs::read(&out).unwrap(), b"precious");
        assert!(!tmp.path().join("precious.offsets.json").exists());
    }
}

#[test]
fn frames_held_at_once_share_the_pixel_limit_and_a_roll_holds_a_few() {
    let tmp = tempfile::tempdir().unwrap();
    let (_, frames) = letters_frames(tmp.path(), 8);
    let out = tmp.path().join("o.png");
    // 8 frames of 320 × 240 are 614 400 pixels; each alone is 76 800.
    let with = |rest: &[&'static str]| -> Vec<String> {
        ["--max-pixels", "200000", "fuse"]
            .into_iter()
            .map(String::from)
            .chain(frames.iter().cloned())
            .chain(["--out".to_string(), out.to_str().unwrap().to_string()])
            .chain(rest.iter().map(|s| s.to_string()))
            .collect()
    };
    let mosaic = with(&["--mode", "mosaic"]);
    let mosaic: Vec<&str> = mosaic.iter().map(String::as_str).collect();
    fails_saying(&mosaic, "over the limit of 200000 held at once");
    let roll = with(&["--mode", "roll"]);
    let roll: Vec<&str> = roll.iter().map(String::as_str).collect();
    let run = rollfuse(&roll);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
}
