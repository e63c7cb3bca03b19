//! A streaming session: configure the device, receive its messages, check every one,
//! stitch the tiles into a strip, and account for everything that went wrong.
//!
//! Nothing is lost silently: every message that fails to decode is counted by kind, every
//! sequence gap is counted with the number of messages missing, every missing tile index
//! is listed, and the device's own counters (frames, tiles emitted, tiles dropped) are
//! kept from its last status. A stream cut off midway keeps every tile received.
//!
//! Outputs, in the session's folder: `strip.png` (rewritten every
//! [`STRIP_WRITE_INTERVAL`] while tiles arrive, and at the end; missing tiles are black
//! rows) and `manifest.json`. Both depend only on the messages received, so playing a
//! recording back ([`crate::link::replay`]) writes the same bytes. Timings are printed,
//! not written.

use crate::link::replay::Recorder;
use crate::link::{Received, Transport};
use anyhow::{Context, bail};
use rollfuse_core::protocol::{
    self, Command, DecodeError, DeviceConfig, DeviceInfo, DeviceMessage, MAX_MESSAGE, SeqEvent,
    SeqTracker, StatusCounters,
};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// How often the strip on disk is brought up to date while tiles arrive.
pub const STRIP_WRITE_INTERVAL: Duration = Duration::from_secs(2);

/// How long a live device may stay silent before the session gives up on it.
pub const SILENCE_LIMIT: Duration = Duration::from_secs(5);

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
    /// Show a progress bar.
    pub progress: bool,
}

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
    /// Tiles whose index had already been received (the first copy is kept).
    pub duplicate_tiles: u64,
    /// Tiles of another width or height than the first (not placed).
    pub mismatched_tiles: u64,
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
            + self.mismatched_tiles
    }
}

/// What `manifest.json` holds.
#[derive(Debug, Default, Clone, Serialize)]
pub struct Manifest {
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
    /// The device, from its reply to hello.
    pub device: Option<DeviceInfo>,
    /// The device's counters from its last status.
    pub device_counters: Option<StatusCounters>,
    /// Commands the device refused.
    pub refused: Vec<String>,
    /// The device's log lines.
    pub log: Vec<String>,
    /// Whether the device said it stopped streaming (otherwise the link ended first).
    pub device_stopped: bool,
}

/// The tiles received, by index.
#[derive(Default)]
struct StripTiles {
    size: Option<(u16, u16)>,
    tiles: BTreeMap<u32, Vec<u8>>,
}

impl StripTiles {
    /// Writes the strip: rows from the first to the last index, missing tiles black.
    fn write(&self, path: &Path) -> anyhow::Result<()> {
        let (Some((w, t)), Some((&first, _)), Some((&last, _))) = (
            self.size,
            self.tiles.first_key_value(),
            self.tiles.last_key_value(),
        ) else {
            return Ok(());
        };
        let tile_bytes = usize::from(w) * usize::from(t);
        let count = (last - first) as usize + 1;
        let mut pixels = vec![0u8; count * tile_bytes];
        for (&index, tile) in &self.tiles {
            let at = (index - first) as usize * tile_bytes;
            pixels[at..at + tile_bytes].copy_from_slice(tile);
        }
        let img = image::GrayImage::from_raw(u32::from(w), (count * usize::from(t)) as u32, pixels)
            .context("strip buffer does not match its size")?;
        // Written aside and renamed, so a reader never sees half a file.
        let tmp = path.with_extension("png.part");
        img.save_with_format(&tmp, image::ImageFormat::Png)
            .with_context(|| format!("cannot write {}", tmp.display()))?;
        std::fs::rename(&tmp, path).with_context(|| format!("cannot write {}", path.display()))
    }
}

/// Missing indices between the first and last present, as inclusive ranges.
fn gaps(indices: impl Iterator<Item = u32>) -> Vec<[u32; 2]> {
    let mut out = Vec::new();
    let mut prev: Option<u32> = None;
    for i in indices {
        if let Some(p) = prev
            && i > p + 1
        {
            out.push([p + 1, i - 1]);
        }
        prev = Some(i);
    }
    out
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
    pub manifest: Manifest,
    /// Why it stopped.
    pub stop: StopReason,
    /// Wall time of the session.
    pub elapsed: Duration,
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

/// Runs a session on `link`, writing to `opts.out`.
pub fn run(link: &mut dyn Transport, opts: &Options) -> anyhow::Result<Outcome> {
    std::fs::create_dir_all(&opts.out)
        .with_context(|| format!("cannot create {}", opts.out.display()))?;
    let strip_path = opts.out.join("strip.png");
    let manifest_path = opts.out.join("manifest.json");
    let mut recorder = opts.record.as_deref().map(Recorder::create).transpose()?;
    let started = Instant::now();
    let live = link.is_live();

    let mut cmd_seq = 0u32;
    // Commands whose refusal ends the session.
    let mut essential = Vec::new();
    if live {
        send(link, &mut cmd_seq, &Command::Hello)?;
        if let Some(cfg) = opts.config {
            essential.push((
                send(link, &mut cmd_seq, &Command::Configure(cfg))?,
                "configure",
            ));
        }
        essential.push((
            send(link, &mut cmd_seq, &Command::StreamStart)?,
            "stream start",
        ));
    }

    let bar = if opts.progress {
        crate::commands::simulate::progress_spinner("receiving tiles")
    } else {
        indicatif::ProgressBar::hidden()
    };
    let mut manifest = Manifest::default();
    let mut strip = StripTiles::default();
    let mut seqs = SeqTracker::new();
    // Room beyond the largest message, so an oversized transfer arrives whole enough to
    // be counted as too long rather than failing the read.
    let mut buf = vec![0u8; 2 * MAX_MESSAGE];
    let mut last_message = Instant::now();
    let mut last_write = Instant::now();
    let mut stop_sent = false;
    let mut stop = StopReason::LinkClosed;
    loop {
        // Ask the device to stop once a limit is reached; its flush and status follow.
        if live && !stop_sent {
            let limit = if opts.max_tiles.is_some_and(|n| manifest.tiles_received >= n) {
                Some(StopReason::TileLimit)
            } else if opts.max_duration.is_some_and(|d| started.elapsed() >= d) {
                Some(StopReason::TimeLimit)
            } else {
                None
            };
            if let Some(reason) = limit {
                send(link, &mut cmd_seq, &Command::StreamStop)?;
                stop_sent = true;
                stop = reason;
            }
        }
        let n = match link.receive(&mut buf, Duration::from_millis(200))? {
            Received::Message(n) => n,
            Received::Timeout => {
                if last_message.elapsed() > SILENCE_LIMIT {
                    stop = StopReason::Silent;
                    break;
                }
                continue;
            }
            Received::Closed => {
                if !stop_sent {
                    stop = StopReason::LinkClosed;
                }
                break;
            }
        };
        last_message = Instant::now();
        let bytes = &buf[..n];
        if let Some(r) = recorder.as_mut() {
            r.record(bytes)?;
        }
        manifest.messages += 1;
        manifest.bytes += n as u64;
        let (header, msg) = match protocol::decode::<DeviceMessage>(bytes) {
            Ok(m) => m,
            Err(e) => {
                manifest.faults.count(e);
                bar.println(format!("refused a message: {e}"));
                continue;
            }
        };
        match seqs.observe(header.seq) {
            SeqEvent::InOrder => {}
            SeqEvent::Gap { missing } => {
                manifest.faults.sequence_gaps += 1;
                manifest.faults.messages_missing += u64::from(missing);
                bar.println(format!("{missing} message(s) lost before #{}", header.seq));
            }
            SeqEvent::Repeat => {
                manifest.faults.repeated += 1;
                continue;
            }
        }
        match msg {
            DeviceMessage::Info(info) => manifest.device = Some(info),
            DeviceMessage::Ack { .. } | DeviceMessage::RawChunk(_) => {}
            DeviceMessage::Nak {
                command_seq,
                reason,
            } => {
                let what = essential
                    .iter()
                    .find(|(s, _)| *s == command_seq)
                    .map(|(_, w)| *w);
                manifest.refused.push(format!(
                    "{} refused: {reason:?}",
                    what.unwrap_or("a command")
                ));
                if let Some(what) = what {
                    write_manifest(&manifest_path, &manifest)?;
                    bail!("the device refused {what}: {reason:?}");
                }
            }
            DeviceMessage::Status(c) => {
                manifest.device_counters = Some(c);
                if !c.streaming {
                    manifest.device_stopped = true;
                    if !stop_sent {
                        stop = StopReason::DeviceStopped;
                    }
                    break;
                }
            }
            DeviceMessage::Log(line) => {
                bar.println(format!("device: {line}"));
                manifest.log.push(line.to_string());
            }
            DeviceMessage::Tile(tile) => {
                let size = (tile.width, tile.height);
                if *strip.size.get_or_insert(size) != size {
                    manifest.faults.mismatched_tiles += 1;
                    continue;
                }
                if strip.tiles.contains_key(&tile.index) {
                    manifest.faults.duplicate_tiles += 1;
                    continue;
                }
                strip.tiles.insert(tile.index, tile.pixels.to_vec());
                *manifest.observations.entry(tile.observations).or_default() += 1;
                manifest.tiles_received += 1;
                let secs = started.elapsed().as_secs_f64().max(1e-9);
                bar.set_message(format!(
                    "{} tiles, {:.0} tiles/s, {:.2} MB/s",
                    manifest.tiles_received,
                    manifest.tiles_received as f64 / secs,
                    manifest.bytes as f64 / secs / 1e6
                ));
                bar.tick();
                if last_write.elapsed() >= STRIP_WRITE_INTERVAL {
                    strip.write(&strip_path)?;
                    last_write = Instant::now();
                }
            }
        }
    }
    bar.finish_and_clear();
    if let Some(r) = recorder {
        r.finish()?;
    }
    manifest.tile_size = strip.size.map(|(w, t)| [w, t]);
    manifest.index_range = strip
        .tiles
        .first_key_value()
        .zip(strip.tiles.last_key_value())
        .map(|((&a, _), (&b, _))| [a, b]);
    manifest.gaps = gaps(strip.tiles.keys().copied());
    strip.write(&strip_path)?;
    write_manifest(&manifest_path, &manifest)?;
    Ok(Outcome {
        manifest,
        stop,
        elapsed: started.elapsed(),
    })
}

fn write_manifest(path: &Path, manifest: &Manifest) -> anyhow::Result<()> {
    std::fs::write(path, serde_json::to_string_pretty(manifest)? + "\n")
        .with_context(|| format!("cannot write {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::gaps;

    #[test]
    fn gaps_are_inclusive_ranges_between_present_indices() {
        assert_eq!(gaps([3, 4, 7, 8, 10].into_iter()), vec![[5, 6], [9, 9]]);
        assert!(gaps([1, 2, 3].into_iter()).is_empty());
        assert!(gaps(std::iter::empty()).is_empty());
    }
}
