//! The HTTP/1.1 the live page needs and no more: one request a connection, its head
//! parsed by `httparse`, every size and every wait bounded, no request body ever read
//! into memory.
//!
//! | what a client sends | what it gets |
//! | --- | --- |
//! | a head (request line and headers) over [`MAX_HEAD_BYTES`] | 431, connection closed |
//! | more than [`MAX_HEADERS`] headers | 431 |
//! | a target over [`MAX_TARGET_BYTES`] | 414 |
//! | no complete head within [`HEAD_TIMEOUT`] | 408 |
//! | a version other than HTTP/1.0 or 1.1 | 505 |
//! | anything else that does not parse | 400 |
//! | a body (any `Content-Length`, any `Transfer-Encoding`) | the answer, then the connection closed; at most [`DRAIN_BYTES`] of the body are read and dropped |
//!
//! An answer that cannot be written within [`WRITE_TIMEOUT`] is abandoned.

use std::io::{Read, Write};
use std::net::{Shutdown, TcpStream};
use std::time::{Duration, Instant};

/// The largest request head taken, bytes.
pub const MAX_HEAD_BYTES: usize = 16 * 1024;
/// The most headers a request may have.
pub const MAX_HEADERS: usize = 32;
/// The longest request target (path and query), bytes.
pub const MAX_TARGET_BYTES: usize = 2048;
/// How long a client has to send its whole request head.
pub const HEAD_TIMEOUT: Duration = Duration::from_secs(10);
/// How long one write of an answer may wait for a client that does not read.
pub const WRITE_TIMEOUT: Duration = Duration::from_secs(10);
/// The most of an unread body dropped before the connection closes (so the client sees
/// the answer rather than a reset), and how long that may take.
pub const DRAIN_BYTES: u64 = 64 * 1024;
const DRAIN_TIME: Duration = Duration::from_millis(200);

/// A request's head.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Request {
    /// `GET`, `HEAD`, `POST`, … as sent.
    pub method: String,
    /// The path and query as sent.
    pub target: String,
    /// HTTP/1.`minor`.
    pub minor: u8,
    /// Header names and values (values not UTF-8 are dropped).
    pub headers: Vec<(String, String)>,
}

impl Request {
    /// The first value of header `name` (case-insensitive).
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(n, _)| n.eq_ignore_ascii_case(name))
            .map(|(_, v)| v.as_str())
    }

    /// The target's path and its query (empty without one).
    pub fn path_and_query(&self) -> (&str, &str) {
        self.target.split_once('?').unwrap_or((&self.target, ""))
    }

    /// Whether a body follows the head.
    pub fn has_body(&self) -> bool {
        self.header("Transfer-Encoding").is_some()
            || self
                .header("Content-Length")
                .is_some_and(|v| v.trim() != "0")
    }
}

/// An answer held in memory.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Answer {
    /// Status code.
    pub code: u16,
    /// `Content-Type`.
    pub content_type: &'static str,
    /// Further headers.
    pub headers: Vec<(&'static str, String)>,
    /// The body.
    pub body: Vec<u8>,
}

impl Answer {
    /// An answer of `body` as `content_type`, never cached.
    pub fn new(code: u16, content_type: &'static str, body: Vec<u8>) -> Self {
        Self {
            code,
            content_type,
            headers: Vec::new(),
            body,
        }
    }

    /// A one-line plain-text answer.
    pub fn text(code: u16, message: &str) -> Self {
        Self::new(
            code,
            "text/plain; charset=utf-8",
            format!("{message}\n").into_bytes(),
        )
    }

    /// The answer with one more header.
    pub fn with_header(mut self, name: &'static str, value: &str) -> Self {
        self.headers.push((name, value.to_string()));
        self
    }
}

/// The reason phrase of the codes answered.
fn reason(code: u16) -> &'static str {
    match code {
        200 => "OK",
        202 => "Accepted",
        400 => "Bad Request",
        401 => "Unauthorized",
        403 => "Forbidden",
        404 => "Not Found",
        405 => "Method Not Allowed",
        408 => "Request Timeout",
        409 => "Conflict",
        414 => "URI Too Long",
        421 => "Misdirected Request",
        431 => "Request Header Fields Too Large",
        500 => "Internal Server Error",
        503 => "Service Unavailable",
        505 => "HTTP Version Not Supported",
        _ => "",
    }
}

/// Writes `answer` (its head only when `head_only`: a `HEAD` request); the connection
/// closes after it.
pub fn write_answer(out: &mut impl Write, answer: &Answer, head_only: bool) -> std::io::Result<()> {
    let mut head = format!(
        "HTTP/1.1 {} {}\r\nContent-Type: {}\r\nContent-Length: {}\r\nCache-Control: no-store\r\nConnection: close\r\n",
        answer.code,
        reason(answer.code),
        answer.content_type,
        answer.body.len()
    );
    for (name, value) in &answer.headers {
        head.push_str(&format!("{name}: {value}\r\n"));
    }
    head.push_str("\r\n");
    out.write_all(head.as_bytes())?;
    if !head_only {
        out.write_all(&answer.body)?;
    }
    out.flush()
}

/// Why no request was read.
#[derive(Debug, PartialEq, Eq)]
pub enum NoRequest {
    /// Answer this and close.
    Refuse(Answer),
    /// The client went away (or sent nothing at all): close without a word.
    Gone,
}

/// Reads one request head from `stream`, within [`HEAD_TIMEOUT`] and [`MAX_HEAD_BYTES`].
pub fn read_request(stream: &mut TcpStream) -> Result<Request, NoRequest> {
    let deadline = Instant::now() + HEAD_TIMEOUT;
    let mut head = Vec::with_capacity(1024);
    let mut chunk = [0u8; 2048];
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() || stream.set_read_timeout(Some(left)).is_err() {
            return Err(timed_out(&head));
        }
        let n = match stream.read(&mut chunk) {
            Ok(0) => return Err(NoRequest::Gone),
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) =>
            {
                return Err(timed_out(&head));
            }
            Err(_) => return Err(NoRequest::Gone),
        };
        let searched_from = head.len().saturating_sub(3);
        head.extend_from_slice(&chunk[..n]);
        if let Some(end) = find_end(&head[searched_from..]) {
            return parse(&head[..searched_from + end]);
        }
        if head.len() > MAX_HEAD_BYTES {
            return Err(too_large());
        }
    }
}

fn timed_out(head: &[u8]) -> NoRequest {
    if head.is_empty() {
        NoRequest::Gone
    } else {
        NoRequest::Refuse(Answer::text(
            408,
            &format!(
                "the request's head did not arrive within {} s",
                HEAD_TIMEOUT.as_secs()
            ),
        ))
    }
}

fn too_large() -> NoRequest {
    NoRequest::Refuse(Answer::text(
        431,
        &format!("the request's head is over {MAX_HEAD_BYTES} bytes or {MAX_HEADERS} headers"),
    ))
}

/// Where the blank line ending a head ends in `bytes`.
fn find_end(bytes: &[u8]) -> Option<usize> {
    bytes
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .map(|i| i + 4)
}

/// Parses a complete head (ending in its blank line).
pub fn parse(head: &[u8]) -> Result<Request, NoRequest> {
    if head.len() > MAX_HEAD_BYTES {
        return Err(too_large());
    }
    let mut headers = [httparse::EMPTY_HEADER; MAX_HEADERS];
    let mut request = httparse::Request::new(&mut headers);
    match request.parse(head) {
        Ok(httparse::Status::Complete(_)) => {}
        Ok(httparse::Status::Partial) => return Err(bad("the request's head is incomplete")),
        Err(httparse::Error::TooManyHeaders) => return Err(too_large()),
        Err(httparse::Error::Version) => {
            return Err(NoRequest::Refuse(Answer::text(
                505,
                "this server speaks HTTP/1.0 and HTTP/1.1 only",
            )));
        }
        Err(e) => return Err(bad(&format!("the request does not parse: {e}"))),
    }
    let (Some(method), Some(target), Some(minor)) = (request.method, request.path, request.version)
    else {
        return Err(bad("the request line is incomplete"));
    };
    if target.len() > MAX_TARGET_BYTES {
        return Err(NoRequest::Refuse(Answer::text(
            414,
            &format!("the request's target is over {MAX_TARGET_BYTES} bytes"),
        )));
    }
    Ok(Request {
        method: method.to_string(),
        target: target.to_string(),
        minor,
        headers: request
            .headers
            .iter()
            .filter_map(|h| {
                Some((
                    h.name.to_string(),
                    std::str::from_utf8(h.value).ok()?.to_string(),
                ))
            })
            .collect(),
    })
}

fn bad(message: &str) -> NoRequest {
    NoRequest::Refuse(Answer::text(400, message))
}

/// Closes a connection whose answer is written: the sending side first, then at most
/// [`DRAIN_BYTES`] of what the client still sends (an unread body) are dropped, so the
/// client reads the answer instead of a reset.
pub fn close(mut stream: TcpStream) {
    let _ = stream.flush();
    let _ = stream.shutdown(Shutdown::Write);
    if stream.set_read_timeout(Some(DRAIN_TIME)).is_ok() {
        let _ = std::io::copy(&mut (&mut stream).take(DRAIN_BYTES), &mut std::io::sink());
    }
}

/// Whether `host` (a `Host` header's value) names this server: an IP address (which no
/// other site's page can be served from, so DNS rebinding cannot use it), `localhost`, or
/// one of `allowed`; a port, if any, is not looked at.
pub fn known_host(host: &str, allowed: &[String]) -> bool {
    let host = host.trim();
    let name = if let Some(rest) = host.strip_prefix('[') {
        // [IPv6]:port
        match rest.split_once(']') {
            Some((ip, _)) => return ip.parse::<std::net::Ipv6Addr>().is_ok(),
            None => return false,
        }
    } else {
        match host.rsplit_once(':') {
            Some((name, port)) if port.bytes().all(|b| b.is_ascii_digit()) => name,
            _ => host,
        }
    };
    name.parse::<std::net::Ipv4Addr>().is_ok()
        || name.eq_ignore_ascii_case("localhost")
        || allowed.iter().any(|a| a.eq_ignore_ascii_case(name))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn refused_with(head: &[u8]) -> u16 {
        match parse(head) {
            Err(NoRequest::Refuse(a)) => a.code,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_request_head_parses_into_its_parts() {
        let r = parse(
            b"GET /strip.png?rows=9 HTTP/1.1\r\nHost: 127.0.0.1:8\r\nContent-Length: 0\r\n\r\n",
        )
        .unwrap();
        assert_eq!(
            (r.method.as_str(), r.target.as_str(), r.minor),
            ("GET", "/strip.png?rows=9", 1)
        );
        assert_eq!(r.header("host"), Some("127.0.0.1:8"));
        assert!(!r.has_body());
        let r = parse(b"POST /x HTTP/1.0\r\ncontent-length: 9223372036854775807\r\n\r\n").unwrap();
        assert!(r.has_body());
    }

    #[test]
    fn heads_out_of_bounds_are_refused_with_their_code() {
        assert_eq!(refused_with(b"GET / HTTP/2.0\r\n\r\n"), 505);
        assert_eq!(refused_with(b"GET / HTTP/1.1\r\nno colon\r\n\r\n"), 400);
        let many: String = (0..=MAX_HEADERS).map(|i| format!("X-{i}: 1\r\n")).collect();
        assert_eq!(
            refused_with(format!("GET / HTTP/1.1\r\n{many}\r\n").as_bytes()),
            431
        );
        let long = "a".repeat(MAX_TARGET_BYTES);
        assert_eq!(
            refused_with(format!("GET /{long} HTTP/1.1\r\n\r\n").as_bytes()),
            414
        );
    }

    #[test]
    fn only_addresses_localhost_and_allowed_names_are_known_hosts() {
        let allowed = vec!["line3.plant".to_string()];
        for host in [
            "127.0.0.1:8080",
            "192.168.1.9",
            "[::1]:80",
            "localhost:1",
            "LINE3.plant:80",
        ] {
            assert!(known_host(host, &allowed), "{host}");
        }
        for host in [
            "evil.example:8080",
            "127.0.0.1.evil.example",
            "[::1",
            "",
            "localhost.evil",
        ] {
            assert!(!known_host(host, &allowed), "{host}");
        }
    }

    #[test]
    fn an_answer_is_written_with_its_length_and_without_a_body_for_head() {
        let mut out = Vec::new();
        let a = Answer::text(404, "no").with_header("X-A", "b");
        write_answer(&mut out, &a, false).unwrap();
        let text = String::from_utf8(out).unwrap();
        assert!(text.starts_with("HTTP/1.1 404 Not Found\r\n"), "{text}");
        assert!(text.contains("Content-Length: 3\r\n") && text.contains("X-A: b\r\n"));
        assert!(text.ends_with("\r\n\r\nno\n"), "{text}");
        let mut out = Vec::new();
        write_answer(&mut out, &a, true).unwrap();
        assert!(String::from_utf8(out).unwrap().ends_with("\r\n\r\n"));
    }
}
