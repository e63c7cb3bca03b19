//! A streaming session: configure the device, receive its messages, check every one,
//! stitch the tiles into a strip, and account for everything that went wrong.
//!
//! Nothing is lost silently: every message that fails to decode is counted by kind, every
//! sequence gap is counted with the number of messages missing, every missing tile index
//! is listed, and the device's own counters (frames, tiles emitted, tiles dropped) are
//! kept from its last status. A stream cut off midway keeps every tile received.
//!
//! Outputs, in the session's folder: the strip, written as it grows
//! ([`crate::strip_file`]: `strip.png`, or segments `strip.0000.png` … once it is longer
//! than a segment, with `strip.json` listing their belt rows), and `manifest.json`. Tiles
//! are written in index order as soon as the tiles before them are in (a late tile may
//! overtake up to [`REORDER_TILES`] others); up to [`FILL_GAP_TILES`] missing tiles are
//! black rows where they belong, a longer jump of the index starts a new segment. Memory
//! does not grow with the stream. Every output depends only on the messages received, so
//! playing a recording back ([`crate::link::replay`]) writes the same bytes. Timings are
//! printed, not written.

use crate::link::replay::Recorder;
use crate::link::{Received, Transport};
use crate::progress::Progress;
use crate::records::RollKeeper;
use crate::strip_file::{Segment, StripWriter};
use anyhow::{Context, bail};
use rollfuse_core::device::{PipelineConfig, Sensor};
use rollfuse_core::protocol::{
    self, Command, DecodeError, DeviceConfig, DeviceInfo, DeviceMessage, MAX_MESSAGE, NakReason,
    SeqEvent, SeqTracker, StatusCounters,
};
use rollfuse_records::Status;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Tiles held back waiting for a missing index before it is declared lost.
pub const REORDER_TILES: usize = 16;

/// Missing tiles drawn as black rows in the strip; a longer jump starts a new segment.
pub const FILL_GAP_TILES: usize = 64;

/// How long a live device may stay silent before the session gives up on it.
pub const SILENCE_LIMIT: Duration = Duration::from_secs(5);

/// How often a session asks a live device for its status: the device takes a host that
/// sends nothing for 3 s as gone, and stops the roller and streaming.
pub const HEARTBEAT: Duration = Duration::from_secs(1);

/// What the session should do.
#[derive(Debug, Clone)]
pub struct Options {
    /// The folder for `strip.png` and `manifest.json`.
    pub out: PathBuf,
    /// Configuration to send before streaming (live devices).
    pub config: Option<DeviceConfig>,
    /// Stop after this many tiles (live devices; the device's flush still arrives).
    pub max_tiles: Option<u64>,
    /// Stop after this long (live devices).
    pub max_duration: Option<Duration>,
    /// Record every received message here.
    pub record: Option<PathBuf>,
    /// Most rows per strip segment.
    pub segment_rows: usize,
    /// Keep the roll in the inspection records: each segment recorded as soon as it is
    /// whole on disk (and then written in place: [`StripWriter::in_place`]).
    pub keep: Option<crate::records::KeepRoll>,
}

impl Options {
    /// A session writing into the folder `out`: the device's own configuration, no
    /// limits, no recording, not kept in the records.
    pub fn into_folder(out: &Path) -> Options {
        Options {
            out: out.to_path_buf(),
            config: None,
            max_tiles: None,
            max_duration: None,
            record: None,
            segment_rows: crate::strip_file::DEFAULT_SEGMENT_ROWS,
            keep: None,
        }
    }
}

/// Follows a session as it goes, for live views (the served page) and for programs that
/// take the tiles as they come (the Python package). Every method has a default that does
/// nothing. Called on the session's thread: a watcher that blocks holds up the session,
/// so it should hand work elsewhere and return.
pub trait Watch {
    /// A tile was taken into the strip (the manifest already counts it).
    fn tile(&mut self, _tile: &protocol::Tile<'_>, _manifest: &StreamRecord) {}
    /// A message was taken: the manifest's figures (faults, device status) may have moved.
    fn message(&mut self, _manifest: &StreamRecord) {}
    /// A command to send to a live device now, if any (e.g. a control on a served page);
    /// asked about once per turn of the session's loop.
    fn command(&mut self) -> Option<Command> {
        None
    }
    /// Defects found on the strip since the last call (a served page's detector), for the
    /// records: each its kind, score and box in strip columns and belt rows.
    fn defects(&mut self) -> Vec<crate::records::StripBox> {
        Vec::new()
    }
}

/// A watcher that does nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct Unwatched;

impl Watch for Unwatched {}

/// Messages refused, by reason.
#[derive(Debug, Default, Clone, Serialize, PartialEq, Eq)]
pub struct Faults {
    /// Bad CRC.
    pub bad_crc: u64,
    /// Shorter than any message.
    pub truncated: u64,
    /// Longer than any message.
    pub too_long: u64,
    /// Another protocol version.
    pub wrong_version: u64,
    /// Good CRC, undecodable body.
    pub malformed: u64,
    /// A length inside beyond its limit.
    pub over_limit: u64,
    /// Sequence gaps seen.
    pub sequence_gaps: u64,
    /// Messages missing in those gaps.
    pub messages_missing: u64,
    /// Messages seen twice or out of order.
    pub repeated: u64,
    /// Messages numbered far past the sequence (a stray or crafted number; not taken).
    pub far_ahead: u64,
    /// Times the device's numbering moved and was followed (a restart).
    pub renumbered: u64,
    /// Tiles whose index had already been received (the first copy is kept).
    pub duplicate_tiles: u64,
    /// Tiles that arrived after their index had been declared lost (not placed).
    pub late_tiles: u64,
    /// Tiles of another width or height than the first (not placed).
    pub mismatched_tiles: u64,
    /// Messages in a recording after the device's final status (a recording out of
    /// order or spliced; they are read and checked like the others).
    pub after_final_status: u64,
}

impl Faults {
    fn count(&mut self, e: DecodeError) {
        let field = match e {
            DecodeError::BadCrc => &mut self.bad_crc,
            DecodeError::Truncated => &mut self.truncated,
            DecodeError::TooLong => &mut self.too_long,
            DecodeError::Version(_) => &mut self.wrong_version,
            DecodeError::Malformed => &mut self.malformed,
            DecodeError::Limit(_) => &mut self.over_limit,
        };
        *field += 1;
    }

    /// Everything that went wrong, summed.
    pub fn total(&self) -> u64 {
        self.bad_crc
            + self.truncated
            + self.too_long
            + self.wrong_version
            + self.malformed
            + self.over_limit
            + self.sequence_gaps
            + self.repeated
            + self.duplicate_tiles
            + self.late_tiles
            + self.mismatched_tiles
    }
}

/// The files a session writes into `out`, the strip first: `strip.png` (or its segments
/// `strip.NNNN.png`, [`crate::strip_file`]), its index `strip.json`, and `manifest.json`.
pub fn output_files(out: &Path) -> [PathBuf; 3] {
    [
        out.join("strip.png"),
        StripWriter::index_path(&out.join("strip.png")),
        out.join("manifest.json"),
    ]
}

/// The format a stream's `manifest.json` declares (its `format` field), so that no reader
/// takes it for the frames manifest `rollfuse simulate` writes (`sim::Manifest`).
pub const STREAM_FORMAT: &str = "rollfuse-stream-1";

/// What a stream records of itself, its folder's `manifest.json` (with `format`:
/// [`STREAM_FORMAT`]).
#[derive(Debug, Default, Clone, Serialize)]
pub struct StreamRecord {
    /// Messages received (good or not).
    pub messages: u64,
    /// Bytes received.
    pub bytes: u64,
    /// Tiles placed in the strip.
    pub tiles_received: u64,
    /// Tile size, columns × rows.
    pub tile_size: Option<[u16; 2]>,
    /// First and last tile index received.
    pub index_range: Option<[u32; 2]>,
    /// Missing tile indices between them, as inclusive ranges.
    pub gaps: Vec<[u32; 2]>,
    /// Observations per tile: how many tiles had each count.
    pub observations: BTreeMap<u8, u64>,
    /// Refused messages and link faults.
    pub faults: Faults,
    /// The device as it announced itself in its first reply to hello (its `config` is the
    /// one it ran then, not necessarily the tiles': see `configurations`).
    pub device: Option<DeviceInfo>,
    /// The configurations the device confirmed for the tiles it sent, in order: each
    /// from the first tile that came after the device reported it, with the tile size it
    /// makes. A configuration no tile came under is not listed, nor one whose tiles have
    /// another size (a recording made before the device was asked to confirm its
    /// configuration).
    pub configurations: Vec<Configured>,
    /// The device's counters from its last status.
    pub device_counters: Option<StatusCounters>,
    /// Commands the device refused.
    pub refused: Vec<String>,
    /// The device's log lines.
    pub log: Vec<String>,
    /// Whether the device said it stopped streaming (otherwise the link ended first).
    pub device_stopped: bool,
}

impl StreamRecord {
    /// The record as its file holds it: pretty JSON led by `format` ([`STREAM_FORMAT`]).
    pub fn to_json(&self) -> serde_json::Result<String> {
        #[derive(Serialize)]
        struct Tagged<'a> {
            format: &'static str,
            #[serde(flatten)]
            record: &'a StreamRecord,
        }
        let tagged = Tagged {
            format: STREAM_FORMAT,
            record: self,
        };
        Ok(serde_json::to_string_pretty(&tagged)? + "\n")
    }
}

/// A configuration the device ran and the tiles it applies to.
#[derive(Debug, Clone, Serialize, PartialEq, Eq)]
pub struct Configured {
    /// The first tile index made with it (`None` until a tile comes).
    pub from_tile: Option<u32>,
    /// The configuration, as the device reported it.
    pub config: DeviceConfig,
    /// The tiles it makes, columns × rows.
    pub tile_size: [u16; 2],
}

/// The configuration in one line, as printed: `db2, 1 level, 1× (tiles 320 × 16), …`.
pub fn describe(c: &DeviceConfig, [w, h]: [u16; 2]) -> String {
    let wavelet = match c.wavelet {
        protocol::WaveletId::Haar => "haar",
        protocol::WaveletId::Db2 => "db2",
    };
    let norm = match c.norm {
        protocol::NormMode::PerTile => "per-tile",
        protocol::NormMode::PerFrame => "per-frame",
    };
    format!(
        "{wavelet}, {} level{}, {}× (tiles {w} × {h}), {} frames per tile, {} px between \
         frames, refinement ±{} rows, {norm} normalization",
        c.levels,
        if c.levels == 1 { "" } else { "s" },
        c.downsample,
        c.frames_per_tile,
        c.frame_spacing_px,
        c.refine_rows,
    )
}

/// The strip as tiles arrive: written in index order, late tiles held back a little.
struct StreamedStrip {
    out: PathBuf,
    segment_rows: usize,
    /// Segments in place as they are written ([`StripWriter::in_place`]).
    in_place: bool,
    size: Option<(u16, u16)>,
    writer: Option<StripWriter>,
    /// Tiles received ahead of the next index to write.
    pending: BTreeMap<u32, Vec<u8>>,
    /// The next index to write.
    next: Option<u32>,
}

/// Why a tile was not taken.
enum Refused {
    Mismatched,
    Duplicate,
    Late,
}

impl StreamedStrip {
    fn new(out: PathBuf, segment_rows: usize, in_place: bool) -> Self {
        Self {
            out,
            segment_rows,
            in_place,
            size: None,
            writer: None,
            pending: BTreeMap::new(),
            next: None,
        }
    }

    /// Fixes the tile size before the first tile, where the device's configuration says
    /// it (else the first tile sets it): a stray tile of another size that comes first
    /// is then the one counted mismatched, not every tile after it.
    fn expect(&mut self, size: (u16, u16)) {
        if self.writer.is_none() && self.pending.is_empty() {
            self.size = Some(size);
        }
    }

    /// Takes a tile; writes every tile that is now in order.
    fn take(
        &mut self,
        index: u32,
        size: (u16, u16),
        pixels: &[u8],
        m: &mut StreamRecord,
    ) -> anyhow::Result<Result<(), Refused>> {
        if *self.size.get_or_insert(size) != size {
            return Ok(Err(Refused::Mismatched));
        }
        if self.pending.contains_key(&index) {
            return Ok(Err(Refused::Duplicate));
        }
        if self.next.is_some_and(|n| index < n) {
            let lost = m.gaps.iter().any(|[a, b]| (*a..=*b).contains(&index));
            return Ok(Err(if lost {
                Refused::Late
            } else {
                Refused::Duplicate
            }));
        }
        self.next.get_or_insert(index);
        self.pending.insert(index, pixels.to_vec());
        m.index_range = Some(match m.index_range {
            Some([lo, hi]) => [lo.min(index), hi.max(index)],
            None => [index, index],
        });
        self.drain(m, REORDER_TILES)?;
        Ok(Ok(()))
    }

    /// Writes pending tiles in order, declaring missing indices lost while more than
    /// `hold` tiles wait.
    fn drain(&mut self, m: &mut StreamRecord, hold: usize) -> anyhow::Result<()> {
        while let Some((&lowest, _)) = self.pending.first_key_value() {
            let next = self.next.unwrap_or(lowest);
            if lowest != next {
                if self.pending.len() <= hold {
                    break;
                }
                m.gaps.push([next, lowest - 1]);
            }
            let pixels = self.pending.remove(&lowest).unwrap_or_default();
            self.write_tile(lowest, &pixels)?;
            self.next = lowest.checked_add(1);
        }
        Ok(())
    }

    fn write_tile(&mut self, index: u32, pixels: &[u8]) -> anyhow::Result<()> {
        let Some((w, t)) = self.size else {
            return Ok(());
        };
        let (w, t) = (usize::from(w), usize::from(t));
        if self.writer.is_none() {
            let writer = StripWriter::new(&self.out, w, 1, 8, self.segment_rows)?
                .fill_gaps(FILL_GAP_TILES * t);
            self.writer = Some(if self.in_place {
                writer.in_place()
            } else {
                writer
            });
        }
        let writer = self.writer.as_mut().context("no strip writer")?;
        let mut row = vec![0f32; w];
        for (r, line) in pixels.chunks_exact(w).take(t).enumerate() {
            for (v, &p) in row.iter_mut().zip(line) {
                *v = f32::from(p);
            }
            writer.push(i64::from(index) * t as i64 + r as i64, &[&row])?;
        }
        Ok(())
    }

    /// Ends the segment being collected and lands it with the full ones ([`Self::land`]).
    fn end_and_land(&mut self, keeper: &mut RollKeeper) -> anyhow::Result<()> {
        if let Some(writer) = &mut self.writer {
            writer.end_segment()?;
        }
        self.land(keeper)
    }

    /// Puts the full segments in place and records them ([`RollKeeper::land`]).
    fn land(&mut self, keeper: &mut RollKeeper) -> anyhow::Result<()> {
        match &mut self.writer {
            Some(writer) => keeper.land(writer),
            None => Ok(()),
        }
    }

    /// Writes every tile still held and the strip's index; the strip's segments (none
    /// without a tile).
    /// The last segment is recorded by `keeper`, if the strip is kept in the records.
    fn finish(
        mut self,
        m: &mut StreamRecord,
        keeper: Option<&mut RollKeeper>,
    ) -> anyhow::Result<Vec<Segment>> {
        self.drain(m, 0)?;
        if let Some(keeper) = keeper {
            self.end_and_land(keeper)?;
        }
        let Some(writer) = self.writer else {
            return Ok(Vec::new());
        };
        Ok(writer.finish(serde_json::json!({
            "tile_size": m.tile_size,
            "configurations": m.configurations,
        }))?)
    }
}

/// Why the session stopped asking for tiles (printed, not in the manifest).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopReason {
    /// `--tiles` reached.
    TileLimit,
    /// `--seconds` reached.
    TimeLimit,
    /// The device stopped streaming on its own (e.g. the virtual device's scene ended).
    DeviceStopped,
    /// The link closed (end of a recording, device gone).
    LinkClosed,
    /// A live device went silent.
    Silent,
}

/// The session's result.
pub struct Outcome {
    /// What was written to `manifest.json`.
    pub manifest: StreamRecord,
    /// The roll's id in the records, if kept there.
    pub roll: Option<i64>,
    /// The strip's files in the output folder, in belt order (none without a tile).
    pub strip_files: Vec<String>,
    /// Why it stopped.
    pub stop: StopReason,
    /// Wall time of the session.
    pub elapsed: Duration,
}

/// Greets a live device, configures it, asks it again for its description (its reply
/// names the configuration in force, and a recording keeps it) and starts its stream;
/// the commands whose refusal ends the session, with their names.
fn start_session(
    link: &mut dyn Transport,
    opts: &Options,
    cmd_seq: &mut u32,
) -> anyhow::Result<Vec<(u32, &'static str)>> {
    let mut essential = Vec::new();
    send(link, cmd_seq, &Command::Hello)?;
    if let Some(cfg) = opts.config {
        essential.push((send(link, cmd_seq, &Command::Configure(cfg))?, "configure"));
        send(link, cmd_seq, &Command::Hello)?;
    }
    essential.push((send(link, cmd_seq, &Command::StreamStart)?, "stream start"));
    Ok(essential)
}

/// The limit (`--tiles`, `--seconds`) the session has reached, if any.
fn limit_reached(opts: &Options, manifest: &StreamRecord, started: Instant) -> Option<StopReason> {
    if opts.max_tiles.is_some_and(|n| manifest.tiles_received >= n) {
        Some(StopReason::TileLimit)
    } else if opts.max_duration.is_some_and(|d| started.elapsed() >= d) {
        Some(StopReason::TimeLimit)
    } else {
        None
    }
}

/// Counts what sequence number `seq` says about lost or repeated messages; `false` for a
/// repeat, which is not taken.
fn in_sequence(
    seqs: &mut SeqTracker,
    seq: u32,
    faults: &mut Faults,
    progress: &dyn Progress,
) -> bool {
    match seqs.observe(seq) {
        SeqEvent::InOrder => true,
        SeqEvent::Gap { missing } => {
            faults.sequence_gaps += 1;
            faults.messages_missing += u64::from(missing);
            progress.note(&format!("{missing} message(s) lost before #{seq}"));
            true
        }
        SeqEvent::Repeat => {
            faults.repeated += 1;
            false
        }
        SeqEvent::FarAhead => {
            faults.far_ahead += 1;
            progress.note(&format!(
                "message #{seq} is far past the sequence: not taken"
            ));
            false
        }
        SeqEvent::Renumbered => {
            faults.renumbered += 1;
            progress.note(&format!("the device's numbering went on from #{seq}"));
            true
        }
    }
}

/// The size of the tiles a device of `info` makes once `configured` (if sent; else the
/// configuration `info` reports) is in force; `None` for a configuration it would refuse.
fn configured_tile(info: &DeviceInfo, configured: Option<DeviceConfig>) -> Option<(u16, u16)> {
    let sensor = Sensor {
        width: usize::from(info.sensor_width),
        height: usize::from(info.sensor_height),
        format: info.pixel_format,
    };
    let tile = PipelineConfig::from_wire(&configured.unwrap_or(info.config), sensor)
        .ok()?
        .tile_dims();
    Some((
        u16::try_from(tile.width()).ok()?,
        u16::try_from(tile.height()).ok()?,
    ))
}

/// Places a tile in the strip, or counts why not; whether it was placed.
fn take_tile(
    strip: &mut StreamedStrip,
    tile: &protocol::Tile<'_>,
    manifest: &mut StreamRecord,
) -> anyhow::Result<bool> {
    let size = (tile.width, tile.height);
    let fault = match strip.take(tile.index, size, tile.pixels, manifest)? {
        Ok(()) => {
            *manifest.observations.entry(tile.observations).or_default() += 1;
            manifest.tiles_received += 1;
            return Ok(true);
        }
        Err(Refused::Mismatched) => &mut manifest.faults.mismatched_tiles,
        Err(Refused::Duplicate) => &mut manifest.faults.duplicate_tiles,
        Err(Refused::Late) => &mut manifest.faults.late_tiles,
    };
    *fault += 1;
    Ok(false)
}

/// Sends a command, returning its sequence number.
fn send(link: &mut dyn Transport, seq: &mut u32, cmd: &Command) -> anyhow::Result<u32> {
    let mut buf = [0u8; 256];
    let n = protocol::encode(*seq, cmd, &mut buf)
        .map_err(|e| anyhow::anyhow!("cannot encode {cmd:?}: {e:?}"))?;
    link.send(&buf[..n])?;
    *seq = seq.wrapping_add(1);
    Ok(seq.wrapping_sub(1))
}

/// What the link gave the session.
enum Next {
    /// A message of this many bytes.
    Message(usize),
    /// Nothing yet.
    Wait,
    /// Nothing more will come.
    Over,
}

/// Whether the session goes on after a message.
#[derive(PartialEq, Eq)]
enum Flow {
    Continue,
    Stop,
}

/// A session under way: what has been received, and where the device stands.
struct Session<'a> {
    /// Removed again if the session ends having written nothing to it.
    _folder: crate::files::NewFolder,
    opts: &'a Options,
    progress: &'a dyn Progress,
    watch: &'a mut dyn Watch,
    live: bool,
    started: Instant,
    recorder: Option<Recorder>,
    manifest: StreamRecord,
    manifest_path: PathBuf,
    strip: StreamedStrip,
    /// The roll in the records, if kept there.
    keeper: Option<RollKeeper>,
    seqs: SeqTracker,
    /// The next command's sequence number.
    cmd_seq: u32,
    /// The commands whose refusal ends the session, with their names.
    essential: Vec<(u32, &'static str)>,
    last_message: Instant,
    last_heartbeat: Instant,
    stop_sent: bool,
    stop: StopReason,
}

impl<'a> Session<'a> {
    /// Makes the output folder and the recording, and starts a live device streaming.
    fn open(
        link: &mut dyn Transport,
        opts: &'a Options,
        progress: &'a dyn Progress,
        watch: &'a mut dyn Watch,
    ) -> anyhow::Result<Self> {
        let folder = crate::files::NewFolder::create(&opts.out)?;
        let [strip_path, _, manifest_path] = output_files(&opts.out);
        let keeper = (opts.keep.as_ref())
            .map(|k| RollKeeper::start(k, &strip_path))
            .transpose()?;
        let recorder = opts.record.as_deref().map(Recorder::create).transpose()?;
        let started = Instant::now();
        let live = link.is_live();
        let mut cmd_seq = 0u32;
        let essential = if live {
            start_session(link, opts, &mut cmd_seq)?
        } else {
            Vec::new()
        };
        progress.start("receiving tiles", None, "tiles");
        Ok(Self {
            _folder: folder,
            opts,
            progress,
            watch,
            live,
            started,
            recorder,
            manifest: StreamRecord::default(),
            manifest_path,
            strip: StreamedStrip::new(strip_path, opts.segment_rows, keeper.is_some()),
            keeper,
            seqs: SeqTracker::new(),
            cmd_seq,
            essential,
            last_message: Instant::now(),
            last_heartbeat: Instant::now(),
            stop_sent: false,
            stop: StopReason::LinkClosed,
        })
    }

    /// Keeps a live device streaming (it takes a silent host as gone) and asks it to stop
    /// once a limit is reached; its flush and final status follow.
    fn steer(&mut self, link: &mut dyn Transport) -> anyhow::Result<()> {
        // Only until stop is sent: the final status must not be mistaken for a reply.
        if !self.live || self.stop_sent {
            return Ok(());
        }
        if let Some(command) = self.watch.command() {
            send(link, &mut self.cmd_seq, &command)?;
        }
        if self.last_heartbeat.elapsed() >= HEARTBEAT {
            send(link, &mut self.cmd_seq, &Command::Status)?;
            self.last_heartbeat = Instant::now();
        }
        if let Some(reason) = limit_reached(self.opts, &self.manifest, self.started) {
            send(link, &mut self.cmd_seq, &Command::StreamStop)?;
            self.stop_sent = true;
            self.stop = reason;
        }
        Ok(())
    }

    /// Waits a little for the next message; a device silent too long ends the session.
    fn receive(&mut self, link: &mut dyn Transport, buf: &mut [u8]) -> anyhow::Result<Next> {
        Ok(match link.receive(buf, Duration::from_millis(200))? {
            Received::Message(n) => {
                self.last_message = Instant::now();
                Next::Message(n)
            }
            Received::Timeout if self.last_message.elapsed() > SILENCE_LIMIT => {
                self.stop = StopReason::Silent;
                Next::Over
            }
            Received::Timeout => Next::Wait,
            Received::Closed => {
                if !self.stop_sent && !self.manifest.device_stopped {
                    self.stop = StopReason::LinkClosed;
                }
                Next::Over
            }
        })
    }

    /// Records and counts a message, checks it, and acts on it if it is sound.
    fn take(&mut self, bytes: &[u8]) -> anyhow::Result<Flow> {
        if self.manifest.device_stopped {
            self.manifest.faults.after_final_status += 1;
        }
        if let Some(r) = self.recorder.as_mut() {
            r.record(bytes)?;
        }
        self.manifest.messages += 1;
        self.manifest.bytes += bytes.len() as u64;
        let (header, msg) = match protocol::decode::<DeviceMessage>(bytes) {
            Ok(m) => m,
            Err(e) => {
                self.manifest.faults.count(e);
                self.progress.note(&format!("refused a message: {e}"));
                return Ok(Flow::Continue);
            }
        };
        let faults = &mut self.manifest.faults;
        if !in_sequence(&mut self.seqs, header.seq, faults, self.progress) {
            return Ok(Flow::Continue);
        }
        let flow = self.on_message(msg)?;
        self.watch.message(&self.manifest);
        Ok(flow)
    }

    /// Acts on a sound message.
    fn on_message(&mut self, msg: DeviceMessage<'_>) -> anyhow::Result<Flow> {
        match msg {
            DeviceMessage::Info(info) => self.on_info(info),
            DeviceMessage::Ack { .. } | DeviceMessage::RawChunk(_) => {}
            DeviceMessage::Nak {
                command_seq,
                reason,
            } => self.on_refusal(command_seq, reason)?,
            DeviceMessage::Status(c) => return Ok(self.on_status(c)),
            DeviceMessage::Log(line) => {
                self.progress.note(&format!("device: {line}"));
                self.manifest.log.push(line.to_string());
            }
            DeviceMessage::Tile(tile) => self.on_tile(&tile)?,
        }
        Ok(Flow::Continue)
    }

    /// The device's description: the first is the manifest's `device`; every one names
    /// the configuration in force from the next tile on.
    fn on_info(&mut self, info: DeviceInfo) {
        // A live device's tiles have the size of the configuration it was sent (its first
        // reply predates it); a recording's first tile sets theirs.
        if self.live
            && let Some(size) = configured_tile(&info, self.opts.config)
        {
            self.strip.expect(size);
        }
        self.manifest.device.get_or_insert(info);
        let Some((w, h)) = configured_tile(&info, None) else {
            return;
        };
        let configs = &mut self.manifest.configurations;
        if configs.last().is_some_and(|c| c.from_tile.is_none()) {
            configs.pop();
        }
        configs.push(Configured {
            from_tile: None,
            config: info.config,
            tile_size: [w, h],
        });
    }

    /// Dates the configuration in force from `tile`, the first of the size it makes.
    fn confirm_configuration(&mut self, tile: &protocol::Tile<'_>) -> anyhow::Result<()> {
        if let Some(last) = self.manifest.configurations.last_mut()
            && last.from_tile.is_none()
            && last.tile_size == [tile.width, tile.height]
        {
            last.from_tile = Some(tile.index);
            if let Some(keeper) = &mut self.keeper {
                keeper.configured(last.config.downsample)?;
            }
            self.progress.note(&format!(
                "from tile {}: {}",
                tile.index,
                describe(&last.config, last.tile_size)
            ));
        }
        Ok(())
    }

    /// A command the device refused: listed, and the end of the session if essential.
    fn on_refusal(&mut self, command_seq: u32, reason: NakReason) -> anyhow::Result<()> {
        let what = self
            .essential
            .iter()
            .find(|(s, _)| *s == command_seq)
            .map(|(_, w)| *w);
        self.manifest.refused.push(format!(
            "{} refused: {reason:?}",
            what.unwrap_or("a command")
        ));
        if let Some(what) = what {
            write_manifest(&self.manifest_path, &self.manifest)?;
            let why = match reason {
                NakReason::Memory => {
                    " (it needs more pipeline memory than the device has: downsample more, \
                     or use shorter tiles or fewer frames per tile)"
                }
                _ => "",
            };
            bail!("the device refused {what}: {reason:?}{why}");
        }
        Ok(())
    }

    /// The device's counters, and whether it has said its last.
    fn on_status(&mut self, c: StatusCounters) -> Flow {
        self.manifest.device_counters = Some(c);
        if c.streaming {
            return Flow::Continue;
        }
        self.manifest.device_stopped = true;
        if !self.stop_sent {
            self.stop = StopReason::DeviceStopped;
        }
        // A live device has said its last; a recording is read to its end, so what
        // follows its final status is seen and counted.
        if self.live {
            Flow::Stop
        } else {
            Flow::Continue
        }
    }

    /// Places a tile in the strip (or counts why not) and reports the rate.
    fn on_tile(&mut self, tile: &protocol::Tile<'_>) -> anyhow::Result<()> {
        self.confirm_configuration(tile)?;
        if !take_tile(&mut self.strip, tile, &mut self.manifest)? {
            return Ok(());
        }
        if let Some(keeper) = &mut self.keeper {
            self.strip.land(keeper)?;
            keeper.defects(self.watch.defects())?;
        }
        self.watch.tile(tile, &self.manifest);
        let m = &self.manifest;
        let secs = self.started.elapsed().as_secs_f64().max(1e-9);
        self.progress.message(&format!(
            "{} tiles, {:.0} tiles/s, {:.2} MB/s",
            m.tiles_received,
            m.tiles_received as f64 / secs,
            m.bytes as f64 / secs / 1e6
        ));
        self.progress.advance_to(m.tiles_received);
        Ok(())
    }

    /// Takes messages until the session ends.
    fn receive_all(&mut self, link: &mut dyn Transport) -> anyhow::Result<()> {
        // Room beyond the largest message, so an oversized transfer arrives whole enough
        // to be counted as too long rather than failing the read.
        let mut buf = vec![0u8; 2 * MAX_MESSAGE];
        loop {
            self.steer(link)?;
            let flow = match self.receive(link, &mut buf)? {
                Next::Message(n) => self.take(&buf[..n])?,
                Next::Wait => Flow::Continue,
                Next::Over => Flow::Stop,
            };
            if flow == Flow::Stop {
                return Ok(());
            }
        }
    }

    /// A failed session's roll is recorded as failed, with `e`, its segments as they were
    /// recorded and the rows collected since as one more, where that can still be done; a
    /// failure to record the roll is added to `e`.
    fn fail_roll(&mut self, e: anyhow::Error) -> anyhow::Error {
        let Some(mut keeper) = self.keeper.take() else {
            return e;
        };
        // Best effort: what cannot be recorded now lands whole when the strip is dropped.
        let _ = self.strip.end_and_land(&mut keeper);
        let why = Status::Failed(format!("{e:#}"));
        match keeper.finish(&fault_counts(&self.manifest), &why) {
            Ok(()) => e,
            // Said after the error, not before it: the records' own failure is often the
            // same one (a full disk), and the roll shows as interrupted on the next open.
            Err(lost) => anyhow::anyhow!(
                "{e:#} (nor could the records mark the roll failed: {lost:#}; it shows as \
                 interrupted from the next start on)"
            ),
        }
    }

    /// A failed session keeps its recording, every message taken before the failure, so
    /// the device's data outlives what went wrong (replay it once that is fixed) — but
    /// only under a new name: it never replaces an older recording. Returns `e`, saying
    /// what became of the recording.
    fn keep_recording(&mut self, e: anyhow::Error) -> anyhow::Error {
        let (Some(r), Some(path)) = (self.recorder.take(), self.opts.record.as_deref()) else {
            return e;
        };
        let path = path.display();
        match r.keep_if_new() {
            Ok(true) => e.context(format!("the session failed; what it received is in {path}")),
            Ok(false) => e.context(format!("the session failed; {path} is left as it was")),
            Err(lost) => e.context(format!("the session failed, and its recording: {lost:#}")),
        }
    }

    /// Writes the strip's last tiles, its index and the manifest.
    fn close(mut self) -> anyhow::Result<Outcome> {
        self.progress.finish();
        if let Some(r) = self.recorder {
            r.finish()?;
        }
        self.manifest.tile_size = self.strip.size.map(|(w, t)| [w, t]);
        // A configuration no tile came under describes none of them.
        let configs = &mut self.manifest.configurations;
        if configs.last().is_some_and(|c| c.from_tile.is_none()) {
            configs.pop();
        }
        let segments = (self.strip).finish(&mut self.manifest, self.keeper.as_mut())?;
        write_manifest(&self.manifest_path, &self.manifest)?;
        let roll = match self.keeper.take() {
            Some(mut keeper) => {
                keeper.defects(self.watch.defects())?;
                let roll = keeper.roll();
                keeper.finish(&fault_counts(&self.manifest), &Status::Complete)?;
                Some(roll)
            }
            None => None,
        };
        let strip_files = segments.into_iter().map(|s| s.file).collect();
        Ok(Outcome {
            manifest: self.manifest,
            roll,
            strip_files,
            stop: self.stop,
            elapsed: self.started.elapsed(),
        })
    }
}

/// Runs a session on `link`, writing to `opts.out`. `progress` counts the tiles placed
/// and is told of every message lost or refused and of the device's log lines.
pub fn run(
    link: &mut dyn Transport,
    opts: &Options,
    progress: &dyn Progress,
) -> anyhow::Result<Outcome> {
    run_watched(link, opts, progress, &mut Unwatched)
}

/// [`run`], telling `watch` of every tile and message as it is taken, and sending the
/// commands it gives to a live device.
pub fn run_watched(
    link: &mut dyn Transport,
    opts: &Options,
    progress: &dyn Progress,
    watch: &mut dyn Watch,
) -> anyhow::Result<Outcome> {
    let mut session = Session::open(link, opts, progress, watch)?;
    match session.receive_all(link) {
        Ok(()) => session.close(),
        Err(e) => {
            let e = session.fail_roll(e);
            Err(session.keep_recording(e))
        }
    }
}

/// The faults of a session as the records count them: the refused messages and link
/// faults by kind, and the tiles lost.
fn fault_counts(m: &StreamRecord) -> Vec<(&'static str, u64)> {
    let f = &m.faults;
    let lost: u64 = m.gaps.iter().map(|[a, b]| u64::from(b - a) + 1).sum();
    vec![
        ("bad_crc", f.bad_crc),
        ("truncated", f.truncated),
        ("too_long", f.too_long),
        ("wrong_version", f.wrong_version),
        ("malformed", f.malformed),
        ("over_limit", f.over_limit),
        ("sequence_gaps", f.sequence_gaps),
        ("messages_missing", f.messages_missing),
        ("repeated", f.repeated),
        ("far_ahead", f.far_ahead),
        ("renumbered", f.renumbered),
        ("duplicate_tiles", f.duplicate_tiles),
        ("late_tiles", f.late_tiles),
        ("mismatched_tiles", f.mismatched_tiles),
        ("after_final_status", f.after_final_status),
        ("tiles_lost", lost),
    ]
}

fn write_manifest(path: &Path, manifest: &StreamRecord) -> anyhow::Result<()> {
    Ok(crate::files::write_bytes_atomic(
        path,
        manifest.to_json()?.as_bytes(),
    )?)
}
