//! The live page's server against requests meant to knock it over, on a loopback port,
//! while a stream runs: a body announced as 2⁶³ bytes, a header that never ends, 600
//! connections that send nothing, foreign Host headers, HTTP/2 request lines, long
//! paths. Each gets its answer (or is closed), the page keeps answering, and the stream
//! finishes with the same strip as without the server.

use rollfuse::link::sim::SimDevice;
use rollfuse::progress::Silent;
use rollfuse::serve::http::{MAX_HEAD_BYTES, MAX_TARGET_BYTES};
use rollfuse::serve::{MAX_REQUESTS, ServeOptions, Server};
use rollfuse::sim::Scene;
use rollfuse::stream;
use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::time::Duration;

use crate::session::{letters, options};

fn server() -> Server {
    Server::start(&ServeOptions {
        addr: "127.0.0.1:0".parse().unwrap(),
        control: false,
        source: "sim".into(),
        live: true,
        allowed_hosts: vec!["line3.plant".into()],
        records: None,
    })
    .unwrap()
}

fn connect(server: &Server) -> TcpStream {
    let s = TcpStream::connect(server.addr()).unwrap();
    // Reads end on the server's answer and close; a minute is only a guard against a hang.
    s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    s
}

/// Sends `bytes` (as much as the server takes: it may close early) and reads the answer
/// to the end: its status code (0: closed without one) and the whole text.
fn exchange(server: &Server, bytes: &[u8]) -> (u16, String) {
    let mut s = connect(server);
    let _ = s.write_all(bytes);
    let mut answer = Vec::new();
    let _ = s.read_to_end(&mut answer);
    let text = String::from_utf8_lossy(&answer).to_string();
    let code = text
        .strip_prefix("HTTP/1.1 ")
        .and_then(|t| t.get(..3))
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    (code, text)
}

fn get(server: &Server, target: &str) -> u16 {
    exchange(
        server,
        format!("GET {target} HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n").as_bytes(),
    )
    .0
}

/// The strip's files of a stream of `scene` with nothing served.
fn unserved(scene: &Scene, out: &Path) {
    let mut dev = SimDevice::start(scene).unwrap();
    stream::run(&mut dev, &options(out), &Silent).unwrap();
}

fn strip(dir: &Path) -> Vec<u8> {
    std::fs::read(dir.join("strip.png")).unwrap()
}

#[test]
fn huge_bodies_endless_headers_and_odd_requests_get_answers_and_the_stream_its_strip() {
    let scene = letters(80);
    let server = server();
    let served = tempfile::tempdir().unwrap();
    let streaming = {
        let (scene, out, mut watch) =
            (scene.clone(), served.path().to_path_buf(), server.watcher());
        std::thread::spawn(move || {
            let mut dev = SimDevice::start(&scene).unwrap();
            stream::run_watched(&mut dev, &options(&out), &Silent, &mut watch).unwrap()
        })
    };
    // A body announced as 2⁶³ − 1 bytes is never read into memory: the status comes back.
    let (code, text) = exchange(
        &server,
        b"GET /status.json HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 9223372036854775807\r\n\r\n",
    );
    assert_eq!(code, 200, "{text}");
    assert!(text.contains("\"source\""), "{text}");
    let (code, _) = exchange(
        &server,
        b"POST /control/roller/stop HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 100000000000\r\n\r\nxxxx",
    );
    assert_eq!(code, 403);
    // A header line that never ends: refused once the head passes its limit.
    let mut endless = b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Long: ".to_vec();
    endless.resize(endless.len() + 4 * MAX_HEAD_BYTES, b'a');
    assert_eq!(exchange(&server, &endless).0, 431);
    // Names this server does not go by (DNS rebinding) and versions it does not speak.
    let (code, _) = exchange(
        &server,
        b"GET /status.json HTTP/1.1\r\nHost: evil.example:80\r\n\r\n",
    );
    assert_eq!(code, 421);
    let (code, _) = exchange(
        &server,
        b"GET /status.json HTTP/1.1\r\nHost: line3.plant\r\n\r\n",
    );
    assert_eq!(code, 200);
    assert_eq!(
        exchange(&server, b"GET /status.json HTTP/1.1\r\n\r\n").0,
        400
    );
    assert_eq!(exchange(&server, b"GET / HTTP/2.0\r\n\r\n").0, 505);
    let just_over = format!("/{}", "p".repeat(MAX_TARGET_BYTES));
    assert_eq!(get(&server, &just_over), 414);
    let (code, text) = exchange(
        &server,
        format!(
            "GET /{} HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n",
            "q".repeat(1000)
        )
        .as_bytes(),
    );
    assert_eq!(code, 404);
    assert!(
        text.len() < 600,
        "a 404 repeats its whole path: {} bytes",
        text.len()
    );
    // HEAD gets the head alone.
    let (code, text) = exchange(
        &server,
        b"HEAD /status.json HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n",
    );
    assert_eq!(code, 200);
    assert!(text.ends_with("\r\n\r\n"), "{text}");

    let outcome = streaming.join().unwrap();
    server.finish(&outcome.manifest);
    assert_eq!(get(&server, "/status.json"), 200);
    let plain = tempfile::tempdir().unwrap();
    unserved(&scene, plain.path());
    assert!(
        strip(plain.path()) == strip(served.path()),
        "the strips differ"
    );
}

#[test]
fn six_hundred_idle_connections_are_turned_away_and_the_page_comes_back() {
    let server = server();
    let idle: Vec<TcpStream> = (0..600).map(|_| connect(&server)).collect();
    // Those past the limit are told so and closed at once; the rest wait for a request.
    let mut busy = 0;
    for mut s in idle.iter().skip(MAX_REQUESTS) {
        let mut answer = String::new();
        let _ = s.read_to_string(&mut answer);
        assert!(answer.starts_with("HTTP/1.1 503 "), "{answer:?}");
        busy += 1;
    }
    assert_eq!(busy, 600 - MAX_REQUESTS);
    // The idle ones go; their places are free again.
    drop(idle);
    let mut answered = get(&server, "/status.json");
    for _ in 0..100 {
        if answered == 200 {
            break;
        }
        // The server may not have seen every idle connection close yet.
        std::thread::sleep(Duration::from_millis(50));
        answered = get(&server, "/status.json");
    }
    assert_eq!(answered, 200);
}
