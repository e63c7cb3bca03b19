//! `rollfuse stream` and `rollfuse devices`: fused tiles from the edge module (or the
//! virtual device, or a recording) into a strip.

use super::named;
use anyhow::bail;
use rollfuse::link::usb;
use rollfuse::names::Named;
use rollfuse::serve;
use rollfuse::session::{self, Fusion, Opened, Request};
use rollfuse::stream::{self, StopReason};
use rollfuse_core::protocol::{DeviceConfig, NormMode, WaveletId};
use std::path::PathBuf;

/// Arguments of `rollfuse stream`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Where tiles come from: `usb`, `sim` (the virtual device, with --scene) or
    /// `replay:FILE` (a recording made with --record).
    #[arg(long)]
    pub device: String,
    /// With --device sim: the scene the virtual device's camera sees.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Output folder: the strip (strip.png, or segments strip.NNNN.png with strip.json)
    /// and manifest.json.
    #[arg(long)]
    pub out: PathBuf,
    /// Record every received message to this file (for --device replay:FILE).
    #[arg(long)]
    pub record: Option<PathBuf>,
    /// Stop after this many tiles (the device's last tiles in fusion still arrive).
    #[arg(long, conflicts_with = "seconds")]
    pub tiles: Option<u64>,
    /// Stop after this many seconds.
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Wavelet the device fuses with (default: the module's, db2).
    #[arg(long, value_parser = named::<WaveletId>(), default_value = DeviceConfig::default().wavelet.name())]
    pub wavelet: WaveletId,
    /// Decomposition levels, 1..=4 (default: the module's).
    #[arg(long, default_value_t = DeviceConfig::default().levels)]
    pub levels: u8,
    /// Box downsampling of camera frames: 1, 2 or 4 (default: the module's, 1: the
    /// camera's full resolution).
    #[arg(long, default_value_t = DeviceConfig::default().downsample)]
    pub downsample: u8,
    /// Tile height along the belt, downsampled rows.
    #[arg(long, default_value_t = DeviceConfig::default().tile_rows)]
    pub tile_rows: u16,
    /// Frames fused into each tile.
    #[arg(long, default_value_t = DeviceConfig::default().frames_per_tile)]
    pub frames_per_tile: u8,
    /// Belt travel between frames, camera pixels (default: the scene's, or the module's
    /// on USB).
    #[arg(long)]
    pub spacing_px: Option<u16>,
    /// Offset refinement search, ± downsampled rows (0 trusts the motion).
    #[arg(long, default_value_t = DeviceConfig::default().refine_rows)]
    pub refine_rows: u8,
    /// Saliency normalization.
    #[arg(long, value_parser = named::<NormMode>(), default_value = DeviceConfig::default().norm.name())]
    pub norm: NormMode,
    /// With --device sim: give the virtual device as much pipeline memory as the
    /// configuration needs, for host-only studies (by default it has the module's, and
    /// refuses what the module refuses).
    #[arg(long)]
    pub unbounded_memory: bool,
    /// With --device sim: capture at most this many frames a second in real time, as
    /// the camera would (by default the virtual device runs in virtual time, as fast as
    /// the host reads). For live views and demos; the tiles are the same.
    #[arg(long)]
    pub frame_rate: Option<f64>,
    /// Serve a live page of the strip, its status and its events on this address while
    /// streaming (e.g. 127.0.0.1:8080; docs/serve.md).
    #[arg(long, value_name = "ADDR")]
    pub serve: Option<String>,
    /// With --serve: take commands for the device (start/stop the roller) from requests
    /// that carry the token printed at start-up.
    #[arg(long, requires = "serve")]
    pub control: bool,
    /// With --control on an address other machines can reach: accept that the token
    /// travels over plain HTTP, readable by anyone on the network path.
    #[arg(long, requires = "control")]
    pub allow_remote_control: bool,
    /// With --serve: a host name the page may be reached by, beside IP addresses and
    /// `localhost` (repeatable); requests naming any other host get 421.
    #[arg(long, value_name = "NAME", requires = "serve")]
    pub allow_host: Vec<String>,
    /// With --serve: run the defect detector over the strip as it grows and draw its boxes
    /// on the page (at the camera's scale: the strip is upsampled by the device's
    /// downsampling first).
    #[arg(long, requires = "serve")]
    pub detect: bool,
    /// With --detect: the detector's model (default: the one built into the tool).
    #[arg(long, requires = "detect")]
    pub model: Option<PathBuf>,
    /// With --detect: anomaly mode instead of the detector, with this model of one fabric
    /// (`rollfuse fit-normal --every-row-alike` on strips or fused tiles of the camera's
    /// scale); regions are drawn as kind `anomaly`.
    #[arg(
        long,
        value_name = "MODEL",
        requires = "detect",
        conflicts_with = "model"
    )]
    pub normal: Option<PathBuf>,
    /// With --serve: once the stream has ended and its files are written, keep the page
    /// up (the strip, the status, the detector's boxes) until interrupted (Ctrl-C).
    #[arg(long, requires = "serve")]
    pub keep_serving: bool,
    /// Most rows per strip segment (a longer strip is written as numbered segments).
    #[arg(long, default_value_t = rollfuse::strip_file::DEFAULT_SEGMENT_ROWS)]
    pub segment_rows: usize,
    /// Where the roll is kept in the inspection records: each segment as soon as it is
    /// whole on disk.
    #[command(flatten)]
    pub record_to: super::rolls::RecordTo,
    /// With --records: belt millimetres a camera pixel, the roll's scale (with --device
    /// sim, default the scene's).
    #[arg(long, requires = "records")]
    pub mm_per_px: Option<f64>,
}

impl Args {
    /// The session the options ask for.
    fn request(&self) -> Request {
        let other_inputs = [("model", &self.model), ("normal model", &self.normal)]
            .into_iter()
            .filter_map(|(what, p)| Some((what, p.clone()?)))
            .collect();
        Request {
            device: self.device.clone(),
            scene: self.scene.clone(),
            out: self.out.clone(),
            record: self.record.clone(),
            tiles: self.tiles,
            seconds: self.seconds,
            fusion: Fusion {
                wavelet: self.wavelet,
                levels: self.levels,
                downsample: self.downsample,
                tile_rows: self.tile_rows,
                frames_per_tile: self.frames_per_tile,
                spacing_px: self.spacing_px,
                refine_rows: self.refine_rows,
                norm: self.norm,
            },
            unbounded_memory: self.unbounded_memory,
            frame_rate: self.frame_rate,
            serve: self.serve.clone(),
            other_inputs,
            segment_rows: self.segment_rows,
            records: self
                .record_to
                .records
                .clone()
                .map(|records| session::RecordsRequest {
                    records,
                    line: self.record_to.line.clone(),
                    mm_per_px: self.mm_per_px,
                }),
        }
    }
}

/// Runs `rollfuse stream`, showing progress as `show` says.
pub fn run(args: Args, show: super::bars::Show) -> anyhow::Result<()> {
    // Every option checked, and no output an input, before the output folder is made.
    let Opened {
        mut link,
        opts,
        serve,
        folder: _folder,
    } = session::open(&args.request())?;
    let server = serve
        .map(|addr| start_server(&args, addr, link.is_live()))
        .transpose()?;
    let bars = super::bars::Bars::new(show);
    let outcome = match &server {
        Some(server) => {
            let outcome = stream::run_watched(link.as_mut(), &opts, &bars, &mut server.watcher())?;
            server.finish(&outcome.manifest);
            // The detector's last windows are checked as the server finishes.
            if let (Some(roll), Some(target)) = (outcome.roll, &args.record_to.records) {
                let late = server.take_unrecorded_defects();
                rollfuse::records::record_late_defects(target, roll, late)?;
            }
            outcome
        }
        None => stream::run(link.as_mut(), &opts, &bars)?,
    };
    print_summary(&args.out, &outcome);
    if let Some(damage) = link.damage() {
        eprintln!("warning: the recording is damaged: {damage}");
    }
    if let Some(d) = server.as_ref().and_then(serve::Server::detector_status) {
        print_defects(&d);
    }
    if let Some(server) = server.filter(|_| args.keep_serving) {
        println!(
            "the stream has ended; the page stays up at http://{}/ until interrupted (Ctrl-C)",
            server.addr()
        );
        // Every output is written: an interrupt loses nothing.
        loop {
            std::thread::park();
        }
    }
    Ok(())
}

/// What the detector found on the strip.
fn print_defects(d: &serve::findings::DetectorStatus) {
    let kinds: Vec<String> = d
        .defects
        .iter()
        .map(|(k, n)| match (k.as_str(), *n) {
            (_, 1) => format!("1 {k}"),
            (rollfuse::detect::anomaly::KIND, n) => format!("{n} anomalies"),
            (_, n) => format!("{n} {k}s"),
        })
        .collect();
    if d.failures > 0 {
        eprintln!(
            "error: the detector failed on {} windows of the strip, whose rows were not checked: {}",
            d.failures,
            d.last_failure.as_deref().unwrap_or("no reason given")
        );
    }
    println!(
        "defects: {} on {} strip rows{}; fabric {}",
        match (kinds.is_empty(), d.failures) {
            (true, 0) => "none".to_string(),
            (true, _) => "none found, but not every row was checked".to_string(),
            (false, _) => kinds.join(", "),
        },
        d.rows_checked,
        if d.rows_skipped > 0 {
            format!(
                " ({} rows passed over: the detector fell behind)",
                d.rows_skipped
            )
        } else {
            String::new()
        },
        match d.fabric.as_deref() {
            None if d.anomaly_mode => "not named (anomaly mode)".to_string(),
            None => "not known".to_string(),
            Some(rollfuse::detect::UNKNOWN_FABRIC) => format!(
                "unknown ({} of {} rows unlike every fabric the model knows)",
                d.unknown_rows, d.rows_checked
            ),
            Some(f) => format!("{f} ({:.0} %)", 100.0 * d.probability),
        },
    );
}

/// The live page's detector: the defect detector, or anomaly mode with `--normal`, whose
/// model must score windows of any height.
fn live_model(args: &Args) -> anyhow::Result<serve::detect::LiveModel> {
    use serve::detect::LiveModel;
    let Some(path) = args.normal.as_deref() else {
        let detector = rollfuse::detect::Detector::load_or_built_in(args.model.as_deref())?;
        return Ok(LiveModel::Defects(Box::new(detector)));
    };
    let model = rollfuse::detect::anomaly::NormalModel::load(path)?;
    anyhow::ensure!(
        model.any_height(),
        "{} learned each row of {}-row images apart; the live strip is checked in windows \
         of other heights: fit it with `rollfuse fit-normal --every-row-alike`",
        path.display(),
        model.height
    );
    Ok(LiveModel::Normal(model))
}

fn start_server(
    args: &Args,
    addr: std::net::SocketAddr,
    live: bool,
) -> anyhow::Result<serve::Server> {
    if !addr.ip().is_loopback() {
        if args.control && !args.allow_remote_control {
            anyhow::bail!(
                "--control on {addr} would send the control token over plain HTTP to anyone on \
                 the network path: serve on a loopback address (127.0.0.1:PORT, reached from \
                 elsewhere through an SSH tunnel), or give --allow-remote-control to accept the risk"
            );
        }
        eprintln!(
            "warning: serving on {addr}, reachable from other machines: anyone who can reach it sees the strip{}",
            if args.control {
                " and can read the control token on the wire"
            } else {
                ""
            }
        );
    }
    let source = match args.device.as_str() {
        "usb" | "sim" => args.device.clone(),
        _ => "replay".to_string(),
    };
    let detector = args.detect.then(|| live_model(args)).transpose()?;
    let options = serve::ServeOptions {
        addr,
        control: args.control,
        source,
        live,
        allowed_hosts: args.allow_host.clone(),
        records: args.record_to.records.clone().map(|records| {
            let strip = stream::output_files(&args.out)[0].clone();
            serve::records::RollView {
                records,
                line: args.record_to.line.clone(),
                strip: std::path::absolute(&strip).unwrap_or(strip),
            }
        }),
    };
    let server = serve::Server::start_detecting(&options, detector)?;
    println!("live page: http://{}/", server.addr());
    if let Some(token) = server.token() {
        println!(
            "control token: {token} (open http://{}/#token={token})",
            server.addr()
        );
    }
    Ok(server)
}

/// The session's summary: tiles and rate, the strip's files, why it stopped, the
/// device's counters, what was missing or faulty.
fn print_summary(out: &std::path::Path, outcome: &stream::Outcome) {
    let m = &outcome.manifest;
    let secs = outcome.elapsed.as_secs_f64().max(1e-9);
    let written = match outcome.strip_files.as_slice() {
        [] => "no strip (no tile was taken)".to_string(),
        [one] => out.join(one).display().to_string(),
        [first, .., last] => format!(
            "{} … {} ({} segments, index strip.json)",
            out.join(first).display(),
            last,
            outcome.strip_files.len()
        ),
    };
    println!(
        "{} tiles in {:.2} s ({:.0} tiles/s, {:.3} MB/s) → {written}",
        m.tiles_received,
        secs,
        m.tiles_received as f64 / secs,
        m.bytes as f64 / secs / 1e6,
    );
    for c in &m.configurations {
        let from = c
            .from_tile
            .map_or(String::new(), |t| format!(" from tile {t}"));
        println!(
            "configuration{from}: {}",
            stream::describe(&c.config, c.tile_size)
        );
    }
    if m.tiles_received > 0 && m.configurations.is_empty() {
        println!(
            "configuration: unknown (none the device reported makes tiles of the size received)"
        );
    }
    match outcome.stop {
        StopReason::TileLimit => println!("stopped at --tiles"),
        StopReason::TimeLimit => println!("stopped at --seconds"),
        StopReason::DeviceStopped => println!("the device ended the stream"),
        StopReason::LinkClosed => println!("the link closed before the device ended the stream"),
        StopReason::Silent => println!(
            "the device was silent for {} s: stopped",
            stream::SILENCE_LIMIT.as_secs()
        ),
    }
    if let Some(c) = &m.device_counters {
        println!(
            "device: {} frames captured, {} fused, {} rejected, {} camera overruns, {} capture timeouts; {} tiles emitted, {} dropped",
            c.frames_captured,
            c.frames_fused,
            c.frames_rejected,
            c.camera_overruns,
            c.camera_timeouts,
            c.tiles_emitted,
            c.tiles_dropped
        );
        if c.fusion_cycles_worst > 0 {
            println!(
                "device: fusion took {} cycles a frame on average, {} at worst",
                c.fusion_cycles_mean, c.fusion_cycles_worst
            );
        }
        if !c.camera_ready {
            println!("device: the camera did not answer or refused its set-up at start-up");
        }
    }
    if !m.gaps.is_empty() {
        println!("missing tiles: {:?}", m.gaps);
    }
    if m.faults.total() > 0 {
        println!("link faults (details in manifest.json): {:?}", m.faults);
    }
}

/// Runs `rollfuse devices`: fails (non-zero exit) when none can be seen, saying why.
pub fn devices() -> anyhow::Result<()> {
    let (found, others) = usb::list()?;
    if found.is_empty() {
        bail!(
            "no rollfuse device ({:04x}:{:04x}) found; {others} other USB device(s) seen",
            usb::VID,
            usb::PID
        );
    }
    for d in found {
        println!(
            "bus {:03} address {:03}  serial {}",
            d.bus,
            d.address,
            d.serial.as_deref().unwrap_or("(unreadable)")
        );
    }
    Ok(())
}
