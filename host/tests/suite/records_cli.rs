//! The inspection records from the command line: a simulated textile roll fused into
//! the records, its defects found and recorded, read back by `rolls list/show/map`; run
//! again without anything recorded twice; and a clear line for what cannot be had.

use crate::common::{fails, rollfuse};
use std::path::Path;

fn ok(args: &[&str]) -> String {
    let out = rollfuse(args);
    assert!(
        out.status.success(),
        "rollfuse {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

fn json(args: &[&str]) -> serde_json::Value {
    serde_json::from_str(&ok(args)).unwrap()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `stream --device sim --scene SCENE --out OUT --records DB`, then `more`.
fn sim_into_records<'a>(
    scene: &'a str,
    out: &'a Path,
    db: &'a Path,
    more: &[&'a str],
) -> Vec<&'a str> {
    let mut args = vec!["stream", "--device", "sim", "--scene", scene];
    args.extend(["--out", s(out), "--records", s(db)]);
    args.extend(more);
    args
}

#[test]
fn a_fused_roll_and_its_defects_are_recorded_and_read_back() {
    let tmp = tempfile::tempdir().unwrap();
    let (sim, db) = (tmp.path().join("sim"), tmp.path().join("records.db"));
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/textile.toml");
    ok(&["simulate", scene, "--out", s(&sim)]);
    let strip = tmp.path().join("strip/roll.png");
    // With the motion record, the strip's belt rows are the simulator's strip rows.
    let manifest = sim.join("manifest.json");
    let fuse = [
        "fuse",
        s(&sim),
        "--manifest",
        s(&manifest),
        "--out",
        s(&strip),
        "--records",
        s(&db),
        "--line",
        "3",
    ];
    assert!(ok(&fuse).contains("records: roll 1, 1 segment (complete)"));

    let rolls = json(&["rolls", "list", "--records", s(&db), "--json"]);
    let roll = &rolls.as_array().unwrap()[0];
    assert_eq!(roll["status"], "complete");
    assert_eq!(roll["line"], "3");
    assert_eq!(roll["mm_per_row"], 0.04, "the manifest's scale");
    assert_eq!(roll["segments"], 1);
    let listed = ok(&["rolls", "list", "--records", s(&db), "--line", "3"]);
    assert!(listed.starts_with("1 complete line 3 started "), "{listed}");
    assert!(ok(&["rolls", "list", "--records", s(&db), "--line", "4"]).is_empty());

    // The detector on the recorded strip: its defects kept on the segment, twice over
    // as once.
    let found = tmp.path().join("found.json");
    let detect = [
        "detect",
        s(&strip),
        "--records",
        s(&db),
        "--json",
        s(&found),
    ];
    ok(&detect);
    ok(&detect);
    let found: serde_json::Value = serde_json::from_slice(&std::fs::read(&found).unwrap()).unwrap();
    let boxes = found[0]["defects"].as_array().unwrap();
    let shown = json(&["rolls", "show", "1", "--records", s(&db), "--json"]);
    let defects = shown["defect_list"].as_array().unwrap();
    assert_eq!(defects.len(), boxes.len(), "{shown}");
    let segment = &shown["segment_list"][0];
    assert_eq!(segment["file"], "roll.png");
    assert_eq!(segment["width"], 320, "read from the PNG");
    let first_row = segment["first_row"].as_f64().unwrap();
    assert_eq!(
        segment["bytes"].as_u64().unwrap(),
        std::fs::metadata(&strip).unwrap().len()
    );
    // The records keep them along the belt; the detector lists them best first.
    let mut centres: Vec<f64> = boxes
        .iter()
        .map(|b| (b["box_px"][1].as_f64().unwrap() + b["box_px"][3].as_f64().unwrap()) / 2.0)
        .collect();
    centres.sort_by(f64::total_cmp);
    for (d, centre) in defects.iter().zip(&centres) {
        let belt_row = d["belt_row"].as_f64().unwrap();
        assert!(
            (belt_row - (first_row + centre)).abs() < 1e-3,
            "{d} {centre}"
        );
    }

    // The map: an SVG and the cutting room's CSV, positions in mm from the roll's start.
    let map = tmp.path().join("maps/roll1.svg");
    ok(&["rolls", "map", "1", "--records", s(&db), "--out", s(&map)]);
    let svg = std::fs::read_to_string(&map).unwrap();
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    let csv = std::fs::read_to_string(map.with_extension("csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(
        lines[0],
        "kind,score,belt_m,belt_mm,across_mm,segment,x,y,w,h"
    );
    assert_eq!(lines.len(), defects.len() + 1);
    for (line, d) in lines[1..].iter().zip(defects) {
        let mm: f64 = line.split(',').nth(3).unwrap().parse().unwrap();
        let want = (d["belt_row"].as_f64().unwrap() - first_row) * 0.04;
        assert!((mm - want).abs() < 0.06, "{line} against {want}");
    }

    // Each defect on the map lies within 1 mm of one the simulator put there, along the
    // belt (from the roll's start) and across it.
    let truth: serde_json::Value =
        serde_json::from_slice(&std::fs::read(sim.join("truth/defects.json")).unwrap()).unwrap();
    let k = truth["mm_per_px"].as_f64().unwrap();
    let centres: Vec<(f64, f64)> = truth["defects"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| {
            let b: Vec<f64> = (0..4).map(|i| d["box_px"][i].as_f64().unwrap()).collect();
            (
                ((b[1] + b[3]) / 2.0 - first_row) * k,
                (b[0] + b[2]) / 2.0 * k,
            )
        })
        .collect();
    assert!(
        !defects.is_empty(),
        "the detector found none of {centres:?}"
    );
    for line in &lines[1..] {
        let f: Vec<&str> = line.split(',').collect();
        let (along, across): (f64, f64) = (f[3].parse().unwrap(), f[4].parse().unwrap());
        let nearest = centres
            .iter()
            .map(|(a, c)| (a - along).hypot(c - across))
            .fold(f64::INFINITY, f64::min);
        assert!(
            nearest <= 1.0,
            "{line}: {nearest:.2} mm from the nearest true defect"
        );
    }

    // Fusing the same frames again replaces the roll's record: one roll, its defects gone
    // with the strip they were found on.
    ok(&fuse);
    let rolls = json(&["rolls", "list", "--records", s(&db), "--json"]);
    assert_eq!(rolls.as_array().unwrap().len(), 1);
    assert_eq!(rolls[0]["id"], 1);
    assert_eq!(rolls[0]["defects"], 0);
}

#[test]
fn records_that_cannot_be_had_are_said_in_one_line() {
    let tmp = tempfile::tempdir().unwrap();
    let db = tmp.path().join("records.db");
    let db = s(&db);
    fails(
        &["rolls", "show", "7", "--records", db],
        "no roll 7 in the records",
    );
    fails(
        &[
            "rolls",
            "list",
            "--records",
            "postgres://line:secret@127.0.0.1:1/records",
        ],
        "cannot open the records at postgres://line:***@127.0.0.1:1/records",
    );
    fails(
        &["rolls", "map", "1", "--records", db, "--out", "map.png"],
        "the map is an .svg file",
    );
    fails(
        &["rolls", "list", "--records", db, "--since", "yesterday"],
        "--since yesterday: not a time",
    );
    // The records' file is an input no output may overwrite.
    let csv = tmp.path().join("map.csv");
    let svg = tmp.path().join("map.svg");
    fails(
        &["rolls", "map", "1", "--records", s(&csv), "--out", s(&svg)],
        "is the records",
    );
    let out = tmp.path().join("roll");
    let strip = out.join("strip.png");
    fails(
        &sim_into_records(LETTERS, &out, &strip, &[]),
        "is the records",
    );
    assert!(!out.exists(), "nothing made");
    let missing = tmp.path().join("no/such/records.db");
    fails(
        &["rolls", "list", "--records", s(&missing)],
        "cannot open the records at",
    );
}

const LETTERS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/letters.toml");

fn roll_json(db: &Path, id: i64) -> Option<serde_json::Value> {
    let id = id.to_string();
    let out = rollfuse(&["rolls", "show", &id, "--records", s(db), "--json"]);
    out.status
        .success()
        .then(|| serde_json::from_slice(&out.stdout).unwrap())
}

#[test]
fn a_stream_killed_midway_leaves_its_roll_interrupted_with_its_whole_segments() {
    // Killed at several points of the roll: after 1, 3 and 6 segments were recorded.
    for kill_after in [1, 3, 6] {
        killed_after(kill_after);
    }
}

/// Streams a paced roll into records, kills it with SIGKILL once `segments` are recorded,
/// and checks what it left.
fn killed_after(segments: i64) {
    let tmp = tempfile::tempdir().unwrap();
    let (out, db) = (tmp.path().join("roll"), tmp.path().join("records.db"));
    // Paced at 5 frames a second (the roll takes 7 s), one tile a segment: segments land
    // one by one, and the stream is still running when it is killed.
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_rollfuse"))
        .args([
            "stream",
            "--device",
            "sim",
            "--scene",
            LETTERS,
            "--frame-rate",
            "5",
        ])
        .args([
            "--out",
            s(&out),
            "--records",
            s(&db),
            "--segment-rows",
            "16",
        ])
        .args(["--progress", "none"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let mut seen = 0;
    for _ in 0..600 {
        seen = roll_json(&db, 1).map_or(0, |r| r["segments"].as_i64().unwrap());
        if seen >= segments {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    assert!(seen >= segments, "the stream recorded {seen} segments");
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();

    let roll = roll_json(&db, 1).expect("the records open after the kill");
    assert_eq!(roll["status"], "interrupted", "{roll}");
    let listed = roll["segment_list"].as_array().unwrap();
    assert!(listed.len() as i64 >= segments);
    for (n, segment) in listed.iter().enumerate() {
        assert_eq!(segment["seq"], n as i64);
        let record: rollfuse_records::SegmentRecord = rollfuse_records::SegmentRecord {
            seq: n as i64,
            file: segment["file"].as_str().unwrap().into(),
            first_row: segment["first_row"].as_i64().unwrap(),
            rows: segment["rows"].as_i64().unwrap(),
            width: segment["width"].as_i64().unwrap(),
            bytes: segment["bytes"].as_i64().unwrap(),
            crc32: segment["crc32"].as_u64().unwrap() as u32,
        };
        assert!(
            record.matches_file(&out.join(&record.file)),
            "{} is whole on disk as recorded",
            record.file
        );
    }
    // And every segment at its name is listed (a kill between a segment's landing and its
    // record included).
    let on_disk = rollfuse::strip_file::StripWriter::segments_on_disk(&out.join("strip.png"), 0);
    assert_eq!(on_disk.len(), listed.len(), "{on_disk:?} against {roll}");
}

#[test]
fn a_recording_streamed_again_replaces_its_roll_and_another_strip_is_not_overwritten() {
    let tmp = tempfile::tempdir().unwrap();
    let (rec, db) = (
        tmp.path().join("session.rfrec"),
        tmp.path().join("records.db"),
    );
    let first = tmp.path().join("first");
    let record = ["--out", s(&first), "--record", s(&rec)];
    ok(&[
        &["stream", "--device", "sim", "--scene", LETTERS][..],
        &record[..],
    ]
    .concat());
    let out = tmp.path().join("replayed");
    let replay = format!("replay:{}", s(&rec));
    let args = [
        "stream",
        "--device",
        &replay,
        "--out",
        s(&out),
        "--records",
        s(&db),
    ];
    ok(&args);
    let once = roll_json(&db, 1).unwrap();
    ok(&args);
    let twice = roll_json(&db, 1).unwrap();
    assert_eq!(once["segment_list"], twice["segment_list"]);
    let rolls = json(&["rolls", "list", "--records", s(&db), "--json"]);
    assert_eq!(rolls.as_array().unwrap().len(), 1, "{rolls}");
    // Another roll into the same folder would land on this one's segments.
    fails(
        &sim_into_records(LETTERS, &out, &db, &[]),
        "holds a strip already",
    );
    assert_eq!(
        roll_json(&db, 1).unwrap()["segment_list"],
        once["segment_list"]
    );
}

#[test]
fn defects_the_live_detector_finds_are_recorded_on_their_segments() {
    let tmp = tempfile::tempdir().unwrap();
    let (out, db) = (tmp.path().join("roll"), tmp.path().join("records.db"));
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/textile.toml");
    let live = ["--serve", "127.0.0.1:0", "--detect", "--segment-rows", "64"];
    let printed = ok(&sim_into_records(scene, &out, &db, &live));
    // `defects: 1 slub, 2 snags on 672 strip rows; …`: the live detector's count.
    let line = printed
        .lines()
        .find(|l| l.starts_with("defects: "))
        .unwrap();
    let counted: i64 = line["defects: ".len()..line.find(" on ").unwrap()]
        .split(", ")
        .map(|n| n.split(' ').next().unwrap().parse::<i64>().unwrap())
        .sum();
    assert!(counted > 0, "{line}");
    let roll = roll_json(&db, 1).unwrap();
    let defects = roll["defect_list"].as_array().unwrap();
    assert_eq!(defects.len() as i64, counted, "{line}\n{roll}");
    for d in defects {
        // Each on the segment holding its centre, its box in that segment's pixels.
        let seq = d["segment_seq"].as_i64().unwrap();
        let segment = &roll["segment_list"][seq as usize];
        let first = segment["first_row"].as_f64().unwrap();
        let rows = segment["rows"].as_f64().unwrap();
        let row = d["belt_row"].as_f64().unwrap();
        assert!((first..first + rows).contains(&row), "{d} on {segment}");
        let [y, h] = [
            d["bbox"][1].as_f64().unwrap(),
            d["bbox"][3].as_f64().unwrap(),
        ];
        assert!((first + y + h / 2.0 - row).abs() <= 1.0, "{d} on {segment}");
    }
}

/// A small tmpfs mounted for a test, unmounted when dropped; none where mounting is not
/// allowed (not root).
struct SmallDisk(std::path::PathBuf);

impl SmallDisk {
    fn mount(at: &Path, size: &str) -> Option<SmallDisk> {
        std::fs::create_dir_all(at).unwrap();
        let done = std::process::Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs", s(at)])
            .stderr(std::process::Stdio::null())
            .status();
        done.is_ok_and(|d| d.success())
            .then(|| SmallDisk(at.to_path_buf()))
    }
}

impl Drop for SmallDisk {
    fn drop(&mut self) {
        let _ = std::process::Command::new("umount").arg(&self.0).status();
    }
}

#[test]
fn records_on_a_full_disk_fail_the_stream_in_a_line_and_keep_what_they_listed() {
    let tmp = tempfile::tempdir().unwrap();
    let Some(disk) = SmallDisk::mount(&tmp.path().join("small"), "200k") else {
        eprintln!("SKIPPED: records on a full disk — no tmpfs can be mounted here (needs root)");
        return;
    };
    let (out, db) = (tmp.path().join("roll"), disk.0.join("records.db"));
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/textile.toml");
    let run = rollfuse(&sim_into_records(
        scene,
        &out,
        &db,
        &["--segment-rows", "16"],
    ));
    // The session's notes, then the error in one line, exit 1.
    let err = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    let last = err.trim_end().lines().last().unwrap();
    assert!(
        last.starts_with("error: records: database or disk is full"),
        "{err}"
    );
    // The records open on the full disk and list only segments whole on disk.
    let roll = roll_json(&db, 1).expect("the records open");
    assert!(
        ["failed", "interrupted"].contains(&roll["status"].as_str().unwrap()),
        "{roll}"
    );
    let listed = roll["segment_list"].as_array().unwrap();
    assert!(
        !listed.is_empty(),
        "the disk filled before any segment: {roll}"
    );
    for segment in listed {
        let bytes = std::fs::read(out.join(segment["file"].as_str().unwrap())).unwrap();
        assert_eq!(bytes.len() as u64, segment["bytes"].as_u64().unwrap());
    }
}
