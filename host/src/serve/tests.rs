//! The client queue's behaviour without sockets: a client that does not read never holds
//! up the watcher, and once it reads again it is told what it missed and goes on from the
//! newest tiles.

use super::state::{Answering, CLIENT_QUEUE, Shared, Status, lock};
use super::{LiveWatch, events};
use crate::stream::{StreamRecord, Watch};
use rollfuse_core::protocol::Tile;
use std::io::Write;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, SyncSender};

/// A client whose every write waits until the test lets it go.
struct HeldClient {
    gate: Receiver<()>,
    written: SyncSender<Vec<u8>>,
}

impl Write for HeldClient {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.gate
            .recv()
            .map_err(|_| std::io::Error::other("released"))?;
        let _ = self.written.send(buf.to_vec());
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

pub(super) fn shared() -> Arc<Shared> {
    Arc::new(Shared {
        started: std::time::Instant::now(),
        token: None,
        live: false,
        status: std::sync::Mutex::new(Status::default()),
        ring: Default::default(),
        clients: Default::default(),
        commands: Default::default(),
        detecting: false,
        findings: Default::default(),
        ended: Default::default(),
        requests: Default::default(),
        request_done: Default::default(),
        records: Default::default(),
    })
}

fn tile(index: u32, pixels: &[u8]) -> Tile<'_> {
    Tile {
        index,
        width: 4,
        height: 2,
        observations: 1,
        pixels,
    }
}

/// The tile indices and skipped-row counts in an event stream, in order.
fn read_events(text: &str) -> (Vec<u64>, Vec<u64>) {
    let (mut tiles, mut skipped) = (Vec::new(), Vec::new());
    for block in text.split("\n\n") {
        let Some((name, data)) = block.split_once("\ndata: ") else {
            continue;
        };
        let json: serde_json::Value = serde_json::from_str(data).unwrap();
        match name {
            "event: tile" => tiles.push(json["index"].as_u64().unwrap()),
            "event: skipped" => skipped.push(json["rows"].as_u64().unwrap()),
            _ => {}
        }
    }
    (tiles, skipped)
}

/// A session's watcher feeding `shared`.
fn watcher(shared: &Arc<Shared>) -> LiveWatch {
    LiveWatch {
        shared: Arc::clone(shared),
        last_status: None,
        tile_size_shown: false,
        samples: Default::default(),
    }
}

/// An event client of `shared` on a thread of its own, writing to a [`HeldClient`]: each
/// send on `release` lets one write through, and `output` has what it wrote.
struct HeldFeed {
    client: std::thread::JoinHandle<()>,
    release: SyncSender<()>,
    output: Receiver<Vec<u8>>,
}

fn held_feed(shared: &Arc<Shared>) -> HeldFeed {
    held_answer(shared, None)
}

/// [`held_feed`], counted as a request being answered while `answering` is held.
fn held_answer(shared: &Arc<Shared>, answering: Option<Answering>) -> HeldFeed {
    let (release, gate) = std::sync::mpsc::sync_channel(0);
    let (written, output) = std::sync::mpsc::sync_channel(10_000);
    let (first, feed) = events::subscribe(shared);
    let client_shared = Arc::clone(shared);
    let client = std::thread::spawn(move || {
        let mut out = HeldClient { gate, written };
        events::serve_client(&mut out, first, feed, &client_shared);
        drop(answering);
    });
    HeldFeed {
        client,
        release,
        output,
    }
}

/// A watcher of `shared` and a client that cannot write a byte, after tiles `0..n` went
/// past it (each of `PIXELS`).
fn tiles_past_a_held_client(shared: &Arc<Shared>, n: u32) -> (LiveWatch, HeldFeed) {
    let mut watch = watcher(shared);
    let feed = held_feed(shared);
    for i in 0..n {
        watch.tile(&tile(i, &PIXELS), &StreamRecord::default());
    }
    (watch, feed)
}

/// The pixels of the tiles the held-client tests send.
const PIXELS: [u8; 8] = [7; 8];

#[test]
fn a_stuck_client_skips_rows_and_never_holds_up_the_watcher() {
    let shared = shared();
    // Four times the queue, while the client cannot write a byte: each call returns.
    let total = 4 * CLIENT_QUEUE as u32;
    let (mut watch, feed) = tiles_past_a_held_client(&shared, total);
    let HeldFeed {
        client,
        release,
        output,
    } = feed;
    // Let the client write again: it says what it skipped.
    let releaser = std::thread::spawn(move || while release.send(()).is_ok() {});
    let mut text = String::new();
    while !text.contains("event: skipped") {
        text += &String::from_utf8(output.recv().unwrap()).unwrap();
    }
    // Then it goes on from the newest tiles.
    for i in total..total + 10 {
        watch.tile(&tile(i, &PIXELS), &StreamRecord::default());
    }
    shared.close_clients();
    client.join().unwrap();
    releaser.join().unwrap();
    text.extend(output.try_iter().map(|b| String::from_utf8(b).unwrap()));
    let (tiles, skipped) = read_events(&text);
    // It skipped once, every row counted, and got the newest tiles in order.
    assert_eq!(skipped, vec![2 * u64::from(total)], "{text}");
    assert_eq!(
        tiles,
        (u64::from(total)..u64::from(total) + 10).collect::<Vec<_>>()
    );
    assert_eq!(lock(&shared.ring).tiles.len() as u32, total + 10);
}

/// A client whose queue was full when the session ended (so its `end` was lost there)
/// still gets `end` last, and one that subscribes after the end gets the kept tiles and
/// `end` and no feed.
#[test]
fn every_client_gets_the_end_even_when_its_queue_lost_it() {
    let shared = shared();
    let (_watch, feed) = tiles_past_a_held_client(&shared, 2 * CLIENT_QUEUE as u32);
    let HeldFeed {
        client,
        release,
        output,
    } = feed;
    lock(&shared.status).state = "ended";
    events::end_all(&shared);
    let releaser = std::thread::spawn(move || while release.send(()).is_ok() {});
    client.join().unwrap();
    releaser.join().unwrap();
    let text = written(&output);
    let names: Vec<&str> = text
        .lines()
        .filter_map(|l| l.strip_prefix("event: "))
        .collect();
    assert_eq!(names.last(), Some(&"end"), "{text}");
    assert_eq!(names.iter().filter(|&&n| n == "end").count(), 1);

    let (late_first, late_feed) = events::subscribe(&shared);
    assert!(
        late_first
            .last()
            .is_some_and(|e| e.text.starts_with("event: end\n"))
    );
    assert_eq!(
        late_first.len(),
        2 * CLIENT_QUEUE + 1,
        "every kept tile, then the end"
    );
    assert!(late_feed.events.recv().is_err(), "no feed after the end");
}

#[test]
fn the_detector_walks_every_kept_row_once_and_steps_over_a_jump() {
    let shared = shared();
    {
        let mut ring = lock(&shared.ring);
        // 20 tiles, then the belt index jumps by 980 tiles, then 20 more.
        for index in (0..20).chain(1000..1020) {
            ring.push(index, (8, 16), &[7; 8 * 16]);
        }
    }
    let detector = crate::detect::Detector::built_in().unwrap();
    let mut windows =
        super::detect::Windows::new(super::detect::LiveModel::Defects(Box::new(detector)));
    let mut owns = Vec::new();
    for last in [false, true] {
        while let Some(w) = windows.next_window(&shared, 2, last) {
            assert!(w.seen.start <= w.own.start && w.own.end <= w.seen.end);
            owns.push(w.own.clone());
            windows.done(&w);
        }
    }
    // Every row of a kept tile is in exactly one window's own rows, and no window is
    // spent on the rows of the tiles that never came.
    let kept: Vec<u64> = (0..320).chain(16_000..16_320).collect();
    let covered: Vec<u64> = owns.iter().flat_map(|o| o.clone()).collect();
    assert_eq!(covered, kept, "{owns:?}");
    assert_eq!(lock(&shared.findings).status.rows_skipped, 0);
}

/// The text a held client wrote so far.
fn written(output: &Receiver<Vec<u8>>) -> String {
    output
        .try_iter()
        .map(|b| String::from_utf8(b).unwrap())
        .collect()
}

/// A server going away waits for an event stream under way to write its `end`, so a
/// process that exits right after does not cut it off; a client that never reads holds
/// it only for the grace given.
#[test]
fn a_server_going_away_lets_the_answers_under_way_write_the_end() {
    let shared = shared();
    let answering = shared.begin_request().unwrap();
    let feed = held_answer(&shared, Some(answering));
    lock(&shared.status).state = "ended";
    events::end_all(&shared);
    assert!(
        !shared.wait_for_requests(std::time::Duration::ZERO),
        "still writing"
    );
    let release = feed.release;
    let releaser = std::thread::spawn(move || while release.send(()).is_ok() {});
    assert!(shared.wait_for_requests(std::time::Duration::from_secs(3600)));
    let text = written(&feed.output);
    assert!(text.contains("event: end\n"), "the end was written: {text}");
    feed.client.join().unwrap();
    releaser.join().unwrap();
}

/// A detector whose network gives no finite numbers (every weight NaN): the windows it
/// fails on are counted with the reason, and nothing is reported as checked and clean.
#[test]
fn a_failing_detector_is_counted_and_shown_never_clean() {
    let shared = shared();
    lock(&shared.status).device = Some(device_of_64_columns());
    {
        let mut ring = lock(&shared.ring);
        for index in 0..40 {
            let pixels: Vec<u8> = (0..64 * 16).map(|i| (i * 7 % 251) as u8).collect();
            ring.push(index, (64, 16), &pixels);
        }
    }
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("nan.safetensors");
    let net = crate::detect::net::Net::new(
        crate::detect::net::Widths([4, 8, 8, 8]),
        17,
        &burn::tensor::Device::flex(),
    );
    let about = crate::detect::model::About {
        widths: crate::detect::net::Widths([4, 8, 8, 8]),
        fabrics: (0..17).map(|i| format!("f{i}")).collect(),
        made_by: "test".into(),
        familiarity: None,
        threshold: None,
    };
    crate::detect::model::save(&path, &net, &about).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, all_nan(&bytes)).unwrap();
    let detector = crate::detect::Detector::load(&path).unwrap();
    super::detect::Windows::new(super::detect::LiveModel::Defects(Box::new(detector)))
        .run(&shared, &std::sync::atomic::AtomicBool::new(true));
    let status = lock(&shared.findings).status.clone();
    assert!(status.failures > 0, "{status:?}");
    let why = status.last_failure.clone().unwrap_or_default();
    assert!(why.contains("not finite"), "{why}");
    assert!(
        status.defects.is_empty() && status.fabric.is_none(),
        "{status:?}"
    );
}

/// A device that streams gray 64-pixel rows at the camera's scale.
fn device_of_64_columns() -> rollfuse_core::protocol::DeviceInfo {
    use rollfuse_core::protocol::{DeviceConfig, DeviceInfo, PixelFormat};
    DeviceInfo {
        firmware: [0, 1, 0],
        sensor_width: 64,
        sensor_height: 48,
        pixel_format: PixelFormat::Gray8,
        config: DeviceConfig::default(),
        max_tile_bytes: 1024,
    }
}

/// A gray image of `pixels`, row by row.
fn gray(width: usize, height: usize, pixels: impl Iterator<Item = u8>) -> crate::image::Planes {
    crate::image::Planes {
        width,
        height,
        planes: vec![pixels.map(f32::from).collect()],
    }
}

/// Cloth of the belt row `row`: a fine irregular texture.
fn cloth_row(row: usize) -> impl Iterator<Item = u8> {
    (0..64usize).map(move |c| (64 + (row * 37 + c * 11 + (row * c) % 23) * 7 % 128) as u8)
}

/// Anomaly mode on the live strip: a model of the clean cloth boxes the rows where a dark
/// patch passes, as kind `anomaly`, names no fabric, and checks every row once.
#[test]
fn anomaly_mode_boxes_what_departs_from_the_clean_cloth() {
    use crate::detect::anomaly::NormalModel;
    let shared = shared();
    lock(&shared.status).device = Some(device_of_64_columns());
    // A dark patch over belt rows 400..432, columns 16..40.
    let patch = |row: usize, col: usize| (400..432).contains(&row) && (16..40).contains(&col);
    {
        let mut ring = lock(&shared.ring);
        for index in 0..50u32 {
            let pixels: Vec<u8> = (0..16)
                .flat_map(|r| {
                    let row = index as usize * 16 + r;
                    cloth_row(row)
                        .enumerate()
                        .map(move |(c, v)| if patch(row, c) { 10 } else { v })
                })
                .collect();
            ring.push(index, (64, 16), &pixels);
        }
    }
    let clean: Vec<crate::image::Planes> = (0..6)
        .map(|k| gray(64, 96, (0..96).flat_map(|r| cloth_row(2000 + 96 * k + r))))
        .collect();
    let model = NormalModel::fit_every_row_alike(&clean).unwrap();
    super::detect::Windows::new(super::detect::LiveModel::Normal(model))
        .run(&shared, &std::sync::atomic::AtomicBool::new(true));
    let findings = lock(&shared.findings);
    let status = &findings.status;
    assert_eq!(
        (status.failures, status.rows_checked),
        (0, 800),
        "{status:?}"
    );
    assert!(status.fabric.is_none() && status.anomaly_mode, "{status:?}");
    assert!(!findings.boxes.is_empty(), "{status:?}");
    for b in &findings.boxes {
        let [x0, y0, x1, y1] = b.strip_box;
        assert_eq!(b.kind, "anomaly");
        assert!(b.score > 1.0, "{b:?}");
        assert!(
            y0 < 432.0 && 400.0 < y1 && x0 < 40.0 && 16.0 < x1,
            "{b:?} off the patch"
        );
    }
    assert_eq!(
        status.defects.get("anomaly"),
        Some(&(findings.boxes.len() as u64))
    );
}

/// A normal model of images of another width (another camera, another downsampling):
/// every window fails with both widths named, none is reported clean.
#[test]
fn anomaly_mode_on_a_strip_of_another_width_fails_with_the_reason() {
    use crate::detect::anomaly::NormalModel;
    let shared = shared();
    lock(&shared.status).device = Some(device_of_64_columns());
    {
        let mut ring = lock(&shared.ring);
        for index in 0..10u32 {
            let pixels: Vec<u8> = (0..16)
                .flat_map(|r| cloth_row(index as usize * 16 + r))
                .collect();
            ring.push(index, (64, 16), &pixels);
        }
    }
    let wide: Vec<crate::image::Planes> = (0..4)
        .map(|k| {
            let rows = (0..64).flat_map(|r| cloth_row(500 + 64 * k + r).chain(cloth_row(900 + r)));
            gray(128, 64, rows)
        })
        .collect();
    let model = NormalModel::fit_every_row_alike(&wide).unwrap();
    super::detect::Windows::new(super::detect::LiveModel::Normal(model))
        .run(&shared, &std::sync::atomic::AtomicBool::new(true));
    let status = lock(&shared.findings).status.clone();
    assert!(
        status.failures > 0 && status.defects.is_empty(),
        "{status:?}"
    );
    let why = status.last_failure.unwrap_or_default();
    assert!(
        why.contains("64 pixels wide") && why.contains("128 wide"),
        "{why}"
    );
}

/// A safetensors file's bytes with every F32 value NaN.
fn all_nan(bytes: &[u8]) -> Vec<u8> {
    use safetensors::{SafeTensors, tensor::TensorView};
    let (_, meta) = SafeTensors::read_metadata(bytes).unwrap();
    let file = SafeTensors::deserialize(bytes).unwrap();
    let nan: Vec<(String, safetensors::Dtype, Vec<usize>, Vec<u8>)> = file
        .tensors()
        .into_iter()
        .map(|(name, t)| {
            let data = f32::NAN.to_le_bytes().repeat(t.data().len() / 4);
            (name, t.dtype(), t.shape().to_vec(), data)
        })
        .collect();
    let views = nan.iter().map(|(name, dtype, shape, data)| {
        (
            name.clone(),
            TensorView::new(*dtype, shape.clone(), data).unwrap(),
        )
    });
    safetensors::serialize(views, meta.metadata().clone()).unwrap()
}
