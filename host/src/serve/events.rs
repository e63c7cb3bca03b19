//! `/events`: Server-Sent Events. Each client first gets the tiles the server keeps, then
//! every new tile and the status as they come, from its own bounded queue. A client that
//! falls behind is told how many rows it missed and goes on from the newest.

use super::findings::{DetectorStatus, LiveBox};
use super::state::{ClientFeed, Event, Shared, Status, TileRing, client_queue, lock};
use base64::Engine;
use std::io::Write;
use std::sync::atomic::Ordering;
use std::sync::mpsc::RecvTimeoutError;
use std::time::Duration;

/// How often an idle connection gets a comment line, so a client that is gone is noticed.
const KEEPALIVE: Duration = Duration::from_secs(10);

/// An event named `name` with a one-line JSON payload.
fn event(name: &str, json: &str, rows: u64) -> Event {
    Event {
        text: format!("event: {name}\ndata: {json}\n\n").into(),
        rows,
    }
}

/// A tile's event: its index, first belt row, size and pixels (8-bit gray, base64).
pub fn tile_event(index: u32, (width, height): (usize, usize), pixels: &[u8]) -> Event {
    let json = serde_json::json!({
        "index": index,
        "row": u64::from(index) * height as u64,
        "width": width,
        "rows": height,
        "pixels": base64::engine::general_purpose::STANDARD.encode(pixels),
    });
    event("tile", &json.to_string(), height as u64)
}

/// Whether `e` is the `end` event.
fn is_end(e: &Event) -> bool {
    e.text.starts_with("event: end\n")
}

/// The status's event; `end` once the session is over.
pub fn status_event(status: &Status) -> Event {
    let name = if status.state == "ended" {
        "end"
    } else {
        "status"
    };
    event(name, &serde_json::to_string(status).unwrap_or_default(), 0)
}

/// New defect boxes on the strip and the detector's summary.
pub fn defects_event(boxes: &[LiveBox], status: &DetectorStatus) -> Event {
    let json = serde_json::json!({ "boxes": boxes, "detector": status });
    event("defects", &json.to_string(), 0)
}

/// The marker a client gets after its queue overflowed.
fn skipped_event(rows: u64) -> Event {
    event("skipped", &format!("{{\"rows\":{rows}}}"), 0)
}

/// The tiles kept so far, oldest first, as events.
fn backlog(ring: &TileRing) -> Vec<Event> {
    let Some(size) = ring.size else {
        return Vec::new();
    };
    let tiles = ring.tiles.iter();
    tiles.map(|(&i, px)| tile_event(i, size, px)).collect()
}

/// Registers a client: the backlog and the status now, then its feed (none once the
/// session is over). Taken under the clients' lock, which the watcher holds while it
/// keeps and hands out a tile, so no tile is both in the backlog and in the feed, and
/// none is in neither.
pub fn subscribe(shared: &Shared) -> (Vec<Event>, ClientFeed) {
    let mut clients = lock(&shared.clients);
    let ring = lock(&shared.ring);
    let (queue, feed) = client_queue();
    let mut first = backlog(&ring);
    drop(ring);
    if shared.detecting {
        let findings = lock(&shared.findings);
        let kept: Vec<LiveBox> = findings.boxes.iter().copied().collect();
        first.push(defects_event(&kept, &findings.status));
    }
    // Once the session is over nothing more comes: the client gets the backlog and the
    // final status, and its feed ends at once (its queue dropped here).
    if !shared.ended.load(Ordering::Acquire) {
        clients.push(queue);
    }
    drop(clients);
    first.push(status_event(&shared.status_now()));
    (first, feed)
}

/// The session is over (its final status set): every client is sent `end` and its feed
/// ends. A client subscribing from now on is not registered; one registered before is
/// closed here.
pub fn end_all(shared: &Shared) {
    let status = shared.status_now();
    shared.ended.store(true, Ordering::Release);
    let mut clients = lock(&shared.clients);
    Shared::broadcast(&mut clients, &status_event(&status));
    drop(clients);
    shared.close_clients();
}

/// Writes the stream to one client until its feed ends or the client goes. A feed that
/// ends with the session ends with `end`, also where the client's full queue lost it.
pub fn serve_client(out: &mut dyn Write, first: Vec<Event>, feed: ClientFeed, shared: &Shared) {
    let _ = serve_client_inner(out, first, feed, shared);
}

fn serve_client_inner(
    out: &mut dyn Write,
    first: Vec<Event>,
    feed: ClientFeed,
    shared: &Shared,
) -> std::io::Result<()> {
    // Whether `end` has been written.
    let mut ended = false;
    for e in first {
        ended |= is_end(&e);
        out.write_all(e.text.as_bytes())?;
    }
    out.flush()?;
    loop {
        let next = match feed.events.recv_timeout(KEEPALIVE) {
            Ok(e) => e,
            Err(RecvTimeoutError::Timeout) => {
                out.write_all(b": keepalive\n\n")?;
                out.flush()?;
                continue;
            }
            Err(RecvTimeoutError::Disconnected) => {
                if !ended && shared.ended.load(Ordering::Acquire) {
                    out.write_all(status_event(&shared.status_now()).text.as_bytes())?;
                    out.flush()?;
                }
                return Ok(());
            }
        };
        let skipped = feed.skipped.swap(0, Ordering::Relaxed);
        if skipped > 0 {
            // Behind: what is queued is old too; drop it and go on from the newest.
            // The newest status among them is kept (it may be the end).
            let mut dropped = skipped + next.rows;
            let mut status = (next.rows == 0).then_some(next);
            while let Ok(e) = feed.events.try_recv() {
                dropped += e.rows;
                if e.rows == 0 {
                    status = Some(e);
                }
            }
            dropped += feed.skipped.swap(0, Ordering::Relaxed);
            out.write_all(skipped_event(dropped).text.as_bytes())?;
            if let Some(status) = status {
                ended |= is_end(&status);
                out.write_all(status.text.as_bytes())?;
            }
        } else {
            ended |= is_end(&next);
            out.write_all(next.text.as_bytes())?;
        }
        out.flush()?;
    }
}
