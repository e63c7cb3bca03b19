//! Fuzzing the live page's request path: request heads built from pieces a client could
//! send (methods, targets, versions, headers with huge or lying values, foreign hosts),
//! then bytes flipped, inserted or cut, are parsed and sent to a running server over a
//! loopback socket. The parser never panics and keeps its limits; the server answers
//! each with a status line (or closes an incomplete head without a word) and still
//! answers `/status.json` after every one.
//!
//! The cases run per test run are `ROLLFUSE_FUZZ_CASES` (default 64); failures proptest
//! finds are kept in `http_fuzz.proptest-regressions` beside this file and replayed
//! first on every run.

use proptest::prelude::*;
use rollfuse::serve::http::{MAX_HEAD_BYTES, MAX_HEADERS, MAX_TARGET_BYTES, NoRequest, parse};
use rollfuse::serve::{ServeOptions, Server};
use std::io::{Read, Write};
use std::net::{Shutdown, TcpStream};
use std::sync::OnceLock;
use std::time::Duration;

fn cases() -> u32 {
    std::env::var("ROLLFUSE_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(64)
}

/// One server for every case, with control on so control paths are reached.
fn server() -> &'static Server {
    static SERVER: OnceLock<Server> = OnceLock::new();
    SERVER.get_or_init(|| {
        Server::start(&ServeOptions {
            addr: "127.0.0.1:0".parse().unwrap(),
            control: true,
            source: "sim".into(),
            live: true,
            allowed_hosts: Vec::new(),
            records: None,
        })
        .unwrap()
    })
}

/// Sends `bytes`, closes the sending side, and reads the answer to its end.
fn send(bytes: &[u8]) -> Vec<u8> {
    let mut s = TcpStream::connect(server().addr()).unwrap();
    // Only a guard against a hang: every answer comes at once.
    s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    let _ = s.write_all(bytes);
    let _ = s.shutdown(Shutdown::Write);
    let mut answer = Vec::new();
    let _ = s.read_to_end(&mut answer);
    answer
}

fn method() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("GET".to_string()),
        Just("HEAD".to_string()),
        Just("POST".to_string()),
        Just("PUT".to_string()),
        "[A-Z]{1,12}",
    ]
}

fn target() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("/".to_string()),
        Just("/status.json".to_string()),
        Just("/strip.png?rows=99999999999999999999".to_string()),
        Just("/strip.png?rows=-1&rows=2".to_string()),
        Just("/control/roller/start?speed_um_s=4294967296".to_string()),
        Just("/control/roller/stop".to_string()),
        Just("/../../etc/passwd".to_string()),
        Just("http://evil.example/status.json".to_string()),
        "/[ -~]{0,64}",
        (0usize..3 * MAX_TARGET_BYTES).prop_map(|n| format!("/{}", "a".repeat(n))),
    ]
}

fn version() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("HTTP/1.1".to_string()),
        Just("HTTP/1.0".to_string()),
        Just("HTTP/2.0".to_string()),
        Just("HTTP/0.9".to_string()),
        "[ -~]{0,10}",
    ]
}

fn header() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("Host: 127.0.0.1".to_string()),
        Just("Host: evil.example".to_string()),
        Just("Content-Length: 9223372036854775807".to_string()),
        Just("Content-Length: -1".to_string()),
        Just("Transfer-Encoding: chunked".to_string()),
        Just("Authorization: Bearer 00000000000000000000000000000000".to_string()),
        "[A-Za-z-]{1,20}: [ -~]{0,80}",
        (0usize..2 * MAX_HEAD_BYTES).prop_map(|n| format!("X-Long: {}", "b".repeat(n))),
    ]
}

/// A head from its pieces, then damaged: (position, byte) replacements, an insertion, a
/// cut.
fn request() -> impl Strategy<Value = Vec<u8>> {
    (
        method(),
        target(),
        version(),
        prop::collection::vec(header(), 0..(MAX_HEADERS + 4)),
        prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..4),
        prop::option::of((
            any::<prop::sample::Index>(),
            prop::collection::vec(any::<u8>(), 1..16),
        )),
        prop::option::of(any::<prop::sample::Index>()),
    )
        .prop_map(|(m, t, v, headers, flips, insert, cut)| {
            let mut bytes = format!(
                "{m} {t} {v}\r\n{}\r\n",
                headers
                    .iter()
                    .map(|h| format!("{h}\r\n"))
                    .collect::<String>()
            )
            .into_bytes();
            for (at, b) in flips {
                let i = at.index(bytes.len());
                bytes[i] = b;
            }
            if let Some((at, extra)) = insert {
                let i = at.index(bytes.len());
                bytes.splice(i..i, extra);
            }
            if let Some(at) = cut {
                bytes.truncate(at.index(bytes.len() + 1));
            }
            bytes
        })
}

/// The status code an answer starts with.
fn code(answer: &[u8]) -> Option<u16> {
    let text = std::str::from_utf8(answer.get(..12)?).ok()?;
    text.strip_prefix("HTTP/1.1 ")?.parse().ok()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases()))]

    #[test]
    fn any_request_head_gets_an_answer_within_the_limits(bytes in request()) {
        // The parser alone, on the head up to its blank line.
        let end = bytes.windows(4).position(|w| w == b"\r\n\r\n").map(|i| i + 4);
        if let Some(end) = end {
            match parse(&bytes[..end]) {
                Ok(r) => {
                    prop_assert!(r.target.len() <= MAX_TARGET_BYTES);
                    prop_assert!(r.headers.len() <= MAX_HEADERS);
                    prop_assert!(end <= MAX_HEAD_BYTES);
                }
                Err(NoRequest::Refuse(a)) => {
                    prop_assert!([400, 414, 431, 505].contains(&a.code), "{}", a.code);
                }
                Err(NoRequest::Gone) => prop_assert!(false, "a whole head is never Gone"),
            }
        }
        // Over the wire: a status line, or (a head never completed) a close.
        let answer = send(&bytes);
        match code(&answer) {
            Some(c) => prop_assert!((200..600).contains(&c), "{c}"),
            None => prop_assert!(
                answer.is_empty() && (end.is_none() || end.is_some_and(|e| e > MAX_HEAD_BYTES)),
                "no status line for a whole head: {:?}",
                String::from_utf8_lossy(&answer[..answer.len().min(200)])
            ),
        }
        // And the page still answers.
        let status = send(b"GET /status.json HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
        prop_assert_eq!(code(&status), Some(200));
    }
}
