//! `stream --serve` over real HTTP on a loopback port: the endpoints and their errors, the
//! event stream delivering every tile in order, the control token, clients that read
//! slowly or not at all, and the command line's outputs unchanged by serving.

use crate::common::rollfuse;
use rollfuse::detect::Detector;
use rollfuse::link::sim::{DeviceMemory, SimDevice};
use rollfuse::progress::Silent;
use rollfuse::serve::{ServeOptions, Server};
use rollfuse::sim::Scene;
use rollfuse::stream::{self, Options, Outcome};
use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use crate::session::{letters, options};

fn serve_options(control: bool) -> ServeOptions {
    ServeOptions {
        addr: "127.0.0.1:0".parse().unwrap(),
        control,
        source: "sim".into(),
        live: true,
        allowed_hosts: Vec::new(),
        records: None,
    }
}

fn server(control: bool) -> Server {
    Server::start(&serve_options(control)).unwrap()
}

/// Streams `scene` from the virtual device into `out`, feeding `server`, and finishes it.
fn stream_served(scene: &Scene, out: &Path, server: &Server) -> Outcome {
    let mut dev = SimDevice::start(scene).unwrap();
    let outcome = stream::run_watched(&mut dev, &options(out), &Silent, &mut server.watcher());
    let outcome = outcome.unwrap();
    server.finish(&outcome.manifest);
    outcome
}

fn agent() -> ureq::Agent {
    let config = ureq::Agent::config_builder()
        .http_status_as_error(false)
        .timeout_global(Some(Duration::from_secs(60)))
        .build();
    ureq::Agent::new_with_config(config)
}

/// Status and body of a GET.
fn get(server: &Server, path: &str) -> (u16, Vec<u8>) {
    let url = format!("http://{}{path}", server.addr());
    let mut response = agent().get(&url).call().unwrap();
    let status = response.status().as_u16();
    (status, response.body_mut().read_to_vec().unwrap())
}

/// Status of a POST with the given token, if any.
fn post(server: &Server, path: &str, token: Option<&str>) -> u16 {
    let url = format!("http://{}{path}", server.addr());
    let mut request = agent().post(&url);
    if let Some(t) = token {
        request = request.header("Authorization", &format!("Bearer {t}"));
    }
    request.send_empty().unwrap().status().as_u16()
}

/// A tile event's index and pixels.
struct TileEvent {
    index: u32,
    pixels: Vec<u8>,
}

/// What a client read from `/events`.
struct Events {
    tiles: Vec<TileEvent>,
    /// Every event's name, in order.
    names: Vec<String>,
    /// The `defects` events' payloads.
    defects: Vec<serde_json::Value>,
}

/// Reads `/events` until the stream's end.
fn read_events(reader: impl Read) -> Events {
    use base64::Engine;
    let (mut tiles, mut names, mut defects) = (Vec::new(), Vec::new(), Vec::new());
    let mut name = String::new();
    for line in BufReader::new(reader).lines() {
        let line = line.unwrap();
        if let Some(n) = line.strip_prefix("event: ") {
            name = n.to_string();
            names.push(name.clone());
        } else if let Some(data) = line.strip_prefix("data: ") {
            let json: serde_json::Value = serde_json::from_str(data).unwrap();
            if name == "tile" {
                let b64 = json["pixels"].as_str().unwrap();
                tiles.push(TileEvent {
                    index: json["index"].as_u64().unwrap() as u32,
                    pixels: base64::engine::general_purpose::STANDARD
                        .decode(b64)
                        .unwrap(),
                });
            }
            if name == "defects" {
                defects.push(json.clone());
            }
            if name == "end" {
                break;
            }
        }
    }
    Events {
        tiles,
        names,
        defects,
    }
}

/// Opens `/events` and reads it on a thread until the end.
fn follow(server: &Server) -> std::thread::JoinHandle<Events> {
    let url = format!("http://{}/events", server.addr());
    let response = agent().get(&url).call().unwrap();
    assert_eq!(response.status().as_u16(), 200);
    std::thread::spawn(move || read_events(response.into_body().into_reader()))
}

/// The strip's rows as 8-bit gray: width and pixels.
fn strip_pixels(png: &[u8]) -> (u32, u32, Vec<u8>) {
    let img = image::load_from_memory(png).unwrap().to_luma8();
    (img.width(), img.height(), img.into_raw())
}

#[test]
fn endpoints_answer_with_the_strip_and_status_and_refuse_bad_requests() {
    let tmp = tempfile::tempdir().unwrap();
    let server = server(false);
    assert_eq!(get(&server, "/strip.png").0, 503, "no tile yet");
    let outcome = stream_served(&letters(36), tmp.path(), &server);
    let status: serde_json::Value =
        serde_json::from_slice(&get(&server, "/status.json").1).unwrap();
    assert_eq!(status["tiles"], outcome.manifest.tiles_received);
    assert_eq!(status["bytes"], outcome.manifest.bytes);
    assert_eq!(status["state"], "ended");
    assert_eq!(
        status["last_tile_index"],
        outcome.manifest.index_range.unwrap()[1]
    );
    // The newest 64 rows are the last 64 rows of the strip written to disk.
    let (code, png) = get(&server, "/strip.png?rows=64");
    assert_eq!(code, 200);
    let (w, h, served) = strip_pixels(&png);
    let (fw, fh, file) = strip_pixels(&std::fs::read(tmp.path().join("strip.png")).unwrap());
    assert_eq!((w, h), (fw, 64));
    assert_eq!(served, file[((fh - 64) * fw) as usize..]);
    let (code, page) = get(&server, "/");
    assert_eq!(code, 200);
    let page = String::from_utf8(page).unwrap();
    assert!(page.contains("<canvas") && !page.contains("src=\"http"));
    for (path, code) in [
        ("/strip.png?rows=0", 400),
        ("/strip.png?rows=4097", 400),
        ("/strip.png?rows=ten", 400),
        ("/nothing-here", 404),
    ] {
        assert_eq!(get(&server, path).0, code, "{path}");
    }
    assert_eq!(post(&server, "/status.json", None), 405);
}

#[test]
fn events_deliver_every_tile_in_order_with_its_pixels() {
    let tmp = tempfile::tempdir().unwrap();
    let server = server(false);
    let reader = follow(&server);
    let outcome = stream_served(&letters(36), tmp.path(), &server);
    let Events { tiles, names, .. } = reader.join().unwrap();
    assert_eq!(tiles.len() as u64, outcome.manifest.tiles_received);
    assert!(tiles.windows(2).all(|w| w[1].index == w[0].index + 1));
    assert_eq!(names.last().map(String::as_str), Some("end"));
    assert!(!names.iter().any(|n| n == "skipped"));
    let (_, _, file) = strip_pixels(&std::fs::read(tmp.path().join("strip.png")).unwrap());
    let all: Vec<u8> = tiles.iter().flat_map(|t| t.pixels.clone()).collect();
    assert_eq!(all, file);
}

#[test]
fn control_needs_the_token_and_without_it_changes_nothing() {
    let scene = letters(12);
    let tmp = tempfile::tempdir().unwrap();
    let roller_after = |server: &Server| {
        let outcome = stream_served(&scene, tmp.path(), server);
        outcome.manifest.device_counters.unwrap().roller_running
    };
    let controlled = server(true);
    let token = controlled.token().unwrap().to_string();
    let start = "/control/roller/start?speed_um_s=20000";
    assert_eq!(post(&controlled, start, None), 401);
    assert_eq!(
        post(&controlled, start, Some("0123456789abcdef0123456789abcdef")),
        401
    );
    assert!(
        !roller_after(&controlled),
        "a refused request reached the device"
    );
    let controlled = server(true);
    let token_now = controlled.token().unwrap().to_string();
    assert_ne!(token_now, token, "each server has its own token");
    assert_eq!(
        post(
            &controlled,
            "/control/roller/start?speed_um_s=0",
            Some(&token_now)
        ),
        400
    );
    assert_eq!(post(&controlled, "/control/nothing", Some(&token_now)), 404);
    assert_eq!(post(&controlled, start, Some(&token_now)), 202);
    assert!(
        roller_after(&controlled),
        "the command did not reach the device"
    );
    // Without --control no command is taken, token or not.
    assert_eq!(post(&server(false), start, Some(&token_now)), 403);
}

/// Every strip file byte for byte, and the manifest but for what the session's heartbeat
/// moves (a live device answers one status a second of wall time, so the message and byte
/// counts follow the run's duration, served or not).
fn assert_same_outputs(a: &Path, b: &Path) {
    let names = |d: &Path| {
        let mut v: Vec<_> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        v.sort();
        v
    };
    assert_eq!(names(a), names(b));
    for name in names(a) {
        let (x, y) = (
            std::fs::read(a.join(&name)).unwrap(),
            std::fs::read(b.join(&name)).unwrap(),
        );
        if name == "manifest.json" {
            assert_eq!(without_heartbeat(&x), without_heartbeat(&y));
        } else {
            assert!(x == y, "{name:?} differs");
        }
    }
}

fn without_heartbeat(manifest: &[u8]) -> serde_json::Value {
    let mut m: serde_json::Value = serde_json::from_slice(manifest).unwrap();
    let o = m.as_object_mut().unwrap();
    o.remove("messages");
    o.remove("bytes");
    o["device_counters"]
        .as_object_mut()
        .unwrap()
        .remove("messages_sent");
    m
}

/// A client that asks for `/events` and then never reads a byte.
fn stuck_client(server: &Server) -> std::net::TcpStream {
    let mut s = std::net::TcpStream::connect(server.addr()).unwrap();
    write!(s, "GET /events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n").unwrap();
    s
}

#[test]
fn stuck_and_many_clients_change_nothing_in_the_stream() {
    let scene = letters(120);
    let plain = tempfile::tempdir().unwrap();
    let mut dev = SimDevice::start_with(&scene, DeviceMemory::Firmware).unwrap();
    let unwatched = stream::run(&mut dev, &options(plain.path()), &Silent).unwrap();
    let served = tempfile::tempdir().unwrap();
    let server = server(false);
    let _stuck: Vec<_> = (0..3).map(|_| stuck_client(&server)).collect();
    let readers: Vec<_> = (0..20).map(|_| follow(&server)).collect();
    let outcome = stream_served(&scene, served.path(), &server);
    assert_eq!(
        outcome.manifest.tiles_received,
        unwatched.manifest.tiles_received
    );
    assert_same_outputs(plain.path(), served.path());
    for r in readers {
        let tiles = r.join().unwrap().tiles;
        assert!(tiles.windows(2).all(|w| w[0].index < w[1].index));
    }
}

fn scene_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/letters.toml")
}

#[test]
fn the_command_line_writes_the_same_files_with_and_without_serve() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = scene_path();
    let run = |name: &str, extra: &[&str]| {
        let out = tmp.path().join(name);
        let mut args = vec!["stream", "--device", "sim", "--scene"];
        args.extend([scene.to_str().unwrap(), "--out", out.to_str().unwrap()]);
        args.extend(extra);
        let o = rollfuse(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        (out, String::from_utf8(o.stdout).unwrap())
    };
    let (plain, _) = run("plain", &[]);
    let (served, said) = run("served", &["--serve", "127.0.0.1:0", "--control"]);
    assert!(said.contains("live page: http://127.0.0.1:"), "{said}");
    assert!(said.contains("control token: "), "{said}");
    assert_same_outputs(&plain, &served);
}

#[test]
fn the_command_line_refuses_bad_serve_options_clearly() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let scene = scene_path();
    let base = [
        "stream",
        "--device",
        "sim",
        "--scene",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let in_use = taken.local_addr().unwrap().to_string();
    for (extra, says) in [
        (
            vec!["--serve", "localhost"],
            "--serve must be an IP address and port",
        ),
        (vec!["--serve", &in_use], "cannot serve on"),
        (vec!["--control"], "--serve"),
        (
            vec!["--serve", "0.0.0.0:0", "--control"],
            "--allow-remote-control",
        ),
        (vec!["--keep-serving"], "--serve"),
        (vec!["--frame-rate", "0"], "--frame-rate must be from"),
    ] {
        let mut args = base.to_vec();
        args.extend(extra.iter().copied());
        let o = rollfuse(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && err.contains(says),
            "{extra:?}: {err}"
        );
        // A port in use, like every failed start, leaves no output folder behind.
        assert!(!out.exists(), "{extra:?} left {}", out.display());
    }
}

#[test]
fn after_the_end_a_new_client_gets_the_strip_and_the_end_and_commands_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let server = server(true);
    let outcome = stream_served(&letters(36), tmp.path(), &server);
    // Read to the end of the body: the connection closes after `end`.
    let (code, body) = get(&server, "/events");
    assert_eq!(code, 200);
    let Events { tiles, names, .. } = read_events(&body[..]);
    assert_eq!(tiles.len() as u64, outcome.manifest.tiles_received);
    assert_eq!(names.last().map(String::as_str), Some("end"));
    let (_, _, file) = strip_pixels(&std::fs::read(tmp.path().join("strip.png")).unwrap());
    let all: Vec<u8> = tiles.iter().flat_map(|t| t.pixels.clone()).collect();
    assert_eq!(all, file);
    let token = server.token().unwrap().to_string();
    assert_eq!(post(&server, "/control/roller/stop", Some(&token)), 409);
    assert_eq!(post(&server, "/control/roller/stop", None), 401);
}

#[test]
fn keep_serving_keeps_the_page_up_after_the_stream_with_its_files_written() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let scene = scene_path();
    let mut child = Command::new(env!("CARGO_BIN_EXE_rollfuse"))
        .args([
            "stream",
            "--device",
            "sim",
            "--scene",
            scene.to_str().unwrap(),
        ])
        .args(["--out", out.to_str().unwrap(), "--serve", "127.0.0.1:0"])
        .arg("--keep-serving")
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let stdout = child.stdout.take().unwrap();
    // The line that says the stream ended and where the page stays; None if the process
    // ended (its stdout closed) without saying it.
    let ended = BufReader::new(stdout)
        .lines()
        .map_while(Result::ok)
        .find(|l| l.contains("the page stays up at http://"));
    let checked = ended.map(|line| {
        let addr = line
            .split("http://")
            .nth(1)
            .unwrap()
            .split('/')
            .next()
            .unwrap();
        let get = |path: &str| {
            let mut r = agent().get(&format!("http://{addr}{path}")).call().unwrap();
            (r.status().as_u16(), r.body_mut().read_to_vec().unwrap())
        };
        let status: serde_json::Value = serde_json::from_slice(&get("/status.json").1).unwrap();
        let (code, png) = get("/strip.png?rows=16");
        let manifest = std::fs::read(out.join("manifest.json")).ok();
        (status, code, png, manifest)
    });
    let still_running = child.try_wait().unwrap().is_none();
    let _ = child.kill();
    let _ = child.wait();
    let (status, code, png, manifest) = checked.expect("the command never said the page stays up");
    assert!(still_running, "the command exited instead of serving on");
    assert_eq!(status["state"], "ended");
    assert_eq!(code, 200);
    assert_eq!(strip_pixels(&png).1, 16);
    let manifest: serde_json::Value = serde_json::from_slice(&manifest.unwrap()).unwrap();
    assert_eq!(manifest["tiles_received"], status["tiles"]);
}

#[test]
fn a_replayed_stream_takes_no_commands() {
    let server = Server::start(&ServeOptions {
        addr: "127.0.0.1:0".parse().unwrap(),
        control: true,
        source: "replay".into(),
        live: false,
        allowed_hosts: Vec::new(),
        records: None,
    })
    .unwrap();
    let token = server.token().unwrap().to_string();
    assert_eq!(post(&server, "/control/roller/stop", Some(&token)), 409);
}

/// Boxes `[x0, y0, x1, y1]` overlap: intersection over union.
fn iou(a: [f64; 4], b: [f64; 4]) -> f64 {
    let w = (a[2].min(b[2]) - a[0].max(b[0])).max(0.0);
    let h = (a[3].min(b[3]) - a[1].max(b[1])).max(0.0);
    let area = |r: [f64; 4]| (r[2] - r[0]) * (r[3] - r[1]);
    w * h / (area(a) + area(b) - w * h)
}

#[test]
fn the_detector_boxes_the_strips_defects_before_the_stream_ends() {
    let tmp = tempfile::tempdir().unwrap();
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/textile.toml");
    let scene = Scene::load(&path).unwrap();
    let detector = Detector::built_in().unwrap();
    let live = rollfuse::serve::detect::LiveModel::Defects(Box::new(detector));
    let server = Server::start_detecting(&serve_options(false), Some(live)).unwrap();
    let reader = follow(&server);
    stream_served(&scene, tmp.path(), &server);
    let Events {
        tiles,
        names,
        defects,
    } = reader.join().unwrap();
    // Every box reaches the page before it is told the stream ended.
    assert_eq!(names.last().map(String::as_str), Some("end"));
    assert!(!defects.is_empty());
    let summary = &defects.last().unwrap()["detector"];
    let strip_rows = tiles.len() * 16;
    assert_eq!(summary["rows_checked"], strip_rows, "every row checked");
    assert_eq!(summary["rows_skipped"], 0);
    assert_eq!(summary["fabric"], "twill_2_2", "the scene's fabric");
    let status: serde_json::Value =
        serde_json::from_slice(&get(&server, "/status.json").1).unwrap();
    assert_eq!(&status["detector"], summary);
    // The defects `rollfuse detect` finds on the strip written (the device streams the
    // camera's scale by default), each boxed on the page with its kind (the page's rows are belt rows: the file's from the
    // first tile's).
    let live: Vec<(String, [f64; 4])> = defects
        .iter()
        .flat_map(|d| d["boxes"].as_array().unwrap().clone())
        .map(|b| {
            let r: Vec<f64> = b["strip_box"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect();
            (
                b["kind"].as_str().unwrap().to_string(),
                [r[0], r[1], r[2], r[3]],
            )
        })
        .collect();
    let run = rollfuse(&[
        "detect",
        tmp.path().join("strip.png").to_str().unwrap(),
        "--json",
        tmp.path().join("found.json").to_str().unwrap(),
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let found: serde_json::Value =
        serde_json::from_slice(&std::fs::read(tmp.path().join("found.json")).unwrap()).unwrap();
    let offline = found[0]["defects"].as_array().unwrap();
    assert!(!offline.is_empty(), "the scene has defects");
    assert_eq!(live.len(), offline.len(), "{live:?}\n{offline:?}");
    for d in offline {
        let r: Vec<f64> = d["box_px"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let kind = d["kind"].as_str().unwrap();
        let top = f64::from(tiles[0].index * 16);
        let on_belt = [r[0], r[1] + top, r[2], r[3] + top];
        assert!(
            live.iter()
                .any(|(k, b)| k == kind && iou(*b, on_belt) >= 0.3),
            "{kind} at {on_belt:?} on the belt is not on the page: {live:?}"
        );
    }
}

#[test]
fn without_the_detector_the_status_says_none() {
    let server = server(false);
    let status: serde_json::Value =
        serde_json::from_slice(&get(&server, "/status.json").1).unwrap();
    assert!(status["detector"].is_null());
}

#[test]
fn the_page_shows_the_configuration_the_tiles_are_made_with() {
    let tmp = tempfile::tempdir().unwrap();
    let server = server(false);
    let mut dev = SimDevice::start(&letters(12)).unwrap();
    let opts = Options {
        config: Some(rollfuse_core::protocol::DeviceConfig {
            downsample: 2,
            ..dev.default_config()
        }),
        ..options(tmp.path())
    };
    let outcome = stream::run_watched(&mut dev, &opts, &Silent, &mut server.watcher()).unwrap();
    server.finish(&outcome.manifest);
    let status: serde_json::Value =
        serde_json::from_slice(&get(&server, "/status.json").1).unwrap();
    // Not the 1× the device announced before it was configured.
    assert_eq!(status["device"]["config"]["downsample"], 2, "{status}");
    assert_eq!(status["tile_size"], serde_json::json!([160, 16]));
}

#[test]
fn the_page_shows_the_roll_s_map_and_its_line_s_last_rolls_from_the_records() {
    let tmp = tempfile::tempdir().unwrap();
    let (out, db) = (tmp.path().join("roll"), tmp.path().join("records.db"));
    let db = db.to_str().unwrap().to_string();
    let strip = std::path::absolute(stream::output_files(&out)[0].clone()).unwrap();
    let server = Server::start(&ServeOptions {
        records: Some(rollfuse::serve::records::RollView {
            records: db.clone(),
            line: "3".into(),
            strip,
        }),
        ..serve_options(false)
    })
    .unwrap();
    assert_eq!(get(&server, "/roll.svg").0, 404, "no roll yet");
    let keep = rollfuse::records::KeepRoll {
        records: db,
        start: rollfuse_records::RollStart {
            source: "the page's test".into(),
            line: "3".into(),
            device: "sim".into(),
            configuration: "{}".into(),
            out: String::new(),
            mm_per_row: None,
        },
        mm_per_px: Some(0.05),
    };
    let opts = stream::Options {
        keep: Some(keep),
        segment_rows: 64,
        ..options(&out)
    };
    let mut dev = SimDevice::start(&letters(12)).unwrap();
    let outcome = stream::run_watched(&mut dev, &opts, &Silent, &mut server.watcher()).unwrap();
    server.finish(&outcome.manifest);
    // The records are read every 2 s: the roll appears by the next reading.
    let mut shown = serde_json::Value::Null;
    for _ in 0..100 {
        let (code, body) = get(&server, "/rolls.json");
        assert_eq!(code, 200);
        shown = serde_json::from_slice(&body).unwrap();
        if shown["rolls"][0]["status"] == "complete" {
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    assert_eq!(shown["line"], "3", "{shown}");
    assert_eq!(shown["current"], 1, "{shown}");
    assert_eq!(shown["rolls"][0]["status"], "complete", "{shown}");
    assert!(shown["error"].is_null(), "{shown}");
    let (code, svg) = get(&server, "/roll.svg");
    assert_eq!(code, 200);
    assert!(String::from_utf8(svg).unwrap().starts_with("<svg"));
    let status: serde_json::Value =
        serde_json::from_slice(&get(&server, "/status.json").1).unwrap();
    assert_eq!(status["records"], true);
    // Without --records there is nothing to show.
    let plain = Server::start(&serve_options(false)).unwrap();
    assert_eq!(get(&plain, "/rolls.json").0, 404);
}
