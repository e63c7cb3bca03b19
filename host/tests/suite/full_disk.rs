//! Every command on a disk that fills up: with `ROLLFUSE_FAIL_WRITES_AFTER=N` the
//! process's outputs fail once N bytes are written in all, as a disk filling up midway
//! would. Each command is run once to have outputs,
//! then again on the "full" disk: it must fail with a non-zero exit and one clear line, and
//! leave every file as the good run left it — nothing half-written, nothing destroyed, no
//! temporary behind. And outputs that would overwrite an input are refused.

use rollfuse::depth::lights::Lights;
use rollfuse::depth::synthetic::ball;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn rollfuse(args: &[&str], fail_after: Option<u64>) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_rollfuse"));
    cmd.args(args);
    if let Some(n) = fail_after {
        cmd.env(rollfuse::files::FAIL_WRITES_AFTER, n.to_string());
    }
    cmd.output().unwrap()
}

/// Every file below `dir`, with its bytes.
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut files = BTreeMap::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                todo.push(path);
            } else {
                files.insert(path.clone(), std::fs::read(&path).unwrap());
            }
        }
    }
    files
}

/// Runs `args` well, then `again` (the same outputs with other content, so a partial
/// update would show) on a disk that fills at once, after 100 bytes, and halfway through
/// what the good run wrote: each fails and changes nothing.
fn survives_a_full_disk(dir: &Path, args: &[&str], again: &[&str]) {
    let inputs = snapshot(dir);
    let good = rollfuse(args, None);
    assert!(
        good.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&good.stderr)
    );
    let before = snapshot(dir);
    // What the good run wrote (new or changed files).
    let written: u64 = before
        .iter()
        .filter(|(p, b)| inputs.get(*p) != Some(*b))
        .map(|(_, b)| b.len() as u64)
        .sum();
    for fail_after in [0, 100, written / 2] {
        let run = rollfuse(again, Some(fail_after));
        let err = String::from_utf8_lossy(&run.stderr);
        assert!(!run.status.success(), "{again:?} succeeded on a full disk");
        assert!(!err.contains("panicked"), "{again:?}: {err}");
        assert!(
            err.contains("no space left"),
            "{again:?}: the error does not say why: {err}"
        );
        assert!(
            err.contains("cannot write "),
            "{again:?}: the error does not say what it was writing: {err}"
        );
        let after = snapshot(dir);
        let changed: Vec<_> = after
            .keys()
            .chain(before.keys())
            .filter(|p| before.get(*p) != after.get(*p))
            .collect();
        assert!(
            changed.is_empty(),
            "{again:?} with {fail_after} bytes of room changed {changed:?}"
        );
    }
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn simulate_fuse_and_splice_leave_their_outputs_whole_on_a_full_disk() {
    let tmp = tempfile::tempdir().unwrap();
    let sim = tmp.path().join("sim");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/letters.toml");
    let simulate = ["simulate", scene, "--out", s(&sim), "--frames", "8"];
    survives_a_full_disk(
        tmp.path(),
        &simulate,
        &[&simulate[..], &["--seed", "99"]].concat(),
    );
    let frames: Vec<String> = (0..8)
        .map(|k| s(&sim.join(format!("frame_{k:04}.png"))).to_string())
        .collect();
    let frames: Vec<&str> = frames.iter().map(String::as_str).collect();
    for (command, out) in [("fuse", "strip.png"), ("splice", "spliced.png")] {
        let out = tmp.path().join(out);
        let out = ["--out", s(&out)];
        survives_a_full_disk(
            tmp.path(),
            &[&[command], &frames[..], &out].concat(),
            &[&[command], &frames[1..7], &out].concat(),
        );
    }
    // A roll cut into segments, then another of other bits over it: the older strip's
    // segments and index stay whole until the new strip is.
    let roll = tmp.path().join("roll.png");
    let roll = ["--mode", "roll", "--segment-rows", "16", "--out", s(&roll)];
    survives_a_full_disk(
        tmp.path(),
        &[&["fuse"], &frames[..], &roll].concat(),
        &[&["fuse"], &frames[..], &roll, &["--out-bits", "16"]].concat(),
    );
}

#[test]
fn depth_calibrate_and_stream_leave_their_outputs_whole_on_a_full_disk() {
    let tmp = tempfile::tempdir().unwrap();
    let l = Lights::product(0.02);
    let lights = tmp.path().join("lights.toml");
    l.save(&lights).unwrap();
    let ball_png = |name: &str, press: f64| {
        let (_, img) = ball((120, 100), (60.0, 50.0), 1.0, press, &l, 180.0);
        let path = tmp.path().join(name);
        img.save_png(&path).unwrap();
        s(&path).to_string()
    };
    let (deep, shallow) = (ball_png("ball.png", 0.2), ball_png("other.png", 0.15));
    let d = tmp.path().join("d");
    let depth = |image: &str| -> Vec<String> {
        [
            "depth",
            image,
            "--lights",
            s(&lights),
            "--out",
            s(&d),
            "--ply",
        ]
        .map(String::from)
        .to_vec()
    };
    let (good, again) = (depth(&deep), depth(&shallow));
    survives_a_full_disk(tmp.path(), &strs(&good), &strs(&again));
    let cal = tmp.path().join("cal.toml");
    let calibrate = |radius: &str| -> Vec<String> {
        [
            "calibrate",
            &deep,
            "--radius-mm",
            radius,
            "--mm-per-px",
            "0.02",
            "--out",
            s(&cal),
        ]
        .map(String::from)
        .to_vec()
    };
    survives_a_full_disk(tmp.path(), &strs(&calibrate("1")), &strs(&calibrate("1.1")));
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/letters.toml");
    let (out, rec) = (tmp.path().join("live"), tmp.path().join("rec.bin"));
    let stream = |tiles: &str| -> Vec<String> {
        [
            "stream",
            "--device",
            "sim",
            "--scene",
            scene,
            "--out",
            s(&out),
            "--tiles",
            tiles,
            "--record",
            s(&rec),
        ]
        .map(String::from)
        .to_vec()
    };
    survives_a_full_disk(tmp.path(), &strs(&stream("6")), &strs(&stream("9")));
}

fn strs(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}

#[test]
fn outputs_that_are_inputs_are_refused_before_anything_is_written() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/letters.toml");
    let rec = tmp.path().join("rec.bin");
    let live = tmp.path().join("live");
    let made = rollfuse(
        &[
            "stream",
            "--device",
            "sim",
            "--scene",
            scene,
            "--out",
            s(&live),
            "--tiles",
            "4",
            "--record",
            s(&rec),
        ],
        None,
    );
    assert!(made.status.success());
    let recording = std::fs::read(&rec).unwrap();
    // The recording replayed into itself, reached through `..`.
    let twisted = tmp.path().join("live").join("..").join("rec.bin");
    let replay = format!("replay:{}", s(&rec));
    let again = tmp.path().join("again");
    let run = rollfuse(
        &[
            "stream",
            "--device",
            &replay,
            "--out",
            s(&again),
            "--record",
            s(&twisted),
        ],
        None,
    );
    assert!(!run.status.success());
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(err.contains("refusing to overwrite an input"), "{err}");
    assert_eq!(
        std::fs::read(&rec).unwrap(),
        recording,
        "the recording was touched"
    );
    assert!(
        !again.exists(),
        "the output folder was made before the refusal"
    );
    // `depth --out` whose stem names the background: its .png would be the background.
    let lights = tmp.path().join("lights.toml");
    rollfuse::depth::lights::Lights::product(0.02)
        .save(&lights)
        .unwrap();
    let rgb = rollfuse::image::Planes {
        width: 8,
        height: 8,
        planes: vec![vec![0.5; 64]; 3],
    };
    let (img, bg) = (tmp.path().join("img.png"), tmp.path().join("bg.png"));
    rgb.save_png(&img).unwrap();
    rgb.save_png(&bg).unwrap();
    let background = std::fs::read(&bg).unwrap();
    let stem = tmp.path().join("bg");
    let run = rollfuse(
        &[
            "depth",
            s(&img),
            "--lights",
            s(&lights),
            "--background",
            s(&bg),
            "--out",
            s(&stem),
        ],
        None,
    );
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(
        !run.status.success() && err.contains("is the background"),
        "{err}"
    );
    assert_eq!(std::fs::read(&bg).unwrap(), background);
    // `demo --out` holding its own scene: the folder is replaced whole.
    let mine = tmp.path().join("mine");
    std::fs::create_dir(&mine).unwrap();
    let letters = mine.join("letters.toml");
    std::fs::copy(scene, &letters).unwrap();
    let run = rollfuse(&["demo", "--out", s(&mine), "--letters", s(&letters)], None);
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(
        !run.status.success() && err.contains("refusing to remove an input"),
        "{err}"
    );
    assert!(letters.exists());
    // `calibrate --out` naming its own image.
    let image = tmp.path().join("img.png");
    let planes = rollfuse::image::Planes {
        width: 8,
        height: 8,
        planes: vec![vec![0.5; 64]; 3],
    };
    planes.save_png(&image).unwrap();
    let before = std::fs::read(&image).unwrap();
    let run = rollfuse(
        &[
            "calibrate",
            s(&image),
            "--radius-mm",
            "1",
            "--mm-per-px",
            "0.02",
            "--out",
            s(&image),
        ],
        None,
    );
    assert!(!run.status.success());
    assert_eq!(std::fs::read(&image).unwrap(), before);
    // `--seconds` too long for a duration is a clear refusal, not a panic.
    let run = rollfuse(
        &[
            "stream",
            "--device",
            "sim",
            "--scene",
            scene,
            "--out",
            s(&again),
            "--seconds",
            "1e300",
        ],
        None,
    );
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success() && !err.contains("panicked"), "{err}");
    assert!(err.contains("--seconds"), "{err}");
    session_outputs_and_simulations_refuse_their_inputs(tmp.path(), &rec, scene);
}

/// A stream's strip, index, segments and manifest are outputs too: neither the recording
/// nor a recording replayed may be one of them. A simulation never replaces its scene.
/// Two images drawn to one file are refused.
fn session_outputs_and_simulations_refuse_their_inputs(dir: &Path, rec: &Path, scene: &str) {
    let session = dir.join("session");
    let recording = std::fs::read(rec).unwrap();
    let replay = format!("replay:{}", s(rec));
    for name in ["manifest.json", "strip.png", "strip.json", "strip.0002.png"] {
        let record = session.join(name);
        let run = rollfuse(
            &[
                "stream",
                "--device",
                &replay,
                "--out",
                s(&session),
                "--record",
                s(&record),
            ],
            None,
        );
        let err = String::from_utf8_lossy(&run.stderr);
        assert!(
            !run.status.success() && err.contains("--record"),
            "{name}: {err}"
        );
        assert!(!session.exists(), "{name}: the session began");
    }
    // The recording replayed from where the session writes its strip.
    std::fs::create_dir(&session).unwrap();
    let inside = session.join("strip.png");
    std::fs::copy(rec, &inside).unwrap();
    let run = rollfuse(
        &[
            "stream",
            "--device",
            &format!("replay:{}", s(&inside)),
            "--out",
            s(&session),
        ],
        None,
    );
    assert!(!run.status.success());
    assert_eq!(std::fs::read(&inside).unwrap(), recording);
    // A scene named as a simulation's output, in its folder.
    for name in [
        "manifest.json",
        "frame_0000.png",
        "frame_0500.png",
        "lights.toml",
    ] {
        let copied = session.join(name);
        std::fs::copy(scene, &copied).unwrap();
        let before = std::fs::read(&copied).unwrap();
        let run = rollfuse(&["simulate", s(&copied), "--out", s(&session)], None);
        let err = String::from_utf8_lossy(&run.stderr);
        assert!(
            !run.status.success() && err.contains("refusing"),
            "{name}: {err}"
        );
        assert_eq!(std::fs::read(&copied).unwrap(), before, "{name}");
        std::fs::remove_file(&copied).unwrap();
    }
    // Two images of one file name drawn into one folder.
    let (a, b) = (
        dir.join("x").join("frame.png"),
        dir.join("y").join("frame.png"),
    );
    for p in [&a, &b] {
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        rollfuse::image::Planes {
            width: 64,
            height: 64,
            planes: vec![vec![0.5; 64 * 64]],
        }
        .save_png(p)
        .unwrap();
    }
    let drawn = dir.join("drawn");
    let run = rollfuse(&["detect", s(&a), s(&b), "--draw", s(&drawn)], None);
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(
        !run.status.success() && err.contains("written twice"),
        "{err}"
    );
    assert!(!drawn.exists(), "drawn before the refusal");
}

#[test]
fn eval_and_tradeoff_leave_their_outputs_whole_on_a_full_disk() {
    let tmp = tempfile::tempdir().unwrap();
    let dots = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/dots.toml");
    let e = tmp.path().join("eval");
    let lines = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/lines.toml");
    survives_a_full_disk(
        tmp.path(),
        &["eval", "--scene", dots, "--out", s(&e)],
        &["eval", "--scene", lines, "--out", s(&e)],
    );
    // The depth table has one form; its rewrite fails all the same.
    let depth = ["eval", "--depth", "--out", s(&e)];
    survives_a_full_disk(tmp.path(), &depth, &depth);
    // Timings differ run to run: the rewrite has other content by itself.
    let t = tmp.path().join("tradeoff");
    let tradeoff = [
        "tradeoff",
        "--out",
        s(&t),
        "--repeats",
        "1",
        "--bench",
        "/nonexistent.csv",
    ];
    survives_a_full_disk(tmp.path(), &tradeoff, &tradeoff);
}

/// Apart from the others: its detection stage is most of this file's time, and the
/// suite's tests run side by side.
#[test]
fn the_demo_leaves_its_report_whole_on_a_full_disk() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path().join("demo");
    let demo = ["demo", "--out", s(&d)];
    let fabric = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/fabric.toml");
    survives_a_full_disk(
        tmp.path(),
        &demo,
        &[&demo[..], &["--letters", fabric]].concat(),
    );
}
