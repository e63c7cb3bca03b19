//! One `--out` rule for every command (README, "Outputs"): a file for a single output, a
//! stem for `depth`'s set of one map, a folder for many files; missing parent folders are
//! made, and made folders go again when the command fails before writing into them.

use crate::common::rollfuse;
use rollfuse::depth::lights::Lights;
use rollfuse::depth::synthetic::ball;
use std::path::Path;

fn ok(args: &[&str]) {
    let run = rollfuse(args);
    assert!(
        run.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&run.stderr)
    );
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn every_command_writes_under_folders_it_makes() {
    let tmp = tempfile::tempdir().unwrap();
    let new = |name: &str| tmp.path().join("new").join(name).join("out");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/dots.toml");
    // Folders: simulate, eval, stream, detect --draw (tradeoff and demo, slower, make theirs
    // with the same helpers; train its file as fit-normal does).
    let frames = new("simulate");
    ok(&["simulate", scene, "--frames", "6", "--out", s(&frames)]);
    assert!(frames.join("frame_0005.png").is_file());
    ok(&["eval", "--depth", "--out", s(&new("eval"))]);
    assert!(new("eval").join("depth.md").is_file());
    let stream = new("stream");
    let letters = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/letters.toml");
    ok(&[
        "stream",
        "--device",
        "sim",
        "--scene",
        letters,
        "--out",
        s(&stream),
    ]);
    assert!(stream.join("manifest.json").is_file());
    // Files: fuse (roll and mosaic), splice, detect --json, fit-normal, calibrate.
    let strip = new("fuse").join("strip.png");
    ok(&["fuse", s(&frames), "--out", s(&strip), "--mode", "roll"]);
    assert!(strip.is_file() && strip.with_extension("json").is_file());
    let f: Vec<String> = (0..4)
        .map(|k| s(&frames.join(format!("frame_{k:04}.png"))).to_string())
        .collect();
    let f: Vec<&str> = f.iter().map(String::as_str).collect();
    let mosaic = new("mosaic").join("m.png");
    ok(&[
        &["fuse"],
        &f[..],
        &["--out", s(&mosaic), "--mode", "mosaic"],
    ]
    .concat());
    assert!(mosaic.is_file());
    let spliced = new("splice").join("s.png");
    ok(&[&["splice"], &f[..], &["--out", s(&spliced)]].concat());
    assert!(spliced.is_file());
    let json = new("detect").join("d.json");
    let drawn = new("draw");
    ok(&["detect", f[0], "--json", s(&json), "--draw", s(&drawn)]);
    assert!(json.is_file() && drawn.is_dir());
    let normal = new("normal").join("n.json");
    ok(&[&["fit-normal"], &f[..], &["--out", s(&normal)]].concat());
    assert!(normal.is_file());
    // A stem: depth writes STEM.npy and STEM.png (an extension of its own is dropped).
    let l = Lights::product(0.02);
    let lights = tmp.path().join("lights.toml");
    l.save(&lights).unwrap();
    let (_, img) = ball((120, 100), (60.0, 50.0), 1.0, 0.3, &l, 180.0);
    let ball_png = tmp.path().join("ball.png");
    img.save_png(&ball_png).unwrap();
    let stem = new("depth").join("d.png");
    ok(&[
        "depth",
        s(&ball_png),
        "--lights",
        s(&lights),
        "--out",
        s(&stem),
    ]);
    assert!(stem.with_extension("npy").is_file() && stem.is_file());
    assert!(!stem.with_extension("png.npy").exists());
    let fitted = new("calibrate").join("l.toml");
    let calibrate = [
        "calibrate",
        s(&ball_png),
        "--radius-mm",
        "1",
        "--mm-per-px",
        "0.02",
        "--out",
        s(&fitted),
    ];
    ok(&calibrate);
    assert!(fitted.is_file());
}

#[test]
fn a_failed_command_leaves_no_folder_it_made() {
    let tmp = tempfile::tempdir().unwrap();
    let made = tmp.path().join("made");
    let missing = tmp.path().join("missing.png");
    let run = rollfuse(&[
        "fuse",
        s(&missing),
        s(&missing),
        "--out",
        s(&made.join("deeper/strip.png")),
    ]);
    assert!(!run.status.success());
    assert!(!made.exists(), "an empty folder was left behind");
    // Under a file no folder can be made: said before any work.
    let file = tmp.path().join("file");
    std::fs::write(&file, "x").unwrap();
    let run = rollfuse(&["eval", "--depth", "--out", s(&file.join("eval"))]);
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success() && err.contains("file"), "{err}");
}
