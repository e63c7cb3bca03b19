//! A streaming session under link faults: bit flips, truncations, drops, duplicates,
//! wrong versions and oversized transfers injected into a real stream from the virtual
//! device. Every fault must be counted, every untouched tile kept exactly, and nothing
//! may panic. Also: a stream cut off midway keeps what arrived, and the command line
//! fails clearly when there is no USB device.

use crate::common::rollfuse;
use proptest::prelude::*;
use rollfuse::link::sim::SimDevice;
use rollfuse::link::{self, Received, Transport};
use rollfuse::progress::Silent;
use rollfuse::sim::Scene;
use rollfuse::stream::{self, Options};
use rollfuse_core::protocol::{self, DeviceMessage, MAX_MESSAGE};
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::OnceLock;
use std::time::Duration;

/// Plays a list of messages; the end closes the link.
struct Scripted {
    messages: std::vec::IntoIter<Vec<u8>>,
}

impl Transport for Scripted {
    fn send(&mut self, _: &[u8]) -> Result<(), link::Error> {
        Ok(())
    }
    fn receive(&mut self, buf: &mut [u8], _: Duration) -> Result<Received, link::Error> {
        Ok(match self.messages.next() {
            Some(m) => {
                let n = m.len().min(buf.len());
                buf[..n].copy_from_slice(&m[..n]);
                Received::Message(n)
            }
            None => Received::Closed,
        })
    }
    fn is_live(&self) -> bool {
        false
    }
}

/// The messages of one clean stream of the letters scene (10 frames), recorded once.
fn clean_stream() -> &'static Vec<Vec<u8>> {
    static STREAM: OnceLock<Vec<Vec<u8>>> = OnceLock::new();
    STREAM.get_or_init(|| {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/letters.toml");
        let mut scene = Scene::load(&path).unwrap();
        scene.sensor.frames = 10;
        let tmp = tempfile::tempdir().unwrap();
        let rec = tmp.path().join("rec.bin");
        let mut dev = SimDevice::start(&scene).unwrap();
        stream::run(&mut dev, &options(tmp.path(), Some(&rec)), &Silent).unwrap();
        let bytes = std::fs::read(&rec).unwrap();
        let mut rest = &bytes[8..];
        let mut out = Vec::new();
        while !rest.is_empty() {
            let n = u32::from_le_bytes(rest[..4].try_into().unwrap()) as usize;
            out.push(rest[4..4 + n].to_vec());
            rest = &rest[4 + n..];
        }
        out
    })
}

fn options(out: &Path, record: Option<&Path>) -> Options {
    Options {
        record: record.map(Path::to_path_buf),
        ..Options::into_folder(out)
    }
}

/// Tile index → pixels of the tile messages in `messages` that decode.
fn tiles_in(messages: &[Vec<u8>]) -> BTreeMap<u32, Vec<u8>> {
    messages
        .iter()
        .filter_map(|m| match protocol::decode::<DeviceMessage>(m) {
            Ok((_, DeviceMessage::Tile(t))) => Some((t.index, t.pixels.to_vec())),
            _ => None,
        })
        .collect()
}

#[derive(Debug, Clone, Copy)]
enum Fault {
    Flip(usize),
    Truncate(usize),
    Drop,
    Duplicate,
    WrongVersion,
    Oversize,
}

fn fault() -> impl Strategy<Value = Option<Fault>> {
    prop_oneof![
        12 => Just(None),
        1 => any::<usize>().prop_map(|b| Some(Fault::Flip(b))),
        1 => any::<usize>().prop_map(|n| Some(Fault::Truncate(n))),
        1 => Just(Some(Fault::Drop)),
        1 => Just(Some(Fault::Duplicate)),
        1 => Just(Some(Fault::WrongVersion)),
        1 => Just(Some(Fault::Oversize)),
    ]
}

/// The message with its version byte changed and its CRC made right again.
fn with_version(msg: &[u8], version: u8) -> Vec<u8> {
    let mut body = msg[..msg.len() - 4].to_vec();
    body[0] = version;
    let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC).checksum(&body);
    body.extend_from_slice(&crc.to_le_bytes());
    body
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn faults_are_counted_and_untouched_tiles_kept(plan in proptest::collection::vec(fault(), 64)) {
        let clean = clean_stream();
        let mut sent = Vec::new();
        let mut kept = Vec::new();
        let (mut lost, mut crc_or_short, mut versions, mut oversized, mut dups) = (0, 0, 0, 0, 0);
        for (i, msg) in clean.iter().enumerate() {
            // The first message starts the sequence and the last is the device's final
            // status: a loss there cannot show as a gap, so they stay intact.
            let f = if i == 0 || i + 1 == clean.len() { None } else { plan[i % plan.len()] };
            match f {
                None => {
                    sent.push(msg.clone());
                    kept.push(msg.clone());
                }
                Some(Fault::Duplicate) => {
                    sent.push(msg.clone());
                    sent.push(msg.clone());
                    kept.push(msg.clone());
                    dups += 1;
                }
                Some(Fault::Flip(bit)) => {
                    let mut m = msg.clone();
                    let bit = bit % (m.len() * 8);
                    m[bit / 8] ^= 1 << (bit % 8);
                    sent.push(m);
                    lost += 1;
                    crc_or_short += 1;
                }
                Some(Fault::Truncate(n)) => {
                    sent.push(msg[..n % msg.len()].to_vec());
                    lost += 1;
                    crc_or_short += 1;
                }
                Some(Fault::Drop) => lost += 1,
                Some(Fault::WrongVersion) => {
                    sent.push(with_version(msg, protocol::PROTOCOL_VERSION + 1));
                    lost += 1;
                    versions += 1;
                }
                Some(Fault::Oversize) => {
                    let mut m = msg.clone();
                    m.resize(MAX_MESSAGE + 1, 0);
                    sent.push(m);
                    lost += 1;
                    oversized += 1;
                }
            }
        }
        let tmp = tempfile::tempdir().unwrap();
        let mut link = Scripted { messages: sent.into_iter() };
        let out = stream::run(&mut link, &options(tmp.path(), None), &Silent).unwrap();
        let f = &out.manifest.faults;
        prop_assert_eq!(f.bad_crc + f.truncated, crc_or_short);
        prop_assert_eq!(f.wrong_version, versions);
        prop_assert_eq!(f.too_long, oversized);
        prop_assert_eq!(f.repeated, dups);
        prop_assert_eq!(f.messages_missing, lost);
        prop_assert!(out.manifest.device_stopped);

        // Every tile that arrived intact is in the strip, exactly.
        let expected = tiles_in(&kept);
        prop_assert_eq!(out.manifest.tiles_received, expected.len() as u64);
        let strip = image::open(tmp.path().join("strip.png")).unwrap().to_luma8();
        let first = *tiles_in(clean).keys().next().unwrap();
        let first_here = out.manifest.index_range.unwrap()[0];
        prop_assert!(first_here >= first);
        let bytes = expected.values().next().unwrap().len();
        for (index, pixels) in &expected {
            let at = (index - first_here) as usize * bytes;
            prop_assert_eq!(&strip.as_raw()[at..at + bytes], &pixels[..]);
        }
        // Missing tiles inside the range are listed.
        let missing: u32 = out.manifest.gaps.iter().map(|[a, b]| b - a + 1).sum();
        let [lo, hi] = out.manifest.index_range.unwrap();
        prop_assert_eq!(u64::from(hi - lo + 1 - missing), out.manifest.tiles_received);
    }
}

#[test]
fn a_stream_cut_off_midway_keeps_every_tile_received() {
    let clean = clean_stream();
    let cut = clean.len() / 2;
    let tmp = tempfile::tempdir().unwrap();
    let kept: Vec<Vec<u8>> = clean[..cut].to_vec();
    let mut link = Scripted {
        messages: kept.into_iter(),
    };
    let out = stream::run(&mut link, &options(tmp.path(), None), &Silent).unwrap();
    let expected = tiles_in(&clean[..cut]);
    assert!(!expected.is_empty());
    assert_eq!(out.manifest.tiles_received, expected.len() as u64);
    assert!(
        !out.manifest.device_stopped,
        "the device never said it stopped"
    );
    let strip = image::open(tmp.path().join("strip.png"))
        .unwrap()
        .to_luma8();
    let bytes = expected.values().next().unwrap().len();
    assert_eq!(strip.as_raw().len(), expected.len() * bytes);
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(tmp.path().join("manifest.json")).unwrap())
            .unwrap();
    assert_eq!(manifest["tiles_received"], expected.len() as u64);
}

#[test]
fn without_a_device_usb_commands_fail_with_one_clear_line() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("s");
    for args in [
        vec!["devices"],
        vec!["stream", "--device", "usb", "--out", out.to_str().unwrap()],
    ] {
        let run = rollfuse(&args);
        assert!(
            !run.status.success(),
            "{args:?} should fail here: no USB devices"
        );
        let err = String::from_utf8_lossy(&run.stderr);
        assert!(!err.contains("panicked"), "{err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(
            err.contains("rollfuse device") || err.contains("USB"),
            "says why: {err}"
        );
    }
}

#[test]
fn bad_stream_arguments_are_refused_clearly() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("s");
    let o = out.to_str().unwrap();
    let scene = format!("{}/scenes/letters.toml", env!("CARGO_MANIFEST_DIR"));
    let junk = tmp.path().join("junk.bin");
    std::fs::write(&junk, b"not a recording").unwrap();
    let replay = format!("replay:{}", junk.display());
    let missing = format!("replay:{}", tmp.path().join("none.bin").display());
    let cases: [(&[&str], &str); 8] = [
        (&["--device", &missing, "--out", o], "cannot open recording"),
        (&["--device", "sim", "--out", o], "--scene"),
        (&["--device", "tcp", "--out", o], "usb, sim or replay"),
        (
            &["--device", &replay, "--out", o],
            "not a rollfuse stream recording",
        ),
        (
            &[
                "--device", "sim", "--scene", &scene, "--out", o, "--levels", "9",
            ],
            "Levels",
        ),
        (
            &[
                "--device",
                "sim",
                "--scene",
                &scene,
                "--out",
                o,
                "--frames-per-tile",
                "40",
            ],
            "FramesPerTile",
        ),
        (
            &[
                "--device",
                "sim",
                "--scene",
                &scene,
                "--out",
                o,
                "--downsample",
                "1",
                "--tile-rows",
                "48",
            ],
            "more pipeline memory than the device has",
        ),
        (
            &["--device", "usb", "--out", o, "--unbounded-memory"],
            "--device sim",
        ),
    ];
    for (args, says) in cases {
        let run = rollfuse(&[&["stream"], args].concat());
        assert!(!run.status.success(), "{args:?}");
        let err = String::from_utf8_lossy(&run.stderr);
        assert!(err.contains(says), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
        // A start that fails leaves no empty output folder behind: nothing, or a
        // session's manifest saying what the device refused.
        assert!(
            !out.exists() || out.join("manifest.json").exists(),
            "{args:?} left {} empty",
            out.display()
        );
    }
}

#[test]
fn unbounded_memory_lets_the_virtual_device_stream_what_the_module_cannot_hold() {
    let (_, width, _) = streamed(&[
        "--downsample",
        "1",
        "--tile-rows",
        "48",
        "--unbounded-memory",
    ]);
    // Full resolution: the camera's 320 columns.
    assert_eq!(width, 320);
}

/// A tile message with index `index`, `w × t` pixels of `value`, sequence `seq`.
fn tile_message(seq: u32, index: u32, (w, t): (u16, u16), value: u8) -> Vec<u8> {
    let pixels = vec![value; usize::from(w) * usize::from(t)];
    let tile = DeviceMessage::Tile(protocol::Tile {
        index,
        width: w,
        height: t,
        observations: 1,
        pixels: &pixels,
    });
    encoded(seq, &tile)
}

/// `message` encoded with sequence number `seq`.
fn encoded(seq: u32, message: &DeviceMessage<'_>) -> Vec<u8> {
    let mut buf = vec![0u8; MAX_MESSAGE];
    let n = protocol::encode(seq, message, &mut buf).unwrap();
    buf.truncate(n);
    buf
}

#[test]
fn a_far_jump_of_the_index_starts_a_segment_and_late_tiles_are_counted() {
    // Indices 0, 1, 3 (2 lost: a black tile), then 4 000 000 000: never a canvas between.
    let size = (8, 4);
    let indices = [0u32, 1, 3, 4_000_000_000, 4_000_000_001];
    let mut messages: Vec<Vec<u8>> = indices
        .iter()
        .enumerate()
        .map(|(k, &i)| tile_message(k as u32, i, size, 10 + k as u8))
        .collect();
    // Tile 1 again: a duplicate, not placed.
    messages.push(tile_message(5, 1, size, 99));
    let tmp = tempfile::tempdir().unwrap();
    let mut link = Scripted {
        messages: messages.into_iter(),
    };
    let out = stream::run(&mut link, &options(tmp.path(), None), &Silent).unwrap();
    let m = &out.manifest;
    assert_eq!(m.tiles_received, 5);
    assert_eq!(m.faults.duplicate_tiles, 1);
    assert_eq!(m.gaps, vec![[2, 2], [4, 3_999_999_999]]);
    let index: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(tmp.path().join("strip.json")).unwrap())
            .unwrap();
    let segments = index["segments"].as_array().unwrap();
    assert_eq!(segments.len(), 2, "{index}");
    assert_eq!(segments[1]["first_row"], 16_000_000_000i64);
    let first = image::open(tmp.path().join(segments[0]["file"].as_str().unwrap()))
        .unwrap()
        .to_luma8();
    // Tiles 0, 1, the lost 2 in black, 3.
    let rows: Vec<u8> = first.as_raw().chunks(8).map(|r| r[0]).collect();
    assert_eq!(
        rows,
        [10, 10, 10, 10, 11, 11, 11, 11, 0, 0, 0, 0, 12, 12, 12, 12]
    );
}

/// A live device that says nothing for a while, then reports it stopped; records the
/// commands it is sent.
struct Quiet {
    until: std::time::Instant,
    sent: std::sync::Arc<std::sync::Mutex<Vec<rollfuse_core::protocol::Command>>>,
    done: bool,
}

impl Transport for Quiet {
    fn send(&mut self, message: &[u8]) -> Result<(), link::Error> {
        let (_, c) = protocol::decode::<rollfuse_core::protocol::Command>(message).unwrap();
        self.sent.lock().unwrap().push(c);
        Ok(())
    }
    fn receive(&mut self, buf: &mut [u8], timeout: Duration) -> Result<Received, link::Error> {
        if std::time::Instant::now() < self.until {
            std::thread::sleep(timeout.min(Duration::from_millis(50)));
            return Ok(Received::Timeout);
        }
        if self.done {
            return Ok(Received::Closed);
        }
        self.done = true;
        let status = DeviceMessage::Status(rollfuse_core::protocol::StatusCounters::default());
        Ok(Received::Message(
            protocol::encode(1, &status, buf).unwrap(),
        ))
    }
    fn is_live(&self) -> bool {
        true
    }
}

#[test]
fn a_live_session_asks_for_status_every_second_so_the_device_knows_it_is_there() {
    use rollfuse_core::protocol::Command;
    let sent = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
    let mut link = Quiet {
        until: std::time::Instant::now() + stream::HEARTBEAT * 2 + Duration::from_millis(300),
        sent: sent.clone(),
        done: false,
    };
    let tmp = tempfile::tempdir().unwrap();
    stream::run(&mut link, &options(tmp.path(), None), &Silent).unwrap();
    let sent = sent.lock().unwrap();
    assert!(
        matches!(sent[..2], [Command::Hello, Command::StreamStart]),
        "{sent:?}"
    );
    let heartbeats = sent.iter().filter(|c| matches!(c, Command::Status)).count();
    assert!(heartbeats >= 2, "{sent:?}");
}

#[test]
fn stream_names_the_strip_it_wrote_and_says_when_there_is_none() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/letters.toml");
    let out = tmp.path().join("live");
    let run = rollfuse(&[
        "stream",
        "--device",
        "sim",
        "--scene",
        scene,
        "--out",
        out.to_str().unwrap(),
        "--tiles",
        "4",
    ]);
    let said = String::from_utf8_lossy(&run.stdout);
    assert!(run.status.success(), "{said}");
    let named = said
        .lines()
        .find_map(|l| l.split(" → ").nth(1))
        .expect("a line naming the strip");
    assert!(
        Path::new(named).is_file(),
        "{named} was not written: {said}"
    );
    // A recording with no message at all: no strip, and it says so.
    let empty = tmp.path().join("empty.bin");
    std::fs::write(&empty, b"RFSTRM01").unwrap();
    let out = tmp.path().join("none");
    let run = rollfuse(&[
        "stream",
        "--device",
        &format!("replay:{}", empty.display()),
        "--out",
        out.to_str().unwrap(),
    ]);
    let said = String::from_utf8_lossy(&run.stdout);
    assert!(said.contains("no strip (no tile was taken)"), "{said}");
    assert!(!out.join("strip.png").exists());
}

#[test]
fn a_reversed_recording_is_read_to_its_end_and_its_faults_counted() {
    let mut reversed = clean_stream().clone();
    reversed.reverse();
    let n = reversed.len() as u64;
    let tmp = tempfile::tempdir().unwrap();
    let mut link = Scripted {
        messages: reversed.into_iter(),
    };
    let out = stream::run(&mut link, &options(tmp.path(), None), &Silent).unwrap();
    let f = &out.manifest.faults;
    // The final status comes first; everything after it is counted, and each message
    // goes back in sequence.
    assert_eq!(f.after_final_status, n - 1, "{f:?}");
    assert_eq!(f.repeated, n - 1, "{f:?}");
    assert_eq!(out.manifest.tiles_received, 0);
    // In order, nothing is counted.
    let mut link = Scripted {
        messages: clean_stream().clone().into_iter(),
    };
    let tmp = tempfile::tempdir().unwrap();
    let out = stream::run(&mut link, &options(tmp.path(), None), &Silent).unwrap();
    assert_eq!(out.manifest.faults.after_final_status, 0);
}

/// Keeps the tiles it is shown and, once it has seen `ask_after` of them, asks for LED
/// duties the device must refuse.
struct Watcher {
    tiles: Vec<(u32, Vec<u8>)>,
    messages: u64,
    ask_after: usize,
    asked: bool,
}

/// The command the watcher gives: a duty beyond full, which the device refuses.
const BAD_LEDS: protocol::Command = protocol::Command::Leds(protocol::LedDuty {
    red: protocol::LedDuty::FULL + 1,
    green: 0,
    blue: 0,
});

impl stream::Watch for Watcher {
    fn tile(&mut self, tile: &protocol::Tile<'_>, manifest: &stream::StreamRecord) {
        assert_eq!(manifest.tiles_received, self.tiles.len() as u64 + 1);
        self.tiles.push((tile.index, tile.pixels.to_vec()));
    }

    fn message(&mut self, manifest: &stream::StreamRecord) {
        self.messages += 1;
        assert!(manifest.messages >= self.messages);
    }

    fn command(&mut self) -> Option<protocol::Command> {
        if self.asked || self.tiles.len() < self.ask_after {
            return None;
        }
        self.asked = true;
        Some(BAD_LEDS)
    }
}

/// A link that keeps a copy of every message sent through it.
struct Tapped<T> {
    link: T,
    sent: Vec<Vec<u8>>,
}

impl<T: Transport> Transport for Tapped<T> {
    fn send(&mut self, message: &[u8]) -> Result<(), link::Error> {
        self.sent.push(message.to_vec());
        self.link.send(message)
    }

    fn receive(&mut self, buf: &mut [u8], timeout: Duration) -> Result<Received, link::Error> {
        self.link.receive(buf, timeout)
    }
}

#[test]
fn a_watcher_sees_every_tile_as_it_comes_and_its_commands_reach_the_device() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/letters.toml");
    let mut scene = Scene::load(&path).unwrap();
    scene.sensor.frames = 12;
    let tmp = tempfile::tempdir().unwrap();
    let mut watcher = Watcher {
        tiles: Vec::new(),
        messages: 0,
        ask_after: 1,
        asked: false,
    };
    let mut link = Tapped {
        link: SimDevice::start(&scene).unwrap(),
        sent: Vec::new(),
    };
    let out =
        stream::run_watched(&mut link, &options(tmp.path(), None), &Silent, &mut watcher).unwrap();
    assert!(out.manifest.device_stopped);
    // The watcher's command went out on the link, once.
    let commands: Vec<protocol::Command> = link
        .sent
        .iter()
        .map(|m| protocol::decode::<protocol::Command>(m).unwrap().1)
        .collect();
    assert_eq!(commands.iter().filter(|&&c| c == BAD_LEDS).count(), 1);
    // Every tile placed was shown, with the pixels the strip holds.
    assert!(!watcher.tiles.is_empty());
    assert_eq!(watcher.tiles.len() as u64, out.manifest.tiles_received);
    let strip = image::open(tmp.path().join("strip.png"))
        .unwrap()
        .to_luma8();
    let first = watcher.tiles[0].0;
    for (index, pixels) in &watcher.tiles {
        let at = (index - first) as usize * pixels.len();
        assert_eq!(&strip.as_raw()[at..at + pixels.len()], &pixels[..]);
    }
}

/// Plays some messages, then fails as a device pulled out mid-session does.
struct Unplugged {
    messages: std::collections::VecDeque<Vec<u8>>,
}

impl Transport for Unplugged {
    fn send(&mut self, _: &[u8]) -> Result<(), link::Error> {
        Ok(())
    }
    fn receive(&mut self, buf: &mut [u8], _: Duration) -> Result<Received, link::Error> {
        let m = self
            .messages
            .pop_front()
            .ok_or_else(|| link::Error::Other("no such device".into()))?;
        buf[..m.len()].copy_from_slice(&m);
        Ok(Received::Message(m.len()))
    }
    fn is_live(&self) -> bool {
        false
    }
}

/// A kept roll whose link fails midway is recorded failed with every segment whole on
/// disk, the rows collected since the last full one included.
#[test]
fn a_failed_session_s_roll_lists_every_segment_it_wrote() {
    let messages = clean_stream();
    let tmp = tempfile::tempdir().unwrap();
    let db = tmp.path().join("records.db");
    let keep = rollfuse::records::KeepRoll {
        records: db.to_string_lossy().into_owned(),
        start: rollfuse_records::RollStart {
            source: "unplugged".into(),
            line: "1".into(),
            device: "sim".into(),
            configuration: "{}".into(),
            out: String::new(),
            mm_per_row: None,
        },
        mm_per_px: None,
    };
    let opts = Options {
        keep: Some(keep),
        // Not a whole number of tiles a segment: the last rows are a short segment.
        segment_rows: 40,
        ..options(tmp.path(), None)
    };
    let mut unplugged = Unplugged {
        messages: messages[..messages.len() / 2].iter().cloned().collect(),
    };
    let Err(err) = stream::run(&mut unplugged, &opts, &Silent) else {
        panic!("the session did not fail");
    };
    let mut records = rollfuse_records::Records::open(&db.to_string_lossy()).unwrap();
    let roll = records.roll(1).unwrap();
    assert_eq!(roll.summary.status, "failed", "{err:#}");
    let strip = tmp.path().join("strip.png");
    let on_disk = rollfuse::strip_file::StripWriter::segments_on_disk(&strip, 0);
    assert!(on_disk.len() >= 2, "{on_disk:?}");
    assert_eq!(roll.segment_list.len(), on_disk.len(), "{roll:?}");
    for s in &roll.segment_list {
        assert!(s.matches_file(&tmp.path().join(&s.file)), "{s:?}");
    }
    let last = roll.segment_list.last().unwrap();
    assert!(last.rows < 40, "the short last segment is kept: {roll:?}");
}

/// A session whose link fails midway keeps its recording, every message taken before
/// the failure, so the device's data can be replayed; but it never replaces an older
/// recording of the same name.
#[test]
fn a_failed_session_keeps_its_recording_but_never_over_an_older_one() {
    let messages = clean_stream();
    let taken = messages.len() / 2;
    let tmp = tempfile::tempdir().unwrap();
    let rec = tmp.path().join("rec.bin");
    let unplugged = || Unplugged {
        messages: messages[..taken].iter().cloned().collect(),
    };
    let Err(err) = stream::run(&mut unplugged(), &options(tmp.path(), Some(&rec)), &Silent) else {
        panic!("the session did not fail");
    };
    assert!(format!("{err:#}").contains("no such device"), "{err:#}");
    assert!(format!("{err:#}").contains("rec.bin"), "{err:#}");
    // The recording holds exactly the messages taken, and plays back.
    let mut replay = rollfuse::link::replay::Replay::open(&rec).unwrap();
    let mut buf = vec![0u8; 2 * MAX_MESSAGE];
    let mut played = Vec::new();
    while let Received::Message(n) = replay.receive(&mut buf, Duration::ZERO).unwrap() {
        played.push(buf[..n].to_vec());
    }
    assert_eq!(played, messages[..taken]);
    // Again over that recording: the failed session leaves it as it was.
    let before = std::fs::read(&rec).unwrap();
    let short = Unplugged {
        messages: messages[..2].iter().cloned().collect(),
    };
    let Err(err) = stream::run(&mut { short }, &options(tmp.path(), Some(&rec)), &Silent) else {
        panic!("the session did not fail");
    };
    assert!(format!("{err:#}").contains("left as it was"), "{err:#}");
    assert_eq!(
        std::fs::read(&rec).unwrap(),
        before,
        "the older recording changed"
    );
    let leftovers: Vec<_> = std::fs::read_dir(tmp.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .filter(|n| n.to_string_lossy().starts_with('.'))
        .collect();
    assert!(leftovers.is_empty(), "temporaries left: {leftovers:?}");
}

/// A live device whose first tile is replaced by one of another size (a stray tile, as a
/// session before this one could leave in flight), same number and index.
struct StrayFirstTile<T> {
    link: T,
    replaced: bool,
}

impl<T: Transport> Transport for StrayFirstTile<T> {
    fn send(&mut self, message: &[u8]) -> Result<(), link::Error> {
        self.link.send(message)
    }

    fn receive(&mut self, buf: &mut [u8], timeout: Duration) -> Result<Received, link::Error> {
        let got = self.link.receive(buf, timeout)?;
        let Received::Message(n) = got else {
            return Ok(got);
        };
        let stray = match protocol::decode::<DeviceMessage>(&buf[..n]) {
            Ok((header, DeviceMessage::Tile(t))) if !self.replaced => {
                tile_message(header.seq, t.index, (t.width / 2, t.height), 200)
            }
            _ => return Ok(got),
        };
        self.replaced = true;
        buf[..stray.len()].copy_from_slice(&stray);
        Ok(Received::Message(stray.len()))
    }

    fn is_live(&self) -> bool {
        true
    }
}

#[test]
fn a_stray_first_tile_of_another_size_is_the_one_refused() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/letters.toml");
    let mut scene = Scene::load(&path).unwrap();
    scene.sensor.frames = 10;
    let tmp = tempfile::tempdir().unwrap();
    let clean = stream::run(
        &mut SimDevice::start(&scene).unwrap(),
        &options(&tmp.path().join("clean"), None),
        &Silent,
    )
    .unwrap();
    let mut link = StrayFirstTile {
        link: SimDevice::start(&scene).unwrap(),
        replaced: false,
    };
    let out = stream::run(
        &mut link,
        &options(&tmp.path().join("stray"), None),
        &Silent,
    )
    .unwrap();
    assert!(link.replaced);
    let (m, c) = (&out.manifest, &clean.manifest);
    assert_eq!(m.faults.mismatched_tiles, 1);
    assert_eq!(m.tiles_received + 1, c.tiles_received);
    // The strip is the clean run's from its second tile on.
    let strip = |dir: &str| {
        image::open(tmp.path().join(dir).join("strip.png"))
            .unwrap()
            .to_luma8()
            .into_raw()
    };
    let (clean_strip, stray_strip) = (strip("clean"), strip("stray"));
    let tile_bytes = clean_strip.len() / c.tiles_received as usize;
    assert_eq!(clean_strip[tile_bytes..], stray_strip[..]);
}

/// `rollfuse stream` of the letters scene's first tiles with `extra` options: the
/// manifest and the strip's width.
fn streamed(extra: &[&str]) -> (serde_json::Value, u32, String) {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("s");
    let scene = format!("{}/scenes/letters.toml", env!("CARGO_MANIFEST_DIR"));
    let mut args = vec![
        "stream",
        "--device",
        "sim",
        "--scene",
        &scene,
        "--out",
        out.to_str().unwrap(),
        "--tiles",
        "3",
    ];
    args.extend_from_slice(extra);
    let run = rollfuse(&args);
    let stdout = String::from_utf8_lossy(&run.stdout).into_owned();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap();
    let width = image::open(out.join("strip.png")).unwrap().width();
    (manifest, width, stdout)
}

#[test]
fn a_stream_runs_the_modules_defaults_and_its_manifest_names_the_tiles_configuration() {
    let (m, width, stdout) = streamed(&[]);
    // The module's defaults: db2, 1 level, the camera's full 320 columns.
    assert_eq!(width, 320);
    assert_eq!(m["tile_size"], serde_json::json!([320, 16]));
    let configs = m["configurations"].as_array().unwrap();
    assert_eq!(configs.len(), 1, "{m}");
    let c = &configs[0];
    assert_eq!(c["from_tile"], m["index_range"][0]);
    assert_eq!(c["config"]["wavelet"], "Db2");
    assert_eq!(c["config"]["levels"], 1);
    assert_eq!(c["config"]["downsample"], 1);
    assert_eq!(c["tile_size"], m["tile_size"]);
    assert!(
        stdout.contains(": db2, 1 level, 1× (tiles 320 × 16)"),
        "{stdout}"
    );

    let (m, width, _) = streamed(&["--downsample", "2", "--levels", "2"]);
    assert_eq!(width, 160);
    let c = &m["configurations"][0];
    assert_eq!(c["config"]["downsample"], 2);
    assert_eq!(c["config"]["levels"], 2);
    assert_eq!(c["tile_size"], serde_json::json!([160, 16]));
    assert_eq!(c["tile_size"], m["tile_size"]);
    // What the device announced before it was configured is kept apart.
    assert_eq!(m["device"]["config"]["downsample"], 1);
}

/// An info message of a 320 × 240 gray camera running `config`.
fn info_message(seq: u32, config: protocol::DeviceConfig) -> Vec<u8> {
    let info = DeviceMessage::Info(protocol::DeviceInfo {
        firmware: [1, 0, 0],
        sensor_width: 320,
        sensor_height: 240,
        pixel_format: protocol::PixelFormat::Gray8,
        config,
        max_tile_bytes: 16_000,
    });
    encoded(seq, &info)
}

#[test]
fn a_reconfiguration_is_recorded_from_the_tile_it_applies_to() {
    let full = protocol::DeviceConfig::default();
    let halved = protocol::DeviceConfig {
        downsample: 2,
        ..full
    };
    let messages = vec![
        info_message(0, full),
        tile_message(1, 0, (320, 16), 10),
        tile_message(2, 1, (320, 16), 11),
        info_message(3, halved),
        tile_message(4, 2, (160, 16), 12),
    ];
    let tmp = tempfile::tempdir().unwrap();
    let mut link = Scripted {
        messages: messages.into_iter(),
    };
    let m = stream::run(&mut link, &options(tmp.path(), None), &Silent)
        .unwrap()
        .manifest;
    let from: Vec<_> = m
        .configurations
        .iter()
        .map(|c| (c.from_tile, c.config.downsample, c.tile_size))
        .collect();
    assert_eq!(
        from,
        [(Some(0), 1, [320, 16]), (Some(2), 2, [160, 16])],
        "{m:?}"
    );
    // One strip holds one tile size: the later tiles are counted, not placed.
    assert_eq!(m.faults.mismatched_tiles, 1);

    // A recording whose only description predates its tiles' configuration names none.
    let messages = vec![info_message(0, full), tile_message(1, 0, (160, 16), 10)];
    let mut link = Scripted {
        messages: messages.into_iter(),
    };
    let m = stream::run(&mut link, &options(tmp.path(), None), &Silent)
        .unwrap()
        .manifest;
    assert!(m.configurations.is_empty(), "{m:?}");
    assert_eq!(m.tiles_received, 1);
}

/// A recording's bytes from its messages.
fn recording_of(messages: &[Vec<u8>]) -> Vec<u8> {
    let mut bytes = b"RFSTRM01".to_vec();
    for m in messages {
        bytes.extend((m.len() as u32).to_le_bytes());
        bytes.extend(m);
    }
    bytes
}

/// Replays `bytes` from the command line: the manifest, and stderr.
fn replayed(bytes: &[u8]) -> (serde_json::Value, String) {
    let tmp = tempfile::tempdir().unwrap();
    let rec = tmp.path().join("rec.bin");
    std::fs::write(&rec, bytes).unwrap();
    let out = tmp.path().join("s");
    let o = rollfuse(&[
        "stream",
        "--device",
        &format!("replay:{}", rec.display()),
        "--out",
        out.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(o.status.success(), "{err}");
    let manifest = std::fs::read(out.join("manifest.json")).unwrap();
    (serde_json::from_slice(&manifest).unwrap(), err)
}

/// A flipped bit in a length prefix near the end, and two recordings joined: every tile
/// the damage did not touch is kept, and the damage is said.
#[test]
fn a_damaged_or_joined_recording_keeps_every_tile_around_the_damage() {
    let messages = clean_stream();
    let good = recording_of(messages);
    let (clean, _) = replayed(&good);
    let tiles = clean["tiles_received"].as_u64().unwrap();
    // The length prefix of the third message from the end, its top byte flipped.
    let k = messages.len() - 3;
    let at = 8 + messages[..k].iter().map(|m| 4 + m.len()).sum::<usize>();
    let mut damaged = good.clone();
    damaged[at + 3] ^= 0x40;
    let (manifest, err) = replayed(&damaged);
    let kept = manifest["tiles_received"].as_u64().unwrap();
    assert!(kept + 1 >= tiles && kept > 0, "{kept} of {tiles} tiles");
    assert!(err.contains("damaged bytes skipped in 1 places"), "{err}");
    // Two recordings joined with cat: the second's tiles repeat the first's indices, so
    // they are counted as repeats; every message of both is read.
    let mut joined = good.clone();
    joined.extend(&good);
    let (manifest, err) = replayed(&joined);
    assert_eq!(
        manifest["messages"].as_u64().unwrap(),
        2 * clean["messages"].as_u64().unwrap()
    );
    assert!(err.contains("2 joined recordings"), "{err}");
}
