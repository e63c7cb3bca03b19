//! `rollfuse stream` and `rollfuse devices`: fused tiles from the edge module (or the
//! virtual device, or a recording) into a strip.

use super::WaveletArg;
use crate::link::Transport;
use crate::link::replay::Replay;
use crate::link::sim::{DeviceMemory, SimDevice};
use crate::link::usb::{self, Usb};
use crate::serve;
use crate::sim::Scene;
use crate::stream::{self, Options, StopReason};
use anyhow::{Context, bail, ensure};
use rollfuse_core::protocol::{DeviceConfig, NormMode, WaveletId};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// `--norm`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum NormArg {
    /// Saliency normalized by each tile's own maximum.
    PerTile,
    /// By the maximum over the rows of the frame its tiles come from.
    PerFrame,
}

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
    #[arg(long, value_enum, default_value_t = WaveletArg::from(DeviceConfig::default().wavelet))]
    pub wavelet: WaveletArg,
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
    #[arg(long, value_enum, default_value_t = NormArg::from(DeviceConfig::default().norm))]
    pub norm: NormArg,
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
}

impl From<NormMode> for NormArg {
    fn from(n: NormMode) -> Self {
        match n {
            NormMode::PerTile => NormArg::PerTile,
            NormMode::PerFrame => NormArg::PerFrame,
        }
    }
}

impl Args {
    fn config(&self, spacing_default: u16) -> DeviceConfig {
        DeviceConfig {
            wavelet: match self.wavelet {
                WaveletArg::Haar => WaveletId::Haar,
                WaveletArg::Db2 => WaveletId::Db2,
            },
            levels: self.levels,
            downsample: self.downsample,
            tile_rows: self.tile_rows,
            frames_per_tile: self.frames_per_tile,
            frame_spacing_px: self.spacing_px.unwrap_or(spacing_default),
            refine_rows: self.refine_rows,
            norm: match self.norm {
                NormArg::PerTile => NormMode::PerTile,
                NormArg::PerFrame => NormMode::PerFrame,
            },
        }
    }
}

/// A session ready to run: its link, options and the address to serve on.
pub struct Opened {
    /// The device, virtual device or recording.
    pub link: Box<dyn Transport>,
    /// The session's options.
    pub opts: Options,
    /// `--serve`'s address.
    pub serve: Option<std::net::SocketAddr>,
    /// The output folder, removed again if the session writes nothing to it.
    pub folder: crate::files::NewFolder,
}

/// Checks every option of `args` (and that no output is an input), makes the output
/// folder and opens the link: what `rollfuse stream` runs, and the Python package's
/// `rollfuse.stream`.
pub fn open(args: &Args) -> anyhow::Result<Opened> {
    let checked = check(args)?;
    let folder = crate::files::NewFolder::create(&args.out)?;
    super::check_writable(&args.out.join("manifest.json"))?;
    if let Some(r) = &args.record {
        super::check_writable(r)?;
    }
    let (link, config) = open_link(args, &checked)?;
    let opts = Options {
        out: args.out.clone(),
        config,
        max_tiles: args.tiles,
        max_duration: checked.max_duration,
        record: args.record.clone(),
    };
    Ok(Opened {
        link,
        opts,
        serve: checked.serve,
        folder,
    })
}

/// Runs `rollfuse stream`, showing progress as `show` says.
pub fn run(args: Args, show: super::bars::Show) -> anyhow::Result<()> {
    // Every option checked, and no output an input, before the output folder is made.
    let Opened {
        mut link,
        opts,
        serve,
        folder: _folder,
    } = open(&args)?;
    let server = serve
        .map(|addr| start_server(&args, addr, link.is_live()))
        .transpose()?;
    let bars = super::bars::Bars::new(show);
    let outcome = match &server {
        Some(server) => {
            let outcome = stream::run_watched(link.as_mut(), &opts, &bars, &mut server.watcher())?;
            server.finish(&outcome.manifest);
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
            (crate::detect::anomaly::KIND, n) => format!("{n} anomalies"),
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
            Some(crate::detect::UNKNOWN_FABRIC) => format!(
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
        return crate::detect::Detector::load_or_built_in(args.model.as_deref())
            .map(|d| LiveModel::Defects(Box::new(d)));
    };
    let model = crate::detect::anomaly::NormalModel::load(path)?;
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

/// What the options say, once checked.
struct Checked {
    /// `--device replay:FILE`'s file.
    replay: Option<std::path::PathBuf>,
    /// `--seconds`.
    max_duration: Option<Duration>,
    /// `--serve`.
    serve: Option<std::net::SocketAddr>,
    /// `--frame-rate`, as the time between frames.
    frame_period: Option<Duration>,
}

/// Checks the options and that the recording written is none of the inputs.
fn check(args: &Args) -> anyhow::Result<Checked> {
    if let Some(s) = args.seconds
        && !(s > 0.0 && s.is_finite())
    {
        bail!("--seconds must be a positive number, got {s}");
    }
    if args.tiles == Some(0) {
        bail!("--tiles must be at least 1");
    }
    let max_duration = args
        .seconds
        .map(Duration::try_from_secs_f64)
        .transpose()
        .map_err(|_| anyhow::anyhow!("--seconds is too long: {:?}", args.seconds))?;
    let replay = match args.device.as_str() {
        "usb" | "sim" => None,
        other => match other.strip_prefix("replay:") {
            Some(file) if !file.is_empty() => Some(std::path::PathBuf::from(file)),
            _ => bail!("--device must be usb, sim or replay:FILE, got `{other}`"),
        },
    };
    if args.device == "sim" && args.scene.is_none() {
        bail!("--device sim needs --scene SCENE.toml (e.g. host/scenes/letters.toml)");
    }
    if args.unbounded_memory && args.device != "sim" {
        bail!("--unbounded-memory is for the virtual device (--device sim) only");
    }
    let frame_period = args.frame_rate.map(frame_period).transpose()?;
    if frame_period.is_some() && args.device != "sim" {
        bail!("--frame-rate is for the virtual device (--device sim) only");
    }
    let serve = args.serve.as_deref().map(serve::parse_addr).transpose()?;
    refuse_overwriting_inputs(args, replay.as_deref())?;
    Ok(Checked {
        replay,
        max_duration,
        serve,
        frame_period,
    })
}

/// Refuses, before the session, a run that would overwrite what it reads or records: the
/// recording (`--record`) or an input (the replayed recording, the scene, the model)
/// where the session writes its strip, its segments, its index or its manifest, or the
/// recording over an input.
fn refuse_overwriting_inputs(args: &Args, replay: Option<&Path>) -> anyhow::Result<()> {
    let mut inputs: Vec<(&str, &Path)> = Vec::new();
    inputs.extend(replay.map(|p| ("recording replayed", p)));
    inputs.extend(args.scene.as_deref().map(|p| ("scene", p)));
    inputs.extend(args.model.as_deref().map(|p| ("model", p)));
    inputs.extend(args.normal.as_deref().map(|p| ("normal model", p)));
    let session = stream::output_files(&args.out);
    let outputs: Vec<&Path> = session.iter().map(PathBuf::as_path).collect();
    crate::files::refuse_overwriting(&outputs, &inputs)?;
    let strip = &session[0];
    crate::strip_file::refuse_segment_names(strip, &inputs)?;
    if let Some(r) = args.record.as_deref() {
        crate::files::refuse_overwriting(&[r], &inputs)?;
        let at = crate::files::resolved(r);
        let session_writes = outputs.iter().any(|o| crate::files::resolved(o) == at)
            || crate::strip_file::is_segment_name(strip, r);
        ensure!(
            !session_writes,
            "--record {} is where the session writes its strip, index or manifest: record \
             to another file",
            r.display()
        );
    }
    Ok(())
}

/// `--frame-rate`'s period: a rate from 0.01 to 10 000 frames a second.
fn frame_period(rate: f64) -> anyhow::Result<Duration> {
    if !(0.01..=10_000.0).contains(&rate) {
        bail!("--frame-rate must be from 0.01 to 10000 frames a second, got {rate}");
    }
    Ok(Duration::from_secs_f64(1.0 / rate))
}

/// The link the options name, and the configuration to send (none to a recording).
fn open_link(
    args: &Args,
    checked: &Checked,
) -> anyhow::Result<(Box<dyn Transport>, Option<DeviceConfig>)> {
    Ok(match checked.replay.as_deref() {
        Some(file) => (Box::new(Replay::open(file)?), None),
        None if args.device == "usb" => (
            Box::new(Usb::open()?),
            Some(args.config(DeviceConfig::default().frame_spacing_px)),
        ),
        None => {
            let path = args.scene.as_ref().context("--device sim needs --scene")?;
            let memory = if args.unbounded_memory {
                DeviceMemory::Unbounded
            } else {
                DeviceMemory::Firmware
            };
            let dev = SimDevice::start_paced(&Scene::load(path)?, memory, checked.frame_period)?;
            let spacing = dev.default_config().frame_spacing_px;
            (Box::new(dev), Some(args.config(spacing)))
        }
    })
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
