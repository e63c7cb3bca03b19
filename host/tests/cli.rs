//! The `rollfuse` command line: help, version, unknown commands, and each command's basics.

use std::process::Command;

fn rollfuse(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_rollfuse"))
        .args(args)
        .output()
        .expect("run rollfuse")
}

#[test]
fn help_lists_the_demo() {
    let out = rollfuse(&["--help"]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("demo"), "{text}");
}

#[test]
fn demo_refuses_a_missing_scene_before_any_work() {
    let out = tempfile::tempdir().unwrap();
    let dir = out.path().join("demo");
    let run = rollfuse(&[
        "demo",
        "--out",
        dir.to_str().unwrap(),
        "--letters",
        "/nonexistent/letters.toml",
    ]);
    assert!(!run.status.success());
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(err.contains("/nonexistent/letters.toml"), "{err}");
    assert!(!dir.join("report.html").exists());
}

#[test]
fn unknown_subcommand_fails_with_a_message() {
    let out = rollfuse(&["frobnicate"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("frobnicate"));
}

#[test]
fn simulate_writes_frames_truth_and_manifest() {
    let out = tempfile::tempdir().unwrap();
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/dots.toml");
    let dir = out.path().join("dots");
    let run = rollfuse(&[
        "simulate",
        scene,
        "--out",
        dir.to_str().unwrap(),
        "--frames",
        "3",
        "--seed",
        "9",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    for f in [
        "frame_0000.png",
        "frame_0002.png",
        "manifest.json",
        "contact_sheet.png",
        "truth/height.npy",
        "truth/height.png",
        "truth/ideal.png",
    ] {
        assert!(dir.join(f).is_file(), "{f} missing");
    }
    assert!(!dir.join("frame_0003.png").exists());
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(manifest["seed"], 9);
    assert_eq!(manifest["frames"].as_array().unwrap().len(), 3);
}

#[test]
fn simulate_refuses_missing_and_bad_scenes_in_one_line() {
    let out = tempfile::tempdir().unwrap();
    let o = out.path().to_str().unwrap();
    let missing = rollfuse(&["simulate", "/no/such/scene.toml", "--out", o]);
    assert!(!missing.status.success());
    let msg = String::from_utf8_lossy(&missing.stderr);
    assert!(msg.contains("cannot read scene file"), "{msg}");

    let bad = out.path().join("bad.toml");
    let text =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/dots.toml")).unwrap();
    std::fs::write(
        &bad,
        text.replace("roller_radius_mm = 12.0", "roller_radius_mm = -1.0"),
    )
    .unwrap();
    let run = rollfuse(&["simulate", bad.to_str().unwrap(), "--out", o]);
    assert!(!run.status.success());
    let msg = String::from_utf8_lossy(&run.stderr);
    assert!(msg.contains("sensor.roller_radius_mm"), "{msg}");
    assert!(!msg.contains("panicked"), "{msg}");

    let zero = rollfuse(&[
        "simulate",
        concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/dots.toml"),
        "--out",
        o,
        "--frames",
        "0",
    ]);
    assert!(!zero.status.success());
    assert!(String::from_utf8_lossy(&zero.stderr).contains("sensor.frames"));
}
