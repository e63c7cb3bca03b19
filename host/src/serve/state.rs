//! What the server shares between the session's thread (the watcher) and the threads
//! answering requests: the newest tiles, the status, the event clients and the commands
//! waiting for the device. Every lock is held only to copy or push, never across I/O.

use super::findings::{DetectorStatus, Findings};
use crate::stream::{Faults, StreamRecord};
use rollfuse_core::protocol::{Command, DeviceInfo, StatusCounters};
use serde::Serialize;
use std::collections::{BTreeMap, VecDeque};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// Connections answered at once; beyond, a connection gets 503 and is closed (each
/// `/events` client counts, and so does a connection that has not sent its request yet,
/// for at most [`super::http::HEAD_TIMEOUT`]).
pub const MAX_REQUESTS: usize = 128;

/// Rows of the strip the server keeps in memory (the page shows as many; the strip's
/// files on disk hold the rest).
pub const KEPT_ROWS: usize = 4096;

/// Events waiting for one client before it counts as behind and skips ahead.
pub const CLIENT_QUEUE: usize = 64;

/// Commands waiting for the session to send them.
pub const COMMAND_QUEUE: usize = 8;

/// One event for the clients, serialized once and shared by all of them.
#[derive(Clone)]
pub struct Event {
    /// The event in the Server-Sent Events format, blank line included.
    pub text: Arc<str>,
    /// Strip rows it carries (counted when it is skipped).
    pub rows: u64,
}

/// The sending end of one client's queue.
pub struct ClientQueue {
    sender: SyncSender<Event>,
    /// Rows dropped since the client last caught up.
    skipped: Arc<AtomicU64>,
}

/// The receiving end of one client's queue.
pub struct ClientFeed {
    /// The events, in order.
    pub events: Receiver<Event>,
    /// Rows dropped because the queue was full; the client skips ahead when it is not 0.
    pub skipped: Arc<AtomicU64>,
}

/// A client's bounded queue: both ends.
pub fn client_queue() -> (ClientQueue, ClientFeed) {
    let (sender, events) = std::sync::mpsc::sync_channel(CLIENT_QUEUE);
    let skipped = Arc::new(AtomicU64::new(0));
    let feed = ClientFeed {
        events,
        skipped: Arc::clone(&skipped),
    };
    (ClientQueue { sender, skipped }, feed)
}

/// The newest tiles, by index, up to [`KEPT_ROWS`] rows.
#[derive(Default)]
pub struct TileRing {
    /// Tile width and height, pixels.
    pub size: Option<(usize, usize)>,
    /// Tile pixels by index.
    pub tiles: BTreeMap<u32, Arc<[u8]>>,
}

impl TileRing {
    /// Keeps a tile, dropping the oldest beyond [`KEPT_ROWS`] rows.
    pub fn push(&mut self, index: u32, size: (usize, usize), pixels: &[u8]) {
        self.size.get_or_insert(size);
        self.tiles.insert(index, Arc::from(pixels));
        let most = (KEPT_ROWS / size.1.max(1)).max(1);
        while self.tiles.len() > most {
            self.tiles.pop_first();
        }
    }

    /// The belt rows the kept tiles span, `first..end` (missing tiles within count).
    pub fn span(&self) -> Option<std::ops::Range<u64>> {
        let (_, height) = self.size?;
        let (&first, _) = self.tiles.first_key_value()?;
        let (&last, _) = self.tiles.last_key_value()?;
        Some(u64::from(first) * height as u64..(u64::from(last) + 1) * height as u64)
    }

    /// The first belt row at or after `row` that a kept tile holds.
    pub fn kept_row_from(&self, row: u64) -> Option<u64> {
        let height = self.size?.1 as u64;
        let (&index, _) = self.tiles.range((row / height) as u32..).next()?;
        Some((u64::from(index) * height).max(row))
    }

    /// The end (first row past it) of the run of consecutive kept tiles that holds `row`.
    pub fn kept_run_end(&self, row: u64) -> Option<u64> {
        let height = self.size?.1 as u64;
        let mut last = u32::try_from(row / height).ok()?;
        self.tiles.get(&last)?;
        for (&index, _) in self.tiles.range(last.checked_add(1)?..) {
            if index != last + 1 {
                break;
            }
            last = index;
        }
        Some((u64::from(last) + 1) * height)
    }

    /// Belt rows `rows` of the strip (clipped to what is kept), missing tiles black: width,
    /// the first row given, its height and pixels. None before the first tile.
    pub fn rows(&self, rows: std::ops::Range<u64>) -> Option<(usize, u64, usize, Vec<u8>)> {
        let (width, height) = self.size?;
        let span = self.span()?;
        let (start, end) = (
            rows.start.max(span.start),
            rows.end.min(span.end).max(rows.start.max(span.start)),
        );
        let shown = (end - start) as usize;
        let mut pixels = vec![0u8; shown * width];
        for (&index, tile) in self.tiles.range((start / height as u64) as u32..) {
            for (r, line) in tile.chunks_exact(width).enumerate() {
                let row = u64::from(index) * height as u64 + r as u64;
                if (start..end).contains(&row) {
                    let at = (row - start) as usize * width;
                    pixels[at..at + width].copy_from_slice(line);
                }
            }
        }
        Some((width, start, shown, pixels))
    }

    /// The newest `rows` rows of the strip (fewer when it is shorter), in belt order,
    /// missing tiles black: width, height and pixels. None before the first tile.
    pub fn newest_rows(&self, rows: usize) -> Option<(usize, usize, Vec<u8>)> {
        let end = self.span()?.end;
        let (width, _, shown, pixels) = self.rows(end.saturating_sub(rows as u64)..end)?;
        Some((width, shown, pixels))
    }
}

/// Tiles and bytes a second, over the last few seconds.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Rate {
    /// Tiles a second.
    pub tiles_per_s: f64,
    /// Bytes a second received on the link.
    pub bytes_per_s: f64,
}

/// What `/status.json` and the page show.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Status {
    /// Where the tiles come from: `usb`, `sim` or `replay`.
    pub source: String,
    /// `streaming`, then `ended` once the session is over.
    pub state: &'static str,
    /// Seconds since the server started.
    pub uptime_s: f64,
    /// Messages received, good or not.
    pub messages: u64,
    /// Bytes received.
    pub bytes: u64,
    /// Tiles placed in the strip.
    pub tiles: u64,
    /// The highest tile index received.
    pub last_tile_index: Option<u32>,
    /// Tile width and height, pixels.
    pub tile_size: Option<[u16; 2]>,
    /// Tiles missing between those received.
    pub missing_tiles: u64,
    /// The link's rate, recently.
    pub rate: Rate,
    /// Refused messages and link faults, by kind.
    pub faults: Faults,
    /// The device, from its reply to hello, with the configuration it reported last (the
    /// one its tiles are made with once one comes).
    pub device: Option<DeviceInfo>,
    /// The device's counters from its last status.
    pub device_counters: Option<StatusCounters>,
    /// Commands the device refused.
    pub refused: Vec<String>,
    /// Clients following `/events`.
    pub clients: usize,
    /// Whether commands are taken (`--control`).
    pub control: bool,
    /// The defect detector's findings, with `--detect`.
    pub detector: Option<DetectorStatus>,
    /// Whether the page shows the inspection records (`/rolls.json`, `/roll.svg`).
    pub records: bool,
}

impl Status {
    /// Takes the session's figures from its manifest.
    pub fn update(&mut self, m: &StreamRecord, rate: Rate) {
        self.messages = m.messages;
        self.bytes = m.bytes;
        self.tiles = m.tiles_received;
        self.last_tile_index = m.index_range.map(|[_, hi]| hi);
        self.missing_tiles = m.gaps.iter().map(|[a, b]| u64::from(b - a) + 1).sum();
        self.rate = rate;
        self.faults = m.faults.clone();
        self.tile_size = m.tile_size.or(self.tile_size);
        self.device = m.device.map(|mut d| {
            if let Some(c) = m.configurations.last() {
                d.config = c.config;
            }
            d
        });
        self.device_counters = m.device_counters;
        if self.refused.len() != m.refused.len() {
            self.refused = m.refused.clone();
        }
    }
}

/// Everything the server's threads share.
pub struct Shared {
    /// When the server started.
    pub started: Instant,
    /// The control token (`--control`), if commands are taken.
    pub token: Option<String>,
    /// Whether the session talks to a live device (a recording takes no commands).
    pub live: bool,
    /// The latest status (its uptime and client count are filled in when asked).
    pub status: Mutex<Status>,
    /// The newest tiles.
    pub ring: Mutex<TileRing>,
    /// The event clients' queues.
    pub clients: Mutex<Vec<ClientQueue>>,
    /// Commands for the device, oldest first.
    pub commands: Mutex<VecDeque<Command>>,
    /// Whether the defect detector runs (`--detect`).
    pub detecting: bool,
    /// What it found.
    pub findings: Mutex<Findings>,
    /// Whether the session is over ([`super::Server::finish`]): event clients that come
    /// later get what is kept and the end, and control requests are refused.
    pub ended: AtomicBool,
    /// Requests being answered, each on a thread of its own.
    pub requests: Mutex<usize>,
    /// Signalled whenever a request has been answered.
    pub request_done: Condvar,
    /// The records as last read, with `--records` ([`super::roll_view`]).
    pub records: Mutex<Option<super::roll_view::RecordsShown>>,
}

/// A request being answered: counted in [`Shared::requests`] until dropped.
pub struct Answering(Arc<Shared>);

impl Drop for Answering {
    fn drop(&mut self) {
        *lock(&self.0.requests) -= 1;
        self.0.request_done.notify_all();
    }
}

/// Locks a mutex, taking the data even if a thread panicked while holding it: every
/// structure here stays consistent between statements, and the stream must go on.
pub fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

impl Shared {
    /// The status as it stands now.
    pub fn status_now(&self) -> Status {
        let mut status = lock(&self.status).clone();
        status.uptime_s = self.started.elapsed().as_secs_f64();
        status.clients = lock(&self.clients).len();
        if self.detecting {
            status.detector = Some(lock(&self.findings).status.clone());
        }
        status
    }

    /// Hands an event to every client without waiting: a full queue counts the rows as
    /// skipped for that client, a closed one drops the client.
    pub fn broadcast(clients: &mut Vec<ClientQueue>, event: &Event) {
        clients.retain(|c| match c.sender.try_send(event.clone()) {
            Ok(()) => true,
            Err(TrySendError::Full(_)) => {
                c.skipped.fetch_add(event.rows, Ordering::Relaxed);
                true
            }
            Err(TrySendError::Disconnected(_)) => false,
        });
    }

    /// Ends every client's feed (they close their connections once drained).
    pub fn close_clients(&self) {
        lock(&self.clients).clear();
    }

    /// Counts a request as being answered until the guard is dropped; `None` when
    /// [`MAX_REQUESTS`] are answered already.
    pub fn begin_request(self: &Arc<Self>) -> Option<Answering> {
        let mut n = lock(&self.requests);
        if *n >= MAX_REQUESTS {
            return None;
        }
        *n += 1;
        Some(Answering(Arc::clone(self)))
    }

    /// Waits until every request has been answered, or `grace` has passed (a client that
    /// stopped reading can hold its answer forever); whether all were.
    pub fn wait_for_requests(&self, grace: Duration) -> bool {
        let n = lock(&self.requests);
        let (n, _) = self
            .request_done
            .wait_timeout_while(n, grace, |n| *n > 0)
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        *n == 0
    }
}
