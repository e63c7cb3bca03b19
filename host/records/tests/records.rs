//! One suite for both databases: each test runs on a fresh SQLite file and, when
//! `ROLLFUSE_TEST_POSTGRES` names a server (`.ci/run` starts one on loopback), on a fresh
//! PostgreSQL database there; without it the PostgreSQL half prints SKIPPED.

use rollfuse_records::{DefectRecord, Error, Filter, Records, RollStart, SegmentRecord, Status};
use std::sync::atomic::{AtomicUsize, Ordering};

/// A fresh, empty database of one kind; a PostgreSQL one is dropped when done.
struct Fresh {
    target: String,
    _dir: Option<tempfile::TempDir>,
    drop_db: Option<(String, String)>,
}

impl Drop for Fresh {
    fn drop(&mut self) {
        let Some((admin, name)) = &self.drop_db else {
            return;
        };
        if let Ok(mut c) = postgres::Client::connect(admin, postgres::NoTls) {
            let _ = c.batch_execute(&format!("DROP DATABASE IF EXISTS {name} WITH (FORCE)"));
        }
    }
}

fn sqlite() -> Fresh {
    let dir = tempfile::tempdir().unwrap();
    Fresh {
        target: dir.path().join("records.db").to_string_lossy().into_owned(),
        _dir: Some(dir),
        drop_db: None,
    }
}

fn postgres_url() -> Option<String> {
    std::env::var("ROLLFUSE_TEST_POSTGRES")
        .ok()
        .filter(|u| !u.is_empty())
}

fn postgres(test: &str) -> Option<Fresh> {
    let Some(admin) = postgres_url() else {
        eprintln!("SKIPPED: {test} on PostgreSQL — ROLLFUSE_TEST_POSTGRES is not set");
        return None;
    };
    static N: AtomicUsize = AtomicUsize::new(0);
    let name = format!(
        "rollfuse_test_{}_{}",
        std::process::id(),
        N.fetch_add(1, Ordering::SeqCst)
    );
    let mut c = postgres::Client::connect(&admin, postgres::NoTls).expect("the test server");
    c.batch_execute(&format!("CREATE DATABASE {name}")).unwrap();
    let base = admin.rsplit_once('/').unwrap().0;
    Some(Fresh {
        target: format!("{base}/{name}"),
        _dir: None,
        drop_db: Some((admin, name)),
    })
}

/// Runs `body` on each database there is.
fn on_both(test: &str, body: impl Fn(&str)) {
    let lite = sqlite();
    body(&lite.target);
    if let Some(pg) = postgres(test) {
        body(&pg.target);
    }
}

fn start(source: &str, line: &str) -> RollStart {
    RollStart {
        source: source.into(),
        line: line.into(),
        device: "0001".into(),
        configuration: r#"{"downsample":1}"#.into(),
        out: "/lines/strip.png".into(),
        mm_per_row: Some(0.05),
    }
}

fn segment(seq: i64, first_row: i64, rows: i64) -> SegmentRecord {
    SegmentRecord {
        seq,
        file: format!("strip.{seq:04}.png"),
        first_row,
        rows,
        width: 320,
        bytes: 1000 + seq,
        crc32: 0xdead_beef,
    }
}

fn defect(kind: &str, belt_row: f64) -> DefectRecord {
    DefectRecord {
        segment_seq: None,
        kind: kind.into(),
        score: 0.8,
        belt_row,
        across_px: 40.0,
        bbox: [30, 10, 20, 12],
        crop: Some(vec![1, 2, 3]),
    }
}

#[test]
fn a_roll_reads_back_as_it_was_recorded() {
    on_both("a_roll_reads_back_as_it_was_recorded", |target| {
        let mut r = Records::open(target).unwrap();
        let id = r.begin_roll(&start("device 0001 at t0", "3")).unwrap();
        r.add_segment(id, &segment(0, 100, 4096), &[defect("hole", 2100.0)])
            .unwrap();
        r.add_segment(id, &segment(1, 4196, 1000), &[defect("snag", 4500.0)])
            .unwrap();
        r.set_faults(id, &[("crc", 2), ("timeout", 0)]).unwrap();
        r.finish_roll(id, &Status::Complete).unwrap();
        let roll = r.roll(id).unwrap();
        assert_eq!(roll.summary.status, "complete");
        assert!(roll.summary.ended_at.is_some());
        assert_eq!(roll.summary.belt_rows, 5096);
        assert_eq!(roll.summary.belt_mm, Some(5096.0 * 0.05));
        assert_eq!(
            roll.segment_list,
            vec![segment(0, 100, 4096), segment(1, 4196, 1000)]
        );
        let kinds: Vec<&str> = roll.defect_list.iter().map(|d| d.kind.as_str()).collect();
        assert_eq!(kinds, ["hole", "snag"]);
        assert_eq!(roll.defect_list[0].crop, Some(vec![1, 2, 3]));
        // Along the belt from the roll's first row: (2100 − 100) × 0.05 mm.
        assert_eq!(roll.belt_mm(&roll.defect_list[0]), Some(100.0));
        assert_eq!(roll.faults, vec![("crc".to_owned(), 2)]);
        assert_eq!(roll.configuration, r#"{"downsample":1}"#);
    });
}

#[test]
fn the_same_source_again_replaces_its_record() {
    on_both("the_same_source_again_replaces_its_record", |target| {
        let mut r = Records::open(target).unwrap();
        let id = r.begin_roll(&start("recording a.rfrec", "3")).unwrap();
        r.add_segment(id, &segment(0, 0, 10), &[defect("hole", 5.0)])
            .unwrap();
        r.add_segment(id, &segment(0, 0, 12), &[defect("slub", 6.0)])
            .unwrap();
        let roll = r.roll(id).unwrap();
        assert_eq!(
            roll.segment_list.len(),
            1,
            "a segment recorded again replaces"
        );
        assert_eq!(roll.defect_list.len(), 1);
        assert_eq!(roll.defect_list[0].kind, "slub");
        r.finish_roll(id, &Status::Complete).unwrap();

        let again = r.begin_roll(&start("recording a.rfrec", "3")).unwrap();
        assert_eq!(again, id, "a re-run keeps the roll's id");
        let roll = r.roll(id).unwrap();
        assert_eq!(roll.summary.status, "running");
        assert!(roll.segment_list.is_empty() && roll.defect_list.is_empty());
        assert_eq!(r.list(&Filter::default()).unwrap().len(), 1);

        r.replace_defects(id, 0, &[defect("hole", 1.0), defect("hole", 2.0)])
            .unwrap();
        r.replace_defects(id, 0, &[defect("hole", 1.0)]).unwrap();
        assert_eq!(r.roll(id).unwrap().defect_list.len(), 1);
    });
}

#[test]
fn a_failed_segment_leaves_nothing_of_itself() {
    on_both("a_failed_segment_leaves_nothing_of_itself", |target| {
        let mut r = Records::open(target).unwrap();
        let id = r.begin_roll(&start("s", "1")).unwrap();
        let bad = DefectRecord {
            score: f64::NAN,
            ..defect("hole", 3.0)
        };
        let e = r
            .add_segment(id, &segment(0, 0, 10), &[defect("hole", 1.0), bad])
            .unwrap_err();
        assert!(matches!(e, Error::Invalid(_)), "{e}");
        let roll = r.roll(id).unwrap();
        assert!(roll.segment_list.is_empty() && roll.defect_list.is_empty());
        assert_eq!(roll.summary.belt_rows, 0);
        assert!(matches!(r.roll(id + 100), Err(Error::NoSuchRoll(_))));
        assert!(r.add_segment(id + 100, &segment(0, 0, 1), &[]).is_err());
        let no_scale = RollStart {
            mm_per_row: Some(-1.0),
            ..start("t", "1")
        };
        assert!(matches!(r.begin_roll(&no_scale), Err(Error::Invalid(_))));
    });
}

#[test]
fn rolls_are_listed_newest_first_by_line_time_and_kind() {
    on_both(
        "rolls_are_listed_newest_first_by_line_time_and_kind",
        |target| {
            let mut r = Records::open(target).unwrap();
            let a = r.begin_roll(&start("a", "3")).unwrap();
            r.add_segment(a, &segment(0, 0, 10), &[defect("hole", 1.0)])
                .unwrap();
            let b = r.begin_roll(&start("b", "4")).unwrap();
            r.add_segment(b, &segment(0, 0, 10), &[defect("snag", 1.0)])
                .unwrap();
            let ids = |f: Filter, r: &mut Records| -> Vec<i64> {
                r.list(&f).unwrap().iter().map(|s| s.id).collect()
            };
            assert_eq!(ids(Filter::default(), &mut r), [b, a]);
            let line = |l: &str| Filter {
                line: Some(l.into()),
                ..Filter::default()
            };
            assert_eq!(ids(line("3"), &mut r), [a]);
            let kind = Filter {
                kind: Some("snag".into()),
                ..Filter::default()
            };
            assert_eq!(ids(kind, &mut r), [b]);
            let future = Filter {
                since: Some("2999-01-01T00:00:00Z".into()),
                ..Filter::default()
            };
            assert!(ids(future, &mut r).is_empty());
            let summary = &r.list(&line("4")).unwrap()[0];
            assert_eq!((summary.segments, summary.defects), (1, 1));
        },
    );
}

#[test]
fn a_newer_schema_is_refused_untouched() {
    on_both("a_newer_schema_is_refused_untouched", |target| {
        drop(Records::open(target).unwrap());
        let bump = "UPDATE schema_version SET version = 99";
        if target.starts_with("postgres") {
            let mut c = postgres::Client::connect(target, postgres::NoTls).unwrap();
            c.batch_execute(bump).unwrap();
        } else {
            rusqlite::Connection::open(target)
                .unwrap()
                .execute_batch(bump)
                .unwrap();
        }
        let e = Records::open(target).err().expect("refused");
        assert!(
            matches!(
                e,
                Error::NewerSchema {
                    found: 99,
                    supported: rollfuse_records::SCHEMA_VERSION
                }
            ),
            "{e}"
        );
        assert!(e.to_string().contains("newer rollfuse"), "{e}");
    });
}

/// An announced segment: its number, the bytes announced, the bytes on disk when its
/// writer is killed.
type Announced = (i64, &'static [u8], Option<&'static [u8]>);

/// The announced segments of the crash test's roll.
const ANNOUNCED: [Announced; 3] = [
    // Moved into place, not yet confirmed: whole on disk, so listed.
    (2, b"segment two", Some(b"segment two")),
    // Killed before its file was moved into place.
    (3, b"segment three", None),
    // An older run's file still at its name.
    (4, b"segment four", Some(b"older four")),
];

/// The writer a crash test kills: it records a roll's first two segments, announces
/// three more ([`ANNOUNCED`]), says so, and waits to be killed.
#[test]
fn crash_child() {
    let Ok(target) = std::env::var("ROLLFUSE_CRASH_CHILD") else {
        return;
    };
    let folder = std::path::PathBuf::from(std::env::var("ROLLFUSE_CRASH_FOLDER").unwrap());
    let mut r = Records::open(&target).unwrap();
    let out = folder.join("strip.png").to_string_lossy().into_owned();
    let id = r
        .begin_roll(&RollStart {
            out,
            ..start("killed", "1")
        })
        .unwrap();
    r.add_segment(id, &segment(0, 0, 100), &[defect("hole", 5.0)])
        .unwrap();
    r.add_segment(id, &segment(1, 100, 100), &[]).unwrap();
    for (seq, announced, on_disk) in ANNOUNCED {
        let file = format!("strip.{seq:04}.png");
        let record = SegmentRecord::of_bytes(seq, &file, seq * 100, 100, announced);
        r.announce_segment(id, &record).unwrap();
        if let Some(bytes) = on_disk {
            std::fs::write(folder.join(&file), bytes).unwrap();
        }
    }
    println!("ROLL {id}");
    std::thread::sleep(std::time::Duration::from_secs(60));
}

#[test]
fn a_killed_writer_leaves_its_roll_interrupted_with_its_whole_segments() {
    use std::io::BufRead;
    on_both(
        "a_killed_writer_leaves_its_roll_interrupted_with_its_whole_segments",
        |target| {
            let folder = tempfile::tempdir().unwrap();
            let mut child = std::process::Command::new(std::env::current_exe().unwrap())
                .args(["--exact", "crash_child", "--nocapture", "--test-threads=1"])
                .env("ROLLFUSE_CRASH_CHILD", target)
                .env("ROLLFUSE_CRASH_FOLDER", folder.path())
                .stdout(std::process::Stdio::piped())
                .spawn()
                .unwrap();
            let out = std::io::BufReader::new(child.stdout.take().unwrap());
            let id: i64 = out
                .lines()
                .map_while(Result::ok)
                .find_map(|l| l.split("ROLL ").nth(1).map(|n| n.trim().parse().unwrap()))
                .expect("the child recorded a roll");
            {
                let mut r = Records::open(target).unwrap();
                let roll = r.roll(id).unwrap();
                assert_eq!(roll.summary.status, "running", "alive");
                assert_eq!(
                    roll.segment_list.len(),
                    2,
                    "announced segments are not listed"
                );
                assert_eq!(roll.summary.segments, 2);
            }
            child.kill().unwrap(); // SIGKILL
            child.wait().unwrap();
            let mut r = Records::open(target).unwrap();
            let roll = r.roll(id).unwrap();
            assert_eq!(roll.summary.status, "interrupted");
            assert!(roll.summary.reason.unwrap().contains("process ended"));
            let (seq, announced, _) = ANNOUNCED[0];
            let moved = SegmentRecord::of_bytes(seq, "strip.0002.png", 200, 100, announced);
            assert_eq!(
                roll.segment_list,
                vec![segment(0, 0, 100), segment(1, 100, 100), moved],
                "exactly the segments whole on disk"
            );
            assert_eq!(roll.summary.belt_rows, 300);
            assert_eq!(roll.defect_list.len(), 1);
        },
    );
}

fn since_epoch_ms() -> u128 {
    let now = std::time::SystemTime::now();
    now.duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_millis()
}

/// One worker of [`many_writers_open_one_new_file_at_once`]: opens the records, records a
/// roll.
#[test]
fn opening_child() {
    let (Ok(target), Ok(k)) = (
        std::env::var("ROLLFUSE_OPEN_CHILD"),
        std::env::var("ROLLFUSE_OPEN_CHILD_N"),
    ) else {
        return;
    };
    // Every worker opens at the same moment, as a cluster's warm workers do.
    let at: u128 = std::env::var("ROLLFUSE_OPEN_CHILD_AT")
        .unwrap()
        .parse()
        .unwrap();
    while since_epoch_ms() < at {
        std::thread::sleep(std::time::Duration::from_micros(200));
    }
    // A roll at a time, each opening the records anew, as a batch's tasks do.
    for roll in 0..ROLLS_A_WORKER {
        let mut r = Records::open(&target).unwrap();
        let id = r
            .begin_roll(&start(&format!("worker {k} roll {roll}"), "1"))
            .unwrap();
        for seq in 0..3 {
            r.add_segment(id, &segment(seq, seq * 10, 10), &[defect("hole", 1.0)])
                .unwrap();
        }
        r.finish_roll(id, &Status::Complete).unwrap();
    }
}

/// Rolls each worker of [`many_writers_open_one_new_file_at_once`] records.
const ROLLS_A_WORKER: usize = 10;

#[test]
fn many_writers_open_one_new_file_at_once() {
    // A batch's workers, processes, start together on a records file none has made yet.
    let fresh = sqlite();
    let at = since_epoch_ms() + 500;
    let workers: Vec<_> = (0..4)
        .map(|k| {
            std::process::Command::new(std::env::current_exe().unwrap())
                .args(["--exact", "opening_child", "--test-threads=1"])
                .env("ROLLFUSE_OPEN_CHILD", &fresh.target)
                .env("ROLLFUSE_OPEN_CHILD_N", k.to_string())
                .env("ROLLFUSE_OPEN_CHILD_AT", at.to_string())
                .stdout(std::process::Stdio::null())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for w in workers {
        let out = w.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "a worker failed: {err}");
    }
    let mut r = Records::open(&fresh.target).unwrap();
    assert_eq!(
        r.list(&Filter::default()).unwrap().len(),
        4 * ROLLS_A_WORKER
    );
}

#[test]
fn databases_that_cannot_be_had_say_why() {
    let missing = tempfile::tempdir().unwrap();
    let path = missing.path().join("no/such/folder/records.db");
    let e = Records::open(path.to_str().unwrap())
        .err()
        .expect("refused");
    assert!(matches!(e, Error::Open { .. }), "{e}");
    assert!(e.to_string().contains("records.db"), "{e}");

    let e = Records::open("postgres://rollfuse:pw@127.0.0.1:1/records")
        .err()
        .expect("refused");
    let text = e.to_string();
    assert!(text.contains("cannot open the records"), "{text}");
    assert!(!text.contains(":pw@"), "the password is not shown: {text}");

    let Some(url) = postgres_url() else {
        eprintln!("SKIPPED: a wrong password on PostgreSQL — ROLLFUSE_TEST_POSTGRES is not set");
        return;
    };
    let (scheme_user, rest) = url.split_once('@').unwrap();
    let user = scheme_user.rsplit_once(':').map_or(scheme_user, |(u, _)| u);
    let wrong = format!("{user}:not-the-password@{rest}");
    let e = Records::open(&wrong).err().expect("refused");
    let text = e.to_string();
    assert!(text.contains("password authentication failed"), "{text}");
    assert!(!text.contains("not-the-password"), "{text}");
}

#[test]
fn a_user_who_may_only_read_opens_and_lists_the_rolls() {
    let Some(pg) = postgres("a_user_who_may_only_read_opens_and_lists_the_rolls") else {
        return;
    };
    {
        let mut r = Records::open(&pg.target).unwrap();
        let id = r.begin_roll(&start("recorded by a line", "3")).unwrap();
        r.add_segment(id, &segment(0, 0, 10), &[]).unwrap();
        r.begin_roll(&start("cut off", "3")).unwrap();
    }
    let database = pg.target.rsplit_once('/').unwrap().1.to_string();
    let reader = format!("{database}_reader");
    let mut admin = postgres::Client::connect(&pg.target, postgres::NoTls).unwrap();
    // The second roll's process has ended (this host, this PID, another start).
    admin
        .batch_execute(
            "UPDATE rolls SET process = regexp_replace(process, ':[^:]*$', ':0') \
             WHERE source = 'cut off'",
        )
        .unwrap();
    admin
        .batch_execute(&format!(
            "CREATE ROLE {reader} LOGIN PASSWORD 'only-reads';
             GRANT SELECT ON ALL TABLES IN SCHEMA public TO {reader};"
        ))
        .unwrap();
    let (base, rest) = pg.target.split_once("://").unwrap();
    let host_and_db = rest.split_once('@').unwrap().1;
    let as_reader = format!("{base}://{reader}:only-reads@{host_and_db}");
    let mut r = Records::open(&as_reader).unwrap();
    let rolls = r.list(&Filter::default()).unwrap();
    let status = |source: &str| {
        let roll = rolls.iter().find(|r| r.source == source).unwrap();
        (roll.status.as_str(), roll.reason.is_some())
    };
    assert_eq!(status("recorded by a line"), ("running", false));
    // Shown as it is, though this user could not mark it.
    assert_eq!(status("cut off"), ("interrupted", true));
    let stored = admin
        .query_one("SELECT status FROM rolls WHERE source = 'cut off'", &[])
        .unwrap();
    assert_eq!(stored.get::<_, String>(0), "running");
    drop(r);
    admin
        .batch_execute(&format!("DROP OWNED BY {reader}; DROP ROLE {reader};"))
        .unwrap();
}
