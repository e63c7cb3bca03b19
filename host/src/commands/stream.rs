//! `rollfuse stream` and `rollfuse devices`: fused tiles from the edge module (or the
//! virtual device, or a recording) into a strip.

use super::WaveletArg;
use crate::link::Transport;
use crate::link::replay::Replay;
use crate::link::sim::{DeviceMemory, SimDevice};
use crate::link::usb::{self, Usb};
use crate::sim::Scene;
use crate::stream::{self, Options, StopReason};
use anyhow::{Context, bail};
use rollfuse_core::protocol::{DeviceConfig, NormMode, WaveletId};
use std::path::PathBuf;
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
    /// Wavelet the device fuses with.
    #[arg(long, value_enum, default_value = "db2")]
    pub wavelet: WaveletArg,
    /// Decomposition levels, 1..=4.
    #[arg(long, default_value_t = 2)]
    pub levels: u8,
    /// Box downsampling of camera frames: 1, 2 or 4.
    #[arg(long, default_value_t = 2)]
    pub downsample: u8,
    /// Tile height along the belt, downsampled rows.
    #[arg(long, default_value_t = 16)]
    pub tile_rows: u16,
    /// Frames fused into each tile.
    #[arg(long, default_value_t = 4)]
    pub frames_per_tile: u8,
    /// Belt travel between frames, camera pixels (default: the scene's, or 16 on USB).
    #[arg(long)]
    pub spacing_px: Option<u16>,
    /// Offset refinement search, ± downsampled rows (0 trusts the motion).
    #[arg(long, default_value_t = 2)]
    pub refine_rows: u8,
    /// Saliency normalization.
    #[arg(long, value_enum, default_value = "per-frame")]
    pub norm: NormArg,
    /// With --device sim: give the virtual device as much pipeline memory as the
    /// configuration needs, for host-only studies (by default it has the module's, and
    /// refuses what the module refuses).
    #[arg(long)]
    pub unbounded_memory: bool,
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

/// Runs `rollfuse stream`.
pub fn run(args: Args) -> anyhow::Result<()> {
    // Every option checked, and no output an input, before the output folder is made.
    let checked = check(&args)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create output folder {}", args.out.display()))?;
    super::check_writable(&args.out.join("manifest.json"))?;
    if let Some(r) = &args.record {
        super::check_writable(r)?;
    }
    let (mut link, config) = open_link(&args, checked.replay.as_deref())?;
    let opts = Options {
        out: args.out.clone(),
        config,
        max_tiles: args.tiles,
        max_duration: checked.max_duration,
        record: args.record.clone(),
    };
    let outcome = stream::run(link.as_mut(), &opts, &super::bars::Bars::new())?;
    print_summary(&args.out, &outcome);
    Ok(())
}

/// What the options say, once checked.
struct Checked {
    /// `--device replay:FILE`'s file.
    replay: Option<std::path::PathBuf>,
    /// `--seconds`.
    max_duration: Option<Duration>,
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
    if let Some(r) = &args.record {
        let mut inputs: Vec<(&str, &std::path::Path)> = Vec::new();
        inputs.extend(replay.as_deref().map(|p| ("recording replayed", p)));
        inputs.extend(args.scene.as_deref().map(|p| ("scene", p)));
        crate::files::refuse_overwriting(&[r], &inputs)?;
    }
    Ok(Checked {
        replay,
        max_duration,
    })
}

/// The link the options name, and the configuration to send (none to a recording).
fn open_link(
    args: &Args,
    replay: Option<&std::path::Path>,
) -> anyhow::Result<(Box<dyn Transport>, Option<DeviceConfig>)> {
    Ok(match replay {
        Some(file) => (Box::new(Replay::open(file)?), None),
        None if args.device == "usb" => (Box::new(Usb::open()?), Some(args.config(16))),
        None => {
            let path = args.scene.as_ref().context("--device sim needs --scene")?;
            let memory = if args.unbounded_memory {
                DeviceMemory::Unbounded
            } else {
                DeviceMemory::Firmware
            };
            let dev = SimDevice::start_with(&Scene::load(path)?, memory)?;
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
