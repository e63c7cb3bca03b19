//! `rollfuse stream --serve ADDR`: a live page of the strip as it is fused.
//!
//! A [`Server`] answers HTTP on its own threads (one per request, an `/events` client
//! keeping its own): `GET /` the page, `/status.json`, `/strip.png?rows=N`, `/events`
//! (Server-Sent Events) and, with a control token, `POST /control/roller/...`. The session
//! feeds it through a [`LiveWatch`], which only copies into bounded structures and
//! returns: a slow or vanished browser never holds up the stream, it skips rows instead.
//! docs/serve.md has the endpoints and the measurements.

pub mod detect;
mod events;
pub mod findings;
pub mod http;
pub mod records;
mod roll_view;
mod routes;
pub mod state;

use crate::stream::{StreamRecord, Watch};
use anyhow::Context;
use rollfuse_core::protocol::{self, Command};
pub use state::MAX_REQUESTS;
use state::{Rate, Shared, Status, lock};
use std::collections::VecDeque;
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// How often the status is refreshed and pushed to the clients.
pub const STATUS_EVERY: Duration = Duration::from_millis(250);

/// How long the accept thread waits to hand a refusal to a connection over the limit.
const REFUSAL_WRITE: Duration = Duration::from_millis(100);

/// How long a dropped server waits for the answers under way (a client that stopped
/// reading holds its answer until it is cut off).
pub const ANSWER_GRACE: Duration = Duration::from_secs(2);

/// What to serve and how.
#[derive(Debug, Clone)]
pub struct ServeOptions {
    /// The address to listen on (port 0: any free port).
    pub addr: SocketAddr,
    /// Take commands for the device, with a token.
    pub control: bool,
    /// Where the tiles come from, as shown on the page (`usb`, `sim`, `replay`).
    pub source: String,
    /// Whether the session talks to a live device (a recording takes no commands).
    pub live: bool,
    /// Host names (beside IP addresses and `localhost`) the page may be asked for by:
    /// requests naming any other host are refused, so a page on another site cannot read
    /// this one through DNS rebinding.
    pub allowed_hosts: Vec<String>,
    /// The inspection records to show beside the strip: this roll's map and its line's
    /// last rolls ([`records`]).
    pub records: Option<records::RollView>,
}

/// The running server. Dropping it stops it, once the answers under way are written (up
/// to [`ANSWER_GRACE`]).
pub struct Server {
    shared: Arc<Shared>,
    /// The detector's thread, with `--detect` (taken when the session is over).
    detector: std::sync::Mutex<Option<detect::LiveDetector>>,
    /// Set when the server is dropped: the accept thread stops at its next connection.
    stopping: Arc<AtomicBool>,
    addr: SocketAddr,
    accept: Option<JoinHandle<()>>,
    /// The thread reading the records for the page, with `records`.
    records: Option<JoinHandle<()>>,
}

/// Parses a `--serve` address (`127.0.0.1:8080`, `[::1]:8080`, `0.0.0.0:8080`).
pub fn parse_addr(text: &str) -> anyhow::Result<SocketAddr> {
    text.parse().map_err(|_| {
        anyhow::anyhow!(
            "--serve must be an IP address and port such as 127.0.0.1:8080, got `{text}`"
        )
    })
}

/// A fresh control token: 128 bits from the operating system's cryptographic random
/// source, as 32 hex digits.
fn new_token() -> anyhow::Result<String> {
    let mut bytes = [0u8; 16];
    getrandom::fill(&mut bytes).map_err(|e| {
        anyhow::anyhow!(
            "cannot draw a control token from the operating system's random source: {e}"
        )
    })?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

impl Server {
    /// Binds `opts.addr` and starts answering. Fails, saying so, when the address cannot
    /// be had (in use, not this machine's).
    pub fn start(opts: &ServeOptions) -> anyhow::Result<Self> {
        Self::start_detecting(opts, None)
    }

    /// [`Server::start`], with `detector` run over the strip as it grows and its boxes
    /// drawn on the page ([`detect`]).
    pub fn start_detecting(
        opts: &ServeOptions,
        detector: Option<detect::LiveModel>,
    ) -> anyhow::Result<Self> {
        let listener = TcpListener::bind(opts.addr)
            .map_err(|e| anyhow::anyhow!("cannot serve on {}: {e}", opts.addr))?;
        let addr = listener
            .local_addr()
            .with_context(|| format!("cannot serve on {}", opts.addr))?;
        let token = opts.control.then(new_token).transpose()?;
        let shared = Arc::new(Shared {
            started: Instant::now(),
            token,
            live: opts.live,
            status: std::sync::Mutex::new(Status {
                source: opts.source.clone(),
                state: "streaming",
                control: opts.control,
                records: opts.records.is_some(),
                ..Status::default()
            }),
            ring: Default::default(),
            clients: Default::default(),
            commands: Default::default(),
            detecting: detector.is_some(),
            findings: std::sync::Mutex::new(findings::Findings::new(opts.records.is_some())),
            ended: Default::default(),
            requests: Default::default(),
            request_done: Default::default(),
            records: Default::default(),
        });
        let detector = detector
            .map(|d| detect::LiveDetector::start(Arc::clone(&shared), d))
            .transpose()
            .context("cannot start the detector's thread")?;
        let stopping = Arc::new(AtomicBool::new(false));
        let accept = {
            let (shared, stopping) = (Arc::clone(&shared), Arc::clone(&stopping));
            let hosts: Arc<[String]> = opts.allowed_hosts.clone().into();
            std::thread::Builder::new()
                .name("serve-accept".into())
                .spawn(move || accept_loop(&listener, &shared, &stopping, &hosts))
                .context("cannot start the server's thread")?
        };
        let records = (opts.records.clone())
            .map(|view| records::start(view, Arc::clone(&shared), Arc::clone(&stopping)))
            .transpose()
            .context("cannot start the records' thread")?;
        Ok(Self {
            shared,
            detector: std::sync::Mutex::new(detector),
            stopping,
            addr,
            accept: Some(accept),
            records,
        })
    }

    /// The address it listens on (with the port chosen when asked for port 0).
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The detector's findings so far, with `--detect`.
    pub fn detector_status(&self) -> Option<findings::DetectorStatus> {
        self.shared.status_now().detector
    }

    /// The defects found since the session last took them, for the records (with
    /// `--records`; the detector's last windows come after the session has ended).
    pub fn take_unrecorded_defects(&self) -> Vec<crate::records::StripBox> {
        self.watcher().defects()
    }

    /// The control token, with `--control`.
    pub fn token(&self) -> Option<&str> {
        self.shared.token.as_deref()
    }

    /// The watcher that feeds this server from a session.
    pub fn watcher(&self) -> LiveWatch {
        LiveWatch {
            shared: Arc::clone(&self.shared),
            last_status: None,
            tile_size_shown: false,
            samples: VecDeque::new(),
        }
    }

    /// The session is over: the final status goes to the page (`ended`), the event
    /// streams end, and the server goes on answering until dropped (the kept rows, the
    /// final status; event clients that come later get both and the end; control is
    /// refused). Every event stream open now is sent `end` before the server is gone.
    pub fn finish(&self, manifest: &StreamRecord) {
        // The detector checks the last rows first, so the page has every box.
        if let Some(mut d) = lock(&self.detector).take() {
            d.finish();
        }
        // The session's average: there is no recent rate once it is over.
        let secs = self.shared.started.elapsed().as_secs_f64().max(1e-9);
        let rate = Rate {
            tiles_per_s: manifest.tiles_received as f64 / secs,
            bytes_per_s: manifest.bytes as f64 / secs,
        };
        {
            let mut status = lock(&self.shared.status);
            status.update(manifest, rate);
            status.state = "ended";
        }
        events::end_all(&self.shared);
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.shared.close_clients();
        // The answers under way finish first: an event stream writes its `end`, a download
        // its last byte. Without this, a process that exits right after would cut them off.
        self.shared.wait_for_requests(ANSWER_GRACE);
        self.stopping.store(true, Ordering::Release);
        if let Some(t) = self.records.take() {
            let _ = t.join();
        }
        // The accept thread waits for a connection: one to itself wakes it. Should that
        // fail, the thread is left to end with the process.
        let mut wake = self.addr;
        if wake.ip().is_unspecified() {
            wake.set_ip(match wake {
                SocketAddr::V4(_) => std::net::Ipv4Addr::LOCALHOST.into(),
                SocketAddr::V6(_) => std::net::Ipv6Addr::LOCALHOST.into(),
            });
        }
        if TcpStream::connect_timeout(&wake, ANSWER_GRACE).is_ok()
            && let Some(t) = self.accept.take()
        {
            let _ = t.join();
        }
    }
}

/// Takes connections and answers each on a thread of its own, up to [`MAX_REQUESTS`];
/// beyond, a connection is told 503 and closed. Nothing here can fail for good: a
/// failed accept (no descriptors left, say) is retried after a pause.
fn accept_loop(
    listener: &TcpListener,
    shared: &Arc<Shared>,
    stopping: &AtomicBool,
    hosts: &Arc<[String]>,
) {
    loop {
        let accepted = listener.accept();
        if stopping.load(Ordering::Acquire) {
            return;
        }
        let Ok((mut stream, _)) = accepted else {
            std::thread::sleep(Duration::from_millis(50));
            continue;
        };
        let Some(answering) = shared.begin_request() else {
            let _ = stream.set_write_timeout(Some(REFUSAL_WRITE));
            let busy = http::Answer::text(503, "too many connections; try again");
            let _ = http::write_answer(&mut stream, &busy, false);
            continue;
        };
        let (shared, hosts) = (Arc::clone(shared), Arc::clone(hosts));
        // A thread that cannot be had drops the connection and its count with it.
        let _ = std::thread::Builder::new()
            .name("serve-request".into())
            .spawn(move || {
                routes::handle(stream, &shared, &hosts);
                drop(answering);
            });
    }
}

/// Feeds a [`Server`] from a session ([`crate::stream::run_watched`]). Each call copies
/// into bounded structures and returns; it never waits for a client.
pub struct LiveWatch {
    shared: Arc<Shared>,
    last_status: Option<Instant>,
    /// Whether the status has the tile size (the manifest has it only at the end).
    tile_size_shown: bool,
    /// (when, tiles, bytes), for the recent rate.
    samples: VecDeque<(Instant, u64, u64)>,
}

impl LiveWatch {
    /// Tiles and bytes a second over the last two seconds or so.
    fn rate(&mut self, m: &StreamRecord, now: Instant) -> Rate {
        self.samples.push_back((now, m.tiles_received, m.bytes));
        while self.samples.len() > 2
            && self
                .samples
                .front()
                .is_some_and(|s| now - s.0 > Duration::from_secs(2))
        {
            self.samples.pop_front();
        }
        let Some(&(then, tiles, bytes)) = self.samples.front() else {
            return Rate::default();
        };
        let secs = (now - then).as_secs_f64();
        if secs <= 0.0 {
            return Rate::default();
        }
        Rate {
            tiles_per_s: (m.tiles_received - tiles) as f64 / secs,
            bytes_per_s: (m.bytes - bytes) as f64 / secs,
        }
    }
}

impl Watch for LiveWatch {
    fn tile(&mut self, tile: &protocol::Tile<'_>, _manifest: &StreamRecord) {
        let size = (usize::from(tile.width), usize::from(tile.height));
        // The clients' lock is held while the tile is kept and handed out, so a client
        // subscribing meanwhile gets it once (see events::subscribe).
        if !self.tile_size_shown {
            self.tile_size_shown = true;
            lock(&self.shared.status).tile_size = Some([tile.width, tile.height]);
        }
        let mut clients = lock(&self.shared.clients);
        lock(&self.shared.ring).push(tile.index, size, tile.pixels);
        if !clients.is_empty() {
            let event = events::tile_event(tile.index, size, tile.pixels);
            Shared::broadcast(&mut clients, &event);
        }
    }

    fn message(&mut self, manifest: &StreamRecord) {
        let now = Instant::now();
        if self.last_status.is_some_and(|t| now - t < STATUS_EVERY) {
            return;
        }
        self.last_status = Some(now);
        let rate = self.rate(manifest, now);
        lock(&self.shared.status).update(manifest, rate);
        let status = self.shared.status_now();
        let mut clients = lock(&self.shared.clients);
        if !clients.is_empty() {
            Shared::broadcast(&mut clients, &events::status_event(&status));
        }
    }

    fn command(&mut self) -> Option<Command> {
        lock(&self.shared.commands).pop_front()
    }

    fn defects(&mut self) -> Vec<crate::records::StripBox> {
        let mut findings = lock(&self.shared.findings);
        findings
            .unrecorded
            .drain(..)
            .map(|b| b.strip_box())
            .collect()
    }
}

#[cfg(test)]
mod tests;
