//! The server's answers: the page, `/status.json`, `/strip.png`, `/events` and, with
//! `--control`, the commands.

use super::events;
use super::http::{self, Answer, NoRequest, Request};
use super::state::{COMMAND_QUEUE, KEPT_ROWS, Shared, lock};
use rollfuse_core::device::controller::MAX_SPEED_UM_S;
use rollfuse_core::protocol::{Command, RollerCommand};
use std::io::Write;
use std::net::TcpStream;
use std::sync::atomic::Ordering;

/// The page, with its script and style; it loads nothing else.
const PAGE: &str = include_str!("page.html");

/// Rows `/strip.png` gives without `?rows=`.
const DEFAULT_PNG_ROWS: usize = 512;

/// Belt speed a roller start asks for without `?speed_um_s=`, µm/s.
const DEFAULT_SPEED_UM_S: u32 = 10_000;

/// The most of an unknown path a 404 repeats, characters.
const ECHOED_PATH: usize = 120;

/// Answers the one request of a connection (an `/events` request holds its thread until
/// the client goes), then closes it.
pub fn handle(mut stream: TcpStream, shared: &Shared, allowed_hosts: &[String]) {
    let _ = stream.set_write_timeout(Some(http::WRITE_TIMEOUT));
    let request = match http::read_request(&mut stream) {
        Ok(r) => r,
        Err(NoRequest::Gone) => return,
        Err(NoRequest::Refuse(answer)) => {
            let _ = http::write_answer(&mut stream, &answer, false);
            return http::close(stream);
        }
    };
    let head_only = request.method == "HEAD";
    let reply = match request.header("Host") {
        None if request.minor >= 1 => Answer::text(400, "an HTTP/1.1 request needs a Host header"),
        Some(host) if !http::known_host(host, allowed_hosts) => Answer::text(
            421,
            "this server answers to its IP address and localhost (and names given with --allow-host)",
        ),
        _ if request.method == "GET"
            && request.path_and_query().0 == "/events"
            && !request.has_body() =>
        {
            return events_stream(stream, &request, shared);
        }
        _ => route(&request, shared),
    };
    // A client gone before its answer is no concern of the stream.
    let _ = http::write_answer(&mut stream, &reply, head_only);
    http::close(stream);
}

/// The answer to every request but an event stream.
fn route(request: &Request, shared: &Shared) -> Answer {
    let (path, query) = request.path_and_query();
    match (request.method.as_str(), path) {
        ("GET" | "HEAD", "/" | "/index.html") => {
            Answer::new(200, "text/html; charset=utf-8", PAGE.as_bytes().to_vec())
        }
        ("GET" | "HEAD", "/status.json") => status_json(shared),
        ("GET" | "HEAD", "/strip.png") => strip_png(shared, query),
        ("GET" | "HEAD", "/rolls.json") => rolls_json(shared),
        ("GET" | "HEAD", "/roll.svg") => roll_svg(shared),
        ("POST", p) if p.starts_with("/control/") => control(request, shared, p, query),
        (
            _,
            "/" | "/index.html" | "/status.json" | "/strip.png" | "/events" | "/rolls.json"
            | "/roll.svg",
        ) => Answer::text(405, "method not allowed: this path is read with GET"),
        (_, p) if p.starts_with("/control/") => Answer::text(405, "control requests are POST"),
        _ => {
            let shown: String = path.chars().take(ECHOED_PATH).collect();
            let more = if shown.len() < path.len() { "…" } else { "" };
            Answer::text(404, &format!("no such page: {shown}{more}"))
        }
    }
}

/// The records as last read: this roll's id, the line's last rolls, the last error.
fn rolls_json(shared: &Shared) -> Answer {
    match &*lock(&shared.records) {
        Some(shown) => {
            let json = serde_json::to_vec_pretty(shown).unwrap_or_default();
            Answer::new(200, "application/json", json)
        }
        None => Answer::text(404, "no records: the stream was started without --records"),
    }
}

/// This roll's map, as last drawn.
fn roll_svg(shared: &Shared) -> Answer {
    match lock(&shared.records).as_ref().and_then(|s| s.map.clone()) {
        Some(svg) => Answer::new(200, "image/svg+xml", svg.into_bytes()),
        None => Answer::text(
            404,
            "no roll map yet: the roll is recorded with its first segment, and mapped once \
             its scale is known",
        ),
    }
}

fn status_json(shared: &Shared) -> Answer {
    let json = serde_json::to_vec_pretty(&shared.status_now()).unwrap_or_default();
    Answer::new(200, "application/json", json)
}

/// The value of `name` in a query string.
fn query_value<'q>(query: &'q str, name: &str) -> Option<&'q str> {
    query
        .split('&')
        .filter_map(|kv| kv.split_once('='))
        .find_map(|(k, v)| (k == name).then_some(v))
}

/// `?rows=N`, checked: 1..=[`KEPT_ROWS`].
fn rows_asked(query: &str) -> Result<usize, String> {
    let Some(v) = query_value(query, "rows") else {
        return Ok(DEFAULT_PNG_ROWS);
    };
    match v.parse::<usize>() {
        Ok(n) if (1..=KEPT_ROWS).contains(&n) => Ok(n),
        _ => Err(format!(
            "rows must be a whole number from 1 to {KEPT_ROWS} (the rows kept), got `{v}`"
        )),
    }
}

fn strip_png(shared: &Shared, query: &str) -> Answer {
    let rows = match rows_asked(query) {
        Ok(n) => n,
        Err(message) => return Answer::text(400, &message),
    };
    let newest = lock(&shared.ring).newest_rows(rows);
    let Some((width, height, pixels)) = newest else {
        return Answer::text(503, "no tile has arrived yet");
    };
    match encode_png(width, height, &pixels) {
        Ok(png) => Answer::new(200, "image/png", png),
        Err(e) => Answer::text(500, &format!("cannot encode the strip: {e}")),
    }
}

/// 8-bit gray pixels as a PNG file's bytes.
fn encode_png(width: usize, height: usize, pixels: &[u8]) -> anyhow::Result<Vec<u8>> {
    use image::ImageEncoder;
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png).write_image(
        pixels,
        u32::try_from(width)?,
        u32::try_from(height)?,
        image::ExtendedColorType::L8,
    )?;
    Ok(png)
}

/// Hands the connection to the event stream: each event is written as it comes, one
/// chunk each (HTTP/1.1; HTTP/1.0 gets them plain), and the body ends with the feed, so
/// the client knows the stream is over.
fn events_stream(mut stream: TcpStream, request: &Request, shared: &Shared) {
    let (first, feed) = events::subscribe(shared);
    let chunked = request.minor >= 1;
    let head = format!(
        "HTTP/1.1 200 OK\r\nContent-Type: text/event-stream\r\nCache-Control: no-store\r\n\
         Connection: close\r\n{}\r\n",
        if chunked {
            "Transfer-Encoding: chunked\r\n"
        } else {
            ""
        }
    );
    if stream.write_all(head.as_bytes()).is_ok() {
        if chunked {
            events::serve_client(&mut Chunked(&mut stream), first, feed, shared);
            // The last chunk; a client already gone makes this fail, which changes nothing.
            let _ = stream.write_all(b"0\r\n\r\n");
        } else {
            events::serve_client(&mut stream, first, feed, shared);
        }
    }
    http::close(stream);
}

/// Writes each buffer as one HTTP/1.1 chunk (RFC 9112, section 7.1).
struct Chunked<W>(W);

impl<W: Write> Write for Chunked<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        // An empty chunk would end the body.
        if !buf.is_empty() {
            write!(self.0, "{:x}\r\n", buf.len())?;
            self.0.write_all(buf)?;
            self.0.write_all(b"\r\n")?;
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.0.flush()
    }
}

/// Whether the request carries the control token (`Authorization: Bearer TOKEN`).
fn authorized(request: &Request, token: &str) -> bool {
    request.headers.iter().any(|(name, value)| {
        name.eq_ignore_ascii_case("Authorization")
            && value
                .strip_prefix("Bearer ")
                .is_some_and(|given| same_secret(given.trim(), token))
    })
}

/// Compares two strings in time independent of where they differ.
fn same_secret(a: &str, b: &str) -> bool {
    a.len() == b.len() && a.bytes().zip(b.bytes()).fold(0u8, |d, (x, y)| d | (x ^ y)) == 0
}

/// A control request: checked (control on, token, live device), then queued for the
/// session to send.
fn control(request: &Request, shared: &Shared, path: &str, query: &str) -> Answer {
    let Some(token) = &shared.token else {
        return Answer::text(403, "control is off: start the stream with --control");
    };
    if !authorized(request, token) {
        return Answer::text(
            401,
            "a control request needs the token printed at start-up (Authorization: Bearer TOKEN)",
        )
        .with_header("WWW-Authenticate", "Bearer");
    }
    let command = match command_for(path, query) {
        Ok(c) => c,
        Err((code, message)) => return Answer::text(code, &message),
    };
    if !shared.live {
        return Answer::text(
            409,
            "the tiles come from a recording: there is no device to command",
        );
    }
    if shared.ended.load(Ordering::Acquire) {
        return Answer::text(
            409,
            "the stream has ended: there is no session to send commands",
        );
    }
    let mut queue = lock(&shared.commands);
    if queue.len() >= COMMAND_QUEUE {
        return Answer::text(503, "commands are waiting to be sent; try again");
    }
    queue.push_back(command);
    Answer::text(202, "queued for the device")
}

/// The command a control path names.
fn command_for(path: &str, query: &str) -> Result<Command, (u16, String)> {
    let speed = || -> Result<u32, (u16, String)> {
        let Some(v) = query_value(query, "speed_um_s") else {
            return Ok(DEFAULT_SPEED_UM_S);
        };
        match v.parse::<u32>() {
            Ok(s) if (1..=MAX_SPEED_UM_S).contains(&s) => Ok(s),
            _ => Err((
                400,
                format!("speed_um_s must be 1..={MAX_SPEED_UM_S}, got `{v}`"),
            )),
        }
    };
    Ok(match path {
        "/control/roller/start" => Command::Roller(RollerCommand::Start {
            speed_um_s: speed()?,
        }),
        "/control/roller/speed" => Command::Roller(RollerCommand::Speed {
            speed_um_s: speed()?,
        }),
        "/control/roller/stop" => Command::Roller(RollerCommand::Stop),
        _ => {
            return Err((
                404,
                format!(
                    "no such control: {path} (there are /control/roller/start, /control/roller/speed, /control/roller/stop)"
                ),
            ));
        }
    })
}

#[cfg(test)]
mod tests {
    use super::Chunked;
    use std::io::Write;

    /// Each write is one chunk, sized in hex; an empty write writes nothing (an empty
    /// chunk would end the body).
    #[test]
    fn each_write_is_one_chunk() {
        let mut out = Vec::new();
        let mut chunks = Chunked(&mut out);
        chunks.write_all(b"event: end\n\n").unwrap();
        chunks.write_all(b"").unwrap();
        chunks.write_all(&[b'x'; 300]).unwrap();
        let mut want = b"c\r\nevent: end\n\n\r\n12c\r\n".to_vec();
        want.extend([b'x'; 300]);
        want.extend(b"\r\n");
        assert_eq!(out, want);
    }
}
