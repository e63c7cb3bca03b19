//! Every command on a disk that fills up: with `ROLLFUSE_FAIL_WRITES_AFTER=N` each output
//! fails after N bytes, as a full disk would. Each command is run once to have outputs,
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

/// Runs `args` well, then on a disk that fills after 0 and after 100 bytes of each file:
/// both fail and change nothing.
fn survives_a_full_disk(dir: &Path, args: &[&str]) {
    let good = rollfuse(args, None);
    assert!(
        good.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&good.stderr)
    );
    let before = snapshot(dir);
    for fail_after in [0, 100] {
        let run = rollfuse(args, Some(fail_after));
        let err = String::from_utf8_lossy(&run.stderr);
        assert!(!run.status.success(), "{args:?} succeeded on a full disk");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(
            err.contains("no space left"),
            "{args:?}: the error does not say why: {err}"
        );
        let after = snapshot(dir);
        let changed: Vec<_> = after
            .keys()
            .chain(before.keys())
            .filter(|p| before.get(*p) != after.get(*p))
            .collect();
        assert!(
            changed.is_empty(),
            "{args:?} with {fail_after} bytes of room changed {changed:?}"
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
    survives_a_full_disk(
        tmp.path(),
        &["simulate", scene, "--out", s(&sim), "--frames", "8"],
    );
    let frames: Vec<String> = (0..8)
        .map(|k| s(&sim.join(format!("frame_{k:04}.png"))).to_string())
        .collect();
    let frames: Vec<&str> = frames.iter().map(String::as_str).collect();
    let strip = tmp.path().join("strip.png");
    survives_a_full_disk(
        tmp.path(),
        &[&["fuse"], &frames[..], &["--out", s(&strip)]].concat(),
    );
    let spliced = tmp.path().join("spliced.png");
    survives_a_full_disk(
        tmp.path(),
        &[&["splice"], &frames[..], &["--out", s(&spliced)]].concat(),
    );
}

#[test]
fn depth_calibrate_and_stream_leave_their_outputs_whole_on_a_full_disk() {
    let tmp = tempfile::tempdir().unwrap();
    let l = Lights::product(0.02);
    let lights = tmp.path().join("lights.toml");
    l.save(&lights).unwrap();
    let (_, img) = ball((120, 100), (60.0, 50.0), 1.0, 0.2, &l, 180.0);
    let image = tmp.path().join("ball.png");
    img.save_png(&image).unwrap();
    let d = tmp.path().join("d");
    survives_a_full_disk(
        tmp.path(),
        &[
            "depth",
            s(&image),
            "--lights",
            s(&lights),
            "--out",
            s(&d),
            "--ply",
        ],
    );
    let cal = tmp.path().join("cal.toml");
    survives_a_full_disk(
        tmp.path(),
        &[
            "calibrate",
            s(&image),
            "--radius-mm",
            "1",
            "--mm-per-px",
            "0.02",
            "--out",
            s(&cal),
        ],
    );
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/letters.toml");
    let (out, rec) = (tmp.path().join("live"), tmp.path().join("rec.bin"));
    survives_a_full_disk(
        tmp.path(),
        &[
            "stream",
            "--device",
            "sim",
            "--scene",
            scene,
            "--out",
            s(&out),
            "--tiles",
            "6",
            "--record",
            s(&rec),
        ],
    );
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
}
